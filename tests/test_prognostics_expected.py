"""Expected hits and the scores of predictive distributions: hand-computed values, the
statistical check that expected hits predict realised ones on lives simulated by the laws
(independently of the futures' machinery), and the attempts to earn them without forecasting."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from ema_bench.prognostics.distributions import (
    LEVELS,
    check_quantiles,
    columns,
    interval_score,
    level_key,
    reliability,
    weighted_interval_score,
)
from ema_bench.prognostics.expected import at_most, hit_probability
from ema_bench.prognostics.tracking import TrackerError, TrackStep, check_step

INF = math.inf


def test_hit_probability_by_hand():
    rul = np.array([50.0, 100.0, 110.0, 200.0, INF])
    w = np.array([1.0, 2.0, 1.0, 1.0, 5.0])
    # point 100 within +-20 % of R when 100/1.2 <= R <= 100/0.8: R in [83.3, 125]: 100, 110
    assert hit_probability(100.0, rul, w) == pytest.approx(3 / 10)
    # bounds included: 0.8 x 200 = 160
    assert hit_probability(160.0, rul, w) == pytest.approx(1 / 10)
    assert hit_probability(INF, rul, w) == 0.0 and hit_probability(1000.0, rul, w) == 0.0
    with pytest.raises(ValueError):
        hit_probability(1.0, rul, np.zeros(5))


def test_at_most_is_the_poisson_binomial_cdf():
    p = np.array([0.5, 0.2, 0.9])
    # P(0) = .5 .8 .1 = .04; P(1) = .5 .8 .1 + .5 .2 .1 + .5 .8 .9 ... by enumeration
    probs = {}
    for a in (0, 1):
        for b in (0, 1):
            for c in (0, 1):
                pr = (p[0] if a else 1 - p[0]) * (p[1] if b else 1 - p[1]) * (
                    p[2] if c else 1 - p[2])
                probs[a + b + c] = probs.get(a + b + c, 0.0) + pr
    for k in range(4):
        assert at_most(p, k) == pytest.approx(sum(probs[j] for j in range(k + 1)))
    assert at_most(p, 3) == pytest.approx(1.0)


def test_interval_score_and_wis_by_hand():
    # [10, 30] at 95 %: a = 0.05, 2 / a = 40
    assert interval_score(10, 30, 20, 0.95) == 20.0              # inside: the width
    assert interval_score(10, 30, 5, 0.95) == pytest.approx(20.0 + 40 * 5)   # 5 below
    assert interval_score(10, 30, 32, 0.95) == pytest.approx(20.0 + 40 * 2)  # 2 above
    assert interval_score(10, 30, 32, 0.5) == 20.0 + 4 * 2       # a = 0.5: 2 / a = 4
    # WIS of median 20 and a 50 % interval [15, 25], truth 27:
    # (0.5 |27 - 20| + 0.25 (10 + 4 x 2)) / 1.5 = (3.5 + 4.5) / 1.5
    got = weighted_interval_score(np.array([20.0]), {0.5: (np.array([15.0]),
                                                           np.array([25.0]))}, np.array([27.0]))
    assert got[0] == pytest.approx(8.0 / 1.5)


def test_columns_score_what_a_tracker_gives():
    q = {level_key(lv): v for lv, v in zip(LEVELS, (20, 30, 35, 40, 45, 50, 60))}
    rows = [
        # quantiles: truth 42 inside every interval
        {"true_rul": 42.0, "rul": 40.0, "rul_low": 20.0, "rul_high": 60.0, "quantiles": q,
         "at_cut": True},
        # only the 95 % interval: its figures, and nothing else
        {"true_rul": 42.0, "rul": 40.0, "rul_low": 0.0, "rul_high": INF, "at_cut": True},
        # no prediction at the cut: infinite and not covered
        {"true_rul": 42.0, "rul": INF, "rul_low": INF, "rul_high": INF, "at_cut": False},
    ]
    c = columns(rows, horizon=500.0)
    assert c["is95"][0] == 40.0 and c["is50"][0] == 10.0 and c["is80"][0] == 20.0
    assert c["cov50"][0] == 1.0 and c["cov80"][0] == 1.0
    # WIS: (0.5 x 2 + 0.25 x 10 + 0.1 x 20 + 0.025 x 40) / 3.5
    assert c["crps"][0] == pytest.approx((1 + 2.5 + 2 + 1) / 3.5)
    # [0, inf] clipped to the horizon: width 500, no miss
    assert c["is95"][1] == 500.0
    assert all(math.isnan(c[k][1]) for k in ("is50", "is80", "cov50", "cov80", "crps"))
    assert all(math.isinf(c[k][2]) for k in ("is50", "is80", "is95", "crps"))
    assert c["cov50"][2] == 0.0
    assert reliability(rows[:1]) == {"0.5": 1.0, "0.8": 1.0, "0.95": 1.0}
    assert reliability(rows[:2]) == {"0.95": 1.0}     # the 50 / 80 % not given by every unit


def test_quantiles_are_checked_and_recorded_with_inf_as_null(tmp_path):
    from ema_bench.prognostics.track_io import regroup, step_record
    from ema_bench.prognostics.tracking import Inspection

    insp = Inspection("u000", 0, 0, None, {}, {"Fst": 0.6756}, 10)
    est = {"Na": 1.0, "Fst": 0.2, "BLK": 0.0, "Gprop": 1e5}

    def step(qs):
        return TrackStep(0, est, est, est, 50.0, 10.0, 90.0, "Fst", False, 0,
                         rul_quantiles=qs)
    for bad in ({"0.5": 50.0, "0.9": 40.0}, {"1.5": 3.0}, {"0.5": math.nan}, {"x": 1.0}):
        with pytest.raises(TrackerError, match="quantile"):
            check_step(step(bad), insp)
    good = {"0.1": 20.0, "0.5": 50.0, "0.9": INF}
    rec = step_record(insp, check_step(step(good), insp))
    assert json.loads(json.dumps(rec))["rul_quantiles"] == {"0.1": 20.0, "0.5": 50.0,
                                                            "0.9": None}
    steps, _ = regroup([json.loads(json.dumps(rec))])
    assert steps["u000"][0]["rul_quantiles"]["0.9"] == INF
    # not given: not written (lines of trackers without quantiles are as before)
    assert "rul_quantiles" not in step_record(insp, step({}))
    assert "profile_rul" not in step_record(insp, step({}))
    # the unconditioned profile: checked, inf as null, read back as inf
    s = step({})
    s.profile_rul = -1.0
    with pytest.raises(TrackerError, match="profile_rul"):
        check_step(s, insp)
    s.profile_rul = INF
    rec = json.loads(json.dumps(step_record(insp, check_step(s, insp))))
    assert rec["profile_rul"] is None
    assert regroup([rec])[0]["u000"][0]["profile_rul"] == INF
    assert check_quantiles({0.25: 1, 0.75: 2}) == {"0.25": 1.0, "0.75": 2.0}


def test_hit_probability_bounds_of_the_point_and_its_refusals():
    """Both ends of ``[(1 - alpha) R, (1 + alpha) R]`` included, another ``alpha``, a point that
    is not finite, and each refusal by its message (found by mutation testing)."""
    one, w1 = np.array([100.0]), np.array([1.0])
    for point, hit in ((80.0, 1.0), (79.99999, 0.0), (120.0, 1.0), (120.00001, 0.0)):
        assert hit_probability(point, one, w1) == hit, point
    assert hit_probability(150.0, one, w1, alpha=0.5) == 1.0
    assert hit_probability(150.00001, one, w1, alpha=0.5) == 0.0
    assert hit_probability(50.0, one, w1, alpha=0.5) == 1.0
    # point 100 at alpha 0.5: R in [66.7, 200] of [50, 100, 110, 200, inf], weights 1 2 1 1 5
    rul = [50, 100, 110, 200, INF]
    assert hit_probability(100, rul, [1, 2, 1, 1, 5], alpha=0.5) == 4 / 10
    assert hit_probability(math.nan, one, w1) == 0.0 and hit_probability(-INF, one, w1) == 0.0
    for alpha in (0.0, 1.0, -0.1, 1.5):
        with pytest.raises(ValueError) as e:
            hit_probability(100.0, one, w1, alpha=alpha)
        assert str(e.value) == f"alpha must lie in (0, 1), got {alpha!r}"
    futures = "futures and weights must be non-empty, of one length, weights > 0"
    for r, w in ((one, np.ones(2)), ([], []), (one, [0.0]), ([100.0, 90.0], [1.0, -1.0]),
                 ([100.0, 90.0], [1.0, -2.0])):
        with pytest.raises(ValueError) as e:
            hit_probability(100.0, r, w)
        assert str(e.value) == futures


def test_at_most_edges():
    p = [0.5, 0.2, 0.9]
    assert at_most(p, 1.0) == at_most(np.array(p), 1) == pytest.approx(
        0.5 * 0.8 * 0.1 + 0.5 * 0.2 * 0.1 + 0.5 * 0.8 * 0.9 + 0.5 * 0.8 * 0.1)
    assert at_most(p, -1) == 0.0 and at_most(p, 7) == pytest.approx(1.0)
    assert at_most([], 0) == 1.0 and at_most([1.0, 1.0], 1) == 0.0
    assert at_most([0.0, 0.0], 0) == 1.0


def test_expected_hits_are_each_rows_hit_probability_under_its_units_futures():
    from ema_bench.prognostics.expected import expected_hits

    futures = {"a": (np.array([100.0, 200.0]), np.array([3.0, 1.0])),
               "b": (np.array([10.0]), np.array([1.0]))}
    rows = [{"unit": "b", "rul": 11}, {"unit": "a", "rul": 100.0}, {"unit": "a", "rul": INF},
            {"unit": "a", "rul": 170.0}]
    got = expected_hits(rows, futures)
    assert got.dtype == float and got.tolist() == [1.0, 0.75, 0.0, 0.25]
    # alpha reaches each row: at 0.5, 170 lies within [50, 150] of neither; 100 of both
    assert expected_hits(rows, futures, alpha=0.5).tolist() == [1.0, 1.0, 0.0, 0.25]
    assert expected_hits([], futures).shape == (0,)


TWIN = Path(__file__).resolve().parents[1] / "leaderboards" / "campaign" / "twin" / "campaign"


def test_campaign_futures_draw_unit_k_of_the_sorted_truth_from_child_k_of_the_seed():
    """The committed twin campaign's truth of u008..u012 (u009 and u012 never fail): each
    failing unit's futures are ``unit_futures`` from its true state with child ``k`` of the
    seed (``k``: its place in the sorted truth), the thresholds given, the cut rule's ``stop``
    (0.5, 0.95 when it names none) and the paths asked for; by default seed 1 and 4,000
    paths."""
    from ema_bench.prognostics.expected import campaign_futures
    from ema_bench.prognostics.oracle import unit_futures
    from ema_bench.seeding import child

    m = json.loads((TWIN / "manifest.json").read_text())
    every = json.loads((TWIN / "truth.json").read_text())["units"]
    truth = {u: every[u] for u in ("u012", "u010", "u009", "u008")}
    assert [u for u in sorted(truth) if truth[u]["eol"] is None] == ["u009", "u012"]
    law = (m["laws"], m["thresholds"], m["inspection_every"])

    def direct(unit, k, stop, seed, n):
        return unit_futures(truth[unit], *law, stop, np.random.default_rng(child(seed, k)), n)

    for rule, stop in (({"stop": [0.3, 0.6]}, (0.3, 0.6)), ({}, (0.5, 0.95))):
        got = campaign_futures(truth, *law, rule, n_paths=64, seed=7)
        assert list(got) == ["u008", "u010"]
        for k, unit in ((0, "u008"), (2, "u010")):
            rul, w, _ = direct(unit, k, stop, 7, 64)
            assert len(got[unit]) == 2 and rul.shape == (64,)
            assert np.array_equal(got[unit][0], rul) and np.array_equal(got[unit][1], w)
    assert not np.array_equal(campaign_futures(truth, *law, {}, n_paths=64, seed=7)["u008"][1],
                              direct("u008", 0, (0.3, 0.6), 7, 64)[1])
    # the thresholds reach the futures (the campaign's are the default ones)
    lower = {k: 0.9 * v for k, v in m["thresholds"].items()}
    got = campaign_futures(truth, m["laws"], lower, m["inspection_every"], {}, 64, 7)["u008"]
    rul, _, _ = unit_futures(truth["u008"], m["laws"], lower, m["inspection_every"],
                             (0.5, 0.95), np.random.default_rng(child(7, 0)), 64)
    assert np.array_equal(got[0], rul)
    assert not np.array_equal(rul, direct("u008", 0, (0.5, 0.95), 7, 64)[0])
    one = {"u008": truth["u008"]}
    got = campaign_futures(one, *law, m["cut_rule"])["u008"]
    rul, w, _ = direct("u008", 0, tuple(m["cut_rule"]["stop"]), 1, 4000)
    assert np.array_equal(got[0], rul) and np.array_equal(got[1], w)


@pytest.mark.slow
def test_expected_hits_predict_realised_hits_on_lives_the_laws_simulate():
    """Independently of the futures' machinery: 300 lives simulated from flight 0 by
    ``unit_history``, cut by the real cut rule; a fixed rule's point (0.6 x the age) hits the
    realised RUL about as often as its expected hits from each unit's true state say
    (binomial error about 0.03; 20 CPU-s)."""
    from ema_bench.prognostics.campaign import _inspection_flights
    from ema_bench.prognostics.expected import expected_hits
    from ema_bench.prognostics.laws import THRESHOLDS, FleetLaws, unit_history
    from ema_bench.prognostics.oracle import unit_futures
    from ema_bench.seeding import child

    laws = FleetLaws()
    rng = np.random.default_rng(11)
    realised, expected = [], []
    for k in range(300):
        h = unit_history(child(np.random.SeedSequence(123), k), laws)
        if h.eol is None:
            continue
        cut = _inspection_flights(h, 10, "test", (0.5, 0.95), rng)[-1]
        truth = {"unit": "u", "eol": h.eol, "last_flight": cut,
                 "faults": {str(cut): [float(v) for v in h.faults[cut]]},
                 "params": h.params.to_dict()}
        point = 0.6 * cut
        rul, w, _ = unit_futures(truth, laws.to_dict(), THRESHOLDS, 10, (0.5, 0.95),
                                 np.random.default_rng(k), 400)
        expected.append(expected_hits([{"unit": "u", "rul": point}], {"u": (rul, w)})[0])
        realised.append(abs(point - (h.eol - cut)) <= 0.2 * (h.eol - cut))
    n = len(realised)
    assert n > 200
    gap = np.mean(realised) - np.mean(expected)
    assert abs(gap) < 3 * math.sqrt(0.25 / n), (np.mean(realised), np.mean(expected))
    assert 0.1 < np.mean(expected) < 0.9   # a rule that hits sometimes: the check has power
