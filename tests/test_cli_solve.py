"""``ema-bench solve`` and ``ema-bench solvers`` as a user types them: in the test process
(tests/inprocess.py), and once in a fresh interpreter, where a library's first import would
print its chatter."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from inprocess import CliRun, run_cli

ZOO = ("random", "cmaes", "de", "ngopt", "ng-de", "ng-pso", "least-squares", "nelder-mead",
       "lbfgsb", "powell")
RESULT_KEYS = {"solver", "case", "track", "seed", "x", "fitness", "evaluations", "wall_s",
               "stop_reason", "library"}
TRUTH_KEYS = {"accuracy", "range_error", "success", "truth", "fitness_at_truth",
              "evals_to_success"}
FAULTS = {"Na", "Fst", "BLK", "Gprop"}


def cli(*args: str, cwd: Path | None = None, fresh: bool = False
        ) -> CliRun | subprocess.CompletedProcess:
    """``ema-bench ARGS``; ``fresh``: the console script in a new interpreter."""
    if not fresh:
        return run_cli(*args, cwd=cwd)
    script = Path(sys.executable).with_name("ema-bench")
    cmd = [str(script)] if script.exists() else [sys.executable, "-m", "ema_bench.cli"]
    return subprocess.run([*cmd, *args], capture_output=True, text=True, cwd=cwd, timeout=300)


def solve_json(*args: str, fresh: bool = False) -> dict:
    r = cli("solve", *args, "--json", fresh=fresh)
    assert r.returncode == 0, r.stderr
    assert r.stderr == ""  # no progress bar with --json, no library chatter
    return json.loads(r.stdout)


def test_solve_json_twin():
    out = solve_json("--case", "small", "--track", "twin", "--solver", "random", "--budget",
                     "50", "--seed", "0")
    assert RESULT_KEYS | TRUTH_KEYS <= set(out)
    assert out["solver"] == "random" and out["case"] == "small" and out["track"] == "twin"
    assert out["seed"] == 0
    assert 0 < out["evaluations"] <= 50
    assert set(out["x"]) == set(out["truth"]) == set(out["accuracy"]) == FAULTS
    assert out["truth"] == {"Na": 0.95, "Fst": 0.3378, "BLK": 0.01, "Gprop": 1e5}
    assert isinstance(out["success"], bool)
    first = out["evals_to_success"]
    assert first is None or 1 <= first <= out["evaluations"]
    assert out["fitness"] >= 0 and out["fitness_at_truth"] >= 0
    assert "scipy" in out["library"] and "ema-bench" in out["library"]


def test_solve_json_reference_with_effect_and_raw():
    out = solve_json("--case", "full", "--solver", "cmaes", "--budget", "30", "--seed", "2",
                     "--effect", "eccentricity=0.05", "--raw", fresh=True)
    assert out["track"] == "reference" and out["case"] == "full"
    assert out["evaluations"] <= 30
    assert out["normalised"] is False
    assert out["effects"] == {"eccentricity": 0.05}
    assert TRUTH_KEYS <= set(out)


def test_solve_is_reproducible():
    args = ("--case", "seeded", "--heterogeneity", "0.5", "--track", "twin", "--solver", "de",
            "--budget", "40", "--seed", "7")
    a, b = solve_json(*args), solve_json(*args)
    assert a["x"] == b["x"] and a["fitness"] == b["fitness"] and a["truth"] == b["truth"]
    assert a["case"].startswith("seeded")


def test_solve_human_table():
    r = cli("solve", "--case", "small", "--track", "twin", "--solver", "random", "--budget",
            "20")
    assert r.returncode == 0, r.stderr
    assert r.stderr == ""  # stderr is not a TTY here: no progress bar
    for word in ("estimate", "truth", "accuracy %", "Na", "Gprop", "success"):
        assert word in r.stdout


def test_solve_measured_file_and_plot(tmp_path):
    traces = tmp_path / "traces.csv"
    r = cli("simulate", "--case", "small", "--model", "monitor", "--seed", "1", "--out",
            str(traces))
    assert r.returncode == 0, r.stderr
    png = tmp_path / "fit.png"
    out = solve_json("--measured", str(traces), "--solver", "nelder-mead", "--budget", "30",
                     "--plot", str(png))
    assert RESULT_KEYS <= set(out)
    assert not TRUTH_KEYS & set(out)  # measured data: nothing to score against
    assert out["track"] == "measured" and out["measured"] == str(traces)
    assert out["evaluations"] <= 30
    assert png.stat().st_size > 10_000
    r = cli("solve", "--measured", str(traces), "--solver", "random", "--budget", "10")
    assert r.returncode == 0, r.stderr
    assert "estimate" in r.stdout and "truth" not in r.stdout


def test_solvers_json_and_table():
    r = cli("solvers", "--json")
    assert r.returncode == 0, r.stderr
    listed = {s["name"]: s for s in json.loads(r.stdout)}
    assert set(ZOO) <= set(listed)
    for s in listed.values():
        assert s["description"] and s["library"]
    # every zoo solver declares global or local search, or a baseline (the v2 report's
    # global-vs-local comparison reads it)
    assert {s["scope"] for n, s in listed.items() if n in ZOO} <= {"global", "local",
                                                                    "baseline"}
    r = cli("solvers")
    assert r.returncode == 0
    for name in ZOO:
        assert name in r.stdout
        line = next(x for x in r.stdout.splitlines() if x.split()[0] == name)
        assert line.split()[2] == listed[name]["scope"]


@pytest.mark.parametrize("args, message", [
    (("--solver", "no-such-solver"), "unknown solver 'no-such-solver'"),
    (("--case", "huge"), "unknown case 'huge'"),
    (("--budget", "0"), "argument --budget: must be from 1 to"),
    (("--budget", "-5"), "argument --budget: must be from 1 to"),
    (("--heterogeneity", "2"), "heterogeneity must lie in [0, 1]"),
    (("--seed", "-1"), "argument --seed: must be from 0 to"),
    (("--faults", "Na=2"), "Na=2"),
    (("--faults", "Na"), "expected NAME=VALUE"),
    (("--measured", "missing.csv"), "file not found"),
    (("--effect", "warp=1"), "unknown effect 'warp'"),
])
def test_bad_input_exits_2_with_one_line(args, message, tmp_path):
    r = cli("solve", *args, "--json", cwd=tmp_path)
    assert r.returncode == 2
    assert r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith("ema-bench solve: error:") and message in lines[0]


def test_solve_explicit_faults(tmp_path):
    r = cli("solve", "--faults", "Na=0.9,BLK=0.02", "--track", "twin", "--solver", "powell",
            "--budget", "30", "--json", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    from ema_bench.faults import NOMINAL, faults_to_dict

    assert out["truth"] == {**faults_to_dict(NOMINAL), "Na": 0.9, "BLK": 0.02}
    assert out["case"] == "custom" and out["evaluations"] == 30


def test_solve_effects_reach_the_data(tmp_path):
    """`solve --effect` switches the effect on in the model that makes the data: the fitness
    at the truth is the API's for the same effect, and not the one without it."""
    from ema_bench.seeding import run_seed
    from ema_bench.suites.problem import make_problem

    r = cli("solve", "--case", "small", "--track", "twin", "--effect", "delay=6e-4",
            "--solver", "random", "--budget", "2", "--json", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    with_effect = make_problem("small", track="twin", seed=run_seed(0, 0), budget=1,
                               effects={"delay": 6e-4}).fitness_at_truth()
    without = make_problem("small", track="twin", seed=run_seed(0, 0),
                           budget=1).fitness_at_truth()
    assert out["fitness_at_truth"] == with_effect
    assert with_effect > 2 * without
    assert out["effects"] == {"delay": 6e-4}
