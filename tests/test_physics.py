"""Each physics block alone, against hand-computed expectations (DESIGN sections 1 and 8).

The blocks are the compiled (numba) functions the integrators call; every expectation below is
worked out from the parameter table (V_dc = 270 V, R = 0.5 ohm, L = 0.5 mH, Ke = 0.05 V s/rad,
2 pole pairs, J_m = 5e-5 kg m^2, ...), not read back from the code.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from ema_bench.effects import effects_vector
from ema_bench.params import (
    DEFAULT_PARAMS,
    P_JM,
    P_JU,
    P_KS,
    P_KSTOP,
    P_TAU,
    P_THSTOP,
    EMAParams,
)
from ema_bench.physics.ace import ace_update
from ema_bench.physics.bldc import (
    PHASE_SHIFT,
    bldc_step,
    commutation,
    emf_constants,
    pair_constants,
    sector,
    trapezoid,
)
from ema_bench.physics.command import (
    KINDS,
    command_samples,
    command_value,
    make_command,
)
from ema_bench.physics.load import hinge_moment
from ema_bench.physics.mechanics import friction_speed, gear_torque, mech_step
from ema_bench.physics.sensors import SENSORS, measure, quantise

P = DEFAULT_PARAMS.to_array()
PAR = DEFAULT_PARAMS
DEG = math.pi / 180.0
V_DC, R, L, KE, PP = PAR.V_dc, PAR.R, PAR.L, PAR.Ke, PAR.pole_pairs
BAND = PAR.hyst_band
DT = 1e-6

# six-step order from 30 electrical degrees: (phase driven +, phase driven -), phases a=0 b=1 c=2
SIX_STEP = ((0, 1), (0, 2), (1, 2), (1, 0), (2, 0), (2, 1))


def run_locked(i_ref: float, th_m: float, n: int, na: float = 1.0):
    """Phase currents (n, 3) and torques (n,) with the rotor held at ``th_m``."""
    ia = ib = ic = 0.0
    sa = sb = sc = 0
    cur = np.empty((n, 3))
    torque = np.empty(n)
    for k in range(n):
        ia, ib, ic, sa, sb, sc, t = bldc_step(ia, ib, ic, sa, sb, sc, i_ref, th_m, 0.0, na, 0.0,
                                              1.0, V_DC, P, DT)
        cur[k] = ia, ib, ic
        torque[k] = t
    return cur, torque


# --------------------------------------------------------------------------------------------
# BLDC motor and its drive
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("s", range(6))
def test_locked_rotor_current_rises_to_bus_over_pair_resistance(s):
    # rotor held in the middle of sector s, current demand far above what the bus can push:
    # the conducting pair sees V_dc across 2R in series with 2L
    th_m = (60.0 + 60.0 * s) * DEG / PP
    cur, torque = run_locked(1e3, th_m, 12_000)
    pos, neg = SIX_STEP[s]
    idle = 3 - pos - neg
    i_pair = cur[:, pos]
    i_inf = V_DC / (2.0 * R)   # 270 A
    assert i_inf == pytest.approx(270.0)
    # rises monotonically, never beyond V_dc / 2R
    assert np.all(np.diff(i_pair) > 0.0)
    assert i_pair.max() <= i_inf * (1.0 + 1e-12)
    # L/R = 1 ms: 1 - 1/e of the way after 1 ms, and there after 12 time constants
    assert i_pair[999] == pytest.approx(i_inf * (1.0 - math.exp(-1.0)), rel=2e-3)
    assert i_pair[-1] == pytest.approx(i_inf, rel=1e-4)
    # the pair carries the same current the other way; the idle leg carries nothing
    np.testing.assert_allclose(cur[:, neg], -i_pair, rtol=1e-12)
    assert np.all(cur[:, idle] == 0.0)
    # torque = 2 Ke I, positive (the commutation drives the rotor forwards)
    np.testing.assert_allclose(torque, 2.0 * KE * i_pair, rtol=1e-12)


def test_locked_rotor_time_constant_with_shorted_turns():
    # Na = 0.8 in a sector where phase a conducts: R_pair = 1.8 R, L_pair = 1.64 L
    na = 0.8
    cur, _ = run_locked(1e3, 60.0 * DEG / PP, 25_000, na=na)
    i_inf = V_DC / ((1.0 + na) * R)       # 300 A
    tau_el = (1.0 + na * na) * L / ((1.0 + na) * R)
    k = int(round(tau_el / DT)) - 1
    assert cur[k, 0] == pytest.approx(i_inf * (1.0 - math.exp(-1.0)), rel=3e-3)
    assert cur[-1, 0] == pytest.approx(i_inf, rel=1e-4)
    assert cur[:, 0].max() <= i_inf * (1.0 + 1e-12)


def test_locked_rotor_hysteresis_regulates_inside_band():
    i_ref = 20.0
    cur, _ = run_locked(i_ref, 60.0 * DEG / PP, 3000)
    ia = cur[:, 0]
    first = int(np.argmax(ia >= i_ref))
    # the initial rise from 0 takes 2L i_ref / V_dc = 74 us (a little more with the R drop)
    assert 70 <= first <= 80
    after = ia[first:]
    # one step of rise (V_dc - 2 R i) dt / 2L, or of fall (V_dc + 2 R i) dt / 2L, past the band
    rise = V_DC * DT / (2.0 * L)                                   # 0.27 A
    fall = (V_DC + 2.0 * R * (i_ref + BAND / 2)) * DT / (2.0 * L)  # 0.29 A
    assert after.max() <= i_ref + BAND / 2 + rise
    assert after.min() >= i_ref - BAND / 2 - fall
    # it really switches (both comparator thresholds are crossed many times)
    assert (after > i_ref + BAND / 2).sum() > 10
    assert (after < i_ref - BAND / 2).sum() > 10
    assert after.mean() == pytest.approx(i_ref, abs=0.1)
    np.testing.assert_allclose(cur[:, 1], -ia, rtol=1e-12)


def test_no_load_speed_approaches_bus_over_pair_back_emf():
    # motor alone: w' = T / J_m, no friction, no load, current demand far above the bus limit
    ia = ib = ic = 0.0
    sa = sb = sc = 0
    th, w = 0.1, 0.0
    n = 40_000
    speeds = np.empty(n)
    for k in range(n):
        ia, ib, ic, sa, sb, sc, t = bldc_step(ia, ib, ic, sa, sb, sc, 1e3, th, w, 1.0, 0.0, 1.0,
                                              V_DC, P, DT)
        w += DT * t / P[P_JM]
        th += DT * w
        speeds[k] = w
    w0 = V_DC / (2.0 * KE)   # 2700 rad/s: the pair back-EMF equals the bus
    assert w0 == pytest.approx(2700.0)
    assert 0.8 * w0 < speeds[-1] < w0
    assert speeds.max() < w0
    # torque always drives forwards: the speed never falls back by more than a rounding step
    assert np.all(np.diff(speeds) > -1e-9)
    # the initial acceleration is the locked-rotor one, i.e. slower than 2 Ke V_dc/(2R) / J_m
    assert speeds[99] < 100 * DT * 2.0 * KE * (V_DC / (2.0 * R)) / P[P_JM]


def test_trapezoid_shape():
    x = np.linspace(0.0, 360.0, 36_001)[:-1]   # 0.01 degree grid
    y = np.array([trapezoid(v * DEG) for v in x])
    top = (x > 30.0) & (x < 150.0)
    bottom = (x > 210.0) & (x < 330.0)
    edges = np.isin(x, [30.0, 150.0, 210.0, 330.0])
    assert np.all(y[top] == 1.0)
    assert np.all(y[bottom] == -1.0)
    np.testing.assert_allclose(np.abs(y[edges]), 1.0, atol=1e-12)
    assert np.all(np.abs(y[~top & ~bottom & ~edges]) < 1.0)
    # flat tops are 120 degrees wide
    on_top = x[y > 1.0 - 1e-9]
    on_bottom = x[y < -1.0 + 1e-9]
    assert on_top.max() - on_top.min() == pytest.approx(120.0, abs=0.011)
    assert on_bottom.max() - on_bottom.min() == pytest.approx(120.0, abs=0.011)
    # linear ramps between, through zero at 0 and 180 degrees
    for deg, value in [(0.0, 0.0), (15.0, 0.5), (165.0, 0.5), (180.0, 0.0), (195.0, -0.5),
                       (345.0, -0.5), (360.0, 0.0), (-15.0, -0.5), (375.0, 0.5)]:
        assert trapezoid(deg * DEG) == pytest.approx(value, abs=1e-12)
    for lo, hi in [(0.0, 30.0), (150.0, 210.0), (330.0, 360.0)]:
        seg = y[(x > lo + 0.005) & (x < hi - 0.005)]
        np.testing.assert_allclose(np.diff(seg, 2), 0.0, atol=1e-9)
    # odd half-wave symmetry: F(x + 180) = -F(x)
    np.testing.assert_allclose([trapezoid((v + 180.0) * DEG) for v in x[::97]],
                               -y[::97], atol=1e-12)


def test_commutation_six_step_sequence():
    seen = []
    for s in range(6):
        for frac in (0.02, 0.5, 0.98):
            th_e = (30.0 + 60.0 * (s + frac)) * DEG
            c = commutation(th_e)
            assert sorted(c) == [-1, 0, 1]
            pos, neg = c.index(1), c.index(-1)
            # the positive phase sits on its positive flat top, the negative one on its negative
            assert trapezoid(th_e - PHASE_SHIFT[pos]) == 1.0
            assert trapezoid(th_e - PHASE_SHIFT[neg]) == -1.0
            assert sector(th_e) == s
            if frac == 0.5:
                seen.append((pos, neg))
    assert seen == list(SIX_STEP)   # a+b-, a+c-, b+c-, a-b+, a-c+, b-c+
    # periodic over an electrical turn, negative angles included (the sine test runs the
    # motor backwards)
    for deg in np.arange(35.0, 390.0, 10.0):
        for turns in (-3, -1, 1, 2):
            assert commutation((deg + 360.0 * turns) * DEG) == commutation(deg * DEG)


@pytest.mark.parametrize("s", range(6))
def test_torque_is_two_ke_i_in_every_sector(s):
    current = 7.0
    th_m = (60.0 + 60.0 * s) * DEG / PP
    ke = emf_constants(th_m, 1.0, 0.0, P)
    c = commutation(PP * th_m)
    torque = sum(k * ci * current for k, ci in zip(ke, c))
    assert torque == pytest.approx(2.0 * KE * current, rel=1e-12)


@pytest.mark.parametrize("na", [0.8, 1.0])
def test_pair_constants_average_to_design_values(na):
    # uniform grid of one mechanical turn whose cells never straddle a sector boundary
    n = 1200
    th = (np.arange(n) + 0.5) * 2.0 * math.pi / n
    kt, r, el = np.array([pair_constants(t, na, 0.0, P) for t in th]).T
    assert kt.mean() == pytest.approx(2.0 * KE * (na + 2.0) / 3.0, rel=1e-12)
    assert r.mean() == pytest.approx(2.0 * R * (na + 2.0) / 3.0, rel=1e-12)
    assert el.mean() == pytest.approx(2.0 * L * (na * na + 2.0) / 3.0, rel=1e-12)


@pytest.mark.parametrize("na,zeta", [(1.0, 0.0), (0.8, 0.0), (0.9, 0.1)])
def test_pair_constant_matches_three_phase_torque(na, zeta):
    # inside each sector the conducting phases are on their flat tops, so the pair's torque
    # constant must equal sum(c_x ke_x) of the three-phase model at the same angle
    for s in range(12):   # two electrical turns = one mechanical turn
        for frac in (0.1, 0.5, 0.9):
            th_m = (30.0 + 60.0 * (s + frac)) * DEG / PP
            ke = emf_constants(th_m, na, zeta, P)
            c = commutation(PP * th_m)
            kt, _, _ = pair_constants(th_m, na, zeta, P)
            assert kt == pytest.approx(sum(k * ci for k, ci in zip(ke, c)), rel=1e-12)


def test_shorted_turns_scale_phase_a_back_emf():
    th_m = 60.0 * DEG / PP   # phase a on its flat top
    ka, kb, kc = emf_constants(th_m, 0.8, 0.0, P)
    assert ka == pytest.approx(0.8 * KE)
    assert kb == pytest.approx(-KE)
    # eccentricity modulates each phase by 1 + zeta cos(th_m - phi_x)
    ka_e, kb_e, _ = emf_constants(th_m, 1.0, 0.1, P)
    assert ka_e == pytest.approx(KE * (1.0 + 0.1 * math.cos(th_m)))
    assert kb_e == pytest.approx(-KE * (1.0 + 0.1 * math.cos(th_m - 2.0 * math.pi / 3.0)))


# --------------------------------------------------------------------------------------------
# mechanics: backlash, friction, energy, end stops
# --------------------------------------------------------------------------------------------

BLK, KS, CS = 0.04, 3e5, 1000.0


@pytest.mark.parametrize("delta", [-0.02, -0.0199, -0.01, 0.0, 0.005, 0.0199999, 0.02])
@pytest.mark.parametrize("rate", [-50.0, 0.0, 50.0])
def test_backlash_dead_band_transmits_nothing(delta, rate):
    assert gear_torque(delta, rate, BLK, KS, CS) == 0.0


@pytest.mark.parametrize("delta", [0.021, 0.025, 0.1, -0.021, -0.03])
def test_backlash_contact_is_a_spring_at_rest(delta):
    expected = KS * (abs(delta) - BLK / 2) * math.copysign(1.0, delta)
    assert gear_torque(delta, 0.0, BLK, KS, CS) == pytest.approx(expected, rel=1e-12)
    # and with damping, the rate adds c * rate while in contact
    assert gear_torque(delta, 0.1 * math.copysign(1.0, delta), BLK, KS, CS) == pytest.approx(
        expected + CS * 0.1 * math.copysign(1.0, delta), rel=1e-12)


def test_backlash_contact_never_pulls():
    # separating fast: the damper would pull, the contact gives zero instead
    assert gear_torque(0.021, -10.0, BLK, KS, CS) == 0.0       # 300 - 10000 < 0
    assert gear_torque(-0.021, 10.0, BLK, KS, CS) == 0.0
    for delta in np.linspace(-0.05, 0.05, 101):
        for rate in (-100.0, -1.0, 0.0, 1.0, 100.0):
            t = gear_torque(delta, rate, BLK, KS, CS)
            assert t * delta >= 0.0                              # same sign as the twist
    # without backlash the stiffness is linear through zero
    assert gear_torque(1e-4, 0.0, 0.0, KS, 0.0) == pytest.approx(30.0)
    assert gear_torque(-1e-4, 0.0, 0.0, KS, 0.0) == pytest.approx(-30.0)


FST, FDYN, J, W_STICK = 0.5, 0.25, 5e-5, 1e-3


@pytest.mark.parametrize("t_drive", [0.0, 0.3, 0.49, 0.5, -0.49, -0.5])
def test_friction_sticks_below_breakaway(t_drive):
    w = 0.0
    for _ in range(2000):
        w = friction_speed(w, t_drive, FST, FDYN, J, DT, W_STICK)
        assert w == 0.0


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_friction_breakaway_accelerates_against_dynamic_level(sign):
    t_drive = sign * 0.6
    w = 0.0
    for _ in range(100):
        w = friction_speed(w, t_drive, FST, FDYN, J, DT, W_STICK)
    # (0.6 - 0.25) / 5e-5 = 7000 rad/s^2 for 100 us
    assert w == pytest.approx(sign * 100 * DT * (0.6 - FDYN) / J, rel=1e-9)
    assert abs(w) == pytest.approx(0.7, rel=1e-9)


def test_friction_moving_shaft_keeps_sliding_between_dynamic_and_static_level():
    # 0.3 N m is below breakaway (0.5) but above the dynamic level (0.25): a moving shaft
    # speeds up, a resting one stays stuck
    w = friction_speed(1.0, 0.3, FST, FDYN, J, DT, W_STICK)
    assert w == pytest.approx(1.0 + DT * 0.05 / J)
    assert friction_speed(0.0, 0.3, FST, FDYN, J, DT, W_STICK) == 0.0


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_friction_coasting_shaft_stops_exactly_without_reversing(sign):
    w = sign * 1.0012
    decel = DT * FDYN / J          # 5e-3 rad/s per step
    speeds = [w]
    for _ in range(400):
        w = friction_speed(w, 0.0, FST, FDYN, J, DT, W_STICK)
        speeds.append(w)
    speeds = np.array(speeds) * sign
    assert np.all(speeds >= 0.0)                     # never reverses
    assert np.all(np.diff(speeds) <= 0.0)
    moving = np.nonzero(speeds > 0.0)[0]
    steps = np.diff(speeds[: moving[-1] + 1])
    np.testing.assert_allclose(steps, -decel, rtol=1e-6)
    assert moving[-1] == int(1.0012 / decel)        # 200 steps of 5e-3, then the stop
    assert speeds[-1] == 0.0 and np.all(speeds[moving[-1] + 1:] == 0.0)


def test_friction_stop_sets_exact_zero():
    assert friction_speed(0.002, 0.0, FST, FDYN, J, DT, W_STICK) == 0.0
    assert friction_speed(-0.002, 0.0, FST, FDYN, J, DT, W_STICK) == 0.0


def _energy(p, th_m, w_m, th_u, w_u):
    delta = p[P_TAU] * th_m - th_u
    return 0.5 * p[P_JM] * w_m**2 + 0.5 * p[P_JU] * w_u**2 + 0.5 * p[P_KS] * delta**2


def _free_oscillation(params: EMAParams, n: int, dt: float):
    p = params.to_array()
    th_m, w_m, th_u, w_u = 1e-3 / params.tau, 0.0, 0.0, 0.0   # 1 mrad twist at the surface
    e = np.empty(n + 1)
    e[0] = _energy(p, th_m, w_m, th_u, w_u)
    for k in range(n):
        th_m, w_m, th_u, w_u, _ = mech_step(th_m, w_m, th_u, w_u, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
                                            p, dt)
        e[k + 1] = _energy(p, th_m, w_m, th_u, w_u)
    return e, (th_m, w_m, th_u, w_u)


def test_energy_conserved_without_damping():
    params = DEFAULT_PARAMS.replace(C_s=0.0, C_m=0.0)
    # mode: J_m/tau^2 = 4.5 with J_u = 1 and K_s = 3e5 -> 605 rad/s, ~10 ms period;
    # 10k steps of 5 us = 5 periods
    e, state = _free_oscillation(params, 10_000, 5e-6)
    assert e[0] == pytest.approx(0.5 * 3e5 * 1e-6)
    assert e.max() <= e[0] * 1.01
    assert e.min() >= e[0] * 0.99
    # it really oscillated (the energy went kinetic and back)
    assert state[2] != 0.0


def test_energy_decays_monotonically_with_damping():
    e, _ = _free_oscillation(DEFAULT_PARAMS, 10_000, 5e-6)
    assert np.all(np.diff(e) <= 1e-9 * e[0])
    assert e[-1] < 0.01 * e[0]


def test_end_stop_pushes_back():
    p = P
    th_u = p[P_THSTOP] + 0.01
    # motor far away in the backlash so the gear transmits nothing
    _, _, _, w_u, t_g = mech_step(th_u / p[P_TAU], 0.0, th_u, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, p,
                                  DT)
    assert t_g == 0.0
    assert w_u == pytest.approx(-DT * p[P_KSTOP] * 0.01 / p[P_JU])
    # inside the stops nothing happens
    _, _, _, w_u, _ = mech_step(0.4 / p[P_TAU], 0.0, 0.4, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, p, DT)
    assert w_u == 0.0


def test_hinge_moment():
    off = effects_vector()
    assert hinge_moment(0.1, 0.2, P, off) == pytest.approx(-800.0 * 0.1 - 50.0 * 0.2)
    spring = effects_vector({"aero_spring": 200.0})
    assert hinge_moment(0.1, 0.0, P, spring) == pytest.approx(-1000.0 * 0.1)
    # decoys: quadratic damping -c w|w| and hinge friction opposing the motion
    quad = effects_vector({"quadratic_damping": 100.0})
    assert hinge_moment(0.0, -0.5, P, quad) == pytest.approx(50.0 * 0.5 + 100.0 * 0.25)
    fric = effects_vector({"hinge_friction": 10.0})
    assert hinge_moment(0.0, 1.0, P, fric) == pytest.approx(-50.0 - 10.0, rel=1e-6)


# --------------------------------------------------------------------------------------------
# ACE
# --------------------------------------------------------------------------------------------


def test_ace_linear_region():
    # e = 1e-4 rad at the surface -> 0.03 rad at the motor; loop gain K_GP Gprop = 100 1/s
    i_ref, integ = ace_update(1e-4, 0.0, 1.0, 0.1, 1e5, P)
    w_ref = 100.0 * 0.03                   # 3 rad/s
    t_ref = 0.05 * (w_ref - 1.0) + 2.0 * 0.1   # 0.3 N m
    assert i_ref == pytest.approx(t_ref / (2.0 * KE))   # 3 A
    assert integ == pytest.approx(0.1 + (w_ref - 1.0) * 5e-5)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_ace_speed_demand_saturates_at_w_max(sign):
    # 0.3 rad error would ask for 9000 rad/s; limited to 750. With the motor at 740 rad/s the
    # speed error is 10 rad/s -> 0.5 N m -> 5 A (unsaturated it would be 20 A)
    i_ref, _ = ace_update(sign * 0.3, 0.0, sign * 740.0, 0.0, 1e5, P)
    assert i_ref == pytest.approx(sign * 5.0)
    i_ref, _ = ace_update(sign * 0.3, 0.0, sign * 750.0, 0.0, 1e5, P)
    assert i_ref == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_ace_torque_saturates_and_integral_does_not_wind_up(sign):
    integ = 0.0
    for _ in range(1000):
        i_ref, integ = ace_update(sign * 0.3, 0.0, 0.0, integ, 1e5, P)
        assert i_ref == pytest.approx(sign * PAR.T_max / (2.0 * KE))   # 20 A
    assert integ == 0.0     # saturated in the error's direction: no integration
    # the integral unwinds when the speed error reverses even though still saturated
    _, integ2 = ace_update(sign * 0.3, 0.0, sign * 800.0, sign * 10.0, 1e5, P)
    assert integ2 == pytest.approx(sign * (10.0 - 50.0 * 5e-5))


# --------------------------------------------------------------------------------------------
# sensors
# --------------------------------------------------------------------------------------------


def test_quantise_twelve_bits():
    spec = SENSORS[0]       # surface, -0.5 .. 0.5 rad
    assert spec.lsb == pytest.approx(1.0 / 4095.0)
    y = np.array([-0.7, -0.5, 0.1234, 0.3, 0.5, 0.9])
    q = quantise(y, spec)
    assert q[0] == -0.5 and q[-1] == pytest.approx(0.5)        # clipped to the span
    assert q[1] == -0.5
    assert q[2] == pytest.approx(-0.5 + 2553 / 4095, abs=1e-15)   # 0.6234 * 4095 = 2552.8
    assert q[3] == pytest.approx(0.3, abs=1e-12)                   # 0.8 * 4095 = 3276 exactly
    grid = np.linspace(-0.5, 0.5, 10_001)
    qg = quantise(grid, spec)
    assert np.abs(qg - grid).max() <= spec.lsb / 2 + 1e-15
    assert len(np.unique(np.round((qg + 0.5) / spec.lsb, 6))) == 4096
    cur = SENSORS[3]
    assert quantise(np.array([-1.0, 41.0]), cur).tolist() == pytest.approx([0.0, 40.0])


def test_measure_noise_seeded_and_sized():
    y = np.zeros((20_000, 4))
    y[:, 3] = 10.0
    a = measure(y, np.random.default_rng(7), adc=False)
    b = measure(y, np.random.default_rng(7), adc=False)
    c = measure(y, np.random.default_rng(8), adc=False)
    assert np.array_equal(a, b)
    assert not np.allclose(a, c)
    for k, spec in enumerate(SENSORS):
        assert np.std(a[:, k] - y[:, k]) == pytest.approx(1e-3 * (spec.hi - spec.lo), rel=0.03)
    assert np.abs(np.mean(a - y, axis=0)).max() < 0.05 * max(s.noise_std for s in SENSORS)
    # quantised output lies on the ADC grid
    d = measure(y, np.random.default_rng(7), adc=True)
    for k, spec in enumerate(SENSORS):
        codes = (d[:, k] - spec.lo) / spec.lsb
        np.testing.assert_allclose(codes, np.round(codes), atol=1e-6)
    # no noise, no ADC: unchanged copy
    clean = measure(y, None, noise=False, adc=False)
    assert np.array_equal(clean, y) and clean is not y


# --------------------------------------------------------------------------------------------
# commands
# --------------------------------------------------------------------------------------------


def test_step_command():
    c = make_command("step", 0.3, t0=0.01, duration=0.3)
    assert command_value(c, 0.0) == 0.0
    assert command_value(c, 0.00999) == 0.0
    assert command_value(c, 0.01) == 0.3
    assert command_value(c, 0.2) == 0.3


def test_sine_command():
    c = make_command("sine", 0.25, freq=1.0, duration=1.0)
    assert command_value(c, 0.0) == pytest.approx(0.0, abs=1e-15)
    assert command_value(c, 0.25) == pytest.approx(0.25)
    assert command_value(c, 0.5) == pytest.approx(0.0, abs=1e-15)
    assert command_value(c, 0.75) == pytest.approx(-0.25)
    assert command_value(c, 1.0 / 12.0) == pytest.approx(0.125)   # sin(30 deg) = 0.5
    c2 = make_command("sine", 0.1, t0=0.2, freq=2.0, duration=1.0)
    assert command_value(c2, 0.1) == 0.0
    assert command_value(c2, 0.2 + 0.125) == pytest.approx(0.1)


def test_ramp_command():
    c = make_command("ramp", 0.2, t0=0.1, freq=4.0, duration=1.0)   # full value after 0.25 s
    assert command_value(c, 0.05) == 0.0
    assert command_value(c, 0.1 + 0.125) == pytest.approx(0.1)
    assert command_value(c, 0.35) == pytest.approx(0.2)
    assert command_value(c, 0.9) == pytest.approx(0.2)


def test_chirp_command():
    # 1 Hz -> 3 Hz over 1 s: phase 2 pi (s + s^2)
    c = make_command("chirp", 0.1, freq=1.0, freq_end=3.0, duration=1.0)
    assert command_value(c, 0.25) == pytest.approx(0.1 * math.sin(2 * math.pi * 0.3125))
    assert command_value(c, 0.5) == pytest.approx(0.1 * math.sin(2 * math.pi * 0.75))   # -0.1
    assert command_value(c, 0.5) == pytest.approx(-0.1)
    # zero crossings where s + s^2 = k/2, i.e. s = (sqrt(1 + 2k) - 1) / 2: closer and closer
    s = np.linspace(0.0, 1.0, 100_001)
    v = np.array(command_samples(c, s.size, 1e-5))
    inner = slice(1, -1)
    sv = np.sign(v[inner])
    crossings = s[inner][1:][sv[1:] != sv[:-1]]
    expected = [(math.sqrt(1.0 + 2.0 * k) - 1.0) / 2.0 for k in (1, 2, 3)]   # .366 .618 .823
    np.testing.assert_allclose(crossings, expected, atol=2e-5)


def test_command_samples_match_values():
    c = make_command("sine", 0.25, freq=1.0, duration=1.0)
    v = command_samples(c, 101, 0.01)
    np.testing.assert_allclose(v, [command_value(c, k * 0.01) for k in range(101)], rtol=0,
                               atol=0)


def test_make_command_rejects_bad_input():
    assert set(KINDS) == {"step", "sine", "ramp", "chirp"}
    with pytest.raises(ValueError, match="unknown command kind 'square'"):
        make_command("square", 0.3)
    with pytest.raises(ValueError):
        make_command("step", float("nan"))
    with pytest.raises(ValueError):
        make_command("step", 0.3, t0=2.0, duration=1.0)
    with pytest.raises(ValueError):
        make_command("sine", 0.3, freq=0.0)
