"""The package's import graph, read from the sources with ``ast``: no circles, nothing imports
the package face from inside, no private name crosses a package, no consumer leans on another.

Every import counts, also one inside a function (it is a dependency all the same, only a late
one) and ``import ... as``; only ``if TYPE_CHECKING:`` blocks are left out (never run).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import ema_bench

PACKAGE = Path(ema_bench.__file__).resolve().parent
FACE = "ema_bench"
# packages that each run a command's workflow: none may import another's modules
CONSUMERS = ("ema_bench.diagnosis", "ema_bench.prognostics", "ema_bench.leaderboard")
# no consumer-to-consumer arrow remains: the sweep engine (ema_bench/sweep/) lies below them all
ALLOWED_CONSUMER_ARROWS: set[tuple[str, str]] = set()


def modules(root: Path = PACKAGE, face: str = FACE) -> dict[str, tuple[Path, bool]]:
    """Dotted module name -> (file, is a package's ``__init__``)."""
    out = {}
    for f in sorted(root.rglob("*.py")):
        parts = list(f.relative_to(root.parent).with_suffix("").parts)
        is_pkg = parts[-1] == "__init__"
        out[".".join(parts[:-1] if is_pkg else parts)] = (f, is_pkg)
    assert face in out
    return out


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip.update(id(n) for n in ast.walk(node))
    return skip


def imports(mods: dict[str, tuple[Path, bool]]) -> list[tuple[str, str, str | None, int]]:
    """Every import of a package module: (importer, imported module, imported name or None
    for a module, line)."""
    out = []
    for mod, (path, is_pkg) in mods.items():
        tree = ast.parse(path.read_text(), str(path))
        skip = _type_checking_nodes(tree)
        for node in ast.walk(tree):
            if id(node) in skip or not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            if isinstance(node, ast.Import):
                targets = [(a.name, None) for a in node.names]
            else:
                if node.level:
                    base = mod.split(".") if is_pkg else mod.split(".")[:-1]
                    base = base[:len(base) - (node.level - 1)]
                    module = ".".join(base + ([node.module] if node.module else []))
                else:
                    module = node.module or ""
                # ``from pkg import mod`` imports the module pkg.mod
                targets = [(f"{module}.{a.name}", None) if f"{module}.{a.name}" in mods
                           else (module, a.name) for a in node.names]
            for target, name in targets:
                if target.split(".")[0] != FACE:
                    continue
                while target not in mods:       # import a.b.c of a package's module a.b
                    target = target.rsplit(".", 1)[0]
                out.append((mod, target, name, node.lineno))
    return out


def cycles(edges: set[tuple[str, str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), each a circle
    of imports or several."""
    graph: dict[str, list[str]] = {}
    for a, b in edges:
        graph.setdefault(a, []).append(b)
        graph.setdefault(b, [])
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def package_of(mod: str, mods: dict[str, tuple[Path, bool]]) -> str:
    return mod if mods[mod][1] else mod.rsplit(".", 1)[0]


@pytest.fixture(scope="module")
def graph():
    mods = modules()
    return mods, imports(mods)


def test_the_reader_sees_the_circles_it_must_catch():
    """The checks below are only as good as this reader: a lazy import inside a function, a
    relative ``from . import module`` and a three-module circle are all found."""
    assert cycles({("a", "b"), ("b", "c"), ("c", "a"), ("c", "d")}) == [["a", "b", "c"]]
    assert cycles({("a", "b"), ("b", "c")}) == []
    mods = modules()
    found = {(a, b) for a, b, _, _ in imports(mods)}
    # lazy (inside a function) and relative-module imports of the package, both seen
    assert ("ema_bench.monitor", "ema_bench.monitor_lanes") in found
    assert ("ema_bench.cli", "ema_bench.version") in found


def test_no_import_circles(graph):
    mods, edges = graph
    assert cycles({(a, b) for a, b, _, _ in edges if a != b}) == []


def test_nothing_inside_imports_the_package_face(graph):
    """``ema_bench/__init__`` imports most of the package: a module importing it back (for
    ``__version__``, say) closes a circle through every module the face imports."""
    _, edges = graph
    assert [(a, line) for a, b, _, line in edges if b == FACE and a != FACE] == []


def test_no_private_name_is_imported_across_packages(graph):
    """``_name`` is a module's own business; inside one package (``traces/`` split into
    modules) it may be shared, across packages it must be made public."""
    mods, edges = graph
    crossing = [(a, line, b, name) for a, b, name, line in edges
                if name and name.startswith("_") and not name.startswith("__")
                and package_of(a, mods) != package_of(b, mods)]
    assert crossing == []


def test_consumers_do_not_import_each_other(graph):
    _, edges = graph

    def consumer(mod: str) -> str | None:
        return next((c for c in CONSUMERS if mod == c or mod.startswith(c + ".")), None)

    arrows = {(a, b) for a, b, _, _ in edges
              if consumer(a) and consumer(b) and consumer(a) != consumer(b)}
    assert arrows == ALLOWED_CONSUMER_ARROWS


def test_every_subpackage_is_installed():
    """pyproject lists the packages setuptools installs: a new folder missing there imports
    from a checkout and is absent from a wheel (ema_bench.sweep was, once, for a merge)."""
    import tomllib

    listed = set(tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())
                 ["tool"]["setuptools"]["packages"])
    on_disk = {".".join(f.parent.relative_to(PACKAGE.parent).parts)
               for f in PACKAGE.rglob("__init__.py")}
    assert on_disk - listed == set()
