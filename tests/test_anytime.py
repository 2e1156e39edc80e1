"""Anytime scores (ema_bench.leaderboard.anytime) recomputed by hand on tiny synthetic records:
ECDF area, ERT per target, their bootstrap intervals, fixed-budget precision, the sanity row.

The bootstrap intervals are checked against the exact bootstrap distribution, enumerated by
hand for two- and four-run sets (the percentile interval of 2000 resamples lands on the same
atoms: the margins below are many Monte Carlo standard errors wide).
"""

from __future__ import annotations

import math

import evidence
import numpy as np
import pytest

from ema_bench.leaderboard.anytime import (
    anytime_scores,
    credit,
    ecdf_curve,
    ert_ci,
    hits,
    mean_ci,
    precision_at,
    run_area,
    sanity_scores,
)


def rec(solver="a", case="small", seed=0, f_hits=(None,) * 4, p_hits=(None,) * 3,
        budget=100, status=None):
    """A real-instance record (``small``, twin track: its shipped f*) whose targets are first
    reached at the given evaluations (:func:`evidence.from_hits`)."""
    if status:
        return evidence.record([], solver=solver, case=case, seed=seed, budget=budget,
                               status=status)
    return evidence.from_hits(f_hits, p_hits, budget=budget, solver=solver, case=case,
                              seed=seed)


def test_credit_and_run_area_by_hand():
    assert credit(10, 100) == pytest.approx(0.5)        # (ln 100 - ln 10) / ln 100
    assert credit(1, 100) == 1.0 and credit(100, 100) == 0.0 and credit(None, 100) == 0.0
    r = rec(f_hits=(1, 10, None, None), p_hits=(10, 100, None))
    # fitness: (1 + 0.5 + 0 + 0) / 4; parameters: (0.5 + 0 + 0) / 3; all: 2 / 7
    assert run_area(r, "f") == pytest.approx(0.375)
    assert run_area(r, "p") == pytest.approx(0.5 / 3)
    assert run_area(r) == pytest.approx(2.0 / 7)
    assert hits(r) == {"f0.1": 1, "f0.01": 10, "f0.001": None, "f0.0001": None,
                       "p0.1": 10, "p0.03": 100, "p0.01": None}


def test_ert_and_its_interval_by_hand():
    # runs hit at 10 and 30, one misses at budget 100: ERT (10 + 100 + 30) / 2 = 70
    e, lo, hi = ert_ci([10, None, 30], [100, 100, 100])
    assert e == pytest.approx(70.0)
    # two runs, one hit at 10, one miss: resampled pairs hit twice (p 1/4, rate 2/20),
    # once (p 1/2, rate 1/110) or never (p 1/4, rate 0): the 95 % interval of the rate is
    # [0, 0.1], inverted [10, inf]
    e, lo, hi = ert_ci([10, None], [100, 100])
    assert (e, lo, hi) == (pytest.approx(110.0), pytest.approx(10.0), math.inf)
    assert ert_ci([None, None], [100, 100])[0] == math.inf


def test_mean_interval_by_hand():
    # {0, 0, 0, 1}: the resampled mean is Binomial(4, 1/4) / 4; P(mean <= 0.5) = 0.949 and
    # P(mean = 0) = 0.316, so the 2.5 % and 97.5 % percentiles are 0 and 0.75
    m, lo, hi = mean_ci([0.0, 0.0, 0.0, 1.0])
    assert (m, lo, hi) == (0.25, 0.0, 0.75)
    assert mean_ci([0.3, 0.3, 0.3]) == (0.3, 0.3, 0.3)   # no spread, no interval width
    assert math.isnan(mean_ci([0.3])[1])                  # one run: no interval
    assert mean_ci([0.0, 0.0, 0.0, 1.0]) == mean_ci([0.0, 0.0, 0.0, 1.0])   # seeded


def test_aggregate_excludes_the_sanity_case_and_counts_errors_as_misses():
    records = [rec(f_hits=(1, 1, 1, 1), p_hits=(1, 1, 1), case="nominal"),
               rec(f_hits=(10,) * 4, p_hits=(10,) * 3, seed=0),
               rec(seed=1),                                        # missed everything
               rec(seed=2, status="error")]                        # crashed
    (s,) = anytime_scores(records)
    assert (s.cases, s.runs, s.errors) == ("all", 3, 1)
    assert s.area[0] == pytest.approx(0.5 / 3)            # (0.5 + 0 + 0) / 3, nominal out
    assert s.hit_rate["p0.01"] == pytest.approx(1 / 3)
    assert s.ert["f0.1"][0] == pytest.approx((10 + 100 + 100) / 1)
    per = {x.cases: x.area[0] for x in anytime_scores(records, per_case=True)}
    assert per["nominal"] == 1.0 and per["small"] == pytest.approx(0.5 / 3)
    (san,) = sanity_scores(records)   # its final vector is 0.5 % of range off: it stayed
    assert (san.runs, san.stayed) == (1, 1)


def test_sanity_row_counts_runs_that_stayed_at_nominal():
    # final vectors 0.5 % (p0.01 reached) and 30 % (nothing reached) of Na's range off
    recs = [rec(case="nominal", p_hits=(1, 1, 1)), rec(case="nominal", seed=1)]
    (s,) = sanity_scores(recs)
    assert (s.runs, s.stayed) == (2, 1)
    assert s.median_max_range_error == pytest.approx((0.005 + 0.3) / 2)


def _at(p, seed=0):
    """The fitness at precision p of small/twin/seed's f*-to-nominal gap."""
    return evidence.level("small", "twin", seed, p)


def test_fixed_budget_precision_by_hand():
    x = evidence.vector("small", 0.3)
    r = evidence.record([(1, _at(0.5), x), (20, _at(0.1), x), (50, _at(0.05), x),
                         (100, _at(0.01), x)])
    assert precision_at(r, 10) == pytest.approx(0.5)
    assert precision_at(r, 30) == pytest.approx(0.1)    # the best at 20 still holds at 30
    assert precision_at(r, 100) == pytest.approx(0.01)
    assert math.isnan(precision_at(r, 5))              # before the first checkpoint
    assert math.isnan(precision_at(r, 200))            # beyond the run's budget
    # a run that stopped early at 60 evaluations: its final best holds at 100
    stopped = evidence.record([(1, _at(0.5), x), (50, _at(0.02), x)], evaluations=60)
    assert precision_at(stopped, 100) == pytest.approx(0.02)
    assert precision_at(stopped, 50) == pytest.approx(0.02)
    r2 = evidence.record([(1, _at(1.0, 1), x), (100, _at(0.2, 1), x)], seed=1)
    (s,) = anytime_scores([r, r2])
    assert sorted(s.precision) == [10, 100]            # a tenth of the budget, the budget
    assert s.precision[100][1] == pytest.approx((0.01 + 0.2) / 2)
    assert s.precision[10][1] == pytest.approx((0.5 + 1.0) / 2)


def test_ecdf_curve_counts_run_target_pairs():
    records = [rec(f_hits=(1, 10, None, None), p_hits=(10, 100, None)),
               rec(case="nominal", f_hits=(1,) * 4, p_hits=(1,) * 3)]
    curve = ecdf_curve(records, np.array([1, 9, 10, 100]))
    assert curve.tolist() == pytest.approx([1 / 7, 1 / 7, 3 / 7, 4 / 7])


def test_ert_interval_resamples_runs_as_pairs():
    # 5 runs hit at 10, 5 miss at budget 100.  Resampling runs as (hit, cost) pairs, j hits
    # of 10 draws (j ~ Binomial(10, 1/2)) give the rate j / (10 j + 100 (10 - j)); its exact
    # 2.5 % and 97.5 % quantiles, inverted, are 410 and 35 (j = 2 and j = 8).  Resampled
    # unpaired (hits and costs drawn apart) the interval would be [46.7, 320], 30 % narrower.
    e, lo, hi = ert_ci([10] * 5 + [None] * 5, [100] * 10)
    assert e == pytest.approx(110.0)
    assert (lo, hi) == (pytest.approx(35.0), pytest.approx(410.0))


def test_an_early_stopping_run_is_credited_against_its_budget():
    # stopped after 60 of its 100 evaluations, target reached at 10: (ln 100 - ln 10) /
    # ln 100 = 0.5 (against its own 60 evaluations it would be 0.44)
    x = evidence.vector("small", 0.3)
    r = evidence.record([(1, _at(0.5), x), (10, _at(0.05), x)], budget=100, evaluations=60)
    assert run_area(r, "f") == pytest.approx(0.5 / 4)


def test_the_ranking_puts_the_larger_area_first():
    good = [rec("good", seed=k, f_hits=(1, 2, 3, 4), p_hits=(2, 3, 4)) for k in range(2)]
    bad = [rec("bad", seed=k) for k in range(2)]
    assert [s.solver for s in anytime_scores(bad + good)] == ["good", "bad"]


def test_intervals_do_not_depend_on_the_order_of_the_records():
    recs = [rec(seed=k, f_hits=(k + 1, None, None, None), p_hits=(3 * k + 1, None, None))
            for k in range(6)]
    (a,) = anytime_scores(recs)
    (b,) = anytime_scores(recs[::-1])
    assert a.area == b.area and a.ert == b.ert
    assert a.area[1] < a.area[0] < a.area[2]      # a real interval, not a degenerate one


def test_the_csv_row_of_a_score_names_every_figure():
    recs = [rec(seed=k, f_hits=(k + 1, None, None, None), p_hits=(3 * k + 1, None, None))
            for k in range(3)]
    (s,) = anytime_scores(recs)
    row = s.row()
    assert (row["track"], row["solver"], row["cases"], row["runs"], row["errors"]) == \
        ("twin", "a", "all", 3, 0)
    assert (row["ecdf_area"], row["ecdf_area_lo"], row["ecdf_area_hi"]) == s.area
    assert row["ecdf_area_lo"] < row["ecdf_area"] < row["ecdf_area_hi"]
    assert (row["fitness_area"], row["parameter_area"]) == (s.fitness_area, s.parameter_area)
    assert row["hits_f0.1"] == 1.0 and row["hits_p0.1"] == 1.0 and row["hits_p0.01"] == 0.0
    assert (row["ert_f0.1"], row["ert_f0.1_lo"], row["ert_f0.1_hi"]) == s.ert["f0.1"]
    assert row["ert_f0.1"] == pytest.approx((1 + 2 + 3) / 3)
    b = sorted(s.precision)
    assert row[f"precision_median_at_{b[-1]}"] == s.precision[b[-1]][1]
    assert (row[f"precision_q10_at_{b[0]}"], row[f"precision_q90_at_{b[0]}"]) == \
        (s.precision[b[0]][0], s.precision[b[0]][2])


def test_sanity_rows_name_their_track_and_solver_and_an_empty_ecdf_is_undefined():
    (s,) = sanity_scores([rec("z", case="nominal", p_hits=(1, 1, 1))])
    assert (s.track, s.solver) == ("twin", "z")
    assert np.isnan(ecdf_curve([], np.array([1, 10]))).all()
    assert np.isnan(ecdf_curve([rec(case="nominal")], np.array([1]))).all()   # sanity only
