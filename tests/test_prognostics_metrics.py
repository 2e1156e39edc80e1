"""Prognostics metrics against hand-computed cases (arithmetic in the comments, independent of
the code), edge cases, and an optional cross-check with NASA's progpy.

Each test names the plausible one-line bug it catches."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ema_bench.prognostics import metrics


def phm08_score(pred, true) -> float:
    """The PHM08 challenge's score: its terms summed (the board reports their mean and
    median per unit, :func:`~ema_bench.prognostics.metrics.phm08_mean`)."""
    return float(metrics.phm08_terms(pred, true).sum())


def test_rmse_and_mae():
    # errors 13-10 = 3, 6-10 = -4, 0: RMSE sqrt((9 + 16 + 0) / 3), MAE (3 + 4 + 0) / 3
    assert metrics.rmse([13, 6, 5], [10, 10, 5]) == pytest.approx(math.sqrt(25 / 3))
    assert metrics.mae([13, 6, 5], [10, 10, 5]) == pytest.approx(7 / 3)
    # catches: a sign that cancels (mean error 0 here), a sum instead of a mean
    assert metrics.mae([12, 8], [10, 10]) == 2.0
    assert metrics.rmse([math.inf], [5]) == math.inf


def test_phm08_late_costs_more_with_the_right_constants():
    # d = 60 - 50 = +10 (late): e^(10/10) - 1 = e - 1
    assert phm08_score([60], [50]) == pytest.approx(math.e - 1)
    # d = 37 - 50 = -13 (early): e^(13/13) - 1 = e - 1
    assert phm08_score([37], [50]) == pytest.approx(math.e - 1)
    # d = -10: e^(10/13) - 1 = 1.1581; d = +10: e - 1 = 1.7183; summed, not averaged
    assert phm08_score([40, 60], [50, 50]) == pytest.approx(
        math.exp(10 / 13) - 1 + math.e - 1)
    # catches d = true - pred (then 60 vs 50 would score e^(10/13) - 1) and 13/10 swapped
    assert phm08_score([60], [50]) > phm08_score([40], [50])
    assert metrics.phm08_terms([60, 40], [50, 50]) == pytest.approx(
        [math.e - 1, math.exp(10 / 13) - 1])
    # d = 0 scores 0 on either branch; an infinite late prediction scores inf
    assert phm08_score([50], [50]) == 0.0
    assert phm08_score([math.inf], [50]) == math.inf


def test_alpha_cone_is_inclusive_and_relative_to_the_true_rul():
    # alpha 0.2 around 100: [80, 120], bounds included (catches < for <=)
    assert metrics.within_alpha(120.0, 100.0, 0.2) and metrics.within_alpha(80.0, 100.0, 0.2)
    assert not metrics.within_alpha(120.5, 100.0, 0.2)
    assert not metrics.within_alpha(79.5, 100.0, 0.2)
    # relative: around 10 the cone is [8, 12] (catches an absolute +- alpha EOL cone)
    assert not metrics.within_alpha(13.0, 10.0, 0.2)
    assert not metrics.within_alpha(math.inf, 100.0, 0.2)
    with pytest.raises(ValueError, match="alpha"):
        metrics.within_alpha(1.0, 1.0, 1.5)
    with pytest.raises(ValueError, match="NaN"):
        metrics.within_alpha(math.nan, 1.0, 0.2)


def test_lambda_time_counts_from_the_first_prediction():
    # t_lambda = t_start + lambda (EOL - t_start) = 100 + 0.5 (160 - 100) = 130; from t = 0 it
    # would be 80 (catches the t = 0 bug)
    assert metrics.lambda_flight(100, 160, 0.5) == 130
    assert metrics.lambda_flight(0, 160, 0.5) == 80
    with pytest.raises(ValueError, match="lambda"):
        metrics.lambda_flight(0, 10, 1.5)


def test_prediction_at_picks_the_side_asked():
    flights = [100, 110, 120, 130]
    assert metrics.prediction_at(flights, 118, "after") == 2     # flight 120
    assert metrics.prediction_at(flights, 118, "before") == 1    # flight 110
    assert metrics.prediction_at(flights, 120, "after") == 2     # at t itself: both sides
    assert metrics.prediction_at(flights, 120, "before") == 2
    assert metrics.prediction_at(flights, 131, "after") is None
    assert metrics.prediction_at(flights, 99, "before") is None
    with pytest.raises(ValueError, match="side"):
        metrics.prediction_at(flights, 100, "nearest")


def test_alpha_lambda_judges_one_prediction_at_its_own_true_rul():
    flights = [100, 110, 120, 130]
    eol = 160          # t_lambda = 130 (previous test): the last prediction, true RUL 30
    # cone [24, 36]: 33 in, 40 out; the other predictions do not matter
    assert metrics.alpha_lambda(flights, [0, 0, 0, 33], eol) is True
    assert metrics.alpha_lambda(flights, [0, 0, 0, 40], eol) is False
    # were t_lambda counted from t = 0 (80), the first prediction (true RUL 60) would be
    # judged: 60 is in its cone, so this catches that bug
    assert metrics.alpha_lambda(flights, [60, 0, 0, 0], eol) is False
    # lambda 0.3: t = 100 + 0.3 x 60 = 118. after: flight 120, true RUL 40, cone [32, 48]
    assert metrics.alpha_lambda(flights, [999, 999, 44, 999], eol, lam=0.3) is True
    # before: flight 110, true RUL 50, cone [40, 60]: 59 in (catches judging against the true
    # RUL at t_lambda, 42, whose cone [33.6, 50.4] leaves 59 out)
    assert metrics.alpha_lambda(flights, [999, 59, 999, 999], eol, lam=0.3,
                                side="before") is True
    assert metrics.alpha_lambda(flights, [999, 59, 999, 999], eol, lam=0.3) is False
    # infinite predictions are outside every cone
    assert metrics.alpha_lambda(flights, [math.inf] * 4, eol) is False
    # tracking stopped before t_lambda: nothing to judge
    assert metrics.alpha_lambda([0, 10], [1, 1], 100, lam=0.5) is None


def test_prognostic_horizons_first_entry_and_strict_by_hand():
    eol = 100            # bounds: true RUL +- 0.1 x 100 = +- 10 flights
    flights = [0, 20, 40, 60, 80]
    true = [100, 80, 60, 40, 20]
    # errors 50, 5, 15, 5, 5: in at 20, out at 40, in from 60 on
    # first entry (Saxena, progpy): PH = 100 - 20 = 80; strict (stays inside): 100 - 60 = 40
    pred = [150, 85, 75, 45, 25]
    assert metrics.prognostic_horizon(flights, pred, eol) == 80.0
    assert metrics.prognostic_horizon_strict(flights, pred, eol) == 40.0
    # error exactly 10 at every flight: inside (bounds included): PH = 100 - 0 for both
    assert metrics.prognostic_horizon(flights, [t + 10 for t in true], eol) == 100.0
    assert metrics.prognostic_horizon_strict(flights, [t + 10 for t in true], eol) == 100.0
    # the last prediction outside: strict 0, first entry still counts the entry at 0
    assert metrics.prognostic_horizon_strict(flights, [*true[:-1], 40], eol) == 0.0
    assert metrics.prognostic_horizon(flights, [*true[:-1], 40], eol) == 100.0
    # never inside: 0 for both
    assert metrics.prognostic_horizon(flights, [t + 11 for t in true], eol) == 0.0
    assert metrics.prognostic_horizon_strict(flights, [t + 11 for t in true], eol) == 0.0
    # fixed-width bounds (alpha x EOL), not relative: at flight 80 (true 20) an error of 9 is
    # 45 % of the true RUL but inside +- 10 (catches a relative cone)
    assert metrics.prognostic_horizon_strict(flights, [*true[:-1], 29], eol) == 100.0
    assert metrics.prognostic_horizon(flights, [150, 150, 150, 150, 29], eol) == 20.0
    assert metrics.prognostic_horizon_strict(flights, [*true[:-1], math.inf], eol) == 0.0


def test_monotonicity():
    # 3 steps down, none up: |0 - 3| / 3 = 1
    assert metrics.monotonicity([5, 4, 3, 2]) == 1.0
    # 2 up, 2 down: 0
    assert metrics.monotonicity([5, 6, 5, 6, 5]) == 0.0
    # 2 down, 1 equal: |0 - 2| / 3 (catches dividing by the non-zero steps, which gives 1)
    assert metrics.monotonicity([5, 4, 4, 3]) == pytest.approx(2 / 3)
    # 1 up, 3 down: |1 - 3| / 4 = 0.5 (catches n instead of n - 1: 0.4)
    assert metrics.monotonicity([9, 8, 9, 7, 6]) == pytest.approx(0.5)
    # inf, inf is an equal step; inf -> 150 a step down: |0 - 2| / 3
    assert metrics.monotonicity([math.inf, math.inf, 150, 100]) == pytest.approx(2 / 3)
    assert math.isnan(metrics.monotonicity([1.0]))


def test_coverage_is_inclusive():
    # [0,1] holds 1 (bound), [0,1] misses 2, [2,3] holds 2 (bound): 2 / 3
    assert metrics.coverage([0, 0, 2], [1, 1, 3], [1, 2, 2]) == pytest.approx(2 / 3)
    assert metrics.coverage([0], [math.inf], [1e9]) == 1.0
    with pytest.raises(ValueError, match="one length"):
        metrics.coverage([0, 0], [1], [1])


def test_detection_delay_and_false_alarm_rate():
    # onset 5: flags at 0 (before the onset: not a detection) and 30: 30 - 5 = 25
    assert metrics.detection_delay([0, 10, 20, 30], [True, False, False, True], 5) == 25
    # a flag at the onset's own inspection: 0 (catches > for >=)
    assert metrics.detection_delay([0, 10, 20], [False, True, True], 10) == 0
    assert metrics.detection_delay([0, 10], [False, False], 5) == math.inf
    assert metrics.detection_delay([0, 10], [True, True], None) is None
    # 4 healthy inspections, flagged at 2 of them; the flag at the sick one is no alarm
    flagged = [True, False, True, False, True]
    healthy = [True, True, True, True, False]
    assert metrics.false_alarm_rate(flagged, healthy) == 0.5
    assert math.isnan(metrics.false_alarm_rate([True], [False]))


def test_bad_inputs_are_clear_errors():
    with pytest.raises(ValueError, match="one length"):
        metrics.rmse([1, 2], [1])
    with pytest.raises(ValueError, match="non-empty"):
        metrics.mae([], [])
    with pytest.raises(ValueError, match="NaN"):
        phm08_score([math.nan], [3])
    with pytest.raises(ValueError, match="finite"):
        metrics.rmse([1], [math.inf])
    with pytest.raises(ValueError, match="increasing"):
        metrics.alpha_lambda([0, 20, 10], [1, 1, 1], 100)
    with pytest.raises(ValueError, match="EOL"):
        metrics.prognostic_horizon([0, 10], [5, 5], 10)
    with pytest.raises(ValueError, match="NaN"):
        metrics.monotonicity([1, math.nan])


# --- optional: NASA's progpy on the same predictions -----------------------------------------

def _profile(flights, pred):
    from progpy.predictors import ToEPredictionProfile
    from progpy.uncertain_data import ScalarData

    profile = ToEPredictionProfile()
    for f, p in zip(flights, pred):
        profile.add_prediction(float(f), ScalarData({"EOL": float(f + p)}))
    return profile


def test_alpha_lambda_agrees_with_progpy_on_point_predictions():
    """progpy's beta criterion on a point prediction is "the median strictly in the cone":
    ours on random profiles (no prediction exactly on a bound) with t_lambda passed as the
    absolute time progpy takes."""
    pytest.importorskip("progpy")
    from progpy.metrics import alpha_lambda as pp_alpha_lambda

    rng = np.random.default_rng(0)
    agree = 0
    for _ in range(200):
        flights = np.sort(rng.choice(np.arange(0, 300, 10), size=12, replace=False))
        eol = float(flights[-1] + rng.integers(1, 200))
        pred = (eol - flights) * rng.uniform(0.6, 1.4, flights.size)
        lam = float(rng.uniform(0.1, 0.9))
        t_lam = metrics.lambda_flight(float(flights[0]), eol, lam)
        if metrics.prediction_at(flights, t_lam) is None:
            continue
        theirs = pp_alpha_lambda(_profile(flights, pred), {"EOL": eol}, t_lam, 0.2, 0.5)
        assert metrics.alpha_lambda(flights, pred, eol, 0.2, lam) == theirs["EOL"]
        agree += 1
    assert agree > 100


def test_horizon_and_monotonicity_agree_with_progpy():
    """progpy's horizon counts from the first prediction meeting the criterion, as ours
    (:func:`prognostic_horizon`) on any profile; the strict variant agrees on profiles that
    stay inside once in.  Its monotonicity is of the mean time-to-event, ours of the RUL
    series given: equal."""
    pytest.importorskip("progpy", reason="progpy (the 'prognostics' extra) is not installed")
    from progpy.metrics import monotonicity as pp_monotonicity
    from progpy.metrics import prognostic_horizon as pp_horizon

    rng = np.random.default_rng(1)
    strict = 0
    for _ in range(60):
        flights = np.arange(0, 200, 10, dtype=float)
        eol = 200.0 + float(rng.integers(1, 50))
        true = eol - flights
        err = rng.uniform(-0.3, 0.3, flights.size) * eol * np.linspace(1, 0.1, flights.size)
        pred = np.maximum(true + err, 0.0)

        def criterion(tte, gt, eol=eol):
            return {key: abs(tte.mean[key] - gt[key]) <= 0.1 * eol for key in gt}

        theirs = pp_horizon(_profile(flights, pred), criterion, {"EOL": eol})["EOL"]
        ours = metrics.prognostic_horizon(flights, pred, eol, 0.1)
        assert (0.0 if theirs is None else theirs) == pytest.approx(ours)
        inside = np.abs(pred - true) <= 0.1 * eol
        assert metrics.prognostic_horizon_strict(flights, pred, eol, 0.1) <= ours
        if inside.any() and inside[int(np.argmax(inside)):].all():
            assert metrics.prognostic_horizon_strict(flights, pred, eol, 0.1) == \
                pytest.approx(ours)
            strict += 1
        assert metrics.monotonicity(pred) == pytest.approx(
            pp_monotonicity(_profile(flights, pred))["EOL"])
    assert strict >= 1
    # the hand case: a lucky first prediction (error 0), then out (20), then in for
    # good from flight 20: progpy and ours 100 - 0, strict 100 - 20
    flights, pred, eol = [0, 10, 20, 30], [100, 50, 70, 70], 100.0

    def criterion(tte, gt):
        return {key: abs(tte.mean[key] - gt[key]) <= 10 for key in gt}

    assert pp_horizon(_profile(flights, pred), criterion, {"EOL": eol})["EOL"] == 100.0
    assert metrics.prognostic_horizon(flights, pred, eol, 0.1) == 100.0
    assert metrics.prognostic_horizon_strict(flights, pred, eol, 0.1) == 80.0


def test_headline_metrics_by_hand():
    true = [100.0, 50.0, 20.0, 10.0]
    # 120 = +20 % (bound included), 39 = -22 % (out), 24 = +20 % (in), inf (out)
    pred = [120.0, 39.0, 24.0, math.inf]
    assert metrics.within_share(pred, true, 0.2) == 0.5
    assert metrics.within_share(pred, true, 0.1) == 0.0
    # clipping to a 60-flight horizon: 120 -> 60, inf -> 60; negative -> 0
    assert list(metrics.clip_rul([120, -3, 24, math.inf], 60.0)) == [60.0, 0.0, 24.0, 60.0]
    # PHM08 per unit, clipped at 60: d = -40 (early), -11, +4, +50 (late)
    terms = [math.exp(40 / 13) - 1, math.exp(11 / 13) - 1, math.exp(4 / 10) - 1,
             math.exp(50 / 10) - 1]
    assert metrics.phm08_mean(pred, true, 60.0) == pytest.approx(sum(terms) / 4, rel=1e-12)
    # a sum, not a mean, would be 4 x; unclipped it would be infinite
    assert math.isinf(phm08_score(pred, true))
    with pytest.raises(ValueError, match="horizon"):
        metrics.phm08_mean(pred, true, math.inf)
    # mean width: (20 + 0 + 40) / 3; an infinite bound makes it infinite
    assert metrics.mean_width([10, 5, 0], [30, 5, 40]) == 20.0
    assert math.isinf(metrics.mean_width([0, 5], [math.inf, 6]))
    with pytest.raises(ValueError, match="high < low"):
        metrics.mean_width([2], [1])


def test_bayes_point_and_weighted_quantiles_by_hand():
    from ema_bench.prognostics.bayes import best_point, weighted_quantile

    # candidates 0.8 R: 8 holds {10}; 8.8 holds {10, 11}; 9.6 holds R in [8, 12]: {10, 11,
    # 12}; 24 holds {30}: the point is 9.6 (the median, 11.5, holds only 3 too but is not the
    # smallest; the mean 15.75 holds none)
    assert best_point([10, 11, 12, 30]) == pytest.approx(9.6)
    # weights move it: all the weight on 30
    assert best_point([10, 11, 12, 30], [0, 0, 0, 1]) == pytest.approx(24.0)
    # +-10 %: 0.9 R; 9 holds R in [8.18, 10]: {10}; 9.9 holds [9, 11]: {10, 11}; 10.8 holds
    # [9.8, 12]: {10, 11, 12}
    assert best_point([10, 11, 12, 30], alpha=0.1) == pytest.approx(10.8)
    assert best_point([math.inf, math.inf]) == math.inf
    assert best_point([math.inf, 50.0, math.inf]) == pytest.approx(40.0)
    with pytest.raises(ValueError, match="sum to 0"):
        best_point([1.0, 2.0], [0.0, 0.0])
    assert list(weighted_quantile([4, 1, 3, 2], None, [0.25, 0.5, 1.0])) == [1, 2, 4]
    assert list(weighted_quantile([1, 2], [3, 1], [0.5, 0.8])) == [1, 2]
    assert weighted_quantile([1, math.inf], None, 0.975) == math.inf
