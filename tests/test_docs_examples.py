"""Every Python code block of the README and docs/ runs as written (issue 45).

Each ```` ```python ```` block runs in a fresh namespace, in an empty working folder, unless
the HTML comment just above it (invisible on the rendered page) says otherwise:

- ``<!-- docs-test: continues -->``: the block goes on from the previous block of the page
  (its namespace), as the page's text says;
- ``<!-- docs-test: replace "A" -> "B" -->`` (or single quotes): a long run made small (a
  budget; the reference track's traces, about 40 CPU-s each, by the twin's), the text ``A``
  replaced by ``B`` before the block runs; ``A`` must be in the block, so a stale
  replacement fails;
- ``<!-- docs-test: setup`` + Python lines + ``-->``: hidden setup run first in the block's
  namespace (e.g. writing the file the example reads); ``REPO`` names the checkout there;
- ``<!-- docs-test: check`` + Python lines + ``-->``: hidden assertions run after the block
  (a figure the page states, e.g. the evaluation at which a run succeeds);
- ``<!-- docs-test: needs MODULE -->``: skipped, with the reason, where an optional extra is
  not installed (CI installs them all with ``[test]``).

The Python examples of the package's docstrings (a ``::`` literal block that starts with an
import: the API reference of the docs site shows them) run the same way; their reductions
are in :data:`DOCSTRING_REPLACE`, since a docstring has no hidden comment.

Blocks of other languages (``bash``, ``text``) are commands and outputs: the README's two
commands are CI's (``tests/test_readme.py``); every ``ema-bench`` command line of the pages
is parsed by the real parser here (a stale option fails), and run by the CLI tests.
Solvers and trackers that examples register are removed again after each block.
"""

from __future__ import annotations

import ast
import importlib.util
import re
import textwrap
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
BLOCK = re.compile(r"^```python[ \t]*\n(.*?)^```[ \t]*$", re.S | re.M)
DIRECTIVE = re.compile(r"<!--\s*docs-test:\s*(.*?)-->", re.S)
REPLACE = re.compile(r"""^replace\s+(["'])(.*?)\1\s*->\s*(["'])(.*?)\3\s*$""", re.S)


@dataclass
class Example:
    page: Path
    line: int
    code: str
    continues: bool = False
    setup: list[str] = field(default_factory=list)
    check: list[str] = field(default_factory=list)
    replace: list[tuple[str, str]] = field(default_factory=list)
    needs: list[str] = field(default_factory=list)

    @property
    def id(self) -> str:
        return f"{self.page.relative_to(REPO)}:{self.line}"


def examples(page: Path) -> list[Example]:
    """The Python blocks of a page with the directives in the comments right above each."""
    text = page.read_text(encoding="utf-8")
    out = []
    for m in BLOCK.finditer(text):
        ex = Example(page, text.count("\n", 0, m.start()) + 1, m.group(1))
        before = text[:m.start()].rstrip()
        # the run of directive comments that ends right above the block
        while before.endswith("-->"):
            start = before.rfind("<!--")
            d = DIRECTIVE.fullmatch(before[start:])
            if d is None:
                break
            _directive(ex, d.group(1).strip())
            before = before[:start].rstrip()
        out.append(ex)
    return out


def _directive(ex: Example, body: str) -> None:
    if body == "continues":
        ex.continues = True
    elif body.startswith("setup"):
        ex.setup.insert(0, body[len("setup"):].strip("\n"))
    elif body.startswith("check"):
        ex.check.insert(0, body[len("check"):].strip("\n"))
    elif body.startswith("needs "):
        ex.needs += body.split()[1:]
    elif (r := REPLACE.match(body)) is not None:
        ex.replace.append((r.group(2), r.group(4)))
    else:
        raise ValueError(f"{ex.id}: unknown docs-test directive {body!r}")


#: module -> replacements of its docstring example (the reference track's traces, about 40
#: CPU-s each, by the twin's; a budget cut)
DOCSTRING_REPLACE = {
    "ema_bench/__init__.py": [('track="reference"', 'track="twin"'),
                              ("budget=2000", "budget=300")],
    "ema_bench/env.py": [('track="reference"', 'track="twin"')],
    "ema_bench/adapters/ioh_problem.py": [("budget=500", "budget=100")],
    "ema_bench/adapters/pymoo.py": [("budget=500", "budget=100")],
}
DOCSTRING_BLOCK = re.compile(r"::\n\n((?:    .*\n|[ \t]*\n)+)")


def docstring_examples(path: Path) -> list[Example]:
    """The Python examples in the docstrings of a module."""
    rel = path.relative_to(REPO).as_posix()
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if not isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef)):
            continue
        doc = ast.get_docstring(node, clean=True)
        for m in DOCSTRING_BLOCK.finditer((doc or "") + "\n"):
            code = textwrap.dedent(m.group(1)).strip() + "\n"
            if code.startswith(("import ", "from ")):
                line = getattr(node, "lineno", 1)
                out.append(Example(path, line, code, replace=DOCSTRING_REPLACE.get(rel, [])))
    return out


ALL = [ex for page in PAGES for ex in examples(page)] + [
    ex for module in sorted((REPO / "ema_bench").rglob("*.py"))
    for ex in docstring_examples(module)]


def test_the_pages_have_examples_and_every_directive_parses():
    # a page that stops matching (a renamed fence) would silently drop its examples
    assert len(ALL) >= 13
    assert {ex.page.name for ex in ALL} >= {"README.md", "adapters.md", "uncertainty.md",
                                           "writing-a-solver.md", "submitting-results.md",
                                           "ioh_problem.py", "scipy.py", "env.py"}


@pytest.fixture
def clean_registries():
    """Solvers and trackers an example registers are gone after it."""
    from ema_bench.prognostics.tracking import _TRACKERS
    from ema_bench.registry import _SOLVERS

    saved = [(r, set(r.entries)) for r in (_SOLVERS, _TRACKERS)]
    yield
    for reg, before in saved:
        # the installed plugins stay (their modules are imported once: never registered
        # again); the example's own go
        plugins = {ep.name for ep in entry_points(group=reg.group)}
        for name in set(reg.entries) - before - plugins:
            del reg.entries[name]


def _run(ex: Example, ns: dict) -> None:
    """Run ``ex`` (its setup, then the block with its replacements) in ``ns``."""
    code = ex.code
    for old, new in ex.replace:
        assert old in code, f"{ex.id}: replace {old!r}: not in the block (stale directive)"
        code = code.replace(old, new)
    for setup in ex.setup:
        ns["REPO"] = REPO
        exec(compile(setup, f"{ex.id} (setup)", "exec"), ns)
        ns.pop("REPO")
    exec(compile(code, ex.id, "exec"), ns)
    for check in ex.check:
        exec(compile(check, f"{ex.id} (check)", "exec"), ns)


@pytest.mark.parametrize("ex", ALL, ids=[ex.id for ex in ALL])
def test_example_runs_as_written(ex: Example, tmp_path, monkeypatch, clean_registries):
    page = [e for e in ALL if e.page == ex.page]
    i = page.index(ex)
    # a block that continues runs after the blocks it continues, in one namespace
    first = max(j for j in range(i + 1) if not page[j].continues)
    missing = [m for e in page[first:i + 1] for m in e.needs
               if importlib.util.find_spec(m) is None]
    if missing:
        pytest.skip(f"{ex.id} needs {', '.join(missing)} (pip install 'ema-bench[test]')")
    monkeypatch.chdir(tmp_path)
    ns: dict = {"__name__": "__docs_example__"}
    for e in page[first:i + 1]:
        _run(e, ns)


# --- the command lines of the pages --------------------------------------------------------
FENCE = re.compile(r"^```(\w*)[ \t]*\n(.*?)^```", re.S | re.M)


def command_lines(page: Path) -> list[str]:
    """The ``ema-bench ...`` lines of a page's non-Python blocks (continuations joined,
    ``$ `` prompts and ``VAR=value`` prefixes dropped); diagrams (box drawing) and elided
    lines (``...``) are not commands."""
    out = []
    for m in FENCE.finditer(page.read_text(encoding="utf-8")):
        if m.group(1) == "python" or "─" in m.group(2):
            continue
        for line in m.group(2).replace("\\\n", " ").splitlines():
            line = re.sub(r"^(\w+=\S+ )+", "", line.strip().removeprefix("$ "))
            if line.startswith("ema-bench ") and "..." not in line:
                out.append(line)
    return out


COMMANDS = [(page, line) for page in PAGES for line in command_lines(page)]


def test_every_command_line_of_the_pages_parses():
    """Each ``ema-bench`` command the README and docs/ show is accepted by the real parser
    (a renamed or removed option fails here; the commands' runs are the CLI tests')."""
    import contextlib
    import io
    import shlex

    from ema_bench.cli import build_parser

    parser = build_parser()
    assert len(COMMANDS) >= 35
    bad = []
    for page, line in COMMANDS:
        argv = shlex.split(line, comments=True)
        argv = argv[:argv.index("|")] if "|" in argv else argv
        err = io.StringIO()
        try:
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                parser.parse_args(argv[1:])
        except SystemExit as exc:
            if exc.code:
                bad.append(f"{page.name}: {line}: {err.getvalue().strip().splitlines()[-1]}")
    assert bad == []
