"""Tests of ema_bench.problem: budget, evaluation, residuals, scoring and the hidden truth."""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping

import numpy as np
import pytest

import ema_bench.objective as objective_module
from ema_bench.faults import (
    CASES,
    FAULT_NAMES,
    FAULT_UNITS,
    LOWER,
    NOMINAL,
    UPPER,
    random_faults,
)
from ema_bench.objective import PENALTY, signal_scales
from ema_bench.physics.sensors import SENSORS
from ema_bench.problem import BudgetExhausted, Problem, ProblemError
from ema_bench.scoring import Score
from ema_bench.suites.problem import make_problem
from ema_bench.traces import SIGNALS, Traces

DAMAGED = ("small", "full", "random")


def truth_of(problem: Problem) -> np.ndarray:
    """The hidden truth, through the scorer's door."""
    return np.array(list(problem.score(problem.nominal).truth.values()))


def candidates(n: int, seed: int = 0) -> np.ndarray:
    return LOWER + np.random.default_rng(seed).random((n, 4)) * (UPPER - LOWER)


# ---- budget --------------------------------------------------------------------------------------


def test_budget_is_exact_across_batch_single_and_residual_calls():
    p = make_problem("small", track="twin", seed=0, budget=10)
    X = candidates(20)
    returned = list(p.evaluate(X[:3]))
    returned.append(p.evaluate(X[3]))
    returned.append(float(np.sum(p.residuals(X[4]) ** 2)))
    returned.extend(p.evaluate(X[5:9]))
    assert p.evaluations == 9 and p.remaining == 1
    with pytest.raises(BudgetExhausted, match="2 evaluation"):
        p.evaluate(X[9:11])  # would exceed: nothing scored
    assert p.evaluations == 9
    returned.append(p.evaluate(X[9]))  # the last one fits
    assert p.evaluations == p.budget == 10 and p.remaining == 0
    for call in (lambda: p.evaluate(X[10]), lambda: p.evaluate(X[10:12]),
                 lambda: p.residuals(X[10])):
        with pytest.raises(BudgetExhausted):
            call()
    assert p.evaluations == 10
    h = p.history()
    assert len(h["index"]) == len(h["fitness"]) == len(h["wall_s"]) == 10
    np.testing.assert_array_equal(h["index"], np.arange(10))
    np.testing.assert_array_equal(h["x"], X[:10])
    np.testing.assert_allclose(h["fitness"], returned, rtol=1e-10)
    np.testing.assert_array_equal(h["best"], np.minimum.accumulate(h["fitness"]))
    assert np.all(np.diff(h["wall_s"]) >= 0)
    best_x, best_f = p.best
    assert best_f == h["fitness"].min()
    np.testing.assert_array_equal(best_x, X[int(np.argmin(h["fitness"]))])


def test_empty_batch_costs_nothing_and_best_starts_at_nominal():
    p = make_problem("small", track="twin", seed=0, budget=2)
    assert p.evaluate(np.empty((0, 4))).shape == (0,)
    assert p.evaluations == 0
    x, f = p.best
    np.testing.assert_array_equal(x, NOMINAL)
    assert f == float("inf")
    assert p.history()["fitness"].shape == (0,)


def test_limit_shrinks_the_budget_and_never_grows_it():
    p = make_problem("small", track="twin", seed=0, budget=10)
    X = candidates(10)
    p.evaluate(X[:3])
    p.limit(4)
    assert p.budget == 7 and p.remaining == 4
    p.limit(100)
    assert p.budget == 7
    p.evaluate(X[3:7])
    with pytest.raises(BudgetExhausted):
        p.evaluate(X[7])
    assert len(p.history()["fitness"]) == 7


# ---- evaluation ----------------------------------------------------------------------------------


@pytest.mark.parametrize("normalise", [True, False])
def test_batch_single_and_residuals_agree(normalise):
    X = candidates(6, seed=1)
    batch = make_problem("small", seed=0, budget=6, normalise=normalise).evaluate(X)
    single_p = make_problem("small", seed=0, budget=6, normalise=normalise)
    single = np.array([single_p.evaluate(x) for x in X])
    np.testing.assert_allclose(batch, single, rtol=1e-12, atol=0)
    resid_p = make_problem("small", seed=0, budget=6, normalise=normalise)
    for x, f in zip(X, batch):
        r = resid_p.residuals(x)
        assert r.shape == (resid_p.n_residuals,) == ((300 + 1000) * 4,)
        np.testing.assert_allclose(np.sum(r**2), f, rtol=1e-10)
    np.testing.assert_allclose(resid_p.history()["fitness"], batch, rtol=1e-12)


def test_twin_truth_is_at_noise_level_and_beats_random_vectors():
    p = make_problem("small", track="twin", seed=4, budget=1001)
    truth = truth_of(p)
    f_true = p.evaluate(truth)
    scales = signal_scales(p.measured)
    noise = sum((s.noise_std**2 + s.lsb**2 / 12.0) / scales[t][k] ** 2
                for t in p.measured.tests for k, s in enumerate(SENSORS))
    assert 0.7 * noise < f_true < 1.4 * noise
    f_random = p.evaluate(random_faults(4, n=1000))
    assert f_true < f_random.min()


@pytest.mark.parametrize("case", DAMAGED)
def test_reference_truth_beats_nominal(case):
    p = make_problem(case, seed=0, budget=2)
    f_true, f_nominal = p.evaluate(np.stack([CASES[case].x, NOMINAL]))
    assert f_true < f_nominal
    assert f_true == pytest.approx(p.fitness_at_truth(), rel=1e-12)


def test_normalise_false_gives_the_raw_fitness_dominated_by_motor_signals():
    x = NOMINAL
    raw_p = make_problem("small", seed=0, budget=1, normalise=False)
    f_raw = raw_p.evaluate(x)
    f_norm = make_problem("small", seed=0, budget=1).evaluate(x)
    assert f_raw > 100 * f_norm
    outputs, ok = raw_p.simulate(x)
    assert ok[0]
    mse = np.zeros(4)  # per signal, summed over tests
    for t in raw_p.measured.tests:
        mse += np.mean((outputs[t][0] - raw_p.measured.data[t]) ** 2, axis=0)
    assert f_raw == pytest.approx(mse.sum(), rel=1e-10)
    assert (mse[1] + mse[2]) / mse.sum() > 0.99  # motor angle and speed
    assert raw_p.evaluations == 1  # simulate() is not counted


def test_simulation_failure_scores_penalty_and_is_counted(monkeypatch):
    real = objective_module.simulate_monitor

    def flaky(X, *args, **kwargs):
        outputs, ok = real(X, *args, **kwargs)
        ok = ok.copy()
        ok[::2] = False
        return outputs, ok

    p = make_problem("small", track="twin", seed=0, budget=6)
    monkeypatch.setattr(objective_module, "simulate_monitor", flaky)
    X = candidates(4)
    f = p.evaluate(X)  # must not raise
    np.testing.assert_array_equal(f[[0, 2]], PENALTY)
    assert np.all(f[[1, 3]] < PENALTY)
    assert p.failures == 2 and p.evaluations == 4
    assert p.best[1] == min(f[1], f[3])
    assert p.evaluate(X[0]) == PENALTY and p.failures == 3
    r = p.residuals(X[2])
    np.testing.assert_allclose(np.sum(r**2), PENALTY, rtol=1e-10)
    assert p.failures == 4 and p.evaluations == 6


def test_non_finite_outputs_score_penalty(monkeypatch):
    real = objective_module.simulate_monitor

    def nan_outputs(X, *args, **kwargs):
        outputs, ok = real(X, *args, **kwargs)
        for v in outputs.values():
            v[1, 5, 2] = np.nan  # ok stays True: the fitness check must catch it
        return outputs, ok

    p = make_problem("small", track="twin", seed=0, budget=3)
    monkeypatch.setattr(objective_module, "simulate_monitor", nan_outputs)
    f = p.evaluate(candidates(3))
    assert f[1] == PENALTY and np.all(f[[0, 2]] < PENALTY) and p.failures == 1


# ---- bad input -----------------------------------------------------------------------------------


def test_bad_vectors_raise_problem_error_naming_the_fault():
    p = make_problem("small", track="twin", seed=0, budget=5)
    for bad in (np.zeros(3), np.zeros((2, 3)), np.zeros((2, 2, 4))):
        with pytest.raises(ProblemError, match="shape"):
            p.evaluate(bad)
    x = NOMINAL.copy()
    x[1] = np.nan
    with pytest.raises(ProblemError, match="Fst"):
        p.evaluate(x)
    with pytest.raises(ProblemError, match="Fst"):
        p.residuals(x)
    x = NOMINAL.copy()
    x[2] = 0.05
    with pytest.raises(ProblemError, match=r"BLK.*outside its bounds"):
        p.evaluate(x)
    X = np.stack([NOMINAL, NOMINAL])
    X[1, 3] = 2e5
    with pytest.raises(ProblemError, match=r"Gprop.*row 1"):
        p.evaluate(X)
    assert p.evaluations == 0  # nothing scored


def test_unknown_case_track_or_budget_raise_problem_error():
    with pytest.raises(ProblemError, match="unknown case"):
        make_problem("huge")
    with pytest.raises(ProblemError, match="unknown track"):
        make_problem("small", track="lab")
    with pytest.raises(ProblemError, match="budget"):
        make_problem("small", track="twin", budget=0)
    with pytest.raises(ProblemError):
        make_problem(None)
    with pytest.raises(ProblemError, match="Xa"):
        make_problem({"Xa": 1.0}, track="twin")


# ---- the hidden truth ----------------------------------------------------------------------------


def _holds(obj, truth: np.ndarray, depth: int = 0, seen: set | None = None) -> bool:
    """Does ``obj`` hold the true vector, as an array/sequence or a name -> value mapping,
    anywhere in its public contents (mappings, sequences, dataclasses, Traces)?"""
    seen = set() if seen is None else seen
    if depth > 6 or id(obj) in seen:
        return False
    seen.add(id(obj))
    if isinstance(obj, Mapping):
        if set(obj) == set(FAULT_NAMES):
            try:
                if np.allclose([float(obj[n]) for n in FAULT_NAMES], truth, rtol=1e-9, atol=0):
                    return True
            except (TypeError, ValueError):
                pass
        return any(_holds(v, truth, depth + 1, seen) for v in obj.values())
    if isinstance(obj, str | bytes | int | float | bool | type(None)):
        return False
    if isinstance(obj, list | tuple | np.ndarray):
        try:
            num = np.asarray(obj, dtype=float)
        except (TypeError, ValueError):
            return any(_holds(v, truth, depth + 1, seen) for v in obj)
        if num.ndim >= 1 and num.shape[-1] == 4:
            return bool(np.any(np.all(np.isclose(num.reshape(-1, 4), truth, rtol=1e-9, atol=0),
                                      axis=1)))
        return False
    if isinstance(obj, Traces):
        return _holds(dict(obj.meta), truth, depth + 1, seen)
    if dataclasses.is_dataclass(obj):
        return any(_holds(getattr(obj, f.name), truth, depth + 1, seen)
                   for f in dataclasses.fields(obj))
    return False


@pytest.mark.parametrize(("case", "track"), [("small", "reference"), ("full", "reference"),
                                             ("random", "twin"), ("seeded", "reference"),
                                             ("seeded", "twin")])
def test_truth_is_not_reachable_through_public_attributes(case, track):
    p = make_problem(case, track=track, seed=3, budget=2)
    truth = truth_of(p)
    assert not np.allclose(truth, NOMINAL)
    public = {k: v for k, v in vars(p).items() if not k.startswith("_")}
    for name in dir(p):
        if not name.startswith("_"):
            value = getattr(p, name)
            if not callable(value):
                public[name] = value
    assert "measured" in public and "meta" in public and "best" in public
    for name, value in public.items():
        assert not _holds(value, truth), f"problem.{name} holds the true vector"
    assert _holds({"x": {"a": dict(zip(FAULT_NAMES, truth))}}, truth)  # the search works
    assert p.has_truth


# ---- scoring -------------------------------------------------------------------------------------


def test_score_paper_accuracy_and_range_error():
    p = make_problem("small", track="twin", seed=0, budget=1)
    est = np.array([0.9, 0.3378 * 1.1, 0.012, 1.05e5])
    s = p.score(est)
    assert isinstance(s, Score)
    assert s.truth == dict(zip(FAULT_NAMES, CASES["small"].faults))
    assert s.x == dict(zip(FAULT_NAMES, est.tolist()))
    expected_acc = {"Na": 100 * (1 - 0.05 / 0.95), "Fst": 90.0, "BLK": 80.0, "Gprop": 95.0}
    expected_err = {"Na": 0.25, "Fst": 0.05, "BLK": 0.05, "Gprop": 0.05}
    for n in FAULT_NAMES:
        assert s.accuracy[n] == pytest.approx(expected_acc[n], rel=1e-12)
        assert s.range_error[n] == pytest.approx(expected_err[n], rel=1e-12)
    assert s.success is False
    assert set(s.as_dict()) == {"x", "truth", "accuracy", "range_error", "success"}
    perfect = p.score(CASES["small"].x)
    assert perfect.success and all(a == 100.0 for a in perfect.accuracy.values())


def test_score_zero_truth_uses_the_range_error():
    p = make_problem("nominal", track="twin", seed=0, budget=1)
    assert p.score(NOMINAL).accuracy["BLK"] == 100.0
    s = p.score(NOMINAL + np.array([0, 0, 0.001, 0]))
    assert s.accuracy["BLK"] is None
    assert s.range_error["BLK"] == pytest.approx(0.025)


def test_success_threshold_is_one_percent_of_the_range():
    p = make_problem("small", track="twin", seed=0, budget=1)
    truth = CASES["small"].x
    width = UPPER - LOWER
    assert p.score(truth + 0.0099 * width * np.array([-1, 1, 1, -1])).success
    for j in range(4):
        step = np.zeros(4)
        step[j] = 0.0101 * width[j] * (-1 if j == 0 else 1)
        assert not p.score(truth + step).success, FAULT_NAMES[j]


# ---- seeded instances ----------------------------------------------------------------------------


def test_seeded_instances_are_reproducible_and_inside_bounds():
    truths = []
    for seed in range(20):
        a = make_problem("seeded", track="twin", seed=seed, budget=1)
        b = make_problem("seeded", track="twin", seed=seed, budget=1)
        ta, tb = truth_of(a), truth_of(b)
        np.testing.assert_array_equal(ta, tb)
        np.testing.assert_array_equal(a.measured.stacked(), b.measured.stacked())
        assert np.all(ta >= LOWER) and np.all(ta <= UPPER)
        assert a.label == "seeded(h=1)"
        truths.append(ta)
    assert len({tuple(t) for t in truths}) == 20
    flat = make_problem("seeded", track="twin", seed=0, budget=1, heterogeneity=0.0)
    np.testing.assert_array_equal(truth_of(flat), NOMINAL)
    ref_a = make_problem("seeded", seed=2, budget=1)
    ref_b = make_problem("seeded", seed=2, budget=1)
    np.testing.assert_array_equal(ref_a.measured.stacked(), ref_b.measured.stacked())
    np.testing.assert_array_equal(truth_of(ref_a), truths[2])


def test_limit_refuses_negative_and_score_rejects_bad_estimates():
    p = make_problem("small", track="twin", seed=0, budget=10)
    with pytest.raises(ProblemError, match="n >= 0"):
        p.limit(-1)
    with pytest.raises(ProblemError, match="Na"):
        p.score([2.0, 0.3, 0.01, 1e5])


def test_public_meta_reveals_neither_seed_nor_effects():
    p = make_problem("seeded", track="twin", seed=7, budget=1, effects={"eccentricity": 0.05})
    assert set(p.meta) == {"case", "track"}


def test_augmented_problem_fits_effects_beside_the_faults():
    p = make_problem("small", track="twin", seed=0, budget=10,
                     effects={"eccentricity": 0.1}, augment=("eccentricity", "delay"))
    assert p.names == FAULT_NAMES + ("eccentricity", "delay") and p.dim == 6
    assert p.nominal[4:].tolist() == [0.0, 0.0]
    x_true = np.r_[CASES["small"].x, 0.1, 0.0]
    # the augmented model at the true effect explains the data; at zero it does not
    f_true, f_off = p.evaluate(np.vstack([x_true, np.r_[CASES["small"].x, 0.0, 0.0]]))
    assert f_true < 0.2 * f_off
    np.testing.assert_allclose(p.from_unit(p.to_unit(x_true)), x_true)
    with pytest.raises(ProblemError, match="eccentricity"):
        p.evaluate(np.r_[CASES["small"].x, 5.0, 0.0])
    with pytest.raises(ProblemError, match="shape"):
        p.evaluate(CASES["small"].x)
    assert p.score(x_true).success
    with pytest.raises(ProblemError, match="library"):
        make_problem("small", budget=1, augment=("quadratic_damping",))


def test_same_seed_sequence_object_gives_the_same_instance_twice():
    ss = np.random.SeedSequence(42)
    a = make_problem("small", track="twin", seed=ss, budget=1)
    b = make_problem("small", track="twin", seed=ss, budget=1)
    assert a.measured.allclose(b.measured)


# ---- edges found by mutation testing (docs/mutation-testing.md) ------------------------------


def test_budget_check_edges_and_messages():
    from ema_bench.problem import MAX_BUDGET, check_budget

    assert check_budget(MAX_BUDGET) == MAX_BUDGET and check_budget(np.int64(3)) == 3
    for bad in (True, 0, 2.0, "5"):
        with pytest.raises(ProblemError, match=r"^budget must be a positive integer, got "):
            check_budget(bad)
    with pytest.raises(ProblemError, match=r"^budget 1000000001 is beyond the maximum of 1e\+09 "
                                           r"evaluations \(about 12 days at 1 ms each\)$"):
        check_budget(MAX_BUDGET + 1)


def test_problem_defaults_and_what_it_passes_on():
    measured = make_problem("small", track="twin", seed=0, budget=1).measured
    p = Problem(measured, 3)
    assert (p.label, p.track, p.normalise, p.augment) == ("measured", "measured", True, ())
    assert p.units == FAULT_UNITS
    assert not p.has_truth
    # monitor effects and sample weights reach the objective; augment the search space
    E = np.zeros(objective_module.N_EFFECTS)
    E[0] = 0.05
    twice = {t: np.full(measured.data[t].shape, 2.0) for t in measured.tests}
    q = Problem(measured, 3, monitor_effects=E, augment=("delay",), sample_weights=twice)
    np.testing.assert_array_equal(q.objective.effects, E)
    assert q.augment == ("delay",) and q.units["delay"] == "s"
    base = Problem(measured, 3, monitor_effects=E, augment=("delay",))
    x = np.r_[CASES["small"].x, 5e-4]
    assert q.evaluate(x) == pytest.approx(2 * base.evaluate(x), rel=1e-12)


def test_warm_start_is_kept_read_only():
    x = np.array([0.9, 0.3, 0.01, 1.1e5])
    p = make_problem("small", track="twin", seed=0, budget=1, start=x)
    np.testing.assert_array_equal(p.start, x)
    with pytest.raises(ValueError, match="read-only"):
        p.start[0] = 1.0
    assert make_problem("small", track="twin", seed=0, budget=1).start.tolist() == NOMINAL.tolist()


def test_limit_zero_stops_the_problem():
    p = make_problem("small", track="twin", seed=0, budget=5)
    p.evaluate(NOMINAL)
    p.limit(0)
    assert p.remaining == 0 and p.budget == 1
    with pytest.raises(BudgetExhausted):
        p.evaluate(NOMINAL)


def test_failed_simulations_log_at_most_three_warnings_per_batch(monkeypatch, caplog):
    real = objective_module.simulate_monitor

    def failing(X, *args, **kwargs):
        outputs, ok = real(X, *args, **kwargs)
        return outputs, np.zeros_like(ok)

    p = make_problem("small", track="twin", seed=0, budget=5)
    monkeypatch.setattr(objective_module, "simulate_monitor", failing)
    X = candidates(5)
    with caplog.at_level("WARNING", logger="ema_bench.problem"):
        p.evaluate(X)
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == 3 and p.failures == 5
    assert messages[0] == (f"simulation failed at {dict(zip(FAULT_NAMES, X[0].tolist()))}: scored "
                           f"penalty 1e+12")


class _StubObjective:
    """An objective that scores row i by its first column, instantly (for the log)."""

    def __init__(self, tests):
        self.tests = tests

    def evaluate(self, X):
        return X[:, 0].copy(), {}, np.zeros(len(X), dtype=bool)


def test_the_log_grows_past_its_first_chunk_and_keeps_every_evaluation():
    p = make_problem("small", track="twin", seed=0, budget=20_000)
    p.objective = p._log.objective = _StubObjective(p.objective.tests)  # the counted side
    rng = np.random.default_rng(0)
    X = LOWER + rng.random((15_000, 4)) * (UPPER - LOWER)
    p.evaluate(X[:9000])        # more than twice the first 4096 rows: grows to 9000
    p.evaluate(X[9000:12_000])  # doubles to 18000
    p.evaluate(X[12_000:])      # fits
    h = p.history()
    np.testing.assert_array_equal(h["x"], X)
    np.testing.assert_array_equal(h["fitness"], X[:, 0])
    assert h["wall_s"].dtype == float and np.all(np.diff(h["wall_s"]) >= 0.0)
    assert p.evaluations == 15_000


def test_wall_clock_and_first_success_by_hand():
    import time

    p = make_problem("small", track="twin", seed=0, budget=10)
    t_built = time.perf_counter()
    truth = CASES["small"].x
    time.sleep(0.05)
    p.evaluate(NOMINAL)              # 1: far from the truth
    time.sleep(0.05)
    p.evaluate(truth)                # 2: the truth itself, the best so far
    time.sleep(0.05)
    p.evaluate(candidates(1)[0])     # 3: worse
    t_done = time.perf_counter()
    wall = p.history()["wall_s"]
    assert 0.0 < wall[0] < wall[1] < wall[2] <= t_done - t_built + 0.5
    assert wall[1] - wall[0] >= 0.05 and wall[2] - wall[1] >= 0.05
    assert p.first_success() == 2
    assert p.parameter_hits((1.0, 0.01, 0.0)) == [1, 2, 2]  # every point is within 100 %
    assert p.first_success_wall_s() == wall[1]
    clock = p.first_success_clock()
    assert clock - wall[1] <= t_built and t_built - (clock - wall[1]) < 0.04
    # nothing succeeds yet: None, None, None
    q = make_problem("small", track="twin", seed=0, budget=10)
    q.evaluate(NOMINAL)
    assert q.first_success() is None and q.first_success_wall_s() is None
    assert q.first_success_clock() is None


def test_measured_problems_have_no_truth_to_score():
    measured = make_problem("small", track="twin", seed=0, budget=1).measured
    p = make_problem(measured=measured, budget=2)
    msg = "^the true faults of measured data are unknown"
    with pytest.raises(ProblemError, match=msg + ": no score$"):
        p.score(NOMINAL)
    with pytest.raises(ProblemError, match=msg + "$"):
        p.parameter_hits((0.01,))
    with pytest.raises(ProblemError, match=msg + "$"):
        p.fitness_at_truth()


def test_empty_batch_outputs_have_the_tests_shapes():
    p = make_problem("small", track="twin", seed=0, budget=2)
    f, outputs = p.evaluate_outputs(np.empty((0, 4)))
    assert f.shape == (0,) and p.evaluations == 0
    assert {t: v.shape for t, v in outputs.items()} == {"step": (0, 300, 4),
                                                        "sine": (0, 1000, 4)}


def test_a_replaced_objective_is_what_the_solver_view_evaluates():
    """A stand-in objective (the diagnosis carries acquisition faults this way) is what every
    counted evaluation computes, through the problem and its solver view alike; replacing it
    after the first evaluation would mix two objectives in one log and is refused."""
    from ema_bench.objective import Objective

    p = make_problem("small", track="twin", seed=0, budget=4)
    raw = Objective(p.measured, p.space, normalise=False)
    x = p.nominal.copy()
    expected = float(raw.evaluate(x[None, :])[0][0])
    assert expected != pytest.approx(float(p.objective.evaluate(x[None, :])[0][0]))
    p.objective = raw
    assert p.view().evaluate(x) == expected and p.evaluate(x) == expected
    with pytest.raises(ProblemError, match="before its first evaluation"):
        p.objective = raw


# ---- the problem's own checks, built directly (issue 48: the model shard's survivors) ------


def _measured() -> Traces:
    return make_problem("small", track="twin", seed=0, budget=1).measured


def test_a_problem_without_prior_has_bounds_only_and_takes_no_start():
    """``prior`` is on by default; without it the problem and its solver view hold no
    nominal and no start, the best before any evaluation is the box's centre, and a start is
    refused by its own line.  The view carries the problem's data and fitness kind."""
    m = _measured()
    p = Problem(m, 3, _meta={"instance": "small"})
    assert p.prior and np.array_equal(p.nominal, NOMINAL) and np.array_equal(p.start, NOMINAL)
    q = Problem(m, 3, prior=False, normalise=False)
    v = q.view()
    assert q.nominal is None and q.start is None and v.nominal is None and v.start is None
    np.testing.assert_array_equal(q.lower, LOWER)
    np.testing.assert_array_equal(q.upper, UPPER)
    for best in (q.best, v.best):
        np.testing.assert_array_equal(best[0], 0.5 * (LOWER + UPPER))
        assert best[1] == float("inf")
    assert v.measured is m and v.normalise is False and p.view().normalise is True
    assert q.units == p.units == FAULT_UNITS
    aug = Problem(m, 3, prior=False, augment=("aero_spring",))
    assert aug.augment == aug.view().augment == ("aero_spring",) and aug.nominal is None
    with pytest.raises(ProblemError, match=r"^a problem without prior takes no start$"):
        Problem(m, 3, prior=False, start=NOMINAL)
    blind = p.without_truth()
    assert blind.meta == {"instance": "small"} and blind.meta is not p.meta


def test_a_truth_of_every_searched_parameter_is_judged_on_their_ranges():
    """An augmented problem's truth may hold every searched parameter (suite ``emafdi-v2``):
    it is judged on the searched ranges, here an effect 2 % of its range (2400 N m/rad) off;
    any other number of values is refused by its own line."""
    m = _measured()
    faults = 0.5 * (LOWER + UPPER)
    truth = np.r_[faults, 800.0]
    p = Problem(m, 3, augment=("aero_spring",), _truth=truth)
    assert p.truth_size() == 5 and Problem(m, 3).truth_size() == 0
    assert Problem(m, 3, augment=("aero_spring",), _truth=faults).truth_size() == 4
    p.evaluate(np.r_[faults, 800.0 + 0.02 * 2400.0])
    assert p.parameter_hits((0.025, 0.01)) == [1, None]
    # the effect left out of the judged parameters, or judged on a range twice as wide
    assert p.parameter_hits((0.025, 0.01), judged=np.array([True] * 4 + [False])) == [1, 1]
    assert p.parameter_hits((0.015,), scales=np.r_[UPPER - LOWER, 4800.0]) == [1]
    with pytest.raises(ProblemError,
                       match=r"^the truth must have 4 or 5 values, got shape \(3,\)$"):
        Problem(m, 3, augment=("aero_spring",), _truth=np.ones(3))


def test_residuals_of_a_batch_are_the_rows_of_single_calls():
    """``residuals`` of a batch: one row per candidate, the same bits as one call each, one
    evaluation per row."""
    p = make_problem("small", track="twin", seed=0, budget=6)
    X = candidates(3, seed=1)
    R = p.residuals(X)
    assert R.shape == (3, p.n_residuals) and p.evaluations == 3
    for i in range(3):
        np.testing.assert_array_equal(R[i], p.residuals(X[i]))
    np.testing.assert_allclose(np.sum(R**2, axis=1), p.history()["fitness"][:3], rtol=1e-12)


def test_a_problem_on_fewer_signals_weighs_only_those():
    """``signals`` reaches the fitness: on ``theta_m`` alone it is that output's normalised
    mean squared error summed over the tests, computed here from the monitor's outputs."""
    m = _measured()
    p = Problem(m, 2, signals=("theta_m",))
    x = candidates(1, seed=2)
    outputs, ok = p.simulate(x)
    assert ok.all()
    k = 1   # theta_m, the second of SIGNALS
    scales = signal_scales(m)
    want = sum(np.mean((outputs[t][0, :, k] - m.data[t][:, k]) ** 2) / scales[t][k] ** 2
               for t in m.tests)
    assert p.evaluate(x[0]) == pytest.approx(want, rel=1e-12)
    for bad in (("theta_m", "torque"), (), ("theta_m", "theta_m")):
        with pytest.raises(ProblemError, match=re.escape(
                f"signals takes distinct outputs of {list(SIGNALS)}, got {list(bad)}")):
            Problem(m, 2, signals=bad)
