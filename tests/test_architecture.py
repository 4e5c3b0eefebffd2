"""Architecture rules of the cdpm package, checked on its source.

- The import contracts of pyproject.toml hold (``lint-imports``): layers
  point down from the command line to the shared vocabulary, the analysis
  imports neither Pinocchio nor another cdpm package, no package imports
  another's private module, no cycles among the modules or packages of a
  package. Imports under ``if TYPE_CHECKING:`` count.
- At most MAX_TOP_LEVEL_MODULES modules at the top of ``cdpm/``.
- No import cycles between cdpm modules, a package's ``__init__`` and its
  own modules included (the contracts check siblings only). The graph is read from the source
  with ``ast``: every ``import`` / ``from ... import`` of a cdpm module, at
  module level and inside functions, relative imports resolved; a package's
  ``__init__`` is a module of its own (``cdpm.maps`` is
  ``cdpm/maps/__init__.py``), so a submodule importing its own package
  closes a cycle when the package's ``__init__`` imports that submodule.
  Imports under ``if TYPE_CHECKING:`` are edges too (a type checker
  follows them); ``importlib.import_module`` (cdpm/__init__.py's lazy name
  table) is not.
- Importing cdpm, cdpm.maps or a map worker's modules imports no SciPy,
  zarr, xarray or Pinocchio: a worker of a map without load needs none of
  them, and each costs it start-up time inside the map's run.
"""

from __future__ import annotations

import ast
import subprocess
import sys
import textwrap
from collections import deque
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "cdpm"

#: most modules at the top level of cdpm/ (the shared vocabulary and the
#: package's entry points; everything else lives in a package)
MAX_TOP_LEVEL_MODULES = 10

#: heavy libraries that importing the modules below must not import
HEAVY = ("scipy", "zarr", "xarray", "pinocchio")


@pytest.mark.parametrize("module", ["cdpm", "cdpm.maps", "cdpm.maps._runner"])
def test_light_modules_import_no_heavy_library(module):
    """check_tol once moved beside the analysis and pulled SciPy into every
    map worker (126 -> 454 ms to import cdpm.pipeline.evaluate), which cut the
    paper map's two-process speed-up from about 1.8x to 1.6-1.7x."""
    import subprocess
    import sys

    code = f"import sys, {module}; print(' '.join(m for m in {HEAVY!r} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


# --------------------------------------------------------------------------
# the import graph


def module_files(package_dir: Path) -> dict[str, Path]:
    """Dotted module name -> file, for every .py file under ``package_dir``
    (a package's ``__init__.py`` under the package's own name)."""
    files = {}
    for path in sorted(package_dir.rglob("*.py")):
        parts = list(path.relative_to(package_dir.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        files[".".join(parts)] = path
    return files


class _ImportCollector(ast.NodeVisitor):
    """(line, absolute module name, imported names) of every import
    statement, wherever it stands (module level, functions, classes, try
    blocks, ``if TYPE_CHECKING:``)."""

    def __init__(self, package: str) -> None:
        self.package = package  # the package relative imports start from
        self.found: list[tuple[int, str, list[str]]] = []

    def visit_Import(self, node: ast.Import) -> None:
        for alias in node.names:
            self.found.append((node.lineno, alias.name, []))

    def visit_ImportFrom(self, node: ast.ImportFrom) -> None:
        if node.level:
            base = self.package.split(".")
            base = base[: len(base) - (node.level - 1)]
            module = ".".join(base + ([node.module] if node.module else []))
        else:
            module = node.module or ""
        self.found.append((node.lineno, module, [alias.name for alias in node.names]))


def import_graph(package_dir: Path) -> tuple[dict[str, dict[str, int]], dict[str, Path]]:
    """The package's import graph: module -> {imported module: line of the
    first such import}, and module -> file.

    ``from a.b import c`` imports the submodule ``a.b.c`` when there is one,
    else (a name defined in ``a.b``, ``__version__`` of a package, ...) the
    module ``a.b``. Imports of modules outside the package, or of modules
    that do not exist, are left out; so is a module importing itself.
    """
    files = module_files(package_dir)
    graph: dict[str, dict[str, int]] = {}
    for name, path in files.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        collector = _ImportCollector(package)
        collector.visit(ast.parse(path.read_text(encoding="utf-8"), filename=str(path)))
        edges: dict[str, int] = {}
        for line, module, names in collector.found:
            targets = [f"{module}.{n}" if f"{module}.{n}" in files else module for n in names]
            for target in targets or [module]:
                if target in files and target != name:
                    edges.setdefault(target, line)
        graph[name] = edges
    return graph, files


def strongly_connected(graph: dict[str, dict[str, int]]) -> list[list[str]]:
    """The strongly connected components with more than one module
    (Tarjan's algorithm, iterative), each sorted, in sorted order."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    components: list[list[str]] = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, {})))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    components.append(sorted(component))
    return sorted(components)


def shortest_cycle(graph: dict[str, dict[str, int]], start: str) -> list[str] | None:
    """The shortest cycle start -> ... -> start (breadth first), or None."""
    parent: dict[str, str] = {}
    queue = deque([start])
    while queue:
        node = queue.popleft()
        for child in sorted(graph.get(node, {})):
            if child == start:
                path = [node]
                while path[-1] != start:
                    path.append(parent[path[-1]])
                return [start, *reversed(path[:-1]), start]
            if child not in parent:
                parent[child] = node
                queue.append(child)
    return None


def import_cycles(package_dir: Path) -> list[list[str]]:
    """One shortest cycle through every module that is on a cycle,
    without repeats (a cycle is listed from its smallest module)."""
    graph, _ = import_graph(package_dir)
    cycles: list[list[str]] = []
    seen: set[tuple[str, ...]] = set()
    for component in strongly_connected(graph):
        for module in component:
            cycle = shortest_cycle(graph, module)
            if cycle is None:
                continue
            ring = cycle[:-1]
            first = ring.index(min(ring))
            ring = ring[first:] + ring[:first]
            if tuple(ring) not in seen:
                seen.add(tuple(ring))
                cycles.append([*ring, ring[0]])
    return cycles


def describe_cycle(cycle: list[str], package_dir: Path) -> str:
    """``a/b.py:12 imports a.c -> a/c.py:3 imports a.b``."""
    graph, files = import_graph(package_dir)
    steps = []
    for module, target in zip(cycle, cycle[1:], strict=False):
        where = files[module].relative_to(package_dir.parent).as_posix()
        steps.append(f"{where}:{graph[module][target]} imports {target}")
    return " -> ".join(steps)


# --------------------------------------------------------------------------
# the rules, on cdpm


@pytest.mark.slow
def test_cdpm_has_no_import_cycles():
    graph, files = import_graph(PACKAGE)
    # the graph is read at all: cdpm.maps imports its evaluation module
    assert "cdpm.maps" in files and "cdpm.errors" in files
    assert any(target.startswith("cdpm.maps.") for target in graph["cdpm.maps"])
    cycles = import_cycles(PACKAGE)
    if cycles:
        listed = "\n".join(f"  {describe_cycle(c, PACKAGE)}" for c in cycles)
        pytest.fail(f"{len(cycles)} import cycle(s) in cdpm:\n{listed}", pytrace=False)


def _lint_imports(cwd: Path, *args: str) -> subprocess.CompletedProcess:
    """Run import-linter's ``lint-imports`` in ``cwd``."""
    script = Path(sys.executable).with_name("lint-imports")
    command = [str(script)] if script.exists() else ["lint-imports"]
    return subprocess.run(
        [*command, "--no-cache", *args], cwd=cwd, capture_output=True, text=True, check=False
    )


def test_import_contracts_hold():
    """pyproject.toml's import-linter contracts, every one kept."""
    out = _lint_imports(ROOT)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "Contracts: 4 kept, 0 broken." in out.stdout, out.stdout


def test_top_level_of_cdpm_has_few_modules():
    modules = sorted(p.name for p in PACKAGE.glob("*.py"))
    assert len(modules) <= MAX_TOP_LEVEL_MODULES, modules
    # the shared vocabulary is there, the packages are packages
    assert {"errors.py", "numerics.py", "verdicts.py", "printing.py"} <= set(modules)
    for package in ("model", "dynamics", "analysis", "pipeline", "maps", "regions", "cli"):
        assert (PACKAGE / package / "__init__.py").is_file(), package


def test_contracts_catch_an_upward_import_and_a_private_import(tmp_path):
    """The contract types used on cdpm, on a package with known breaches:
    a low layer importing a high one, and a private module imported from
    another package."""
    _write_package(
        tmp_path,
        {
            "pkg/__init__.py": "",
            "pkg/high/__init__.py": "from pkg.low import f\n",
            "pkg/low/__init__.py": "def f():\n    from pkg.high import g\n",
            "pkg/other/__init__.py": "from pkg.low._inner import h\n",
            "pkg/low/_inner.py": "h = 1\n",
        },
    )
    (tmp_path / ".importlinter").write_text(
        textwrap.dedent(
            """
            [importlinter]
            root_package = pkg

            [importlinter:contract:layers]
            name = layers
            type = layers
            containers = pkg
            layers =
                high
                other
                low

            [importlinter:contract:private]
            name = private
            type = private_modules
            """
        )
    )
    out = _lint_imports(tmp_path, "--config", ".importlinter")
    assert out.returncode == 1, out.stdout + out.stderr
    assert "pkg.low -> pkg.high" in out.stdout
    assert "pkg.other -> pkg.low._inner" in out.stdout


# --------------------------------------------------------------------------
# the checks themselves, on a small package with known answers


def _write_package(root: Path, files: dict[str, str]) -> Path:
    for relative, text in files.items():
        path = root / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text).lstrip("\n"))
    return root / "pkg"


@pytest.fixture
def sample_package(tmp_path) -> Path:
    """pkg with cycles a <-> b (b's import inside a function), sub/__init__
    <-> sub/_x (relative import of the package), x -> pkg/__init__ ->
    x (``__version__``); imports under TYPE_CHECKING, the lazy name table
    and a ``from sub import _y`` submodule import that closes no cycle."""
    return _write_package(
        tmp_path,
        {
            "pkg/__init__.py": """
                import importlib
                from typing import TYPE_CHECKING

                from pkg.x import thing

                __version__ = "1"
                _EXPORTS = {"a": "pkg.a", "helper": "pkg.c"}

                def __getattr__(name):
                    return importlib.import_module(_EXPORTS[name])

                if TYPE_CHECKING:
                    from pkg.c import helper
                else:
                    import pkg.errors
            """,
            "pkg/errors.py": "class Error(Exception):\n    pass\n",
            "pkg/x.py": """
                def thing():
                    from pkg import __version__

                    return __version__
            """,
            "pkg/a.py": "from pkg.b import g\n",
            "pkg/b.py": """
                def g():
                    from . import a

                    return a
            """,
            "pkg/c.py": """
                import typing

                if typing.TYPE_CHECKING:
                    import pkg
                from pkg.sub import _y
            """,
            "pkg/sub/__init__.py": "from ._x import run\n",
            "pkg/sub/_x.py": """
                import pkg.errors

                def run():
                    from .. import sub

                    return sub
            """,
            "pkg/sub/_y.py": "from pkg.errors import Error\n",
        },
    )


def test_import_graph_reads_every_kind_of_import(sample_package):
    graph, files = import_graph(sample_package)
    assert set(files) == {
        "pkg",
        "pkg.errors",
        "pkg.x",
        "pkg.a",
        "pkg.b",
        "pkg.c",
        "pkg.sub",
        "pkg.sub._x",
        "pkg.sub._y",
    }
    # the name table is not an edge; TYPE_CHECKING imports and their else branch are
    assert graph["pkg"] == {"pkg.x": 4, "pkg.c": 13, "pkg.errors": 15}
    assert graph["pkg.x"] == {"pkg": 2}  # __version__: the package's __init__
    assert graph["pkg.b"] == {"pkg.a": 2}  # relative, inside a function
    assert graph["pkg.c"] == {"pkg": 4, "pkg.sub._y": 5}  # a submodule, not pkg.sub
    assert graph["pkg.sub"] == {"pkg.sub._x": 1}
    assert graph["pkg.sub._x"] == {"pkg.errors": 1, "pkg.sub": 4}


def test_import_cycles_are_found_and_named(sample_package):
    cycles = import_cycles(sample_package)
    assert cycles == [
        ["pkg", "pkg.c", "pkg"],  # through a TYPE_CHECKING import
        ["pkg", "pkg.x", "pkg"],
        ["pkg.a", "pkg.b", "pkg.a"],
        ["pkg.sub", "pkg.sub._x", "pkg.sub"],
    ]
    assert describe_cycle(cycles[3], sample_package) == (
        "pkg/sub/__init__.py:1 imports pkg.sub._x -> pkg/sub/_x.py:4 imports pkg.sub"
    )


def test_a_package_without_cycles_passes(tmp_path):
    package = _write_package(
        tmp_path,
        {
            "pkg/__init__.py": "from pkg.a import f\n",
            "pkg/a.py": "from pkg.b import g\n\ndef f():\n    from pkg import b\n",
            "pkg/b.py": "import os\n\ndef g():\n    return os\n",
        },
    )
    assert import_cycles(package) == []


def test_every_compiled_kernel_is_cached_and_releases_the_gil():
    """Every numba kernel is declared through cdpm.jit.kernel: cached
    on disk, and releasing the GIL while it runs."""
    import importlib

    from numba.core.registry import CPUDispatcher

    from cdpm.pipeline.compiled import KERNEL_MODULES

    kernels = {}
    for name in (*KERNEL_MODULES, "cdpm.jit.dense"):
        module = importlib.import_module(name)
        for attr, value in vars(module).items():
            if isinstance(value, CPUDispatcher) and value.__module__ == name:
                kernels[f"{name}.{attr}"] = value
    assert len(kernels) >= 30
    loose = [k for k, d in kernels.items() if not d.targetoptions.get("nogil")]
    uncached = [k for k, d in kernels.items() if type(d._cache).__name__ != "FunctionCache"]
    assert (loose, uncached) == ([], [])
    # and no kernel is declared any other way: no other module uses numba
    elsewhere = [
        str(path.relative_to(ROOT))
        for path in sorted(PACKAGE.rglob("*.py"))
        if path.relative_to(PACKAGE).as_posix() != "jit/__init__.py"
        and any(s in path.read_text() for s in ("njit", "import numba", "from numba"))
    ]
    assert elsewhere == []
