"""Degradation laws: monotone paths, thresholds crossed at the recorded end of life, fleet
variability, gain-drift units that never fail, the confounders' formulas."""

import math

import numpy as np
import pytest

from ema_bench.effects import EFFECT_INDEX
from ema_bench.faults import F_BLK, F_FST, F_GPROP, F_NA, FAULT_INDEX, LOWER, NOMINAL, UPPER
from ema_bench.prognostics.laws import (
    COPPER_ALPHA,
    DAMAGE_SIGN,
    THRESHOLDS,
    FleetLaws,
    backlash_path,
    coil_path,
    cold_viscous_friction,
    confounders,
    crossed,
    end_of_life,
    friction_path,
    gain_path,
    resistance_rise,
    unit_history,
)

LAWS = FleetLaws()


def rng(k: int = 0) -> np.random.Generator:
    return np.random.default_rng(k)


def duty(n: int = 500, k: int = 1) -> np.ndarray:
    return rng(k).gamma(4.0, 0.25, size=n)


@pytest.fixture(scope="module")
def fleet():
    """400 units of fleet-v1's laws (about 0.6 s)."""
    return [unit_history(np.random.SeedSequence(7, spawn_key=(u,)), LAWS) for u in range(400)]


def test_friction_is_a_monotone_gamma_process_with_its_mean_rate():
    d = duty(4000)
    path = friction_path(rng(), d, 0.2, 1e-3, 0.5)
    assert path.shape == (4001,) and path[0] == 0.2
    assert np.all(np.diff(path) >= 0.0)
    # mean growth rate * duty; over 4000 flights the gamma noise is ~2 % (CV 1/sqrt(0.5*4000))
    assert (path[-1] - 0.2) / (1e-3 * d.sum()) == pytest.approx(1.0, rel=0.1)


def test_backlash_wears_with_duty_and_jumps_rarely():
    d = duty(3000)
    no_jumps = backlash_path(rng(), d, 0.001, 5e-5, 0.0, 0.0025)
    assert np.allclose(no_jumps, 0.001 + np.concatenate([[0.0], np.cumsum(5e-5 * d)]))
    path = backlash_path(rng(), d, 0.001, 5e-5, 0.01, 0.0025)
    steps = np.diff(path)
    assert np.all(steps >= 0.0)
    jumps = steps > 5e-5 * d + 1e-12
    # about jump_rate * total duty jumps, of mean size jump_mean
    assert 10 <= jumps.sum() <= 60
    assert (steps - 5e-5 * d)[jumps].mean() == pytest.approx(0.0025, rel=0.5)


def test_coil_is_healthy_until_onset_then_loses_turns_faster_and_faster():
    d = np.ones(400)
    na = coil_path(rng(), d, 100, 0.01, 0.02, 1e9)  # huge shape: no growth noise
    assert np.all(na[:100] == 1.0)
    assert na[100] == pytest.approx(0.99)
    assert np.all(np.diff(na) <= 0.0)
    loss = np.diff(na[100:250])
    assert np.all(np.diff(loss) < 0.0)  # accelerating: each flight loses more than the last
    assert 1.0 - na[300] == pytest.approx(0.01 * math.exp(0.02 * 200), rel=1e-4)
    assert np.all(coil_path(rng(), d, 500, 0.01, 0.02, 4.0) == 1.0)  # onset after the end


def test_gain_walk_stays_inside_the_fault_box():
    lo, hi = LOWER[F_GPROP], UPPER[F_GPROP]
    g = gain_path(rng(), 20000, 1.4e5, 5e3, lo, hi)  # large steps: it hits both walls
    assert g[0] == 1.4e5 and np.all((g >= lo) & (g <= hi))
    assert g.max() > 1.45e5 and g.min() < 5.5e4
    assert np.abs(np.diff(g)).max() <= 6 * 5e3  # a reflection never jumps across the box


def test_thresholds_lie_strictly_inside_the_box_on_the_damage_side():
    assert set(THRESHOLDS) == {"Na", "Fst", "BLK"}
    for name, thr in THRESHOLDS.items():
        j = FAULT_INDEX[name]
        assert LOWER[j] < thr < UPPER[j]
        assert DAMAGE_SIGN[name] * (thr - NOMINAL[j]) > 0
        assert not crossed(name, NOMINAL[j])
        bound = UPPER[j] if DAMAGE_SIGN[name] > 0 else LOWER[j]
        assert crossed(name, bound) and crossed(name, thr)


def test_end_of_life_is_the_first_crossing_and_names_the_fault():
    faults = np.tile(NOMINAL, (6, 1))
    assert end_of_life(faults) == (None, None)
    faults[4:, F_BLK] = 0.031
    faults[3:, F_NA] = 0.85  # at the threshold counts as crossed
    assert end_of_life(faults) == (3, "Na")
    faults[3, F_FST] = 0.8  # same flight, further past its threshold (share of the range)
    assert end_of_life(faults) == (3, "Fst")


def test_unit_paths_are_monotone_and_cross_at_the_recorded_eol(fleet):
    for h in fleet:
        f = h.faults
        assert np.all(np.diff(f[:, F_FST]) >= 0.0)
        assert np.all(np.diff(f[:, F_BLK]) >= 0.0)
        assert np.all(np.diff(f[:, F_NA]) <= 0.0)
        assert np.all((f[:, F_GPROP] >= LOWER[F_GPROP]) & (f[:, F_GPROP] <= UPPER[F_GPROP]))
        assert h.eol is not None and h.horizon == h.eol
        assert crossed(h.failing_fault, f[h.eol, FAULT_INDEX[h.failing_fault]])
        for name in THRESHOLDS:  # no fault crossed before
            assert not np.any(crossed(name, f[:h.eol, FAULT_INDEX[name]]))
        assert np.all((f[:h.eol] >= LOWER) & (f[:h.eol] <= UPPER))  # inside the box before EOL


def test_fleet_life_and_failing_faults_vary(fleet):
    eol = np.array([h.eol for h in fleet])
    q10, q50, q90 = np.percentile(eol, [10, 50, 90])
    assert 120 <= q10 and q90 <= 650 and 250 <= q50 <= 350
    shares = {n: np.mean([h.failing_fault == n for h in fleet]) for n in THRESHOLDS}
    assert all(s >= 0.2 for s in shares.values()), shares
    # unit-level parameters differ across the fleet
    rates = np.array([h.params.fst_rate for h in fleet])
    assert rates.std() / rates.mean() > 0.3


def test_gain_drift_units_never_fail_and_keep_their_other_faults():
    seed = np.random.SeedSequence(3, spawn_key=(1,))
    worn = unit_history(seed, LAWS)
    drift = unit_history(seed, LAWS, wear=False)
    assert drift.eol is None and drift.failing_fault is None and drift.kind == ["Gprop"]
    assert drift.horizon == worn.eol  # as long as its wear would have lasted
    for j in (F_NA, F_FST, F_BLK):
        assert np.all(drift.faults[:, j] == worn.faults[0, j])
    assert np.array_equal(drift.faults[:, F_GPROP], worn.faults[:, F_GPROP])
    assert np.ptp(drift.faults[:, F_GPROP]) > 1e3


def test_same_seed_same_history():
    a = unit_history(np.random.SeedSequence(5), LAWS)
    b = unit_history(np.random.SeedSequence(5), LAWS)
    c = unit_history(np.random.SeedSequence(6), LAWS)
    assert np.array_equal(a.faults, b.faults) and np.array_equal(a.winding, b.winding)
    assert not np.array_equal(a.faults, c.faults)


def test_confounders_follow_copper_and_grease_laws():
    assert COPPER_ALPHA == 0.00393
    assert resistance_rise(20.0) == 0.0
    assert resistance_rise(70.0) == pytest.approx(0.00393 * 50)
    assert resistance_rise(-10.0) == 0.0 and resistance_rise(500.0) == 0.6  # effect bounds
    assert cold_viscous_friction(25.0, 2e-5) == 0.0
    assert cold_viscous_friction(0.0, 2e-5) == pytest.approx(2e-5)  # viscosity doubled
    assert cold_viscous_friction(-20.0, 2e-5) == pytest.approx(2e-5 * 3)
    e = confounders(-20.0, 60.0, 2e-5)
    assert e[EFFECT_INDEX["viscous_friction"]] == pytest.approx(6e-5)
    assert e[EFFECT_INDEX["resistance_rise"]] == pytest.approx(0.00393 * 40)
    assert np.count_nonzero(e) == 2


def test_inspection_conditions_stay_in_plausible_ranges(fleet):
    amb = np.concatenate([h.ambient[:h.eol] for h in fleet[:50]])
    assert -45 < amb.min() and amb.max() < 60
    e = np.array([fleet[0].effects(f) for f in range(0, fleet[0].eol, 10)])
    assert np.all(e[:, EFFECT_INDEX["viscous_friction"]] <= 2e-4)


# --- the laws run forward (ForwardPaths): the law-aware tracker's and the oracle's model -------

def _paths(n=20000, present=False, **over):
    from ema_bench.prognostics.laws import FleetLaws, ForwardPaths

    laws = {**FleetLaws().to_dict(), **over}
    x0 = np.tile([1.0 - (0.02 if present else 0.0), 0.2, 0.001, 1e5], (n, 1))
    rates = {"Fst": np.full(n, 1e-3), "BLK": np.full(n, 5e-5), "Na": np.full(n, 0.02)}
    return ForwardPaths(np.random.default_rng(0), x0, rates, laws, 1.2,
                        np.full(n, present)), laws


def test_forward_paths_follow_the_laws_means():
    p, laws = _paths(present=True)
    x = p.advance(10.0).copy()
    duty = 1.2 * 10.0
    # friction: gamma increments of mean r * duty; backlash: wear plus jumps of mean
    # jump_rate * duty * jump_mean
    assert np.mean(x[:, 1] - 0.2) == pytest.approx(1e-3 * duty, rel=0.02)
    assert np.mean(x[:, 2] - 0.001) == pytest.approx(
        5e-5 * duty + laws["blk_jump_rate"] * duty * laws["blk_jump_mean"], rel=0.05)
    # coil: the shorted share's log grows by g * duty on average
    assert np.mean(np.log(1.0 - x[:, 0]) - np.log(0.02)) == pytest.approx(0.02 * duty, rel=0.02)
    assert (np.diff(np.c_[np.full(len(x), 0.2), x[:, 1]], axis=1) >= 0).all()


def test_forward_paths_onset_is_memoryless_at_the_laws_hazard():
    p, laws = _paths()
    x = p.advance(50.0)
    share = np.mean(x[:, 0] < 1.0)
    assert share == pytest.approx(-np.expm1(-50.0 / laws["na_onset_mean"]), abs=0.01)


def test_first_failure_of_a_nearly_deterministic_path():
    # huge gamma shapes: the increments are their means; friction reaches its threshold at
    # (0.6756 - 0.2) / (1e-3 * 1.2) = 396.3 flights, first seen at the 2-flight step 398
    p, _ = _paths(n=50, fst_shape=1e9, duty_shape=1e9, blk_jump_rate=0.0,
                  na_onset_mean=1e12)
    t = p.first_failure(step=2.0)
    assert np.all(t == 398.0)
