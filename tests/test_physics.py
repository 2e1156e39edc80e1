"""Each physics block alone, against hand-computed expectations (DESIGN sections 1 and 8).

The blocks are the compiled (numba) functions the integrators call; every expectation below is
worked out from the parameter table (V_dc = 270 V, R = 0.5 ohm, L = 0.5 mH, Ke = 0.05 V s/rad,
2 pole pairs, J_m = 5e-5 kg m^2, ...), not read back from the code.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from ema_bench.params import (
    DEFAULT_PARAMS,
    P_CU,
    P_JM,
    P_JU,
    P_KAERO,
    P_KS,
    P_KSTOP,
    P_TAU,
    P_THSTOP,
    EMAParams,
)
from ema_bench.physics.ace import ace_consts, ace_update
from ema_bench.physics.averaged_drive import drive_consts, kt_at, sector_index
from ema_bench.physics.bldc import (
    PHASE_SHIFT,
    bldc_consts,
    bldc_step,
    commutation,
    emf_constants,
    sector,
    trapezoid,
)
from ema_bench.physics.command import (
    KINDS,
    command_samples,
    command_value,
    make_command,
)
from ema_bench.physics.load import hinge_extra
from ema_bench.physics.mechanics import gear_mean, gear_torque, mech_consts, mech_step
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
    bc = bldc_consts(P, na, 0.0, 1.0, V_DC)
    for k in range(n):
        ia, ib, ic, sa, sb, sc, _, _, t, _ = bldc_step(ia, ib, ic, sa, sb, sc, i_ref, th_m, 0.0,
                                                       bc, DT)
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
    # analog comparators: the legs switch at the crossing instant inside the step, so the
    # current never leaves the band (a comparator sampled each microsecond overshot it by one
    # step of rise, 0.27 A, or fall, 0.29 A)
    assert after.max() <= i_ref + BAND / 2 + 1e-9
    assert after.min() >= i_ref - BAND / 2 - 1e-9
    # it really switches: rise V_dc / 2L, fall about -V_dc / 2L, one period about 2 band 2L /
    # V_dc = 7.4 us, so the 2.9 ms after the first rise hold several hundred turning points
    turns = np.sum(np.diff(np.sign(np.diff(after))) != 0)
    assert turns > 300
    # the current sweeps the band: it comes within one step of rise of both thresholds
    rise = V_DC * DT / (2.0 * L)                                   # 0.27 A
    assert after.max() >= i_ref + BAND / 2 - rise
    assert after.min() <= i_ref - BAND / 2 + rise
    # a triangle between the thresholds: mean at the reference (the sampled comparator's
    # overshoot biased it by 10-20 mA)
    assert after.mean() == pytest.approx(i_ref, abs=0.01)
    np.testing.assert_allclose(cur[:, 1], -ia, rtol=1e-12)


def test_no_load_speed_approaches_bus_over_pair_back_emf():
    # motor alone: w' = T / J_m, no friction, no load, current demand far above the bus limit
    ia = ib = ic = 0.0
    sa = sb = sc = 0
    th, w = 0.1, 0.0
    n = 40_000
    speeds = np.empty(n)
    bc = bldc_consts(P, 1.0, 0.0, 1.0, V_DC)
    for k in range(n):
        ia, ib, ic, sa, sb, sc, t, _, _, _ = bldc_step(ia, ib, ic, sa, sb, sc, 1e3, th, w, bc, DT)
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
    ke = emf_constants(th_m, 1.0, 0.0, KE, PP)
    c = commutation(PP * th_m)
    torque = sum(k * ci * current for k, ci in zip(ke, c))
    assert torque == pytest.approx(2.0 * KE * current, rel=1e-12)


@pytest.mark.parametrize("na", [0.8, 1.0])
def test_monitor_sector_constants_average_to_design_values(na):
    # uniform grid of one mechanical turn whose cells never straddle a sector boundary
    dc = drive_consts(P, na, 0.0, 1.0, V_DC, 5e-5)
    n = 1200
    th = (np.arange(n) + 0.5) * 2.0 * math.pi / n
    kt = np.array([kt_at(sector_index(t, PP) % 6, t, dc) for t in th])
    assert kt.mean() == pytest.approx(2.0 * KE * (na + 2.0) / 3.0, rel=1e-12)
    # the pair resistance and inductance of the two kinds of sector
    assert (dc.r_a, dc.r_n) == pytest.approx(((1.0 + na) * R, 2.0 * R), rel=1e-12)
    assert (1.0 / dc.il_a, 1.0 / dc.il_n) == pytest.approx(((1.0 + na * na) * L, 2.0 * L),
                                                           rel=1e-12)


@pytest.mark.parametrize("na,zeta", [(1.0, 0.0), (0.8, 0.0), (0.9, 0.1)])
def test_monitor_sector_matches_three_phase_model(na, zeta):
    # the monitor's sector bookkeeping (averaged_drive) against the three-phase model (bldc):
    # same sector at every angle, and inside each sector the conducting phases sit on their
    # flat tops, so the pair's torque constant is sum(c_x ke_x) at the same angle
    dc = drive_consts(P, na, zeta, 1.0, V_DC, 5e-5)
    for s in range(12):   # two electrical turns = one mechanical turn
        for frac in (0.1, 0.5, 0.9):
            th_m = (30.0 + 60.0 * (s + frac)) * DEG / PP
            assert sector_index(th_m, PP) % 6 == sector(PP * th_m) == s % 6
            ke = emf_constants(th_m, na, zeta, KE, PP)
            c = commutation(PP * th_m)
            kt = kt_at(sector_index(th_m, PP) % 6, th_m, dc)
            assert kt == pytest.approx(sum(k * ci for k, ci in zip(ke, c)), rel=1e-12)
    # and on negative angles (the sine test runs backwards)
    for deg in np.arange(-355.0, 0.0, 10.0):
        assert sector_index(deg * DEG / PP, PP) % 6 == sector(deg * DEG)


def test_shorted_turns_scale_phase_a_back_emf():
    th_m = 60.0 * DEG / PP   # phase a on its flat top
    ka, kb, kc = emf_constants(th_m, 0.8, 0.0, KE, PP)
    assert ka == pytest.approx(0.8 * KE)
    assert kb == pytest.approx(-KE)
    # eccentricity modulates each phase by 1 + zeta cos(th_m - phi_x)
    ka_e, kb_e, _ = emf_constants(th_m, 1.0, 0.1, KE, PP)
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


@pytest.mark.parametrize("d0,dd", [
    (0.015, 100.0),     # enters contact inside the step
    (0.025, -100.0),    # leaves it
    (0.021, -0.295),    # the damped contact lifts off inside the step (at 56 us)
    (0.03, 5.0),        # in contact throughout
    (-0.025, 150.0),    # crosses the whole dead band into the other flank
    (0.0, 1.0),         # in the dead band throughout
])
def test_kernel_step_mean_is_the_mean_of_the_gear_law(d0, dd):
    # the kernel's explicit step mean (gear_mean: contact entry and lift-off located inside
    # the step) against the point law gear_torque averaged along the same straight path by
    # a fine midpoint rule: a wrong crossing time or lift-off point shows here
    h = 1e-4
    t = (np.arange(20_000) + 0.5) * (h / 20_000)
    law = np.mean([gear_torque(d0 + dd * ti, dd, BLK, KS, CS) for ti in t[::10]])
    fine = np.mean([gear_torque(d0 + dd * ti, dd, BLK, KS, CS) for ti in t])
    # the midpoint rule's error at a kink falls as 1/N: 10x the points, a tenth of it
    assert law == pytest.approx(fine, rel=2e-3, abs=1e-6)
    assert gear_mean(d0, dd, BLK / 2, KS, CS, h) == pytest.approx(fine, rel=2e-4, abs=1e-6)


FST, FDYN, J, W_STICK = 0.5, 0.25, 5e-5, 1e-3
# the motor alone: no viscous friction, a backlash so wide the reducer transmits nothing
P_FREE = DEFAULT_PARAMS.replace(C_m=0.0).to_array()
MC_FREE = mech_consts(P_FREE, FST, 0.5, 0.0, 0.0, 1.0, DT)


def motor_step(w, t_m, t0=None, t1=None, mc=MC_FREE):
    """One step of the motor shaft under drive torque ``t_m`` (step mean; start and end values
    default to it); returns (end speed, mean speed)."""
    t0 = t_m if t0 is None else t0
    t1 = t_m if t1 is None else t1
    _, w1, _, _, _, w_mean, _ = mech_step(0.0, w, 0.0, 0.0, t_m, t0, t1, 0.0, 0.0, mc)
    return w1, w_mean


@pytest.mark.parametrize("t_drive", [0.0, 0.3, 0.49, 0.5, -0.49, -0.5])
def test_friction_sticks_below_breakaway(t_drive):
    w = 0.0
    for _ in range(2000):
        w, _ = motor_step(w, t_drive)
        assert w == 0.0


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_friction_breakaway_accelerates_against_dynamic_level(sign):
    t_drive = sign * 0.6
    w = 0.0
    for _ in range(100):
        w, _ = motor_step(w, t_drive)
    # (0.6 - 0.25) / 5e-5 = 7000 rad/s^2 for 100 us
    assert w == pytest.approx(sign * 100 * DT * (0.6 - FDYN) / J, rel=1e-9)
    assert abs(w) == pytest.approx(0.7, rel=1e-9)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_friction_breakaway_is_located_inside_the_step(sign):
    # the drive torque ramps 0.4 -> 0.6 N m over a 50 us step: it crosses the 0.5 N m static
    # level half-way, and the shaft accelerates for the second half only, under the mean
    # excess (0.55 - 0.25) N m
    h = 5e-5
    mc = mech_consts(P_FREE, FST, 0.5, 0.0, 0.0, 1.0, h)
    w, w_mean = motor_step(0.0, sign * 0.5, sign * 0.4, sign * 0.6, mc)
    assert w == pytest.approx(sign * 0.5 * h * (0.55 - FDYN) / J, rel=1e-12)   # 0.15 rad/s
    assert w_mean == pytest.approx(0.25 * w, rel=1e-12)
    # a drive torque that stays below the static level all step never breaks away
    assert motor_step(0.0, 0.45, 0.4, 0.499, mc)[0] == 0.0


def test_friction_moving_shaft_keeps_sliding_between_dynamic_and_static_level():
    # 0.3 N m is below breakaway (0.5) but above the dynamic level (0.25): a moving shaft
    # speeds up, a resting one stays stuck
    w, _ = motor_step(1.0, 0.3)
    assert w == pytest.approx(1.0 + DT * 0.05 / J)
    assert motor_step(0.0, 0.3)[0] == 0.0


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_friction_coasting_shaft_stops_exactly_without_reversing(sign):
    w = sign * 1.0012
    decel = DT * FDYN / J          # 5e-3 rad/s per step
    speeds = [w]
    for _ in range(400):
        w, _ = motor_step(w, 0.0)
        speeds.append(w)
    speeds = np.array(speeds) * sign
    assert np.all(speeds >= 0.0)                     # never reverses
    assert np.all(np.diff(speeds) <= 0.0)
    moving = np.nonzero(speeds > 0.0)[0]
    steps = np.diff(speeds[: moving[-1] + 1])
    np.testing.assert_allclose(steps, -decel, rtol=1e-6)
    assert moving[-1] == int(1.0012 / decel)        # 200 steps of 5e-3, then the stop
    assert speeds[-1] == 0.0 and np.all(speeds[moving[-1] + 1:] == 0.0)


def test_friction_stop_is_located_inside_the_step():
    # 0.002 rad/s left, 5e-3 rad/s lost per step: the shaft stops 40 % into the step, and the
    # step-mean speed is the triangle's, 0.4 * 0.002 / 2
    for sign in (1.0, -1.0):
        w, w_mean = motor_step(sign * 0.002, 0.0)
        assert w == 0.0
        assert w_mean == pytest.approx(sign * 0.5 * 0.4 * 0.002, rel=1e-9)


def _energy(p, th_m, w_m, th_u, w_u):
    delta = p[P_TAU] * th_m - th_u
    return (0.5 * p[P_JM] * w_m**2 + 0.5 * p[P_JU] * w_u**2 + 0.5 * p[P_KS] * delta**2
            + 0.5 * p[P_KAERO] * th_u**2)


def _free_oscillation(params: EMAParams, n: int, dt: float):
    p = params.to_array()
    mc = mech_consts(p, 0.0, 0.0, 0.0, 0.0, 1.0, dt)
    th_m, w_m, th_u, w_u = 1e-3 / params.tau, 0.0, 0.0, 0.0   # 1 mrad twist at the surface
    e = np.empty(n + 1)
    e[0] = _energy(p, th_m, w_m, th_u, w_u)
    for k in range(n):
        th_m, w_m, th_u, w_u, _, _, _ = mech_step(th_m, w_m, th_u, w_u, 0.0, 0.0, 0.0, 0.0, 0.0,
                                                  mc)
        e[k + 1] = _energy(p, th_m, w_m, th_u, w_u)
    return e, (th_m, w_m, th_u, w_u)


@pytest.mark.parametrize("dt", [5e-6, 5e-5])
def test_energy_conserved_without_damping(dt):
    # the trapezoidal rule conserves a linear spring-mass system's energy at any step, the
    # monitor's 50 us included (an explicit step gains or loses it)
    params = DEFAULT_PARAMS.replace(C_s=0.0, C_m=0.0, C_u=0.0)
    # mode: J_m/tau^2 = 4.5 with J_u = 1 and K_s = 3e5 -> 605 rad/s, ~10 ms period;
    # 50 ms = 5 periods
    e, state = _free_oscillation(params, int(round(0.05 / dt)), dt)
    assert e[0] == pytest.approx(0.5 * 3e5 * 1e-6)
    # (the first step starts the shaft from rest explicitly: 4e-7 of the energy at 50 us)
    np.testing.assert_allclose(e, e[0], rtol=1e-6)
    # it really oscillated (the energy went kinetic and back)
    assert state[2] != 0.0


def test_energy_decays_monotonically_with_damping():
    e, _ = _free_oscillation(DEFAULT_PARAMS, 10_000, 5e-6)
    assert np.all(np.diff(e) <= 1e-9 * e[0])
    assert e[-1] < 0.01 * e[0]


def test_end_stop_pushes_back():
    p = P
    th_u = p[P_THSTOP] + 0.01
    # motor far away in the backlash so the gear transmits nothing; the stop and the hinge
    # spring push the surface back (the hinge spring and damping implicitly)
    mc = mech_consts(p, 0.0, 1.0, 0.0, 0.0, 1.0, DT)
    _, _, _, w_u, _, _, _ = mech_step(th_u / p[P_TAU], 0.0, th_u, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                                      mc)
    g_h = 0.25 * p[P_KAERO] * DT + 0.5 * p[P_CU]
    assert w_u == pytest.approx(DT * (-p[P_KSTOP] * 0.01 - p[P_KAERO] * th_u)
                                / (p[P_JU] + DT * g_h), rel=1e-12)
    # inside the stops, without the hinge spring, nothing happens
    mc0 = mech_consts(DEFAULT_PARAMS.replace(K_aero=0.0).to_array(), 0.0, 1.0, 0.0, 0.0, 1.0, DT)
    _, _, _, w_u, _, _, _ = mech_step(0.4 / p[P_TAU], 0.0, 0.4, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                                      mc0)
    assert w_u == 0.0


def test_hinge_terms():
    # the linear hinge lives in the mechanics constants; the aero_spring effect adds to it
    assert mech_consts(P, 0.0, 0.0, 0.0, 0.0, 1.0, DT).ka == 800.0
    assert mech_consts(P, 0.0, 0.0, 0.0, 200.0, 1.0, DT).ka == 1000.0
    assert mech_consts(P, 0.0, 0.0, 0.0, 0.0, 1.0, DT).cu == 50.0
    # decoys: quadratic damping -c w|w| and hinge friction opposing the motion
    assert hinge_extra(-0.5, 0.0, 0.0) == 0.0
    assert hinge_extra(-0.5, 100.0, 0.0) == pytest.approx(100.0 * 0.25)
    assert hinge_extra(1.0, 0.0, 10.0) == pytest.approx(-10.0, rel=1e-6)
    assert hinge_extra(-1.0, 0.0, 10.0) == pytest.approx(10.0, rel=1e-6)


# --------------------------------------------------------------------------------------------
# ACE
# --------------------------------------------------------------------------------------------


def test_ace_linear_region():
    # e = 1e-4 rad at the surface -> 0.03 rad at the motor; loop gain K_GP Gprop = 100 1/s
    i_ref, integ = ace_update(1e-4, 0.0, 1.0, 0.1, ace_consts(P, 1e5))
    w_ref = 100.0 * 0.03                   # 3 rad/s
    t_ref = 0.05 * (w_ref - 1.0) + 2.0 * 0.1   # 0.3 N m
    assert i_ref == pytest.approx(t_ref / (2.0 * KE))   # 3 A
    assert integ == pytest.approx(0.1 + (w_ref - 1.0) * 5e-5)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_ace_speed_demand_saturates_at_w_max(sign):
    # 0.3 rad error would ask for 9000 rad/s; limited to 750. With the motor at 740 rad/s the
    # speed error is 10 rad/s -> 0.5 N m -> 5 A (unsaturated it would be 20 A)
    i_ref, _ = ace_update(sign * 0.3, 0.0, sign * 740.0, 0.0, ace_consts(P, 1e5))
    assert i_ref == pytest.approx(sign * 5.0)
    i_ref, _ = ace_update(sign * 0.3, 0.0, sign * 750.0, 0.0, ace_consts(P, 1e5))
    assert i_ref == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_ace_torque_saturates_and_integral_does_not_wind_up(sign):
    integ = 0.0
    for _ in range(1000):
        i_ref, integ = ace_update(sign * 0.3, 0.0, 0.0, integ, ace_consts(P, 1e5))
        assert i_ref == pytest.approx(sign * PAR.T_max / (2.0 * KE))   # 20 A
    assert integ == 0.0     # saturated in the error's direction: no integration
    # the integral unwinds when the speed error reverses even though still saturated
    _, integ2 = ace_update(sign * 0.3, 0.0, sign * 800.0, sign * 10.0, ace_consts(P, 1e5))
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
