"""Solver plugins: the zoo and third-party packages register through the same entry points.

The third-party test builds a throw-away package (its own pyproject.toml, setuptools, an
``ema_bench.solvers`` entry point) in ``tmp_path``, installs it into a private ``--target``
folder with pip (no network: ``--no-index --no-build-isolation``) and runs the real CLI in a
subprocess with that folder on ``PYTHONPATH``: entry points are discovered from the package
metadata found on ``sys.path``, exactly as for a package installed into site-packages.
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from ema_bench import available_solvers
from ema_bench.registry import ENTRY_POINT_GROUP

ZOO = ("random", "cmaes", "de", "ngopt", "ng-de", "ng-pso", "least-squares", "nelder-mead",
       "lbfgsb", "powell")
PLUGIN = "test-plugin-grid"


def cli(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    script = Path(sys.executable).with_name("ema-bench")
    cmd = [str(script)] if script.exists() else [sys.executable, "-m", "ema_bench.cli"]
    return subprocess.run([*cmd, *args], capture_output=True, text=True, env=env, timeout=300)


def test_zoo_is_found_through_entry_points():
    eps = {ep.name: ep for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP)}
    assert set(ZOO) <= set(eps)
    assert "paper-ga" in eps  # declared; its module is written separately
    for name in ZOO:
        assert eps[name].value.startswith("ema_bench_solvers."), eps[name]
    registered = available_solvers()
    for name in ZOO:
        assert name in registered
        info = registered[name]
        assert info.description and "\n" not in info.description
        assert info.library
        assert info.func.__module__ == eps[name].value


PYPROJECT = f"""\
[build-system]
requires = ["setuptools>=61"]
build-backend = "setuptools.build_meta"

[project]
name = "ema-bench-test-plugin"
version = "0.0.1"
description = "throw-away ema-bench solver plugin for the test suite"
requires-python = ">=3.11"

[project.entry-points."ema_bench.solvers"]
{PLUGIN} = "ema_test_plugin.grid"
test-plugin-broken = "ema_test_plugin.broken"

[tool.setuptools]
packages = ["ema_test_plugin"]
"""

GRID = f'''\
"""A plugin solver: a coarse random grid search, in batches, within the budget."""
import time

import numpy as np

from ema_bench.faults import from_unit
from ema_bench.registry import finish, register_solver


@register_solver("{PLUGIN}", description="test plugin: seeded random probes", library="numpy")
def solve(problem, budget, seed):
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    problem.evaluate(problem.nominal[None, :])
    while problem.remaining > 0:
        k = min(8, problem.remaining)
        problem.evaluate(from_unit(rng.random((k, problem.dim))))
    return finish(problem, "{PLUGIN}", "budget", t0, libraries=("numpy",), plugin=True)
'''


def _install(pkg: Path, site: Path) -> None:
    """pip-install ``pkg`` into ``site``; setuptools < 70.1 cannot build a wheel without the
    separate ``wheel`` package, so fall back to its ``egg_info`` metadata (also discovered by
    ``importlib.metadata``) plus the package files."""
    r = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
                        "--no-build-isolation", "--no-index", "--target", str(site), str(pkg)],
                       capture_output=True, text=True, timeout=300)
    if r.returncode == 0:
        return
    if "bdist_wheel" not in r.stdout + r.stderr:
        pytest.fail(f"pip install of the test plugin failed:\n{r.stdout}\n{r.stderr}")
    site.mkdir(exist_ok=True)
    r = subprocess.run([sys.executable, "-c", "from setuptools import setup; setup()",
                        "egg_info", "--egg-base", str(site)], cwd=pkg, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    shutil.copytree(pkg / "ema_test_plugin", site / "ema_test_plugin")


@pytest.fixture(scope="module")
def plugin_env(tmp_path_factory) -> dict[str, str]:
    root = tmp_path_factory.mktemp("plugin")
    pkg = root / "pkg"
    (pkg / "ema_test_plugin").mkdir(parents=True)
    (pkg / "pyproject.toml").write_text(PYPROJECT)
    (pkg / "ema_test_plugin" / "__init__.py").write_text("")
    (pkg / "ema_test_plugin" / "grid.py").write_text(GRID)
    (pkg / "ema_test_plugin" / "broken.py").write_text(
        textwrap.dedent("""\
            raise ImportError("this plugin is broken on purpose")
        """))
    site = root / "site"
    _install(pkg, site)
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(site), env.get("PYTHONPATH")]))
    return env


def test_plugin_is_listed(plugin_env):
    r = cli("solvers", "--json", env=plugin_env)
    assert r.returncode == 0, r.stderr
    listed = {s["name"]: s for s in json.loads(r.stdout)}
    assert PLUGIN in listed
    assert listed[PLUGIN]["library"] == "numpy"
    assert listed[PLUGIN]["description"] == "test plugin: seeded random probes"
    assert set(ZOO) <= set(listed)  # a broken plugin does not take the zoo down
    assert "test-plugin-broken" in r.stderr and "failed to load" in r.stderr
    r = cli("solvers", env=plugin_env)
    assert r.returncode == 0 and PLUGIN in r.stdout


def test_plugin_solves(plugin_env):
    r = cli("solve", "--case", "small", "--track", "twin", "--solver", PLUGIN, "--budget", "20",
            "--seed", "3", "--json", env=plugin_env)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["solver"] == PLUGIN
    assert out["evaluations"] == 20
    assert out["extra"] == {"plugin": True}
    assert set(out["x"]) == {"Na", "Fst", "BLK", "Gprop"}


def test_plugin_not_visible_without_its_path():
    r = cli("solvers", "--json")
    assert r.returncode == 0, r.stderr
    assert PLUGIN not in {s["name"] for s in json.loads(r.stdout)}


def test_configured_variants_share_one_function():
    """One function, several names: each run gets its variant's keywords (nevergrad's
    optimizer, scipy's method), and a name cannot be re-registered with other keywords."""
    import time

    from ema_bench import make_problem
    from ema_bench.registry import SolverError, finish, get_solver, register_solver, run_solver

    seen = []

    def solve(problem, budget, seed, *, step):
        seen.append(step)
        x = problem.nominal.copy()
        problem.evaluate(x)
        return finish(problem, "variant", "done", time.perf_counter())

    register_solver("test-variant-a", description="a", library="numpy", step=0.1)(solve)
    register_solver("test-variant-b", description="b", library="numpy", step=0.2)(solve)
    assert get_solver("test-variant-b").config == {"step": 0.2}
    res = run_solver("test-variant-b", make_problem("nominal", track="twin", budget=3), seed=0)
    assert seen == [0.2] and res.solver == "test-variant-b" and res.evaluations == 1
    register_solver("test-variant-a", description="a", library="numpy", step=0.1)(solve)
    with pytest.raises(SolverError, match="registered twice"):
        register_solver("test-variant-a", description="a", library="numpy", step=0.3)(solve)
    # the zoo's variants: nevergrad and scipy minimize register keywords, not wrappers
    assert get_solver("ng-de").config == {"optimizer": "TwoPointsDE", "name": "ng-de"}
    assert get_solver("powell").config == {"method": "Powell", "name": "powell"}
    assert get_solver("powell").func is get_solver("nelder-mead").func
