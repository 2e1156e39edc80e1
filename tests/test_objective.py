"""Edge cases of the objective (``ema_bench.objective``) and the scorer (``ema_bench.scoring``)
against values worked out by hand: the search space's bounds and slack, the checks of the
measured traces and their messages, the weights, the residuals' rescaling, and the scorer's
success rule and hit counts.  Found by mutation testing (docs/mutation-testing.md); the
ordinary cases are in ``test_problem.py``.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

import ema_bench.objective as objective_module
from ema_bench.effects import EFFECT_NAMES, N_EFFECTS
from ema_bench.faults import CASES, FAULT_NAMES, LOWER, NOMINAL, UPPER
from ema_bench.monitor import simulate_monitor
from ema_bench.objective import (
    KNOWN_TESTS,
    OUTPUT_DT,
    PENALTY,
    Objective,
    ProblemError,
    SearchSpace,
    fitness_from_outputs,
    signal_scales,
    signal_weights,
)
from ema_bench.physics.sensors import SENSORS
from ema_bench.scoring import (
    first_hits,
    improvements,
    parameter_hits,
    range_error,
    score,
    successes,
)
from ema_bench.suites.problem import make_problem
from ema_bench.traces import Traces


@pytest.fixture(scope="module")
def measured() -> Traces:
    return make_problem("small", track="twin", seed=0, budget=1).measured


# --- the search space -----------------------------------------------------------------------
def test_search_space_names_units_and_read_only_bounds():
    space = SearchSpace.of(("sensor_offset", "aero_spring"))
    assert space.names == FAULT_NAMES + ("sensor_offset", "aero_spring") and space.dim == 6
    assert space.units["sensor_offset"] == "rad" and space.units["aero_spring"] == "N m/rad"
    assert space.units["Gprop"] == SearchSpace.of().units["Gprop"]
    np.testing.assert_array_equal(space.lower[4:], [-0.02, -400.0])
    np.testing.assert_array_equal(space.upper[4:], [0.02, 2000.0])
    for a in (space.lower, space.upper, space.nominal):
        with pytest.raises(ValueError, match="read-only"):
            a[0] = 0.9


def test_search_space_effect_bounds_have_a_slack_of_1e_9_of_the_range():
    # sensor_offset: [-0.02, 0.02], range 0.04, slack 4e-11 (its bounds sum to zero, and the
    # slack is 1e-9 of the range, not of their sum nor 1e-9 / range)
    space = SearchSpace.of(("sensor_offset",))
    lo, hi = -0.02, 0.02
    slack = 1e-9 * (hi - lo)

    def row(v):
        return np.r_[NOMINAL, v][None, :]

    for v, inside in ((lo - slack, lo), (hi + slack, hi), (lo - 0.5 * slack, lo),
                      (hi + 0.5 * slack, hi), (hi, hi), (lo, lo)):
        assert space.check(row(v))[0, 4] == inside, v
    for v in (lo - 2 * slack, hi + 2 * slack, hi + 0.01, np.nan, np.inf):
        with pytest.raises(ProblemError, match=r"^effect sensor_offset=.* in row 0 is not "
                                               r"finite or outside \[-0\.02, 0\.02\]$"):
            space.check(row(v))


def test_effects_for_adds_the_searched_effects_to_the_base():
    space = SearchSpace.of(("delay", "eccentricity"))
    X = np.array([np.r_[NOMINAL, 1e-3, 0.1], np.r_[NOMINAL, 0.0, 0.05]])
    base = np.zeros(N_EFFECTS)
    base[EFFECT_NAMES.index("cogging")] = 0.02
    E = space.effects_for(X, base)
    want = np.tile(base, (2, 1))
    want[:, EFFECT_NAMES.index("delay")] = [1e-3, 0.0]
    want[:, EFFECT_NAMES.index("eccentricity")] = [0.1, 0.05]
    np.testing.assert_array_equal(E, want)
    want[:, EFFECT_NAMES.index("cogging")] = 0.0
    np.testing.assert_array_equal(space.effects_for(X), want)  # no base: zeros


# --- the measured traces --------------------------------------------------------------------
def test_objective_refuses_what_is_not_traces():
    with pytest.raises(ProblemError,
                       match=r"^measured must be a Traces \(see ema_bench\.load_traces\)$"):
        Objective({"step": np.zeros((300, 4))})


@pytest.mark.parametrize("factor", [1 + 1e-7, 1 - 1e-7, 2.0])
def test_objective_refuses_another_sample_rate(measured, factor):
    # rtol 1e-9, no absolute tolerance: 1e-7 of 1 ms is off
    t = Traces({"step": measured.data["step"]}, dt=OUTPUT_DT * factor)
    with pytest.raises(ProblemError, match=r"^measured traces are sampled at "):
        Objective(t)
    if factor == 2.0:
        with pytest.raises(ProblemError, match=r"^measured traces are sampled at 500 Hz; the "
                                               r"monitor model outputs 1000 Hz \(load finer "
                                               r"data with load_traces, which block-averages "
                                               r"it to that rate\)$"):
            Objective(t)


def test_objective_names_unknown_tests_and_wrong_lengths(measured):
    t = Traces({"step": measured.data["step"], "ramp": np.zeros((50, 4))})
    with pytest.raises(ProblemError, match=r"^measured traces hold unknown test\(s\) \['ramp'\]; "
                                           r"the monitor model knows \['step', 'sine', "
                                           r"'sine2'\]$"):
        Objective(t)
    assert list(KNOWN_TESTS) == ["step", "sine", "sine2"]
    t = Traces({"step": measured.data["step"][:250]})
    with pytest.raises(ProblemError, match=r"^test 'step' has 250 samples at 1000 Hz, the "
                                           r"protocol expects 300$"):
        Objective(t)


# --- weights, outputs, fitness ----------------------------------------------------------------
def test_flat_signals_are_scaled_by_ten_adc_steps(measured):
    flat = Traces({"step": np.zeros((300, 4)) + [0.1, 0.2, 0.3, 0.4]})
    scales = signal_scales(flat)["step"]
    np.testing.assert_array_equal(scales, [10.0 * s.lsb for s in SENSORS])
    # normalised weights by default
    np.testing.assert_array_equal(signal_weights(flat)["step"], 1.0 / scales**2)
    obj = Objective(measured)
    assert obj.normalise is True
    for t in measured.tests:
        np.testing.assert_array_equal(obj.weights[t], 1.0 / signal_scales(measured)[t] ** 2)


def test_objective_layout_arrays_are_read_only_and_in_signal_order(measured):
    obj = Objective(measured)
    n = {t: measured.n_samples(t) for t in measured.tests}
    want = np.concatenate([np.repeat(np.arange(4), n[t]) for t in measured.tests])
    np.testing.assert_array_equal(obj.signal_index, want)
    np.testing.assert_array_equal(obj.data, measured.stacked())
    for a in (obj.signal_index, obj.data, obj.factors):
        with pytest.raises(ValueError, match="read-only"):
            a[0] = 1


def test_the_objective_names_the_signals_it_sees_and_its_mask_is_read_only(measured):
    """``signals`` in ``SIGNALS`` order whatever order they were asked in, all four by
    default; the mask the weights were made with cannot be changed afterwards."""
    assert Objective(measured).signals == ("theta_u", "theta_m", "omega_m", "i_eq")
    obj = Objective(measured, signals=("i_eq", "theta_u"))
    assert obj.signals == ("theta_u", "i_eq")
    np.testing.assert_array_equal(obj.mask, [1.0, 0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="read-only"):
        obj.mask[1] = 1.0


def test_objective_monitor_effects_and_a_subset_of_tests(measured):
    E = np.zeros(N_EFFECTS)
    E[EFFECT_NAMES.index("cogging")] = 0.05
    only_sine = Traces({"sine": measured.data["sine"]})
    obj = Objective(only_sine, effects=list(E))
    assert obj.effects.dtype == float and obj.effects.tolist() == E.tolist()
    X = CASES["small"].x[None, :]
    outputs, ok = obj.outputs(X)
    want, _ = simulate_monitor(X, E, tests=(KNOWN_TESTS["sine"],))
    assert list(outputs) == ["sine"] and ok[0]
    np.testing.assert_array_equal(outputs["sine"], want["sine"])
    # by hand: the normalised mean squared error of the one test
    d = want["sine"][0] - only_sine.data["sine"]
    f = np.sum(d**2 / signal_scales(only_sine)["sine"] ** 2) / 1000
    assert obj.evaluate(X)[0][0] == pytest.approx(f, rel=1e-12)
    # integer effects are stored as floats (an augmented column written into them is not
    # truncated)
    assert Objective(only_sine, effects=[0] * N_EFFECTS).effects.dtype == float
    with pytest.raises(ProblemError, match=rf"^effects must have shape \({N_EFFECTS},\)$"):
        Objective(measured, effects=np.zeros(3))


def test_fitness_from_outputs_by_hand(measured):
    rng = np.random.default_rng(1)
    outputs = {t: measured.data[t][None] + rng.normal(0, 0.01, (2,) + measured.data[t].shape)
               for t in measured.tests}
    w = {t: np.array([1.0, 2.0, 3.0, 4.0]) for t in measured.tests}
    want = [sum(np.sum((outputs[t][k] - measured.data[t]) ** 2 * w[t]) / measured.n_samples(t)
                for t in measured.tests) for k in range(2)]
    np.testing.assert_allclose(fitness_from_outputs(outputs, measured, w), want, rtol=1e-12)


def test_overflowing_or_nan_outputs_score_penalty_silently(monkeypatch, measured):
    real = objective_module.simulate_monitor

    def wild(X, *args, **kwargs):
        outputs, ok = real(X, *args, **kwargs)
        for v in outputs.values():
            v[0] = 1e200      # overflows when squared
            v[1, 3, 1] = np.nan
            v[2, 0, 0] = np.inf
        return outputs, ok

    monkeypatch.setattr(objective_module, "simulate_monitor", wild)
    obj = Objective(measured)
    X = np.tile(CASES["small"].x, (3, 1))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        f, outputs, failed = obj.evaluate(X)
        r = obj.residuals(outputs, f)
    assert failed.all() and np.all(f == PENALTY)
    np.testing.assert_allclose(np.sum(r**2, axis=1), PENALTY, rtol=1e-12)


def test_residuals_are_rescaled_only_down_to_a_capped_fitness(measured):
    obj = Objective(measured)
    X = np.stack([CASES["small"].x, NOMINAL])
    f, outputs, _ = obj.evaluate(X)
    r = obj.residuals(outputs, f)
    raw = np.sum(r**2, axis=1)
    np.testing.assert_allclose(raw, f, rtol=1e-12)
    # a fitness below the residuals' sum (a capped one): scaled down to it
    low = obj.residuals(outputs, f / 4)
    np.testing.assert_allclose(low, r / 2, rtol=1e-12)
    # a fitness above it: never scaled up
    np.testing.assert_array_equal(obj.residuals(outputs, 4 * f), r)


# --- the scorer -----------------------------------------------------------------------------
def test_success_is_at_most_one_percent_of_the_range_inclusive():
    true = np.array([0.9, 0.5, 0.02, 1.0e5])
    est = true.copy()
    est[3] = 1.01e5  # |1000| / 1e5 = 0.01 exactly
    assert range_error(est, true)[3] == 0.01
    assert score(est, true).success
    assert successes(est, true) == np.True_
    est[3] = 1.0100001e5
    assert not score(est, true).success and not successes(est, true)


def test_successes_row_by_row():
    true = CASES["small"].x
    width = UPPER - LOWER
    est = np.stack([true, true + 0.005 * width, true + 0.02 * width * np.array([0, 0, 1, 0])])
    np.testing.assert_array_equal(successes(est, true), [True, True, False])


def test_first_hits_by_hand():
    best = [5.0, 3.0, 3.0, 1.0, 0.5]
    assert first_hits(best, [4.0, 3.0, 0.9, 0.1]) == [2, 2, 5, None]
    assert first_hits(np.array([2, 1]), [1]) == [2]
    assert first_hits([], [1.0]) == [None]


def test_improvements_by_hand():
    np.testing.assert_array_equal(improvements([5.0, 6.0, 4.0, 4.0, 1.0, 2.0]), [0, 2, 4])
    np.testing.assert_array_equal(improvements([3, 3, 2]), [0, 2])
    np.testing.assert_array_equal(improvements([7.0]), [0])  # the first evaluation counts
    empty = improvements([])
    assert empty.shape == (0,) and empty.dtype.kind == "i"


def test_parameter_hits_judge_the_best_so_far_point():
    true = CASES["small"].x
    width = UPPER - LOWER
    X = np.stack([
        NOMINAL,                                 # far
        true + 0.002 * width,                    # within 1 % (and 3 %), but worse fitness:
        true + 0.05 * width,                     # not the best-so-far point
        true + 0.02 * width,                     # the best so far: within 3 %, not 1 %
        true + 0.005 * width,                    # the best: within 1 %
    ])
    f = np.array([5.0, 6.0, 4.0, 3.0, 1.0])
    assert parameter_hits(X, f, true, [0.1, 0.03, 0.01, 0.001]) == [3, 4, 5, None]
    assert parameter_hits(X[:0], f[:0], true, [0.1]) == [None]
    # augmented rows: only the fault columns are judged
    Xa = np.hstack([X, np.full((5, 1), 99.0)])
    assert parameter_hits(Xa, f, true, [0.01]) == [5]


# --- per-sample weights -----------------------------------------------------------------------
def test_sample_weights_by_hand(measured):
    # weight 2 on every step sample, 0 on the sine's first signal and 0.5 on the rest of it
    sw = {"step": np.full((300, 4), 2.0), "sine": np.full((1000, 4), 0.5)}
    sw["sine"][:, 0] = 0.0
    X = np.stack([CASES["small"].x, NOMINAL])
    plain = Objective(measured)
    f0, outputs, _ = plain.evaluate(X)
    scales = signal_scales(measured)

    def part(t, k):
        d = outputs[t][k] - measured.data[t]
        return np.sum(sw[t] * d**2 / scales[t] ** 2) / measured.n_samples(t)

    obj = Objective(measured, sample_weights=sw)
    f, _, _ = obj.evaluate(X)
    np.testing.assert_allclose(f, [part("step", k) + part("sine", k) for k in range(2)],
                               rtol=1e-12)
    assert not np.allclose(f, f0)
    r = obj.residuals(outputs, f)
    np.testing.assert_allclose(np.sum(r**2, axis=1), f, rtol=1e-12)


@pytest.mark.parametrize("bad", ["shape", "nan", "negative"])
def test_sample_weights_are_checked_one_condition_at_a_time(measured, bad):
    sw = {t: np.ones(measured.data[t].shape) for t in measured.tests}
    if bad == "shape":
        sw["sine"] = np.ones((999, 4))
    elif bad == "nan":
        sw["sine"][5, 2] = np.nan
    else:
        sw["sine"][5, 2] = -0.5
    shape = "(999, 4)" if bad == "shape" else "(1000, 4)"
    with pytest.raises(ProblemError, match=rf"^sample_weights\['sine'\] must be finite, >= 0 and "
                                           rf"of shape \(1000, 4\), got shape {re.escape(shape)}$"):
        Objective(measured, sample_weights=sw)


def test_sample_weights_zero_and_fractions_are_fine_and_every_test_needs_one(measured):
    sw = {t: np.zeros(measured.data[t].shape) for t in measured.tests}
    sw["step"][:, 1] = 0.5
    Objective(measured, sample_weights=sw)  # no error: >= 0, any size below 1
    with pytest.raises(ProblemError, match="^sample_weights has no entry for test 'sine'$"):
        Objective(measured, sample_weights={"step": sw["step"]})


def test_parameter_hits_on_given_ranges_and_a_judged_mask():
    """The default ranges are the faults' widths (the first fault's lower bound is not 0);
    with every searched parameter, each error is in its own range, and a parameter that
    carries no target (``judged`` False) is not judged.  Errors by hand."""
    true = CASES["small"].x
    width = UPPER - LOWER
    X = np.stack([NOMINAL, true + np.array([0.02 * width[0], 0.0, 0.0, 0.0])])
    f = np.array([2.0, 1.0])
    assert parameter_hits(X, f, true, [0.03, 0.01]) == [2, None]   # 2 % of its width off
    true6 = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    ranges = np.array([10.0, 10.0, 10.0, 10.0, 1.0, 100.0, 1e-9])  # one more than searched
    X6 = np.array([[1.0, 2.0, 3.0, 4.0, 5.0, 56.0, 7.0],      # 50 % of the 6th's range off
                   [1.0, 2.0, 3.0, 4.0, 5.02, 6.5, 7.0],      # 2 % (5th) and 0.5 % (6th)
                   [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 9.0]])      # exact (7th: no parameter)
    f6 = np.array([3.0, 2.0, 1.0])
    assert parameter_hits(X6, f6, true6, [0.03, 0.01], ranges) == [2, 3]
    judged = np.array([True] * 5 + [False])
    assert parameter_hits(X6, f6, true6, [0.03, 0.01], ranges, judged) == [1, 1]
    assert parameter_hits(X6, f6, true6, [0.03], ranges, np.zeros(6, bool)) == [None]


def test_the_objective_simulates_on_its_own_model_version():
    """``Objective(params=...)`` reaches the monitor: on version 2's parameters (libm's sine
    and cosine in eccentricity) its outputs are version 2's monitor outputs, bit for bit,
    and not this installation's default version's."""
    from ema_bench.params import model_params

    m = make_problem("small", track="twin", seed=0, budget=1).measured
    space = SearchSpace.of(("eccentricity",))
    X = np.array([np.r_[NOMINAL, 0.1]])
    E = space.effects_for(X)
    obj = Objective(m, space, params=model_params("2"))
    v2, _ = obj.outputs(X)
    want, _ = simulate_monitor(X[:, :4], E, tests=obj.tests, params=model_params("2"))
    now, _ = simulate_monitor(X[:, :4], E, tests=obj.tests)
    for t in m.tests:
        np.testing.assert_array_equal(v2[t], want[t])
    assert any(not np.array_equal(v2[t], now[t]) for t in m.tests)
