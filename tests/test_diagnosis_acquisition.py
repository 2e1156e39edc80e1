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


def test_a_set_judged_again_is_refitted_from_its_new_start(with_effect):
    """A set fitted before and judged again is fitted again from the new start, and the
    better of its two fits is the one judged (and the verdict's): the trial judged with the
    worse fit is superseded.  The first start is the box's corner with no effect (a small
    budget stops short of the optimum), the second the truth."""
    from ema_bench.diagnosis.fitting import assess
    from ema_bench.diagnosis.workflow import _Search
    from ema_bench.objective import signal_weights

    s = Settings(budget=300, n_boot=5)
    sw = stick_weights(with_effect)
    weights = {t: w[None, :] * sw[t] for t, w in signal_weights(with_effect).items()}
    base = fit(with_effect, (), s, 0)
    first, _ = assess(with_effect, base, weights, s, 1)
    search = _Search(with_effect, weights, s, 5, base, first, lambda m: None,
                     fits={"base": base}, status={"base": first})
    corner = np.r_[0.8, 0.8445, 0.04, 5e4, 0.0]
    t1 = search.run((EFFECT,), corner, None, 0.0)
    t2 = search.run((EFFECT,), np.r_[X, VALUE], None, 0.0)
    assert search.n_trials == 2 and search.evaluations == 2 * s.budget
    assert t2.train_fitness[1] < t1.train_fitness[1]
    assert search.fits[EFFECT].fitness == t2.train_fitness[1]
    assert search.fits[EFFECT].effects[EFFECT] == pytest.approx(VALUE, rel=0.05)
    assert not t1.accepted and "refitted from a better start" in t1.reason
    # a fit put in place just before (``refit=False``) is judged, not fitted again
    search.run((EFFECT,), corner, None, 0.0, refit=False)
    assert search.n_trials == 2 and search.evaluations == 2 * s.budget


@pytest.mark.slow
def test_a_dead_channel_is_named_as_the_recordings():
    """``theta_m`` dead from the start (reading zero), no physical effect: the verdict is
    ``acquisition``, naming that channel stuck over all its samples, and the faults fitted
    through it are the truth's, not the box bounds the base fit ran to (about 40 CPU-s)."""
    tr = decoys.stuck(simulate_reference(X, {}, tests=TESTS, seed=8), "theta_m", 0.0, 0.0)
    d = diagnose(tr, Settings(budget=2500, n_boot=30), seed=2)
    assert d.verdict == "acquisition" and d.effects == []
    (a,) = d.acquisition
    assert a.name == "stuck(theta_m)" and not a.partial
    assert a.value == 1.0 and a.interval[0] > 0.9
    assert "theta_m stuck" in d.message and d.gap["closed"] > 0.9
    after = [d.faults[n]["after"] for n in ("Na", "Fst", "BLK", "Gprop")]
    np.testing.assert_allclose(after, X, rtol=0.02, atol=5e-4)


@pytest.mark.slow
def test_eccentricity_beside_a_slow_lowpass_is_named():
    """The third round's miss (blind suite of root seed 2034, case 6: eccentricity 0.076
    beside a 5.7 ms low-pass on ``omega_m``): the pair grown from the low-pass is refitted
    from there, not judged with the fit started at the eccentricity single's 0.19, and both
    are named, the interval holding the truth (about 40 CPU-s)."""
    from ema_bench.diagnosis.blind import draw_cases, run_case

    case = draw_cases(0, 2034, extra=10)[6]
    assert case.effects == {"eccentricity": pytest.approx(0.07553, rel=1e-3)}
    assert case.decoy_params["signal"] == "omega_m"
    r = run_case(case, 2034, Settings())
    assert r["effect_named"] and r["acquisition_named"] and not r["misnamed"]
    assert r["interval_covers"] == {"eccentricity": True}
