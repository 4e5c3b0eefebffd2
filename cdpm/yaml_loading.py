"""YAML read as data only, with the keys YAML would silently drop reported.

Cable specs are read with a :class:`yaml.SafeLoader` (nothing in the file is
executed). PyYAML keeps the last of two equal keys in a mapping without a
word; :func:`load_yaml` lists them so the spec loader can refuse the file.
PyYAML is imported on first use, so ``import cdpm`` stays fast.
"""

from __future__ import annotations

from typing import Any

__all__ = ["load_yaml"]


def load_yaml(text: str) -> tuple[Any, list[str]]:
    """``yaml.safe_load`` that also lists keys given twice in one mapping.

    YAML parsers keep the last of two equal keys without a word, so a spec
    with ``cables:`` twice would silently lose the first list. Merge keys
    (``<<: *anchor``) may still be overridden, as YAML intends.

    Returns:
        (data, problems): the loaded document and one line per repeated key
        with its line numbers (1-based).
    """
    import yaml

    problems: list[tuple[int, str]] = []

    class _Loader(yaml.SafeLoader):
        pass

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
        return yaml.SafeLoader.construct_mapping(loader, node, deep=deep)

    _Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, construct_mapping)
    data = yaml.load(text, Loader=_Loader)  # noqa: S506 - a SafeLoader subclass
    return data, [message for _, message in sorted(problems)]
