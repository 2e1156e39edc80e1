"""f* at any root seed (issue 45): ``ema-bench targets --root-seed R``, and the board, the
export and validate ranking on it with ``--targets``, or saying plainly that they cannot."""

from __future__ import annotations

import json

import pytest

from ema_bench.leaderboard.run_store import read_records
from ema_bench.seeding import run_seed
from ema_bench.suites import best_known as bk
from ema_bench.suites import find
from ema_bench.suites.problem import make_problem
from ema_bench.suites.targets import TARGETS_ENV, SuiteError
from ema_bench.suites.v1 import best_known, shipped_targets


def best_known_for(case: str, track: str, seed: int, root_seed: int) -> dict | None:
    """The entry a run of ``case`` is scored on (what the re-derivation looks up)."""
    return find(case).best_known(track, seed, root_seed)

#: a short polish (the real one spends 2700 evaluations, ~8 CPU-s an entry)
SHORT = (("least-squares", 40, "truth"),)
NO_TABLE = {TARGETS_ENV: ""}


@pytest.fixture(scope="module")
def table70(tmp_path_factory):
    """A best-known table of root seed 70 for small@twin seed 0, by the real polish."""
    out = tmp_path_factory.mktemp("t70") / "t70.json"
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(bk, "STAGES", SHORT)
        bk.compute_targets(out, workers=1, quiet=True, keys=["small|twin|0"], root_seed=70)
    return out


def test_the_table_is_polished_on_the_root_seeds_own_noise(table70, monkeypatch):
    data = json.loads(table70.read_text())
    assert data["method"]["root_seed"] == 70
    entry = data["entries"]["small|twin|0"]
    # the data of root seed 70 (its own noise draw), independently of the table's code
    p = make_problem("small", track="twin", seed=run_seed(70, 0), budget=2)
    assert entry["fitness_at_truth"] == p.fitness_at_truth()
    assert entry["f_star"] <= p.fitness_at_truth() < entry["f_nominal"]
    shipped = shipped_targets()["entries"]["small|twin|0"]
    assert entry["fitness_at_truth"] != shipped["fitness_at_truth"]   # other noise
    # used only where named, and only for its own root seed
    assert best_known_for("small", "twin", 0, 70) is None
    monkeypatch.setenv(TARGETS_ENV, str(table70))
    assert best_known_for("small", "twin", 0, 70)["f_star"] == entry["f_star"]
    assert best_known("small", "twin", 0, 71) is None
    assert best_known("small", "twin", 0, 0)["f_star"] == shipped["f_star"]
    monkeypatch.setenv(TARGETS_ENV, str(table70.with_name("missing.json")))
    with pytest.raises(SuiteError, match="no such best-known table"):
        best_known("small", "twin", 0, 70)
    root0 = table70.with_name("root0.json")
    root0.write_text(json.dumps({**data, "method": {**data["method"], "root_seed": 0}}))
    monkeypatch.setenv(TARGETS_ENV, str(root0))
    with pytest.raises(SuiteError, match="the package ships"):
        best_known("small", "twin", 0, 70)
    # a table labelled with another model version than its suite's is refused where used,
    # never read as if it were the suite's (v1 is on version 3, v3 on 4)
    other = table70.with_name("v4.json")
    other.write_text(json.dumps({**data, "model_version": "4"}))
    monkeypatch.setenv(TARGETS_ENV, str(other))
    with pytest.raises(SuiteError, match="on model version '4', not 3"):
        best_known("small", "twin", 0, 70)
    v3 = table70.with_name("v3.json")
    v3.write_text(json.dumps({**data, "suite": "emafdi-v3"}))   # v3's table labelled 3
    monkeypatch.setenv(TARGETS_ENV, str(v3))
    with pytest.raises(SuiteError, match="emafdi-v3 on model version '3', not 4"):
        best_known_for("v3-small@prior", "twin", 0, 70)


def test_a_partial_file_of_another_root_seed_is_refused(table70, monkeypatch):
    monkeypatch.setattr(bk, "STAGES", SHORT)
    with pytest.raises(SuiteError, match="root seed 70"):
        bk.compute_targets(table70, workers=1, quiet=True, keys=["small|twin|0"], root_seed=3)


def test_board_export_and_validate_at_root_seed_70(table70, tmp_path, cli):
    board = ["leaderboard", "--solvers", "random", "--cases", "small", "--tracks", "twin",
             "--seeds", "1", "--budget", "30", "--root-seed", "70", "--no-plots",
             "--executor", "serial"]
    # no table: the board says it ranks on parameter targets only, and how to fix it
    res = cli(*board, "--out", tmp_path / "bare", env=NO_TABLE, check=True)
    assert "Targets: parameter targets only" in res.stdout
    assert "--root-seed 70" in res.stdout
    header = (tmp_path / "bare" / "leaderboard_twin.md").read_text().splitlines()[2]
    assert "parameter targets only" in header
    res = cli("export", "--format", "ioh", tmp_path / "bare" / "runs.jsonl", "--value",
              "precision", "--out", tmp_path / "x", env=NO_TABLE)
    assert res.returncode == 2 and "--targets" in res.stderr
    res = cli("export", "--format", "ioh", tmp_path / "bare" / "runs.jsonl", "--out",
              tmp_path / "raw", env=NO_TABLE, check=True)
    assert "f* (run attribute, fitness targets) on 0 of 1 runs" in res.stdout
    assert "targets --root-seed 70" in res.stdout
    # with the table: fitness targets, validate accepts, the export carries f*
    res = cli(*board, "--targets", table70, "--out", tmp_path / "lb", env=NO_TABLE,
              check=True)
    assert "Targets: fitness (best-known f*) and parameter targets." in res.stdout
    (rec,) = read_records(tmp_path / "lb" / "runs.jsonl")
    f_star = json.loads(table70.read_text())["entries"]["small|twin|0"]["f_star"]
    assert rec["targets"]["f_star"] == f_star and rec["targets"]["fitness"] is not None
    runs = tmp_path / "lb" / "runs.jsonl"
    assert cli("validate", runs, "--partial", "--targets", table70, env=NO_TABLE).returncode == 0
    assert cli("validate", runs, "--partial", env=NO_TABLE).returncode != 0
    res = cli("export", "--format", "ioh", runs, "--value", "precision", "--targets", table70,
              "--out", tmp_path / "ioh", env=NO_TABLE, check=True)
    assert "f* (run attribute, fitness targets) on 1 of 1 runs\n" in res.stdout
    (meta,) = (tmp_path / "ioh").rglob("IOHprofiler_*.json")
    run = json.loads(meta.read_text())["scenarios"][0]["runs"][0]
    assert run["f_star"] == f_star and run["root_seed"] == 70
    # a --targets file that is not there: one line, exit 2, before any work
    res = cli(*board, "--targets", tmp_path / "nope.json", "--out", tmp_path / "n",
              env=NO_TABLE)
    assert res.returncode == 2 and "no such best-known table" in res.stderr
    assert not (tmp_path / "n").exists()
