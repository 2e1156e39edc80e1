"""Anytime scores (ema_bench.leaderboard.anytime) recomputed by hand on tiny synthetic records:
ECDF area, ERT per target, their bootstrap intervals, fixed-budget precision, the sanity row.

The bootstrap intervals are checked against the exact bootstrap distribution, enumerated by
hand for two- and four-run sets (the percentile interval of 2000 resamples lands on the same
atoms: the margins below are many Monte Carlo standard errors wide).
"""

from __future__ import annotations

import hashlib
import math

import evidence
import numpy as np
import pytest

from ema_bench.leaderboard.anytime import (
    anytime_scores,
    credit,
    ecdf_curve,
    ert_ci,
    group_seed,
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


def test_the_intervals_are_scipys_percentile_bootstrap_to_the_last_bit():
    """``mean_ci`` and ``ert_ci`` replicate ``scipy.stats.bootstrap`` (percentile method,
    2000 resamples, the same seeded draw) without its per-call overhead: the published
    tables' full-precision CSV figures must not move, so the two are held equal exactly on
    seeded random sets of 2 to 60 runs, at several scales and seeds (a resample drawn with
    another shape, a quantile rule other than type 7, or an off-by-one in the interpolation
    index all fail here)."""
    from scipy import stats

    from ema_bench.leaderboard.anytime import CONFIDENCE, N_RESAMPLES

    rng = np.random.default_rng(44)
    for k in range(40):
        n = int(rng.integers(2, 61))
        seed = int(rng.integers(2**31))
        v = rng.random(n) * [1e-3, 1.0, 1e5][k % 3]
        ref = stats.bootstrap((np.sort(v),), np.mean, n_resamples=N_RESAMPLES,
                              confidence_level=CONFIDENCE, method="percentile",
                              rng=np.random.default_rng(seed)).confidence_interval
        assert mean_ci(v.tolist(), seed)[1:] == (float(ref.low), float(ref.high))
        hit = [int(h) if ok else None for h, ok in zip(rng.integers(1, 900, n),
                                                       rng.random(n) < 0.7)]
        if all(h is None for h in hit):
            hit[0] = 5
        budgets = rng.integers(900, 5000, n).tolist()
        pairs = sorted((float(h is not None), float(h if h is not None else b))
                       for h, b in zip(hit, budgets))
        s, c = (np.array(x) for x in zip(*pairs))
        ref = stats.bootstrap((s, c), lambda s, c, axis=-1: s.sum(axis) / c.sum(axis),
                              paired=True, vectorized=True, n_resamples=N_RESAMPLES,
                              confidence_level=CONFIDENCE, method="percentile",
                              rng=np.random.default_rng(seed)).confidence_interval
        _, lo, hi = ert_ci(hit, budgets, seed)
        assert (lo, hi) == (1.0 / float(ref.high),
                            1.0 / float(ref.low) if ref.low > 0 else math.inf)


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


def test_credit_at_the_edges_of_the_budget():
    # a budget of 1: the only hit is at evaluation 1, full credit (ln 1 = 0 has no share to
    # divide); a budget of 2: a hit at 2 is the end of the log axis, no credit; a hit past the
    # budget (a longer run read at a smaller budget) is a miss
    assert credit(1, 1) == 1.0
    assert credit(2, 2) == 0.0 and credit(1, 2) == 1.0
    assert credit(101, 100) == 0.0


def test_mean_interval_at_its_edges_by_hand():
    # {0, 1}: the resampled mean is 0 (p 1/4), 0.5 (1/2) or 1 (1/4): the interval is [0, 1]
    assert mean_ci([0.0, 1.0]) == (0.5, 0.0, 1.0)
    # two equal values: no spread, an interval of no width (not "no interval")
    assert mean_ci([0.3, 0.3]) == (0.3, 0.3, 0.3)
    # seven runs of 0.1, no spread: the exactly rounded mean 0.1 both sides (a resampled
    # np.mean of seven 0.1 is 0.09999999999999999)
    assert mean_ci([0.1] * 7) == (0.1, 0.1, 0.1)
    m, lo, hi = mean_ci([0.3])                             # one run: no interval either side
    assert m == 0.3 and math.isnan(lo) and math.isnan(hi)
    # nine 0 and one 1: the resampled mean is Binomial(10, 1/10) / 10; P(<= 0.2) = 0.930 and
    # P(<= 0.3) = 0.987, so the percentile interval is [0, 0.3] (BCa would give [0, 0.4])
    assert mean_ci([0.0] * 9 + [1.0]) == (pytest.approx(0.1), 0.0, pytest.approx(0.3))


def test_ert_interval_at_its_edges_by_hand():
    # every run hit at the same evaluation: no spread, the interval is the ERT itself (the
    # inverted rate 2 / 98 would be 49.00000000000001)
    assert ert_ci([49, 49], [100, 100]) == (49.0, 49.0, 49.0)
    e, lo, hi = ert_ci([10], [100])                       # one run: no interval
    assert e == 10.0 and math.isnan(lo) and math.isnan(hi)
    # both runs hit, at 10 and 30: the resampled rate is 2/20, 2/40 or 2/60: [10, 30]
    assert ert_ci([10, 30], [100, 100]) == (20.0, pytest.approx(10.0), pytest.approx(30.0))
    # one hit at 10 in ten runs (the others miss at 100): j resampled hits, j ~ Binomial(10,
    # 1/10), give the rate j / (10 j + 100 (10 - j)); P(j <= 2) = 0.930, P(j <= 3) = 0.987, so
    # the percentile interval of the rate is [0, 3/730], inverted [243.3, inf] (BCa: 160)
    assert ert_ci([10] + [None] * 9, [100] * 10) == (910.0, pytest.approx(730 / 3), math.inf)


def test_the_same_records_give_the_same_interval_in_every_call():
    # twelve runs of spread costs: the 2000 resamples' percentiles fall between distinct
    # atoms, so an unseeded bootstrap would move the bounds from call to call
    hit_list = [3, 7, None, 12, 19, None, 25, 31, 44, None, 58, 77]
    assert ert_ci(hit_list, [100] * 12) == ert_ci(hit_list, [100] * 12)


def test_a_groups_intervals_are_seeded_by_its_identity_alone():
    # the documented seed: BOOTSTRAP_SEED xor the first 8 bytes (little-endian) of the
    # SHA-256 of the identity joined by "|": anyone can recompute a published interval
    def seed(*identity):
        digest = hashlib.sha256("|".join(identity).encode()).digest()
        return 20261123 ^ int.from_bytes(digest[:8], "little")

    assert group_seed("twin", "a", "all") == seed("twin", "a", "all")
    f1 = [3, 7, None, 12, 19, None, 25, 31, 44, 58]     # spread: many bootstrap atoms
    recs = [rec(seed=k, f_hits=(h, None, None, None), p_hits=(5 * k + 1, None, None))
            for k, h in enumerate(f1)]
    (s,) = anytime_scores(recs)
    areas = [run_area(r) for r in recs]
    assert s.area == mean_ci(areas, seed("twin", "a", "all"))
    assert s.area != mean_ci(areas, seed("twin", "b", "all"))   # the seed matters here
    assert s.ert["f0.1"] == ert_ci(f1, [100] * 10, seed("twin", "a", "all", "f0.1"))
    assert s.ert["f0.1"] != ert_ci(f1, [100] * 10, seed("twin", "a", "all", "f0.01"))


def test_fitness_and_parameter_areas_by_hand():
    # run 1: fitness (1 + 0.5 + 0 + 0) / 4, parameters (0.5 + 0 + 0) / 3; run 2 misses all
    recs = [rec(f_hits=(1, 10, None, None), p_hits=(10, 100, None)), rec(seed=1)]
    (s,) = anytime_scores(recs)
    assert s.fitness_area == pytest.approx(0.375 / 2)
    assert s.parameter_area == pytest.approx(0.5 / 3 / 2)
    # a sanity run has no f*: no fitness area, and the score is still written
    (n,) = [x for x in anytime_scores([rec(case="nominal", p_hits=(10, None, None))],
                                      per_case=True) if x.cases == "nominal"]
    assert math.isnan(n.fitness_area) and n.parameter_area == pytest.approx(0.5 / 3)


def test_a_group_of_crashed_runs_still_writes_its_row():
    (s,) = anytime_scores([rec(seed=k, status="error") for k in range(2)])
    assert (s.runs, s.errors, s.area) == (2, 2, (0.0, 0.0, 0.0))
    row = s.row()
    assert all(math.isnan(row[f"precision_{q}_at_100"]) for q in ("q10", "median", "q90"))


def test_a_stopped_run_is_read_at_its_final_fitness():
    # stopped at 60 after improving at 55: at budget 100 its best is the final 2 %, not the
    # 5 % held at the last checkpoint (50) before it stopped
    x = evidence.vector("small", 0.3)
    r = evidence.record([(1, _at(0.5), x), (50, _at(0.05), x), (55, _at(0.02), x)],
                        evaluations=60)
    assert precision_at(r, 100) == pytest.approx(0.02)
    assert precision_at(r, 60) == pytest.approx(0.02)      # at its last evaluation too
    assert precision_at(r, 50) == pytest.approx(0.05)


def test_per_case_rows_follow_the_aggregate_and_rank_by_the_mean_not_the_bound():
    # "a": two runs of area 0.5 (mean 0.5, interval [0.5, 0.5]); "b": areas 1 and 1/7 (mean
    # 0.571, lower bound 1/7): "b" ranks first on its mean though its lower bound is lower
    recs = [rec("a", seed=k, f_hits=(10,) * 4, p_hits=(10,) * 3) for k in range(2)] + \
        [rec("b", f_hits=(1,) * 4, p_hits=(1,) * 3),
         rec("b", seed=1, f_hits=(10, 10, None, None), p_hits=(None,) * 3)]
    scores = anytime_scores(recs, per_case=True)
    assert [(s.cases, s.solver) for s in scores] == \
        [("all", "b"), ("all", "a"), ("small", "b"), ("small", "a")]
    assert scores[0].area[0] == pytest.approx((1 + 1 / 7) / 2)
    assert scores[0].area[1] == pytest.approx(1 / 7)
