"""MkDocs hook of the docs site (mkdocs.yml): the pages made from other sources at build time.

- ``index.md``: the README, its absolute links to docs/ pages made relative;
- ``cli.md``: the command-line reference, every command's ``--help`` as the parser prints it;
- ``api.md``: the API reference (mkdocstrings, from the docstrings of :data:`API_MODULES`);
- ``board.md``: the committed board's tables, and its page ``leaderboard.html`` beside them;
- ``tutorial.md``: ``docs/tutorial.ipynb`` as a page (its cells; ``tests/test_docs_site.py``
  executes the notebook);

and on every page a link into the repository outside docs/ (``../leaderboards/README.md``)
becomes its GitHub address, where the site has no such page.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

from mkdocs.structure.files import File

ROOT = Path(__file__).resolve().parent
BLOB = "https://github.com/ema-bench/ema-bench/blob/main/"
#: the modules of the API reference, in the order a user meets them
API_MODULES = (
    "ema_bench", "ema_bench.problem", "ema_bench.objective", "ema_bench.registry",
    "ema_bench.instances", "ema_bench.suites", "ema_bench.suites.base", "ema_bench.suites.v1",
    "ema_bench.suites.v2", "ema_bench.suites.targets", "ema_bench.records",
    "ema_bench.seeding", "ema_bench.adapters.run", "ema_bench.adapters.scipy",
    "ema_bench.adapters.pymoo", "ema_bench.adapters.ioh_problem", "ema_bench.adapters.nevergrad",
    "ema_bench.leaderboard.ioh", "ema_bench.diagnosis.workflow",
    "ema_bench.prognostics.campaign", "ema_bench.prognostics.tracking",
    "ema_bench.uncertainty.intervals", "ema_bench.sweep.schema",
)
_OUTSIDE = re.compile(r"\]\(\.\./([^)#\s]+)(#[^)]*)?\)")
_DOCS_LINK = re.compile(re.escape(BLOB) + r"docs/([^)#\s]+)")


def on_files(files, config):
    """Add the generated pages (and the board's page) to the site's files."""
    pages = {"index.md": _index(), "cli.md": _cli(), "api.md": _api(),
             "board.md": _board(), "tutorial.md": _tutorial()}
    for name, text in pages.items():
        files.append(File.generated(config, name, content=text))
    files.append(File.generated(config, "board/leaderboard.html",
                                abs_src_path=str(ROOT / "leaderboards" / "leaderboard.html")))
    return files


def on_page_markdown(markdown, page, config, files):
    """Links out of docs/ (``../leaderboards/README.md``) to the repository on GitHub."""
    return _OUTSIDE.sub(lambda m: f"]({BLOB}{m.group(1)}{m.group(2) or ''})", markdown)


def _index() -> str:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    return _DOCS_LINK.sub(lambda m: m.group(1), text)


def _cli() -> str:
    os.environ["COLUMNS"] = "100"   # the help's width, the same on every machine
    from ema_bench.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    out = ["# Command line", "",
           "Every command's `--help`, as `ema-bench COMMAND --help` prints it (generated "
           "when the site is built).", "", "```text", parser.format_help().rstrip(), "```"]
    for name, p in sub.choices.items():
        out += ["", f"## ema-bench {name}", "", "```text", p.format_help().rstrip(), "```"]
    return "\n".join(out) + "\n"


def _api() -> str:
    out = ["# API reference", "",
           "The public modules, from their docstrings (NumPy style, units in brackets).", ""]
    for m in API_MODULES:
        out += [f"## `{m}`", "", f"::: {m}", ""]
    return "\n".join(out)


def _board() -> str:
    lb = ROOT / "leaderboards"
    out = ["# The board", "",
           "The committed board (`leaderboards/`): its sortable page with tables and plots is "
           "[leaderboard.html](board/leaderboard.html); its tables follow.", ""]
    for track in ("reference", "twin"):
        md = (lb / f"leaderboard_{track}.md").read_text(encoding="utf-8")
        out += [re.sub(r"^(#+) ", r"#\1 ", md, flags=re.M), ""]   # one level down
    return "\n".join(out)


def _tutorial() -> str:
    nb = json.loads((ROOT / "docs" / "tutorial.ipynb").read_text(encoding="utf-8"))
    out = []
    for cell in nb["cells"]:
        src = "".join(cell["source"])
        if cell["cell_type"] == "markdown":
            out += [src, ""]
        elif cell["cell_type"] == "code":
            out += ["```python", src, "```", ""]
    out += ["[Download the notebook](tutorial.ipynb)", ""]
    return "\n".join(out)
