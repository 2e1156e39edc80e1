"""COCO scores and the regression check against hand-computed values from hand-written
records (not via the scoring module): the cases where the formulas of plausible bugs differ.

ERT = (evaluations to the first success of each successful run + the budget of each failed
run) / successes.  A group where all runs succeed or all fail cannot tell "divide by runs"
from "divide by successes", nor "charge the budget" from "charge the evaluations to success":
every group here mixes successes and failures with evaluations to success below the budget.
"""

from __future__ import annotations

import math
from pathlib import Path

import evidence
import pytest

from ema_bench.leaderboard.check import compare
from ema_bench.leaderboard.derive import derived
from ema_bench.leaderboard.judge import JudgeError
from ema_bench.leaderboard.scores import ALL, ert, run_cost, score_records
from ema_bench.suites.v1 import SUITE_ID

FAULTS = ("Na", "Fst", "BLK", "Gprop")


def rec(solver: str, seed: int, first: int | None, budget: int = 1000, case: str = "small",
        track: str = "twin", fitness: float = 1e-4, root_seed: int = 1) -> dict:
    """A hand-written run record: its best-so-far point is 30 % of Na's range off the truth
    from evaluation 1, and 0.5 % off (a success) from ``first`` on (never for None).  Root
    seed 1: the suite has no f* there, so only the three parameter targets count."""
    pts = [(1, 10 * fitness, evidence.vector(case, 0.3))]
    if first is not None:
        pts = [(1, 10 * fitness, evidence.vector(case, 0.3))] if first > 1 else []
        pts.append((first, fitness, evidence.vector(case, 0.005)))
    else:
        pts.append((2, fitness, evidence.vector(case, 0.3)))
    return evidence.record(pts, solver=solver, case=case, track=track, seed=seed,
                           budget=budget, root_seed=root_seed)


#: Accuracy and range error of the successful runs' final vector (Na 0.5 % of its range off),
#: by hand: Na's range is 1.0 - 0.8, small's Na is 0.95.
RANGE_ERROR_OK = {"Na": 0.005, "Fst": 0.0, "BLK": 0.0, "Gprop": 0.0}
ACCURACY_OK = {"Na": 100 * (1 - 0.005 * 0.2 / 0.95), "Fst": 100.0, "BLK": 100.0,
               "Gprop": 100.0}


MIXED = [rec("a", 0, 100), rec("a", 1, None), rec("a", 2, 300)]


def test_ert_by_hand():
    # (100 + 1000 + 300) / 2 successes = 700 (dividing by the 3 runs would give 466.7;
    # charging successful runs their budget, (1000 + 1000 + 1000) / 2 = 1500)
    assert ert(MIXED) == pytest.approx(700.0)
    assert ert([rec("a", 0, None), rec("a", 1, None)]) == math.inf
    assert ert([rec("a", 0, 40)]) == pytest.approx(40.0)


def test_group_score_by_hand():
    (s,) = [x for x in score_records(MIXED) if x.case == "small"]
    assert (s.runs, s.successes) == (3, 2)
    assert s.success_rate == pytest.approx(2 / 3)
    assert s.ert == pytest.approx(700.0)
    assert s.median_evals_to_success == pytest.approx(200.0)   # median of 100 and 300
    # the all-cases row pools the runs of every case: (100 + 1000 + 300 + 50 + 1000) / 3
    pooled = MIXED + [rec("a", 0, 50, case="full"), rec("a", 1, None, case="full")]
    (row,) = [x for x in score_records(pooled) if x.case == ALL]
    assert row.ert == pytest.approx(2450.0 / 3)
    assert row.success_rate == pytest.approx(3 / 5)


def _area(hit: int, budget: int = 1000) -> float:
    # by hand: a target reached at h of B is worth (ln B - ln h) / ln B
    return (math.log(budget) - math.log(hit)) / math.log(budget)


def test_check_flags_a_lower_ecdf_area_and_names_its_values():
    committed = [rec("a", k, 100 + 10 * k) for k in range(6)]
    now = [rec("a", k, 900 + 10 * k) for k in range(6)]
    (r,) = compare(now, committed)
    assert (r.track, r.case, r.solver) == ("twin", ALL, "a")
    assert r.what.startswith("ECDF area")
    assert r.committed == pytest.approx(sum(_area(100 + 10 * k) for k in range(6)) / 6)
    assert r.now == pytest.approx(sum(_area(900 + 10 * k) for k in range(6)) / 6)
    # complete separation of 6 against 6: exact one-sided p = 1 / C(12, 6) = 1/924
    assert "p=0.0011" in r.what
    assert compare(committed, now) == []      # better than the baseline: no regression
    assert compare(committed, committed) == []


def test_check_tolerates_one_worse_run_and_splits_alpha_over_comparisons():
    committed = [rec("a", k, 100 + 10 * k) for k in range(6)]
    one_worse = [rec("a", 0, 900)] + committed[1:]
    assert compare(one_worse, committed) == []
    # 4 against 4, completely separated: p = 1/70 = 0.0143 < 0.05 alone ...
    c4 = [rec("b", k, 100 + 10 * k) for k in range(4)]
    n4 = [rec("b", k, 900 + 10 * k) for k in range(4)]
    assert [r.solver for r in compare(n4, c4)] == ["b"]
    # ... but not below 0.05 / 4 when three other solvers are compared at the same time
    others = [rec(s, k, 100 + 10 * k) for s in "xyz" for k in range(4)]
    assert compare(n4 + others, c4 + others) == []
    assert [r.solver for r in compare(n4 + others, c4 + others, alpha=0.2)] == ["b"]
    # the level is strict: p exactly alpha / comparisons (1/70 here) is no regression
    assert compare(n4, c4, alpha=1 / 70) == []
    assert [r.solver for r in compare(n4, c4, alpha=1 / 70 * 1.0001)] == ["b"]


def test_check_goes_on_after_a_solver_whose_runs_are_identical():
    same = [rec("a", k, 100 + 10 * k) for k in range(6)]   # "a" sorts first: unchanged
    c6 = [rec("b", k, 100 + 10 * k) for k in range(6)]
    n6 = [rec("b", k, 900 + 10 * k) for k in range(6)]
    assert [r.solver for r in compare(same + n6, same + c6)] == ["b"]


def test_check_compares_only_the_runs_both_hold_and_skips_the_sanity_case():
    committed = [rec("a", k, 100 + 10 * k) for k in range(6)]
    # today's sweep also ran seeds 6-11 (failures) and another solver: none has a committed
    # counterpart, so none is compared
    now = committed + [rec("a", k, None) for k in range(6, 12)] + [rec("z", 0, None)]
    assert compare(now, committed) == []
    # the healthy actuator is a sanity row, never part of the test
    c = [rec("a", k, 100 + 10 * k, case="nominal") for k in range(6)]
    n = [rec("a", k, None, case="nominal") for k in range(6)]
    assert compare(n, c) == []


def test_check_refuses_another_suite_version_naming_both():
    committed = [{**rec("a", k, 100), "suite": "emafdi-v0"} for k in range(3)]
    legacy = {k: v for k, v in rec("a", 3, 100).items() if k != "suite"}
    with pytest.raises(ValueError) as err:
        compare([rec("a", k, 100) for k in range(3)], committed + [legacy])
    assert str(err.value) == (
        f"the baseline holds runs of suite version emafdi-v0, none; this is {SUITE_ID}: their "
        "targets differ and they cannot be compared (regenerate the baseline with this "
        "version, leaderboards/README.md)")
    with pytest.raises(ValueError, match="^this run holds runs of suite version emafdi-v0;"):
        compare(committed, [rec("a", k, 100) for k in range(3)])
    with pytest.raises(ValueError, match="version none"):
        compare([rec("a", 0, 100)], [{k: v for k, v in rec("a", 0, 100).items()
                                      if k != "suite"}])


def test_run_cost_of_a_run_that_lost_its_success():
    # a run whose best-so-far point was within 1 % at 50, then moved 2 % off (a lower
    # fitness elsewhere): it ends outside the target, a failure that costs its budget
    lost = evidence.record([(1, 1.0, evidence.vector("small", 0.3)),
                            (50, 0.5, evidence.vector("small", 0.005)),
                            (200, 0.1, evidence.vector("small", 0.02))],
                           budget=1000, root_seed=1)
    assert derived(lost).parameter_hits["0.01"] == 50 and not derived(lost).success
    assert run_cost(lost) == 1000 and run_cost(rec("a", 1, 100)) == 100
    assert ert([lost, rec("a", 1, 100)]) == pytest.approx((1000 + 100) / 1)


def test_group_score_reports_every_field():
    recs = [{**rec("a", 0, 100, fitness=1e-4), "wall_s": 1.0},
            {**rec("a", 1, None, fitness=3e-4), "wall_s": 3.0},
            {**rec("a", 2, 300, fitness=2e-4), "wall_s": 2.0}]
    (s,) = [x for x in score_records(recs) if x.case == "small"]
    assert (s.track, s.case, s.solver) == ("twin", "small", "a")
    assert s.median_fitness == pytest.approx(2e-4) and s.median_wall_s == pytest.approx(2.0)
    # medians of two runs 0.5 % off and one 30 % off: the 0.5 % figures
    assert s.accuracy == pytest.approx(ACCURACY_OK)
    assert s.range_error == pytest.approx(RANGE_ERROR_OK)
    # the claims are not read: a record claiming a perfect fit scores the same
    forged = [{**r, "accuracy": dict.fromkeys(FAULTS, 100.0),
               "range_error": dict.fromkeys(FAULTS, 0.0), "fitness": 0.0} for r in recs]
    assert [x for x in score_records(forged) if x.case == "small"] == [s]


def test_baseline_truncation_edges():
    from ema_bench.leaderboard.check import baseline

    records = [rec("a", 5, 10, budget=5000),       # a seed beyond the check, listed first
               rec("a", 0, 400, budget=5000),      # success exactly at the truncated budget
               rec("a", 1, 401, budget=5000),      # one evaluation too late
               rec("a", 2, 10, budget=5000)]       # seed == seeds: beyond the check
    base, used = baseline(records, 400, 2)
    got = {r["seed"]: (r["budget"], derived(r).success) for r in base}
    assert got == {0: (400, True), 1: (400, False)}
    # targets reached after the truncated budget are dropped too, fitness and parameters
    hits = {r["seed"]: derived(r).parameter_hits["0.01"] for r in base}
    assert hits == {0: 400, 1: None}
    assert used["re_scored"] == 2
    x = evidence.vector("small", 0.3)
    fit = evidence.record([(1, evidence.level("small", "twin", 0, 0.5), x),
                           (300, evidence.level("small", "twin", 0, 0.05), x),
                           (450, evidence.level("small", "twin", 0, 0.005), x)], budget=5000)
    (cut,), _ = baseline([fit], 400, 1)
    assert derived(cut).fitness_hits == {"0.1": 300, "0.01": None, "0.001": None,
                                         "0.0001": None}


def test_ranking_puts_the_pooled_rows_first_and_breaks_ert_ties_by_success():
    p = [rec("p", 0, 100), rec("p", 1, 100), rec("p", 2, None)]        # ERT 600, 2/3
    q = [rec("q", 0, 100), rec("q", 1, None, budget=500)]               # ERT 600, 1/2
    order = [(s.case, s.solver) for s in score_records(q + p)]
    assert order == [(ALL, "p"), (ALL, "q"), ("small", "p"), ("small", "q")]


def test_medians_skip_undefined_accuracies():
    # the paper's accuracy is undefined (None) where the truth is 0 and the estimate is not:
    # the nominal case's BLK is 0; one run ends 0.5 % of BLK's range off, two exactly on it
    off = evidence.vector("nominal", 0.005, "BLK")
    recs = [evidence.record([(1, 1.0, off)], case="nominal", seed=0),
            evidence.record([(1, 1.0, evidence.vector("nominal", 0.002))], case="nominal",
                            seed=1),
            evidence.record([(1, 1.0, evidence.vector("nominal", 0.004))], case="nominal",
                            seed=2)]
    assert derived(recs[0]).accuracy["BLK"] is None
    (s,) = [x for x in score_records(recs) if x.case == "nominal"]
    assert s.accuracy["BLK"] == 100.0                   # None skipped, not counted as 0
    assert s.accuracy["Na"] == pytest.approx(100 * (1 - 0.002 * 0.2 / 1.0))   # of 3 runs


def test_baseline_identity_and_staleness_edges():
    from ema_bench.leaderboard.check import baseline

    old = {**rec("a", 1, 10), "model_version": "0"}
    records = [old, old, rec("a", 0, 100, budget=400),
               rec("a", 0, 50, budget=100),                 # smaller budget: never used
               {**rec("a", 1, 20, budget=400), "root_seed": 7}]
    base, used = baseline(records, 400, 2)
    assert used["other_model_version"] == 2                 # both stale records counted
    got = {(r["seed"], r["root_seed"]): r["budget"] for r in base}
    assert got == {(0, 1): 400, (1, 7): 400}                # the stale ones did not stop it
    # keys select runs: root seed is part of a run's identity
    base, _ = baseline(records, 400, 2, keys={("a", "small", "twin", 1, 7)})
    assert [(r["seed"], r["root_seed"]) for r in base] == [(1, 7)]
    assert [r["seed"] for r in baseline(records, 400, 2, keys={("a", "small", "twin", 0, 1)})[0]
            ] == [0]
    # a committed run under another root seed is another run: not compared
    assert compare([rec("a", 1, None)], [{**rec("a", 1, 10), "root_seed": 7}]) == []


def test_table_row_flattens_the_per_fault_figures():
    (s,) = [x for x in score_records(MIXED) if x.case == "small"]
    row = s.row()
    assert "accuracy" not in row and "range_error" not in row
    for n in FAULTS:
        assert row[f"accuracy_{n}"] == pytest.approx(ACCURACY_OK[n])
        assert row[f"range_error_{n}"] == pytest.approx(RANGE_ERROR_OK[n])
    assert (row["solver"], row["runs"], row["successes"]) == ("a", 3, 2)
    assert row["ert"] == pytest.approx(700.0)


def test_committed_run_files_are_found_and_read(tmp_path):
    import json

    from ema_bench.leaderboard.check import committed_files, load_baseline

    def write(path, records):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("".join(json.dumps(r) + "\n" for r in records))

    write(tmp_path / "runs.jsonl", [rec("a", 0, 100, budget=400)])
    write(tmp_path / "quick" / "runs.jsonl", [rec("b", 0, None, budget=400)])
    write(tmp_path / "deep" / "er" / "runs.jsonl", [rec("c", 0, 5, budget=400)])  # too deep
    (tmp_path / "empty").mkdir()
    files = committed_files(tmp_path)
    assert files == [tmp_path / "runs.jsonl", tmp_path / "quick" / "runs.jsonl"]
    assert committed_files(tmp_path / "empty") == []
    # the baseline goes through the judge: hand-made records whose fitness their vectors do
    # not have are refused, not compared
    with pytest.raises(JudgeError, match=r"^--check baseline: 2 finding"):
        load_baseline(tmp_path, 400, 1)
    # real (committed, legacy) records are read, and the keys select
    quick = Path(__file__).resolve().parents[1] / "leaderboards" / "quick" / "runs.jsonl"
    lines = [ln for ln in quick.read_text().splitlines() if '"case": "s00"' in ln][:4]
    write(tmp_path / "real" / "runs.jsonl", [json.loads(ln) for ln in lines])
    base, used = load_baseline(tmp_path / "real", 400, 1)
    first = json.loads(lines[0])
    assert len(base) == sum(json.loads(ln)["seed"] < 1 for ln in lines) == used["same_budget"]
    key = (first["solver"], "s00", first["track"], first["seed"], first["root_seed"])
    base, _ = load_baseline(tmp_path / "real", 400, 1, keys={key})
    assert [(r["solver"], r["track"]) for r in base] == [(first["solver"], first["track"])]


def test_a_failed_run_is_unsuccessful_at_its_budget_and_left_out_of_medians():
    """A run recorded as an error (the solver raised, its worker died) has no fitness: it is
    an unsuccessful run at its budget in runs, success rate and ERT, and no median sees it."""
    failed = {**evidence.record([], seed=2, budget=1000, status="error", root_seed=1),
              "wall_s": 50.0}
    runs = [rec("a", 0, 100, fitness=1e-4), rec("a", 1, None, fitness=3e-4), failed]
    (s,) = [x for x in score_records(runs) if x.case == "small"]
    assert (s.runs, s.successes, s.errors) == (3, 1, 1)
    assert s.success_rate == pytest.approx(1 / 3)
    assert s.ert == pytest.approx(100 + 1000 + 1000)       # the failed run at its budget
    assert s.median_fitness == pytest.approx(2e-4)          # of the two finished runs
    assert s.median_wall_s == pytest.approx(1.0)
    assert s.accuracy["Na"] == pytest.approx((ACCURACY_OK["Na"] + 100 * (1 - 0.3 * 0.2 / 0.95))
                                             / 2)
    (plain,) = [x for x in score_records(MIXED) if x.case == "small"]
    assert plain.errors == 0


def test_the_evaluation_count_a_record_claims_is_not_read():
    # the cost of a success is where its evidence shows it: a claim of none, 0 or 1 changes
    # nothing (formerly a success without a count was charged its budget)
    counted = rec("a", 0, 120, budget=700)
    assert run_cost(counted) == 120
    for claim in (None, 0, 1):
        assert run_cost({**counted, "evals_to_success": claim}) == 120
    assert ert([counted, rec("a", 1, None)]) == pytest.approx((120 + 1000) / 1)
