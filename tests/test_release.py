"""A release (issue 45): the version has one place, a tag must equal it and have its
CHANGELOG section, and the sdist holds what its tests need (pytest runs from the unpacked
sdist: .github/workflows/release.yml)."""

from __future__ import annotations

import subprocess
import sys
import tarfile
import tomllib
from pathlib import Path

import pytest

import ema_bench

ROOT = Path(__file__).resolve().parents[1]
CHECK = ROOT / ".github" / "release_check.py"


def test_the_version_has_one_place():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in project["project"] and "version" in project["project"]["dynamic"]
    attr = project["tool"]["setuptools"]["dynamic"]["version"]["attr"]
    assert attr == "ema_bench.version.__version__"
    from importlib.metadata import version

    assert version("ema-bench") == ema_bench.__version__


def test_a_tag_must_be_the_version_with_a_changelog_section():
    v = ema_bench.__version__
    ok = subprocess.run([sys.executable, CHECK, f"v{v}"], capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    major, minor, patch = (int(p) for p in v.split("."))
    other = f"{major}.{minor}.{patch + 1}"
    bad = subprocess.run([sys.executable, CHECK, other], capture_output=True, text=True)
    assert bad.returncode == 1 and f"tag {other} is not the package's version" in bad.stderr


@pytest.mark.slow   # an isolated build that tars the committed boards (60 MB): ~10 CPU-s
def test_the_sdist_holds_the_tests_and_what_they_read(tmp_path):
    pytest.importorskip("build", reason="build not installed (pip install 'ema-bench[test]')")
    # as the release workflow builds it (an isolated build with the pyproject's setuptools)
    res = subprocess.run([sys.executable, "-m", "build", "--sdist", "--outdir", tmp_path],
                         cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    top = f"ema_bench-{ema_bench.__version__}"
    (sdist,) = tmp_path.glob("*.tar.gz")
    assert sdist.name == f"{top}.tar.gz"
    with tarfile.open(sdist) as tar:
        names = {n.removeprefix(top + "/") for n in tar.getnames()}
    tracked = subprocess.run(["git", "ls-files", "tests", "docs", "benchmarks", ".ci"],
                             cwd=ROOT, capture_output=True, text=True)
    if tracked.returncode == 0 and tracked.stdout:
        missing = sorted(set(tracked.stdout.split()) - names)
        assert missing == [], missing[:10]
    for needed in ("tests/conftest.py", "leaderboards/quick/runs.jsonl",
                   "leaderboards/runs.jsonl", "docs/schemas/run-record.schema.json",
                   "benchmarks/c/monitor.c", ".ci/run", "CHANGELOG.md", "README.md",
                   "mkdocs.yml", "docs_site.py", "docs/tutorial.ipynb"):
        assert needed in names, needed
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")]
