"""The workflow with acquisition-chain faults as suspects: the fitted model carries each kind
beside a physical effect, and a fault of the recording alone is named as the measurement's,
not the actuator's (constructed cases at each new rule's edge; small budgets)."""

from __future__ import annotations

import numpy as np
import pytest

from ema_bench.diagnosis import acquisition as acq
from ema_bench.diagnosis import decoys
from ema_bench.diagnosis.blind import TESTS
from ema_bench.diagnosis.fitting import fit, simulate, subset_traces
from ema_bench.diagnosis.results import TRAIN, Settings
from ema_bench.diagnosis.stiction import stick_weights
from ema_bench.diagnosis.workflow import diagnose
from ema_bench.faults import CASES
from ema_bench.objective import Objective, SearchSpace
from ema_bench.reference import simulate_reference

X = CASES["small"].x
NAMES = tuple(t.name for t in TESTS)
EFFECT, VALUE = "aero_spring", 150.0


@pytest.fixture(scope="module")
def with_effect():
    """The reference model with a stiffer hinge (3x its threshold), a noisy record."""
    return simulate_reference(X, {EFFECT: VALUE}, tests=TESTS, seed=21)


# each kind, its decoy and what the carried fit must find (value, tolerance)
KINDS = [
    ("mains_hum", {"signal": "i_eq", "amplitude": 0.3, "freq": 400.0, "phase": 2.0}, 0.3, 0.05),
    ("drift", {"signal": "omega_m", "rate": -50.0}, -50.0, 0.05),
    ("lowpass", {"signal": "i_eq", "tau": 3e-3}, 3e-3, 0.1),
    ("time_shift", {"signal": "theta_u", "samples": 3}, 3.0, 0.0),
    ("outliers", {"signal": "theta_m", "size": 12.0, "seed": 4}, 7.0, 0.0),
]


@pytest.mark.parametrize("kind, params, value, rel", KINDS)
def test_the_fitted_model_carries_each_kind_beside_an_effect(with_effect, kind, params, value,
                                                             rel):
    """Started where the workflow starts a pair (the fault screened at a fit without the
    effect, the effect at zero), the joint fit recovers both: the physics through the fault,
    then the fault again at the new outputs."""
    measured = decoys.apply(kind, with_effect, params)
    name = f"{kind}({params['signal']})"
    start = np.r_[X, 0.0]
    raw = {t: v[0] for t, v in simulate(start, (EFFECT,), NAMES).items()}
    guess = acq.estimate(name, raw, measured.data, stick_weights(measured), TRAIN).fault
    f = fit(measured, (EFFECT,), Settings(budget=800), 3, start, (guess,))
    (got,) = f.acquisition
    assert got.name == name and got.value == pytest.approx(value, rel=rel)
    assert f.effects[EFFECT] == pytest.approx(VALUE, rel=0.1)
    lo, hi = f.acq_intervals[name]
    assert lo > 0 or hi < 0
    # the record the model predicts is the monitor's outputs through the fault
    out = acq.carry(f.raw, f.acquisition)
    assert all(np.array_equal(out[t], f.outputs[t]) for t in NAMES)
    # and it fits the data better than the same physics without the fault
    train = subset_traces(measured, TRAIN)
    bare = Objective(train, SearchSpace.of((EFFECT,)), sample_weights=stick_weights(train))
    assert f.fitness < 0.5 * float(bare.evaluate(f.x[None, :])[0][0])


def test_a_fault_of_the_recording_alone_is_named_as_the_measurements():
    """No physical effect, a drift of the surface-position channel: the verdict is
    ``acquisition``, naming that drift with an interval around the truth, and nothing about
    the actuator."""
    rate = 0.015                 # rad/s: 15 noise sd per second
    tr = decoys.drift(simulate_reference(X, {}, tests=TESTS, seed=8), "theta_u", rate)
    d = diagnose(tr, Settings(budget=2500, n_boot=30), seed=2)
    assert d.verdict == "acquisition" and d.effects == []
    (a,) = d.acquisition
    assert a.name == "drift(theta_u)" and not a.partial
    assert a.value == pytest.approx(rate, rel=0.05)
    assert a.interval[0] <= rate <= a.interval[1] and a.interval[0] > 0
    assert "the measurement: a drift" in d.message and d.gap["closed"] > 0.9
    assert d.as_dict()["acquisition"][0]["name"] == "drift(theta_u)"
