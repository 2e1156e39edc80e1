"""The docs site and its tutorial notebook (issue 45).

The notebook (docs/tutorial.ipynb) runs in a fresh interpreter, its code cells in order in
one namespace, as a kernel would (without ipykernel, which the test extra does not carry),
and its results are checked.  The site (mkdocs.yml) builds with warnings as errors where the
docs extra is installed (``pip install ".[docs]"``, about 120 MB; the test extra includes it,
so CI builds the site; .github/workflows/pages.yml builds and publishes it)."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK = ROOT / "docs" / "tutorial.ipynb"

RUN_NOTEBOOK = """
import json, sys
nb = json.load(open(sys.argv[1]))
ns = {"__name__": "__main__"}
for i, cell in enumerate(nb["cells"]):
    if cell["cell_type"] == "code":
        exec(compile("".join(cell["source"]), f"tutorial.ipynb cell {i}", "exec"), ns)
ours = {s.solver: s.area[0] for s in ns["anytime_scores"](ns["records"])}
print(json.dumps({"runs": ns["summary"]["runs"], "targets": ns["summary"]["targets"],
                  "areas": ours, "ecdf": {k: v.tolist() for k, v in ns["ecdf"].items()},
                  "verdict": ns["result"].verdict,
                  "effects": [e.name for e in ns["result"].effects],
                  "tracked": ns["scores"]["tracked"], "units": ns["scores"]["units"]}))
"""


def test_the_notebook_is_a_notebook_whose_cells_are_the_tutorials():
    nb = json.loads(NOTEBOOK.read_text())
    assert nb["nbformat"] == 4 and nb["metadata"]["kernelspec"]["language"] == "python"
    code = [c for c in nb["cells"] if c["cell_type"] == "code"]
    assert len(code) == 5 and all(c["outputs"] == [] for c in code)   # no stale outputs
    text = "".join("".join(c["source"]) for c in nb["cells"])
    for step in ("register_solver", "leaderboard(", "ecdf_curve", "diagnose(",
                 "track_campaign("):
        assert step in text, step


@pytest.mark.slow   # about 30 CPU-s: a board of 8 runs, a diagnosis, a 2-unit campaign
def test_the_tutorial_notebook_runs_and_finds_what_it_says(tmp_path):
    res = subprocess.run([sys.executable, "-c", RUN_NOTEBOOK, NOTEBOOK], cwd=tmp_path,
                         capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    out = json.loads(res.stdout.splitlines()[-1])
    assert out["runs"] == 8 and out["targets"].startswith("Targets: fitness")
    # CMA-ES reaches targets within 200 evaluations, random search in batches of 32 none
    assert out["areas"]["cmaes"] > out["areas"]["tutorial-random"]
    curve = out["ecdf"]["cmaes"]
    assert curve == sorted(curve) and 0 < curve[-1] <= 1
    assert out["verdict"] == "effect" and out["effects"] == ["sensor_offset"]
    assert out["tracked"] == out["units"] == 2
    assert (tmp_path / "tutorial-board" / "runs.jsonl").is_file()


def _docs_tools() -> str:
    """Why the site cannot be built here ('' when it can)."""
    missing = [m for m in ("mkdocs", "material", "mkdocstrings", "mkdocstrings_handlers")
               if importlib.util.find_spec(m) is None]
    return f"no {', '.join(missing)} (pip install '.[docs]')" if missing else ""


@pytest.mark.slow   # about 15 s: the site with the API reference of 20 modules
def test_the_site_builds_with_zero_warnings(tmp_path):
    why = _docs_tools()
    if why:
        pytest.skip(why)
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    res = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d",
                          tmp_path / "site"], cwd=ROOT, capture_output=True, text=True,
                         timeout=600, env=env)
    log = res.stdout + res.stderr
    assert res.returncode == 0, log[-3000:]
    assert "WARNING" not in log, log[-3000:]
    site = tmp_path / "site"
    from ema_bench.cli import COMMANDS

    cli = (site / "cli" / "index.html").read_text()
    assert all(f"ema-bench {c}" in cli for c in COMMANDS)          # from --help
    api = (site / "api" / "index.html").read_text()
    assert "make_problem" in api and "AdapterRun" in api            # from the docstrings
    assert (site / "board" / "leaderboard.html").is_file()
    assert "sensor_offset" in (site / "tutorial" / "index.html").read_text()
    assert (site / "schemas" / "run-record.schema.json").is_file()
