"""``ema-bench validate``: third-party records are accepted only when they are what they claim
(suite, manifest, budget, every trajectory vector re-evaluated, every figure re-derived).
tests/test_integrity.py holds the forgeries."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import evidence
import pytest

from ema_bench.leaderboard.tasks import Task, error_record, run_task
from ema_bench.leaderboard.validate import check_complete, check_record, validate

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def records() -> list[dict]:
    # real runs: a seeded instance and a paper case on both tracks
    return [run_task(Task("powell", c, t, 0, 60)) for c in ("s01", "small")
            for t in ("twin", "reference")]


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ema_bench.cli", *args], capture_output=True,
                          text=True, cwd=ROOT, timeout=600)


def write(path: Path, recs: list[dict]) -> Path:
    path.write_text("".join(json.dumps(r) + "\n" for r in recs))
    return path


def test_real_records_are_accepted(records):
    assert validate(records, complete=False) == []


def test_a_fitness_that_its_vector_does_not_have_is_refused(records):
    r = dict(records[0])
    # a plausible lie: a slightly better fitness, the trace doctored to agree with it
    f = records[0]["fitness"] * 0.999
    tj = [list(p) for p in records[0]["trajectory"]]
    tj[-1] = [tj[-1][0], f, tj[-1][2]]
    r.update(fitness=f, trajectory=tj, trace=[[p[0], p[1]] for p in tj])
    if records[0]["trace"][-1][0] != tj[-1][0]:
        r["trace"].append([records[0]["trace"][-1][0], f])
    for b in r["best_at"]:
        if b[0] >= tj[-1][0]:
            b[1] = f
    (msg,) = check_record(r)
    assert msg.startswith(f"fitness at evaluation {tj[-1][0]}: claimed {f!r}, re-derived ")
    assert msg.endswith("(re-evaluated from its vector)")
    # a vector moved, its fitness kept: also caught (x must be the trajectory's last vector)
    r2 = {**records[1], "x": {**records[1]["x"], "Fst": records[1]["x"]["Fst"] * 1.01}}
    assert any(m.startswith("x: claimed ") for m in check_record(r2))


def test_wrong_versions_missing_manifest_and_overspent_budget_are_refused(records):
    r = records[0]
    assert any("suite version 'emafdi-v0'" in m
               for m in check_record({**r, "suite": "emafdi-v0"}, reevaluate=False))
    assert any("model version" in m
               for m in check_record({**r, "model_version": "1"}, reevaluate=False))
    no_man = {k: v for k, v in r.items() if k != "manifest"}
    assert any("missing field(s) ['manifest']" in m for m in check_record(no_man))
    thin = {**r, "manifest": {k: v for k, v in r["manifest"].items() if k != "cpu"}}
    assert any("manifest lacks ['cpu']" in m for m in check_record(thin, reevaluate=False))
    over = {**r, "evaluations": r["budget"] + 1}
    assert any("with a budget of" in m for m in check_record(over, reevaluate=False))
    lie = {**r, "truth": {**r["truth"], "Fst": 0.5}}
    assert any(m.startswith("truth: claimed {") for m in check_record(lie, reevaluate=False))
    late = {**r, "targets": {**r["targets"], "parameters": {"0.1": r["budget"] + 5,
                                                            "0.03": None, "0.01": None}}}
    assert any(m.startswith("targets.parameters: claimed {'0.1': 65")
               for m in check_record(late, reevaluate=False))
    unknown = {**r, "case": "s42"}
    assert any("not an instance of suite" in m for m in check_record(unknown))


def test_fitness_targets_reached_out_of_order_are_refused(records):
    r = records[0]
    fit = dict(r["targets"]["fitness"])
    fit["0.0001"], fit["0.1"] = 5, None      # the finest reached, the coarsest not
    bad = {**r, "targets": {**r["targets"], "fitness": fit}}
    (msg,) = check_record(bad, reevaluate=False)
    assert msg == f"targets.fitness: claimed {fit!r}, re-derived {r['targets']['fitness']!r}"


def test_error_records_pass_and_a_submission_must_cover_the_suite(records):
    err = error_record(Task("powell", "s02", "twin", 0, 60), RuntimeError("boom"))
    assert check_record(err) == []
    (finding,) = [f for f in check_complete(records) if "twin" in f.problem]
    assert finding.key == "*"
    # 23 non-sanity instances, 2 run on seed 0: 21 lacking
    assert "powell on the twin track lacks 21 runs" in finding.problem


def test_cli_exit_codes(records, tmp_path):
    good = write(tmp_path / "good.jsonl", records)
    res = cli("validate", str(good), "--partial", "--json")
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    assert out["accepted"] and out["records"] == 4
    bad = write(tmp_path / "bad.jsonl", [{**records[0], "suite": "emafdi-v0"}])
    res = cli("validate", str(bad), "--partial")
    assert res.returncode == 1 and "REFUSED" in res.stdout and "emafdi-v0" in res.stdout
    res = cli("validate", str(good))                 # incomplete without --partial
    assert res.returncode == 1 and "lacks" in res.stdout
    res = cli("validate", str(tmp_path / "missing.jsonl"))
    assert res.returncode == 2 and "no such file" in res.stderr


def test_a_fitness_below_the_best_known_is_refused_beyond_its_tolerance():
    # f* - 2e-4 of the gap: refused; f* - 0.5e-4 of the gap: within the 1e-4 tolerance
    x = evidence.vector("small", 0.3)
    below = evidence.record([(1, evidence.level("small", "twin", 0, 0.5), x),
                             (5, evidence.level("small", "twin", 0, -2e-4), x)])
    (msg,) = check_record(below, reevaluate=False)
    assert msg.startswith("fitness ") and "beats the suite's best known" in msg
    near = evidence.record([(1, evidence.level("small", "twin", 0, 0.5), x),
                            (5, evidence.level("small", "twin", 0, -0.5e-4), x)])
    assert check_record(near, reevaluate=False) == []
