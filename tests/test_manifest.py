"""The manifest a run record carries: versions, machine, threads and the checkout's commit."""

from __future__ import annotations

import importlib.metadata
import json
import os
import platform
import subprocess
from pathlib import Path

import pytest

import ema_bench
from ema_bench import manifest as mf

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def fresh_cache():
    """Each test sees (and leaves) an empty cache: one test moves the package folder."""
    mf._static.cache_clear()
    yield
    mf._static.cache_clear()


def _git(*args: str) -> str:
    return subprocess.run(["git", "-C", str(REPO), *args], capture_output=True, text=True,
                          check=True, timeout=30).stdout.strip()


def test_required_keys_are_present_and_the_result_is_json():
    m = mf.manifest(["cma", "deap"])
    assert set(mf.REQUIRED_MANIFEST_KEYS) <= set(m)
    assert {"machine", "cpu_count", "git_commit", "git_dirty"} <= set(m)
    assert json.loads(json.dumps(m, allow_nan=False)) == m


def test_versions_are_the_installed_distributions():
    m = mf.manifest(["deap", "cma", "nevergrad", "scipy.optimize", "numpy", "no-such-lib-xyz"])
    version = importlib.metadata.version
    assert m["ema_bench"] == ema_bench.__version__ == version("ema-bench")
    assert m["python"] == platform.python_version()
    for name in ("numpy", "scipy", "numba"):
        assert m[name] == version(name)
    assert m["libraries"] == {
        "deap": version("deap"), "cma": version("cma"), "nevergrad": version("nevergrad"),
        "scipy.optimize": version("scipy"), "numpy": version("numpy"),
        "no-such-lib-xyz": None,
    }
    assert mf.manifest()["libraries"] == {}


def test_machine_and_threads(monkeypatch):
    import numba

    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    monkeypatch.delenv("NUMBA_NUM_THREADS", raising=False)
    m = mf.manifest()
    assert m["platform"] == platform.platform()
    assert m["machine"] == platform.machine()
    assert m["cpu_count"] == os.cpu_count()
    assert m["threads"] == {"numba": numba.get_num_threads(), "OMP_NUM_THREADS": "3"}
    if Path("/proc/cpuinfo").is_file():
        names = [line.split(":", 1)[1].strip() for line in
                 Path("/proc/cpuinfo").read_text().splitlines()
                 if line.split(":", 1)[0].strip() == "model name"]
        assert m["cpu"] == (names[0] if names else platform.processor() or None)


def test_git_commit_is_the_checkouts_head():
    if not (REPO / ".git").exists() or mf.PACKAGE_DIR != REPO / "ema_bench":
        pytest.skip("the package is not imported from this git checkout")
    m = mf.manifest()
    assert m["git_commit"] == _git("rev-parse", "HEAD")
    assert len(m["git_commit"]) == 40
    dirty = _git("status", "--porcelain", "--untracked-files=no") != ""
    assert m["git_dirty"] is dirty


def test_git_commit_is_none_outside_a_checkout(monkeypatch, tmp_path):
    (tmp_path / "__init__.py").write_text("")
    monkeypatch.setattr(mf, "PACKAGE_DIR", tmp_path)
    m = mf.manifest()
    assert m["git_commit"] is None and m["git_dirty"] is None


def test_git_commit_is_none_for_untracked_package_files_in_a_checkout(monkeypatch, tmp_path):
    """A package installed (untracked) inside some clone is not that clone's commit."""
    if subprocess.run(["git", "--version"], capture_output=True).returncode != 0:
        pytest.skip("no git")
    subprocess.run(["git", "init", "-q", str(tmp_path)], check=True, timeout=30)
    env = {**os.environ, "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t",
           "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@t"}
    (tmp_path / "README").write_text("x")
    subprocess.run(["git", "-C", str(tmp_path), "add", "README"], check=True, timeout=30)
    subprocess.run(["git", "-C", str(tmp_path), "commit", "-q", "-m", "x"], check=True,
                   timeout=30, env=env)
    pkg = tmp_path / "site" / "ema_bench"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    monkeypatch.setattr(mf, "PACKAGE_DIR", pkg)
    assert mf.manifest()["git_commit"] is None

    # tracked: the commit, and dirty once a tracked file changes
    subprocess.run(["git", "-C", str(tmp_path), "add", "site"], check=True, timeout=30)
    subprocess.run(["git", "-C", str(tmp_path), "commit", "-q", "-m", "y"], check=True,
                   timeout=30, env=env)
    head = subprocess.run(["git", "-C", str(tmp_path), "rev-parse", "HEAD"], check=True,
                          capture_output=True, text=True, timeout=30).stdout.strip()
    mf._static.cache_clear()
    assert (mf.manifest()["git_commit"], mf.manifest()["git_dirty"]) == (head, False)
    (pkg / "__init__.py").write_text("# edited\n")
    mf._static.cache_clear()
    assert mf.manifest()["git_dirty"] is True


def test_static_part_is_cached_and_results_are_independent(monkeypatch):
    calls = []
    real = mf.git_state
    monkeypatch.setattr(mf, "git_state", lambda folder: calls.append(folder) or real(folder))
    a = mf.manifest(["cma"])
    a["libraries"]["cma"] = "tampered"
    a["python"] = "tampered"
    b = mf.manifest(["cma"])
    assert len(calls) == 1
    assert b["python"] == platform.python_version()
    assert b["libraries"]["cma"] == importlib.metadata.version("cma")


def test_comma_separated_names_and_non_strings():
    version = importlib.metadata.version
    m = mf.manifest(["nevergrad, numpy", "cma"])
    assert m["libraries"] == {"nevergrad": version("nevergrad"), "numpy": version("numpy"),
                              "cma": version("cma")}
    with pytest.raises(TypeError, match="strings"):
        mf.manifest([{"cma": "4.5.0"}])
