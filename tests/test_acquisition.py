"""Acquisition-chain faults as suspects: each kind fitted at a model's outputs recovers the
decoy that made the record (the decoys are an independent implementation), nothing scores on
noise alone, and a fitted fault reproduces the record the decoy made."""

from __future__ import annotations

import numpy as np
import pytest

from ema_bench.diagnosis import acquisition as acq
from ema_bench.diagnosis import channel_faults, decoys
from ema_bench.diagnosis.results import Settings
from ema_bench.objective import KNOWN_TESTS
from ema_bench.reference import simulate_reference
from ema_bench.suites.v1 import instance_faults

TESTS = ("step", "sine", "sine2")
TRAIN = ("step", "sine")
MIN_SCORE = Settings().min_score


@pytest.fixture(scope="module")
def records():
    """The clean outputs of the reference model (standing for a perfect physical fit) and a
    noisy record of them."""
    x = np.array(instance_faults("small"))
    specs = tuple(KNOWN_TESTS[t] for t in TESTS)
    clean = simulate_reference(x, {}, tests=specs, noise=False, adc=False)
    noisy = simulate_reference(x, {}, tests=specs, seed=3)
    return dict(clean.data), noisy


def _ones(tr):
    return {t: np.ones_like(tr.data[t]) for t in tr.tests}


# each kind with its decoy's parameters and what the fit must find
CASES = [
    ("lowpass", {"signal": "omega_m", "tau": 4e-3}, "lowpass(omega_m)", 4e-3, 0.05),
    ("time_shift", {"signal": "i_eq", "samples": 4}, "time_shift(i_eq)", 4.0, 0.0),
    ("drift", {"signal": "theta_u", "rate": -0.015}, "drift(theta_u)", -0.015, 0.03),
    ("mains_hum", {"signal": "i_eq", "amplitude": 0.3, "freq": 400.0, "phase": 1.0},
     "mains_hum(i_eq)", 0.3, 0.03),
]


@pytest.mark.parametrize("decoy, params, name, value, rel", CASES)
def test_each_kind_is_screened_first_and_recovers_its_decoy(records, decoy, params, name,
                                                           value, rel):
    clean, noisy = records
    tr = decoys.apply(decoy, noisy, params)
    best = acq.screen(clean, tr.data, _ones(tr), TRAIN)[0]
    assert best.fault.name == name and best.score > 10 * MIN_SCORE
    assert best.fault.value == pytest.approx(value, rel=rel, abs=1e-12)
    lo, hi = best.interval
    # the interval excludes zero and holds the truth (within the fit's own tolerance)
    assert not lo <= 0.0 <= hi
    assert lo - rel * abs(value) - 1e-12 <= value <= hi + rel * abs(value) + 1e-12
    if decoy == "mains_hum":
        assert best.fault.detail["freq"] == pytest.approx(400.0, abs=channel_faults.HUM_STEP)


def test_outliers_are_found_where_the_decoy_put_them(records):
    clean, noisy = records
    params = {"signal": "theta_m", "size": 30 * float(channel_faults.NOISE_STD[1]), "seed": 11}
    tr = decoys.apply("outliers", noisy, params)
    best = acq.screen(clean, tr.data, _ones(tr), TRAIN)[0]
    assert best.fault.name == "outliers(theta_m)"
    # the decoy hits round(0.5 %) of each test's samples: 2 of the step's 300, 5 of each
    # sine's 1000; the count is of the training tests
    assert best.fault.value == 2 + 5
    spikes = best.fault.detail["spikes"]
    moved = {t: np.flatnonzero(tr.data[t][:, 1] != noisy.data[t][:, 1]) for t in TESTS}
    assert {t: sorted(v) for t, v in spikes.items()} == {t: list(moved[t]) for t in TESTS}
    w = acq.weights([best.fault], {t: tr.data[t].shape for t in TESTS})
    assert all((w[t][moved[t], 1] == 0).all() and w[t].sum() == w[t].size - moved[t].size
               for t in TESTS)


@pytest.mark.parametrize("params, share", [
    ({"signal": "theta_m", "start": 0.0, "value": 0.0}, 1.0),     # dead: reads zero
    ({"signal": "i_eq", "start": 0.12}, 1.0 - 2 * 120 / 1300),     # frozen from 0.12 s
])
def test_a_stuck_channel_is_found_from_where_it_froze(records, params, share):
    """A flat channel (dead, or frozen at its value at 0.12 s) is screened first as
    ``stuck`` on that channel: the frozen span of every test, held-out included, gets
    weight 0 and the model holds the record's level there; the share of frozen training
    samples (the step's 180 of 300 and the sine's 880 of 1000) lies in its interval."""
    clean, noisy = records
    tr = decoys.apply("stuck", noisy, params)
    col = acq.SIGNALS.index(params["signal"])
    best = acq.screen(clean, tr.data, _ones(tr), TRAIN)[0]
    assert best.fault.name == f"stuck({params['signal']})" and best.score > 10 * MIN_SCORE
    assert best.fault.value == pytest.approx(share, abs=2e-3)
    lo, hi = best.interval
    assert 0.0 < lo <= share <= hi <= 1.0
    # where the decoy froze the record (its first flat sample in each test)
    frozen = {t: int(np.searchsorted(noisy.time(t), params["start"])) for t in TESTS}
    w = acq.weights([best.fault], {t: tr.data[t].shape for t in TESTS})
    out = acq.carry(clean, [best.fault])
    for t in TESTS:
        k = best.fault.detail["onset"][t]
        assert abs(k - frozen[t]) <= 2
        assert (w[t][k:, col] == 0).all() and w[t].sum() == w[t].size - (w[t].shape[0] - k)
        np.testing.assert_allclose(out[t][k:, col], np.mean(tr.data[t][k:, col]))
        assert np.array_equal(out[t][:k], clean[t][:k])


def test_a_settled_record_is_not_a_stuck_channel(records):
    """A flat stretch where the model is flat too (the step settled) is no frozen span:
    the noisy record itself scores nothing as ``stuck`` on any channel."""
    clean, noisy = records
    for e in acq.screen(clean, noisy.data, _ones(noisy), TRAIN):
        if e.fault.kind == "stuck":
            assert e.score == 0.0 and e.fault.value == 0.0 and e.fault.detail["onset"] == {}


def test_nothing_scores_on_noise_alone(records):
    """The screen must not buy a fault with noise: every kind on every channel of a clean
    record stays below the score a joint fit needs (the periodogram's best of ~1800 tones
    included)."""
    clean, noisy = records
    ranked = acq.screen(clean, noisy.data, _ones(noisy), TRAIN)
    # the one-channel kinds on every channel, no whole-chain group (none scores alone), and
    # heavy-tailed noise is a test of its own (tests/test_chain_acquisition.py)
    assert len(ranked) == (len(acq.KINDS) - 1) * 4 == 24
    assert ranked[0].score < MIN_SCORE


@pytest.mark.parametrize("decoy, params", [
    ("lowpass", {"signal": "i_eq", "tau": 3e-3}),
    ("time_shift", {"signal": "theta_u", "samples": 5}),
    ("drift", {"signal": "omega_m", "rate": 40.0}),
])
def test_a_carried_fault_reproduces_the_decoys_record(records, decoy, params):
    """``carry`` of the fitted fault on the model's outputs is the decoy applied to them
    (before the ADC): one fault, two implementations, the same record."""
    clean, noisy = records
    tr = decoys.apply(decoy, noisy, params)
    f = acq.screen(clean, tr.data, _ones(tr), TRAIN)[0].fault
    from ema_bench.traces import Traces

    want = decoys.ACQUISITION_DECOYS[decoy](Traces(clean, dt=noisy.dt), **params)
    got = acq.carry(clean, [f])
    col = acq.SIGNALS.index(params["signal"])
    for t in TESTS:
        lsb = 0.03 * float(np.ptp(clean[t][:, col])) + 1e-9   # requantised, fitted tau
        assert np.abs(got[t][:, col] - want.data[t][:, col]).max() < lsb
        others = [k for k in range(4) if k != col]
        assert np.array_equal(got[t][:, others], clean[t][:, others])


def test_names_and_bad_names():
    assert acq.parse("mains_hum(i_eq)") == ("mains_hum", "i_eq")
    assert acq.is_acquisition("drift(theta_u)") and not acq.is_acquisition("delay")
    with pytest.raises(ValueError, match="kind\\(channel\\)"):
        acq.parse("hum(i_eq)")
    with pytest.raises(ValueError, match="kind\\(channel\\)"):
        acq.parse("drift(current)")
    # trivial bands in the channel's unit: the noise sd scales the per-sd kinds
    assert acq.trivial("drift(i_eq)") == pytest.approx(float(channel_faults.NOISE_STD[3]))
    assert acq.trivial("time_shift(i_eq)") == 0.5
    assert len(acq.all_names()) == 24
