"""The v3 board's measured cost (``benchmarks/board_cost.py``): the plan it samples is the
documented command's, the strata are named right, the stratified estimate and its interval
by hand, and a timed rerun of a committed record is compared with it (an edited record
differs)."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def bc():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    sys.modules.pop("board_cost", None)
    try:
        import board_cost
        yield board_cost
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))


def test_the_plan_is_the_documented_commands(bc):
    """The sampled plan is docs/suite-v3.md's board command, and holds 5,936 runs: tier 4's
    23 instances x 4 conditions, tiers 7 and 12's 20 x 3 (step-only is a tier-4 condition),
    x 2 tracks x 7 solvers x 2 seeds, in 140 strata of 46 or 40 runs."""
    doc = (ROOT / "docs" / "suite-v3.md").read_text()
    cmd = re.search(r"nice ema-bench leaderboard --suite emafdi-v3 --tiers (\S+) \\\s+"
                    r"--conditions (\S+) --tracks (\S+) \\\s+--seeds (\d+) --solvers (\S+)", doc)
    assert cmd is not None
    tiers, conds, tracks, seeds, solvers = cmd.groups()
    assert (tuple(tiers.split(",")), tuple(conds.split(",")), tuple(tracks.split(",")),
            int(seeds), tuple(solvers.split(","))) == (
        bc.PLAN["tiers"], bc.PLAN["conditions"], bc.PLAN["tracks"], bc.PLAN["seeds"],
        bc.PLAN["solvers"])
    tasks = bc.plan_tasks()
    assert len(tasks) == (23 * 4 + 20 * 3 + 20 * 3) * 2 * 7 * 2 == 5936
    sizes: dict[str, int] = {}
    for t in tasks:
        s = bc.stratum(t.case, t.track, t.solver)
        sizes[s] = sizes.get(s, 0) + 1
    assert len(sizes) == 140
    assert {n for s, n in sizes.items() if s.startswith("4|")} == {46}
    assert {n for s, n in sizes.items() if not s.startswith("4|")} == {40}


def test_a_runs_stratum_names_its_tier_condition_track_and_solver(bc):
    assert bc.stratum("v3-t12-s06@prior", "twin", "de") == "12|prior|twin|de"
    assert bc.stratum("v3-t7-s19@surface-current", "reference", "powell") == \
        "7|surface-current|reference|powell"
    # the paper cases and v3-sNN are tier 4 (sNN must not read as a tier)
    assert bc.stratum("v3-small@no-prior", "reference", "cmaes") == "4|no-prior|reference|cmaes"
    assert bc.stratum("v3-s11@step-only", "twin", "lbfgsb") == "4|step-only|twin|lbfgsb"


def test_the_draw_is_k_distinct_runs_of_each_stratum_and_seeded(bc):
    pools = {"a": [f"a{i}" for i in range(40)], "b": [f"b{i}" for i in range(46)],
             "c": ["c0"]}
    d = bc.draw(pools, 2, seed=44)
    assert {s: len(v) for s, v in d.items()} == {"a": 2, "b": 2, "c": 1}
    assert all(len(set(v)) == len(v) and set(v) <= set(pools[s]) for s, v in d.items())
    assert bc.draw(pools, 2, seed=44) == d
    others = [bc.draw(pools, 2, seed=s) for s in range(45, 50)]
    assert any(o != d for o in others)


def test_the_stratified_estimate_and_its_interval_by_hand(bc):
    """Stratum a: 10 planned runs, sampled 1 and 3 CPU-s; b: 20 runs, one sample of 6; c:
    planned, never sampled.  Point: (10 x 2 + 20 x 6) / 3600 h; a bootstrap resample of a's
    two values has mean 1, 2 or 3 (a quarter of the time each extreme), b's is fixed, so the
    95 % interval is (10 x 1 + 120, 10 x 3 + 120) / 3600; the wall time on 2 cores is half."""
    e = bc.estimate({"a": 10, "b": 20, "c": 5}, {"a": [1.0, 3.0], "b": [6.0]})
    assert e["cpu_h"] == pytest.approx(140 / 3600, rel=1e-12)
    assert e["cpu_h_95"] == pytest.approx([130 / 3600, 150 / 3600], rel=1e-12)
    assert e["wall_h"] == pytest.approx(70 / 3600, rel=1e-12)
    assert e["wall_h_95"] == pytest.approx([65 / 3600, 75 / 3600], rel=1e-12)
    assert (e["strata"], e["runs"], e["missing"]) == (2, 30, ["c"])


def test_a_timed_rerun_is_compared_with_its_committed_record(bc, tmp_path):
    """The cheapest committed record (a tier-4 ``de`` run, under a second) rerun: reproduced,
    its line carries CPU and recorded wall time; the same record with its final vector
    edited is named as differing, and a rerun of the script's loop skips what is written."""
    store = ROOT / "leaderboards" / "v3" / "runs.jsonl"
    if not store.is_file():
        pytest.skip("no committed v3 store")
    key = "de|v3-s18@step-only|reference|1"
    rec = next(json.loads(ln) for ln in store.read_text().splitlines() if key in ln)
    assert rec["key"] == key
    task = next(t for t in bc.plan_tasks() if t.key == key)
    out = tmp_path / "cost.jsonl"
    edited = {**rec, "x": {**rec["x"], "Na": rec["x"]["Na"] * (1 + 1e-9)}}
    bc._time_one(task, {key: rec}, out)
    bc._time_one(task, {key: edited}, out)
    first, second = (json.loads(ln) for ln in out.read_text().splitlines())
    assert first["differs"] is None and second["differs"] == "x"
    assert first["stratum"] == "4|step-only|reference|de"
    assert first["recorded_wall_s"] == rec["wall_s"] and first["cpu_s"] > 0
    bc.measure([task], {}, out)          # already timed: nothing run, nothing appended
    assert len(out.read_text().splitlines()) == 2


def test_the_committed_measurement_is_the_seeded_draw_and_the_docs_quote_it(bc):
    """``benchmarks/results/v3_board_cost.jsonl`` holds exactly the runs the documented
    command draws (2 of each of the 140 strata, seed 44: a sample left without its dearest
    runs, or timed on fewer, fails), none of its reruns differed from its record, and
    docs/suite-v3.md quotes the estimate computed from it here."""
    lines = [json.loads(ln) for ln in
             (ROOT / "benchmarks" / "results" / "v3_board_cost.jsonl").read_text().splitlines()]
    tasks = bc.plan_tasks()
    by: dict[str, list[str]] = {}
    for t in tasks:
        by.setdefault(bc.stratum(t.case, t.track, t.solver), []).append(t.key)
    drawn = {k for ks in bc.draw(by, 2, 44).values() for k in ks}
    assert sorted(ln["key"] for ln in lines) == sorted(drawn) and len(drawn) == 280
    assert all(ln["stratum"] == bc.stratum(*_case_track_solver(ln["key"])) for ln in lines)
    assert all(ln["cpu_s"] > 0 for ln in lines)
    r = bc.report(tasks, lines)
    assert r["replayed"]["runs"] > 0 and r["replayed"]["differ"] == []
    doc = (ROOT / "docs" / "suite-v3.md").read_text()
    b = r["board"]
    assert b["missing"] == [] and b["runs"] == 5936
    assert (f"| board | 5,936 | **{b['cpu_h']:.2f} [{b['cpu_h_95'][0]:.2f}, "
            f"{b['cpu_h_95'][1]:.2f}]** | **{b['wall_h']:.2f}** |") in doc
    for tier, e in r["by_tier"].items():
        assert (f"| {tier} | {e['runs']:,} | {e['cpu_h']:.2f} [{e['cpu_h_95'][0]:.2f}, "
                f"{e['cpu_h_95'][1]:.2f}] | {e['wall_h']:.2f} |") in doc
    prose = " ".join(doc.split())            # the paragraphs' line breaks are spaces
    assert f"**{b['cpu_h']:.1f} CPU-h, {b['wall_h']:.1f} h of wall time on 2 cores**" in prose
    assert b["wall_h_95"][1] <= 12        # the limit for the regeneration
    p = r["replayed"]
    assert f"{p['recorded_wall_s']:,.0f} s against {p['cpu_s_here']:,.0f} CPU-s" in prose


def _case_track_solver(key: str) -> tuple[str, str, str]:
    solver, case, track, _seed = key.split("|")
    return case, track, solver
