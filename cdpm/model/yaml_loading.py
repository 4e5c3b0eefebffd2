"""YAML read as data only, with the keys YAML would silently drop reported.

Cable specs are read with a :class:`yaml.SafeLoader` (nothing in the file is
executed). PyYAML keeps the last of two equal keys in a mapping without a
word, and reads a number too large for a float (``1.0e+400``) as infinity;
:func:`load_yaml` lists both, and integers too long to be a number
(Python refuses to read one of more than 4,300 digits), so the spec loader
can refuse the file. YAML 1.1 reads ``190:20:30`` as the base-60 number
685230; here it is read as written, the string ``"190:20:30"`` (as YAML 1.2
does), so a number field holding it is refused as not a number.
Before anything is built, the parser's event stream (read without
recursion) is checked against size limits: the text's length, the nesting
depth (with aliases expanded: a chain of aliases nests as deep as it would
when written out), and the number of values after aliases (``*anchor``) are
expanded, so a small file that expands to millions of values (an "alias
bomb") or nests thousands deep is refused at once with a clear message.
PyYAML is imported on first use, so ``import cdpm`` stays fast.

Texts are read with libyaml's parser when PyYAML has it (about fifty times
faster than PyYAML's own, which makes a spec load cost a millisecond, not
ten); a text libyaml refuses is read again with PyYAML's own parser, whose
error shows the offending line, so errors read the same either way.
"""

from __future__ import annotations

import math
import re
import sys
from typing import Any

__all__ = ["load_yaml", "YamlLimitError", "MAX_YAML_CHARS", "MAX_YAML_DEPTH", "MAX_YAML_VALUES"]

#: longest YAML text read [characters]; shipped specs are a few kB
MAX_YAML_CHARS = 10_000_000

#: deepest nesting of mappings and sequences
MAX_YAML_DEPTH = 64

#: most values (scalars, mappings, sequences) a document may hold once its
#: aliases are expanded
MAX_YAML_VALUES = 100_000


class YamlLimitError(ValueError):
    """A YAML text exceeds one of the size limits (the message says which)."""


#: literals that mean infinity (YAML's .inf; inf and infinity under an
#: explicit !!float tag)
_INFINITY = frozenset({".inf", "inf", "infinity"})

#: YAML 1.1's base-60 integers and floats (``190:20:30``, ``1:30.5``), read
#: here as the strings they are written as
_SEXAGESIMAL = re.compile(r"^[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+(?:\.[0-9_]*)?$")


def _safe_loader(fast: bool):
    """libyaml's safe loader when ``fast`` and PyYAML was built with it,
    else PyYAML's pure-Python one (the same constructors and resolvers)."""
    # yaml: loaded on first use
    import yaml

    if fast and getattr(yaml, "__with_libyaml__", False):
        return yaml.CSafeLoader
    return yaml.SafeLoader


def check_yaml_limits(text: str, fast: bool = True) -> None:
    """Refuse YAML that is too long, too deep or expands too far.

    Args:
        text: the YAML text.
        fast: parse with libyaml when available (see the module's notes).

    Raises:
        YamlLimitError: naming the limit and the fix.
        yaml.YAMLError: the text is not valid YAML.
    """
    # yaml: loaded on first use
    import yaml

    if len(text) > MAX_YAML_CHARS:
        raise YamlLimitError(
            f"the file has {len(text):,} characters, more than the {MAX_YAML_CHARS:,} a "
            "spec may have; a cable spec is a few kilobytes"
        )
    sizes: dict[str, int] = {}  # anchor -> values under it, aliases expanded
    heights: dict[str, int] = {}  # anchor -> levels of nesting under it, aliases expanded
    stack: list[list] = []  # open collections: [values so far, anchor, levels under it]
    total = 0
    for event in yaml.parse(text, Loader=_safe_loader(fast)):
        if isinstance(event, yaml.CollectionStartEvent):
            height = 1
        elif isinstance(event, yaml.AliasEvent):
            height = heights.get(event.anchor, 0)
        else:
            height = 0
        if len(stack) + height > MAX_YAML_DEPTH:
            line = event.start_mark.line + 1
            through = " once its aliases (*name) are expanded" if height > 1 else ""
            raise YamlLimitError(
                f"line {line}: mappings and lists nest more than {MAX_YAML_DEPTH} deep"
                f"{through}; a cable spec needs a handful of levels"
            )
        if isinstance(event, yaml.CollectionStartEvent):
            stack.append([1, event.anchor, 1])
            continue
        if isinstance(event, yaml.CollectionEndEvent):
            size, anchor, height = stack.pop()
        elif isinstance(event, yaml.ScalarEvent):
            size, anchor = 1, event.anchor
        elif isinstance(event, yaml.AliasEvent):
            size, anchor = sizes.get(event.anchor, 1), None
        else:
            continue
        if anchor is not None:
            sizes[anchor] = size
            heights[anchor] = height
        if stack:
            stack[-1][0] += size
            stack[-1][2] = max(stack[-1][2], height + 1)
        else:
            total += size
        if total + sum(entry[0] for entry in stack) > MAX_YAML_VALUES:
            line = event.start_mark.line + 1
            raise YamlLimitError(
                f"line {line}: the document expands to more than {MAX_YAML_VALUES:,} values "
                "through its aliases (*name); write the values out or use fewer aliases"
            )


def load_yaml(text: str) -> tuple[Any, list[str]]:
    """``yaml.safe_load`` that also lists keys given twice in one mapping
    and numbers that overflow to infinity.

    YAML parsers keep the last of two equal keys without a word, so a spec
    with ``cables:`` twice would silently lose the first list. Merge keys
    (``<<: *anchor``) may still be overridden, as YAML intends.

    Returns:
        (data, problems): the loaded document and one line per repeated key
        (with its line numbers, 1-based) or overflowing number (a finite
        literal such as ``1.0e+400``, which YAML reads as infinity; ``.inf``
        is infinity as meant), in line order.

    Raises:
        YamlLimitError: the text exceeds a size limit (:func:`check_yaml_limits`).
        yaml.YAMLError: the text is not valid YAML (PyYAML's own parser's
            error, with the offending line shown).
    """
    # yaml: loaded on first use
    import yaml

    try:
        return _load_yaml(text, fast=True)
    except yaml.YAMLError:
        return _load_yaml(text, fast=False)


def _load_yaml(text: str, fast: bool) -> tuple[Any, list[str]]:
    # yaml: loaded on first use
    import yaml

    check_yaml_limits(text, fast)
    base = _safe_loader(fast)

    problems: list[tuple[int, str]] = []

    class _Loader(base):
        pass

    # YAML 1.1's base-60 numbers are read as the strings they are written as:
    # a resolver ahead of the int and float ones claims them for str
    resolvers = {first: list(rules) for first, rules in base.yaml_implicit_resolvers.items()}
    for first in "+-0123456789":
        resolvers.setdefault(first, []).insert(0, ("tag:yaml.org,2002:str", _SEXAGESIMAL))
    _Loader.yaml_implicit_resolvers = resolvers

    def construct_mapping(loader, node, deep=False):
        first_line: dict[Any, int] = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = loader.construct_object(key_node, deep=True)
            try:
                seen = first_line.get(key)
            except TypeError:  # an unhashable key: safe_load reports it
                continue
            line = key_node.start_mark.line + 1
            if seen is None:
                first_line[key] = line
            else:
                problems.append(
                    (
                        line,
                        f"line {line}: key {key!r} is given twice in the same mapping (first on "
                        f"line {seen}); YAML would keep only the last one: remove or merge one",
                    )
                )
        return base.construct_mapping(loader, node, deep=deep)

    def construct_float(loader, node):
        # YAML reads 1.0e+400 as infinity without a word: only .inf means it
        value = base.construct_yaml_float(loader, node)
        if math.isinf(value) and node.value.lstrip("+-").lower() not in _INFINITY:
            line = node.start_mark.line + 1
            problems.append(
                (
                    line,
                    f"line {line}: {node.value} is too large for a number (beyond about "
                    "1.8e308) and would be read as infinity: write a finite number, or .inf "
                    "where no bound is meant",
                )
            )
        return value

    def construct_int(loader, node):
        # Python refuses to read an integer of more than 4,300 digits (a
        # ValueError); one beyond float range would fail later, when used
        try:
            value = base.construct_yaml_int(loader, node)
        except ValueError:
            value = None
        if value is None or abs(value) > sys.float_info.max:
            line = node.start_mark.line + 1
            digits = node.value.lstrip("+-").replace("_", "")
            if digits[:2].lower() in ("0b", "0o", "0x"):
                digits = digits[2:]
            problems.append(
                (
                    line,
                    f"line {line}: an integer of {len(digits):,} digits is too large for a number "
                    "(beyond about 1.8e308): write a number of at most a few dozen digits",
                )
            )
            return 0
        return value

    _Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, construct_mapping)
    _Loader.add_constructor("tag:yaml.org,2002:int", construct_int)
    _Loader.add_constructor("tag:yaml.org,2002:float", construct_float)
    data = yaml.load(text, Loader=_Loader)  # noqa: S506 - a SafeLoader subclass
    return data, [message for _, message in sorted(problems)]
