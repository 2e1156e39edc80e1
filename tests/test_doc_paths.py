"""Every repository file a docstring or comment of ``ema_bench/`` cites exists.

A citation is a path whose first part is a folder of the repository or of the package
(``benchmarks/c/monitor.c``, ``physics/mechanics.py``, ``docs/diagnosis.md``), or a bare
module or upper-case document name (``calibration.py``, ``README.md``); it may be written from
the repository root, from the package or from the citing module's folder.  Placeholders of
files a command writes (``OUT/runs.jsonl``, ``DIR/truth.json``) and other repositories' files
(named beside their github.com address) start with no such folder and are not citations.
"""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

import pytest

import ema_bench

PACKAGE = Path(ema_bench.__file__).resolve().parent
ROOT = PACKAGE.parent
PATH = re.compile(r"(?<![\w/.-])((?:[A-Za-z_][\w.-]*/)+[\w.-]+\.[A-Za-z]{1,5})(?![\w/])")
BARE = re.compile(r"(?<![\w/.-])([A-Za-z_]\w*\.py|[A-Z][A-Z_]+\.md)(?![\w/])")


def _folders() -> set[str]:
    found = {p.name for p in ROOT.iterdir() if p.is_dir() and not p.name.startswith(".")}
    return found | {p.name for p in PACKAGE.iterdir() if p.is_dir()}


def texts(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every comment and docstring of a module."""
    src = path.read_text()
    out = [(t.start[0], t.string) for t in tokenize.generate_tokens(io.StringIO(src).readline)
           if t.type == tokenize.COMMENT]
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            doc = ast.get_docstring(node, clean=False)
            if doc:
                out.append((node.body[0].lineno, doc))
    return out


def citations(text: str, folders: set[str]) -> list[str]:
    paths = [m.group(1) for m in PATH.finditer(text) if m.group(1).split("/")[0] in folders]
    return paths + [m.group(1) for m in BARE.finditer(text)]


def exists(cited: str, module: Path) -> bool:
    if "/" not in cited:   # a bare name: anywhere in the package or the repository's top
        return (ROOT / cited).exists() or any(PACKAGE.rglob(cited)) or \
            any(ROOT.glob(f"*/{cited}"))
    return any((base / cited).exists() for base in (ROOT, PACKAGE, module.parent))


def test_the_reader_finds_citations_and_skips_placeholders():
    folders = {"docs", "physics", "benchmarks"}
    text = ("see docs/diagnosis.md and ``physics/mechanics.py``, OUT/runs.jsonl, "
            "include/ioh/logger/analyzer.hpp of github.com/x, README.md, dc.h, reference.py.")
    assert citations(text, folders) == ["docs/diagnosis.md", "physics/mechanics.py",
                                        "README.md", "reference.py"]
    here = PACKAGE / "diagnosis" / "workflow.py"
    assert exists("physics/mechanics.py", here) and exists("docs/diagnosis.md", here)
    assert not exists("docs/no-such-page.md", here) and not exists("DESIGN.md", here)


@pytest.mark.skipif(not (ROOT / "docs").is_dir(), reason="needs a checkout, not a wheel")
def test_no_docstring_or_comment_cites_a_missing_file():
    folders = _folders()
    missing = [f"{f.relative_to(ROOT)}:{line}: {cited}"
               for f in sorted(PACKAGE.rglob("*.py")) for line, text in texts(f)
               for cited in citations(text, folders) if not exists(cited, f)]
    assert missing == []
