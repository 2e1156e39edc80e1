"""Per-sample weights of the fitness (the diagnosis's stick-state-aware weighting): the
objective's fitness, its residuals and the problem builder agree with a hand computation."""

from __future__ import annotations

import numpy as np
import pytest

from ema_bench import make_problem
from ema_bench.faults import CASES
from ema_bench.objective import Objective, ProblemError, signal_scales
from ema_bench.reference import simulate_reference


@pytest.fixture(scope="module")
def measured():
    return simulate_reference(CASES["small"].x, seed=3)


def test_sample_weights_weigh_each_squared_error(measured):
    rng = np.random.default_rng(0)
    sw = {t: rng.integers(0, 3, size=measured.data[t].shape).astype(float)
          for t in measured.tests}
    obj = Objective(measured, sample_weights=sw)
    x = np.array([[0.97, 0.2, 0.005, 1.05e5]])
    f, outputs, failed = obj.evaluate(x)
    # by hand: sum over tests, samples and signals of w * (model - data)^2 / scale^2 / n
    scales = signal_scales(measured)
    want = sum(np.sum(sw[t] * (outputs[t][0] - measured.data[t]) ** 2 / scales[t] ** 2)
               / measured.n_samples(t) for t in measured.tests)
    assert not failed[0] and f[0] == pytest.approx(want, rel=1e-12)
    # the residuals carry the same weights: their squares sum to the fitness
    r = obj.residuals(outputs, f)
    assert np.sum(r**2) == pytest.approx(f[0], rel=1e-12)
    # all-ones weights are the plain fitness
    ones = {t: np.ones_like(v) for t, v in sw.items()}
    assert Objective(measured, sample_weights=ones).evaluate(x)[0][0] == pytest.approx(
        Objective(measured).evaluate(x)[0][0], rel=1e-12)


def test_bad_sample_weights_are_refused(measured):
    t = measured.tests[0]
    good = {k: np.ones_like(v) for k, v in measured.data.items()}
    with pytest.raises(ProblemError, match="shape"):
        Objective(measured, sample_weights={**good, t: np.ones(3)})
    with pytest.raises(ProblemError, match=">= 0"):
        Objective(measured, sample_weights={**good, t: -good[t]})
    with pytest.raises(ProblemError, match="no entry"):
        Objective(measured, sample_weights={})
    # they weigh given traces; a built case has none to weigh
    with pytest.raises(ProblemError, match="measured"):
        make_problem("small", sample_weights=good)
    p = make_problem(measured=measured, sample_weights=good)
    assert p.objective.evaluate(p.nominal[None, :])[0][0] > 0.0
