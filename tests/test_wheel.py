"""The package stands alone: the wheel, installed outside the checkout's sources, runs the
README's examples (sizes reduced), ``leaderboard --check`` included.

Where this interpreter's environment already holds a non-editable install of this very
checkout, file for file (CI's ``pip install .``, the README's install), that installation is
the wheel under test: its console script runs from a folder outside the checkout.  Otherwise
(an editable development install) the wheel is built and installed into a fresh venv: about
a minute and a half on the 2-core CI machine; skipped with a reason where no wheel can be
built (no network and no cache for its build requirements).
"""

from __future__ import annotations

import importlib.metadata
import json
import re
import site
import subprocess
import sys
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# a wheel build, a venv and a pip install: the fast loop runs the same commands from the
# checkout (test_cli_simulate, test_leaderboard's --check)
pytestmark = pytest.mark.slow


def _run(cmd: list[str], cwd: Path, timeout: int = 600) -> subprocess.CompletedProcess:
    res = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout)
    assert res.returncode == 0, f"{' '.join(cmd)}\n{res.stdout[-1500:]}\n{res.stderr[-3000:]}"
    return res


#: Where the installed distribution's top-level packages come from in the checkout.
SOURCES = {"ema_bench": "ema_bench", "ema_bench_solvers": "solvers",
           "ema_bench_trackers": "trackers"}


def installed_copy() -> Path | None:
    """The bin folder of this interpreter's environment if it holds a non-editable install of
    this checkout whose every Python and data file equals the checkout's (the wheel the
    README's ``pip install .`` built); None otherwise (editable, stale or absent)."""
    # the environment's own (a build in the checkout leaves ema_bench.egg-info beside it)
    found = list(importlib.metadata.distributions(name="ema-bench",
                                                  path=site.getsitepackages()))
    if not found:
        return None
    dist = found[0]
    direct = json.loads(dist.read_text("direct_url.json") or "{}")
    if "dir_info" not in direct or direct["dir_info"].get("editable", False):
        return None
    shipped = {}
    for f in dist.files or ():
        top = f.parts[0]
        if top in SOURCES and f.suffix in (".py", ".json"):
            shipped[ROOT / SOURCES[top] / Path(*f.parts[1:])] = Path(dist.locate_file(f))
    sources = {p for top in SOURCES.values() for ext in ("py", "json")
               for p in (ROOT / top).rglob(f"*.{ext}") if "__pycache__" not in p.parts}
    if set(shipped) != sources:
        return None
    if any(src.read_bytes() != inst.read_bytes() for src, inst in shipped.items()):
        return None
    bin_ = Path(sys.executable).parent
    return bin_ if (bin_ / "ema-bench").exists() else None


@pytest.fixture(scope="module")
def alone(tmp_path_factory) -> tuple[Path, Path]:
    """``(bin folder of an environment where the wheel is installed, a work folder)``, the
    work folder outside the checkout (so nothing imports the checkout's sources)."""
    tmp = tmp_path_factory.mktemp("wheel")
    bin_ = installed_copy()
    if bin_ is not None:
        (tmp / "work").mkdir()
        return bin_, tmp / "work"
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w",
                            str(tmp / "dist"), str(ROOT)], capture_output=True, text=True,
                           timeout=600)
    if build.returncode != 0:
        pytest.skip(f"cannot build the wheel here: {build.stderr.strip()[-300:]}")
    (wheel,) = (tmp / "dist").glob("ema_bench-*.whl")
    # no pip of its own (ensurepip costs about 4 CPU-s): this interpreter's pip installs into
    # it (--python, pip >= 22.3), the wheel and its declared dependencies as ever
    venv.create(tmp / "venv", with_pip=False)
    bin_ = tmp / "venv" / "bin"
    # --no-compile: no .pyc for numba, scipy and matplotlib up front (a minute on CI)
    _run([sys.executable, "-m", "pip", "--python", str(bin_ / "python"), "install", "-q",
          "--no-compile", str(wheel)], tmp)
    work = tmp / "work"
    work.mkdir()
    return bin_, work


def test_the_installed_package_is_the_wheel(alone):
    bin_, work = alone
    res = _run([str(bin_ / "python"), "-c", "import ema_bench; print(ema_bench.__file__)"],
               work)
    assert not Path(res.stdout.strip()).is_relative_to(ROOT / "ema_bench")
    assert "site-packages" in Path(res.stdout.strip()).parts


def test_the_readme_python_example_runs(alone):
    bin_, work = alone
    readme = (ROOT / "README.md").read_text()
    # (the docs-test comments above the block: tests/test_docs_examples.py)
    block = re.search(r"### The problem, from Python\n\n(?:<!--.*?-->\n)*```python\n(.*?)```",
                      readme, flags=re.S).group(1)
    assert "budget=2000" in block   # the README's example, run at a tenth of its budget
    res = _run([str(bin_ / "python"), "-c", block.replace("budget=2000", "budget=200")], work)
    assert res.stdout.strip().endswith("}") and "200" in res.stdout


def test_the_readme_commands_run_and_check_against_the_shipped_baseline(alone):
    bin_, work = alone
    eb = str(bin_ / "ema-bench")
    small = ["--solvers", "nelder-mead", "--cases", "small", "--tracks", "twin", "--seeds",
             "1", "--budget", "60"]
    for cmd in (["--help"], ["params"], ["solvers"],
                ["simulate", "--case", "small", "--model", "reference", "--seed", "0",
                 "--out", "traces.csv", "--plot", "traces.png"],
                ["solve", "--case", "small", "--track", "twin", "--solver", "nelder-mead",
                 "--budget", "60", "--seed", "0", "--json"],
                ["solve", "--measured", "traces.csv", "--solver", "cmaes", "--budget", "30",
                 "--plot", "fit.png"],
                ["leaderboard", "--quick", *small, "--no-plots", "--out", "lb"],
                ["validate", "lb/runs.jsonl", "--partial"],
                ["export", "--format", "ioh", "lb/runs.jsonl", "--out", "ioh"]):
        _run([eb, *cmd], work)
    assert (work / "traces.png").is_file() and (work / "fit.png").is_file()
    assert list((work / "ioh").glob("nelder-mead/IOHprofiler_*.json"))
    # --check without a checkout: the quick baseline the wheel installs (budget 400 runs,
    # re-scored at this budget)
    res = _run([eb, "leaderboard", "--quick", *small, "--no-plots", "--check", "--json"], work)
    summary = json.loads(res.stdout)
    assert summary["regressions"] == [] and summary["baseline"]["re_scored"] == 1
    # a folder without committed runs is refused at once, before any run
    res = subprocess.run([eb, "leaderboard", "--quick", "--check", "nowhere"], cwd=work,
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 2 and "no committed runs" in res.stderr
    assert "share/ema-bench/leaderboards" in res.stderr
