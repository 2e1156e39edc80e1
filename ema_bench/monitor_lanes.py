"""The monitor kernel in lock-step lanes: eight candidates advanced together, vectorised.

The scalar kernel (:mod:`ema_bench.monitor`) runs at the speed of the same equations in plain C
(``benchmarks/c``); what is left is SIMD.  Here the short paths of a step, the controller
(:func:`~ema_bench.physics.ace.ace_update`), the drive inside one sector
(:func:`~ema_bench.physics.averaged_drive.drive_fast`) and the sliding mechanics
(:func:`~ema_bench.physics.mechanics.mech_fast`), run for ``LANES`` candidates in one loop that
LLVM vectorises; a lane whose step leaves a short path (a sector crossing, a commutation, a
contact change, a stuck shaft: about 5 % of steps) runs the general scalar function for that
lane alone, after the vector loop.  The functions are the scalar kernel's own, so the two cannot
drift apart, and the outputs are bit-identical to it: the same operations in the same order,
IEEE vector arithmetic, no fused multiply-add (``tests/test_kernel.py``).

Why one flat array: the lanes' state and their fault-dependent constants live in one float
array at fixed offsets (``_O_*``).  With it the compiler proves the lanes independent and
vectorises; with one array per quantity it needs a runtime alias check per pair of arrays,
gives up beyond a handful and the loop stays scalar (``benchmarks/vectorisation_probe.py``).

Effects (:data:`LANE_EFFECTS`, every effect of suite emafdi-v2's tiers) ride in the lanes,
bit-identical too.  The sensor and controller ones (position-sensor offset, current-channel
gain, feedback delay): the offset and gain per lane in the vector loops, the delay's ring
buffer lane by lane once per controller sample.  The plant ones: viscous friction, the aero
spring and the gear stiffness change the mechanics' constants, which every lane reads from
its own blocks (``_O_K`` .. ``_O_IUF``); cogging's torque and an eccentric rotor's torque
constants at the step start and mid-step run in two more vector loops before the drive's,
on the polynomial sine and cosine of :mod:`ema_bench.physics.trig` (the scalar kernel's and
the C twin's too; libm's scalar calls, which LLVM cannot vectorise, made a tier-12 candidate
five times a tier-4 one; ``ema-bench bench`` reports the tiers' rates now).
The resistance rise, the voltage sag (constants :func:`drive_fast` takes from lane 0) and the
decoys (a hinge moment the lanes do not compute) send their candidate to the scalar kernel
(:mod:`ema_bench.monitor`).

The 8-lane C twin (``benchmarks/c/monitor.c``: ``monitor_lanes_batch``) is this module line
by line, vectorised by GCC; ``ema-bench bench`` times the two side by side
(``c_lanes_time_ratio``), and ``tests/test_kernel.py`` holds the four kernels (scalar and
lanes, numba and C) to the same bits.  Which parts of the step vectorise here:
``benchmarks/vectorisation_probe.py --lanes``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .effects import EFFECT_INDEX, MAX_DELAY_SAMPLES
from .faults import F_GPROP
from .monitor_plant import monitor_consts
from .physics.ace import CtrlConsts, ace_consts, ace_update
from .physics.averaged_drive import (
    drive_fast,
    drive_step_general,
    kt_eccentric,
    kt_eccentric_libm,
    sector_consts,
    sector_index,
)
from .physics.effect_terms import cogging_torque, cogging_wave, sensor_terms
from .physics.mechanics import MechConsts, mech_fast, mech_step_general

LANES = 8   # candidates per group: two AVX2 vectors of doubles, one AVX-512 vector
#: Effects a lane can carry (the others send a candidate to the scalar kernel).
LANE_EFFECTS: tuple[str, ...] = ("sensor_offset", "current_gain", "delay", "eccentricity",
                                  "viscous_friction", "aero_spring", "cogging",
                                  "gear_stiffness")
#: Samples in a lane's delay line: a power of two above the longest delay (a mask, not a
#: division, wraps the index).
_DBUF = 1 << int(math.ceil(math.log2(MAX_DELAY_SAMPLES + 2)))
#: Indices of :data:`LANE_EFFECTS` in an effects vector.
LANE_EFFECT_INDEX = np.array([EFFECT_INDEX[n] for n in LANE_EFFECTS], dtype=np.int64)

# Offsets (in blocks of LANES) of the lanes' quantities in the flat array: state, then the
# fault-dependent constants, then per-step values handed from the vector loops to the
# scalar fall-backs.
(_O_THM, _O_WM, _O_THU, _O_WU, _O_CUR, _O_TRT0, _O_TRLEN, _O_KTF, _O_KTT, _O_TRCR, _O_INTEG,
 _O_THLO, _O_KT, _O_RP, _O_IL, _O_HALF, _O_FDYN, _O_KPOS, _O_IREF, _O_TM, _O_TM0, _O_TM1,
 _O_TRIP, _O_IEQ, _O_DSLOW, _O_MSLOW, _O_A0, _O_A1, _O_A2, _O_A3, _O_OFF, _O_GAIN, _O_FB,
 _O_ECC, _O_KTE, _O_KTM, _O_COG, _O_TCOG,
 # the sector (0..5, as a float: the eccentric torque constants' selects vectorise on it),
 # the eccentricity and the turn fraction of each lane
 _O_SEC, _O_ZETA, _O_NA,
 # the mechanics' constants that the plant effects (viscous friction, aero spring, gear
 # stiffness) change: mech_fast reads them per lane
 _O_K, _O_CM, _O_KA, _O_GH, _O_BC, _O_I11, _O_I12, _O_I22, _O_I11H, _O_I12H, _O_IMF,
 _O_IMFH, _O_IUF,
 _N_BLOCKS) = [LANES * i for i in range(55)]


@njit(cache=True, error_model="numpy")
def _rest(F, M, dc, q):
    """Lane ``q`` at rest, as the scalar kernel starts a test (``monitor_init``)."""
    for o in (_O_THM, _O_WM, _O_THU, _O_WU, _O_CUR, _O_TRLEN, _O_KTF, _O_KTT, _O_TRCR,
              _O_INTEG):
        F[o + q] = 0.0
    F[_O_TRT0 + q] = -1.0
    m = sector_index(0.0, dc.pp)
    M[q] = m
    F[_O_SEC + q] = m % 6
    th_lo, kt, rp, il = sector_consts(m, dc)
    F[_O_THLO + q] = th_lo
    F[_O_KT + q] = kt
    F[_O_RP + q] = rp
    F[_O_IL + q] = il


@njit(cache=True, error_model="numpy")
def lane_group(p, X, E, idx, cmd, cmd_start, n_out, out_start, ticks_out, steps_tick, dt, out,
               ok):
    """Every test of the ``LANES`` candidates ``X[idx]`` in lock-step (effects ``E[idx]``:
    only :data:`LANE_EFFECTS` may be on).

    Lane ``q`` simulates ``X[idx[q]]`` and writes ``out[idx[q]]`` and ``ok[idx[q]]``; a group
    with fewer candidates repeats one (the copies write the same values).  Arguments as
    :func:`ema_bench.monitor.monitor_batch_serial`.
    """
    # Lane 0's constants serve every lane where they depend neither on the faults nor on the
    # lane effects (drive_fast and mech_fast read only those); the others are per lane.
    F = np.zeros(_N_BLOCKS)
    dc0, mc0, F[_O_COG] = monitor_consts(p, X[idx[0]], E[idx[0]], dt)[:3]
    cc0 = ace_consts(p, X[idx[0], F_GPROP])
    dcs = [dc0]
    mcs = [mc0]
    for q in range(1, LANES):
        dc, mc, F[_O_COG + q] = monitor_consts(p, X[idx[q]], E[idx[q]], dt)[:3]
        dcs.append(dc)
        mcs.append(mc)
    M = np.zeros(LANES, dtype=np.int64)
    alive = np.ones(LANES, dtype=np.bool_)
    done = np.ones(LANES, dtype=np.bool_)
    delay = np.zeros(LANES)
    d0 = np.zeros(LANES, dtype=np.int64)   # whole controller samples of each lane's delay
    frac = np.zeros(LANES)                 # and the fraction of one
    buf = np.zeros((_DBUF, LANES))         # the lanes' delay lines, one column each
    delayed = False
    cogged = False
    eccentric = False
    for q in range(LANES):
        mc = mcs[q]
        F[_O_HALF + q] = mc.half
        F[_O_FDYN + q] = mc.fdyn
        for o, v in ((_O_K, mc.k), (_O_CM, mc.cm), (_O_KA, mc.ka), (_O_GH, mc.g_h),
                     (_O_BC, mc.b_c), (_O_I11, mc.i11), (_O_I12, mc.i12), (_O_I22, mc.i22),
                     (_O_I11H, mc.i11h), (_O_I12H, mc.i12h), (_O_IMF, mc.i_m_free),
                     (_O_IMFH, mc.i_m_free_h), (_O_IUF, mc.i_u_free)):
            F[o + q] = v
        F[_O_ECC + q] = 0.0 if dcs[q].zeta == 0.0 else 1.0
        F[_O_ZETA + q] = dcs[q].zeta
        F[_O_NA + q] = dcs[q].na
        eccentric |= dcs[q].zeta != 0.0
        cogged |= F[_O_COG + q] != 0.0
        F[_O_KPOS + q] = cc0.k_pos if q == 0 else ace_consts(p, X[idx[q], F_GPROP]).k_pos
        offset, gain, d = sensor_terms(E[idx[q]], p)
        F[_O_OFF + q] = offset
        F[_O_GAIN + q] = gain
        delay[q] = d
        d0[q] = int(math.floor(d))
        frac[q] = d - d0[q]
        delayed |= d > 0.0
    h = dc0.h
    scale = 1.0 / (ticks_out * steps_tick)
    for t in range(n_out.shape[0]):
        for q in range(LANES):
            _rest(F, M, dcs[q], q)
            alive[q] = True
        k_ctrl = cmd_start[t]
        for k in range(n_out[t]):
            for q in range(LANES):
                F[_O_A0 + q] = 0.0
                F[_O_A1 + q] = 0.0
                F[_O_A2 + q] = 0.0
                F[_O_A3 + q] = 0.0
            for _ in range(ticks_out):
                for q in range(LANES):   # the loop sees the same (offset) position sensor
                    F[_O_FB + q] = F[_O_THU + q] + F[_O_OFF + q]
                if delayed:
                    _delay_lines(F, buf, k_ctrl - cmd_start[t], delay, d0, frac)
                c = cmd[k_ctrl]
                k_ctrl += 1
                for j in range(steps_tick):
                    _step(F, M, dc0, mc0, cc0, dcs, mcs, h, c, j == 0, cogged, eccentric)
            row = out_start[t] + k
            for q in range(LANES):
                a0, a1, a2, a3 = F[_O_A0 + q], F[_O_A1 + q], F[_O_A2 + q], F[_O_A3 + q]
                o = out[idx[q], row]
                o[0] = a0 * scale + F[_O_OFF + q]
                o[1] = a1 * scale
                o[2] = a2 * scale
                o[3] = F[_O_GAIN + q] * a3 * scale
                if alive[q] and not (math.isfinite(a0) and math.isfinite(a1)
                                     and math.isfinite(a2) and math.isfinite(a3)):
                    alive[q] = False   # as the scalar kernel: this test failed
                    _rest(F, M, dcs[q], q)   # and the lane runs on harmlessly
        for q in range(LANES):
            done[q] &= alive[q]
    for q in range(LANES):
        ok[idx[q]] = done[q]


@njit(cache=True, inline="always", error_model="numpy")
def _delay_lines(F, buf, k, delay, d0, frac):
    """The feedback of every lane through its delay line at controller sample ``k`` of the
    test: :func:`~ema_bench.physics.ace.delayed_feedback` for ``LANES`` lanes at once (the
    same samples, the same interpolation, so the same bits; its ring of ``_DBUF`` samples is
    indexed with a mask instead of a division).  A lane without delay keeps its feedback."""
    slot = k & (_DBUF - 1)
    for q in range(LANES):
        fb = F[_O_FB + q]
        buf[slot, q] = fb
        k0 = k - d0[q]
        k1 = k0 - 1
        a = buf[0 if k0 < 0 else k0 & (_DBUF - 1), q]   # before the record: its first sample
        b = buf[0 if k1 < 0 else k1 & (_DBUF - 1), q]
        F[_O_FB + q] = (1.0 - frac[q]) * a + frac[q] * b if delay[q] > 0.0 else fb


@njit(cache=True, inline="always", error_model="numpy")
def _step(F, M, dc0, mc0, cc0, dcs, mcs, h, c, tick, cogged, eccentric):
    """One plant step of every lane, the monitor's ``monitor_step`` (with the decoys, the
    resistance rise and the voltage sag off), after the controller sample under command
    ``c`` (rad) if ``tick``; ``cogged``, ``eccentric``: some lane has cogging, eccentricity.
    (The controller shares the drive's loop: on its own, its loop is short enough that the
    compiler unrolls it before it could vectorise it.)"""
    # model version 2 (``libm_trig``, the same for every lane) takes libm's scalar sine and
    # cosine: loops of their own, so version 3's stay vectorised
    if cogged and dc0.libm:
        for q in range(LANES):
            _cogging_lane_libm(F, q, h, dc0.pp)
    elif cogged:   # vectorised (a polynomial sine): the cogging torque at mid-step
        for q in range(LANES):
            _cogging_lane(F, q, h, dc0.pp)
    if eccentric and dc0.libm:
        for q in range(LANES):
            _eccentric_lane_libm(F, q, h, dc0.ke)
    elif eccentric:   # vectorised: the torque constants at the step start and mid-step
        for q in range(LANES):
            _eccentric_lane(F, q, h, dc0.ke)
    for q in range(LANES):   # vectorised: controller and the drive inside one sector
        _drive_fast_lane(F, q, dc0, cc0, h, c, tick)
    for q in range(LANES):   # the rest of the drive, lane by lane
        if F[_O_DSLOW + q] != 0.0:
            dc = dcs[q]
            ecc = F[_O_ECC + q] != 0.0   # the constants the vector loop gave drive_fast
            kt = F[_O_KTE + q] if ecc else F[_O_KT + q]
            (cur, m, tr_t0, tr_len, kt_from, kt_to, tr_cr, t_mean, t_start, t_end, t_rip,
             i_eq) = drive_step_general(
                F[_O_CUR + q], M[q], F[_O_TRT0 + q], F[_O_TRLEN + q], F[_O_KTF + q],
                F[_O_KTT + q], F[_O_TRCR + q], F[_O_IREF + q], F[_O_THM + q], F[_O_WM + q],
                dc, kt, F[_O_KTM + q] if ecc else kt)
            F[_O_CUR + q] = cur
            M[q] = m
            F[_O_SEC + q] = m % 6
            F[_O_TRT0 + q] = tr_t0
            F[_O_TRLEN + q] = tr_len
            F[_O_KTF + q] = kt_from
            F[_O_KTT + q] = kt_to
            F[_O_TRCR + q] = tr_cr
            F[_O_TM + q] = t_mean + F[_O_TCOG + q]
            F[_O_TM0 + q] = t_start + F[_O_TCOG + q]
            F[_O_TM1 + q] = t_end + F[_O_TCOG + q]
            F[_O_TRIP + q] = t_rip
            F[_O_IEQ + q] = i_eq
            th_lo, kt, rp, il = sector_consts(m, dc)
            F[_O_THLO + q] = th_lo
            F[_O_KT + q] = kt
            F[_O_RP + q] = rp
            F[_O_IL + q] = il
    for q in range(LANES):   # vectorised: the sliding mechanics
        _mech_fast_lane(F, q, _lane_mech_consts(F, q, mc0))
    for q in range(LANES):   # the rest of the mechanics, lane by lane
        if F[_O_MSLOW + q] != 0.0:
            th_m, w_m, th_u, w_u, m_thm, m_wm, m_thu = mech_step_general(
                F[_O_THM + q], F[_O_WM + q], F[_O_THU + q], F[_O_WU + q], F[_O_TM + q],
                F[_O_TM0 + q], F[_O_TM1 + q], F[_O_TRIP + q], 0.0, mcs[q])
            F[_O_THM + q] = th_m
            F[_O_WM + q] = w_m
            F[_O_THU + q] = th_u
            F[_O_WU + q] = w_u
            F[_O_A0 + q] += m_thu
            F[_O_A1 + q] += m_thm
            F[_O_A2 + q] += m_wm
            F[_O_A3 + q] += F[_O_IEQ + q]


@njit(cache=True, inline="always", error_model="numpy")
def _cogging_lane(F, q, h, pp):
    """Lane ``q``'s cogging torque at mid-step (:func:`cogging_torque`'s bits: its +0 without
    cogging by a select, since a branch around the sine would keep the loop scalar)."""
    wave = cogging_wave(F[_O_COG + q], F[_O_THM + q] + 0.5 * h * F[_O_WM + q], pp)
    F[_O_TCOG + q] = wave if F[_O_COG + q] != 0.0 else 0.0


@njit(cache=True, inline="always", error_model="numpy")
def _cogging_lane_libm(F, q, h, pp):
    """:func:`_cogging_lane` under model version 2: :func:`cogging_torque` with libm's sine."""
    F[_O_TCOG + q] = cogging_torque(F[_O_COG + q], F[_O_THM + q] + 0.5 * h * F[_O_WM + q], pp,
                                    True)


@njit(cache=True, inline="always", error_model="numpy")
def _eccentric_lane_libm(F, q, h, ke):
    """:func:`_eccentric_lane` under model version 2 (:func:`kt_eccentric_libm`)."""
    sec = F[_O_SEC + q]
    th = F[_O_THM + q]
    F[_O_KTE + q] = kt_eccentric_libm(sec, th, ke, F[_O_NA + q], F[_O_ZETA + q])
    F[_O_KTM + q] = kt_eccentric_libm(sec, th + 0.5 * h * F[_O_WM + q], ke, F[_O_NA + q],
                                      F[_O_ZETA + q])


@njit(cache=True, inline="always", error_model="numpy")
def _eccentric_lane(F, q, h, ke):
    """Lane ``q``'s torque constants at the step start and mid-step (:func:`kt_eccentric`);
    a lane without eccentricity computes them too, and its drive ignores them.  The sector
    is stale if the rotor left it: that step is not a fast one."""
    sec = F[_O_SEC + q]
    th = F[_O_THM + q]
    F[_O_KTE + q] = kt_eccentric(sec, th, ke, F[_O_NA + q], F[_O_ZETA + q])
    F[_O_KTM + q] = kt_eccentric(sec, th + 0.5 * h * F[_O_WM + q], ke, F[_O_NA + q],
                                 F[_O_ZETA + q])


@njit(cache=True, inline="always", error_model="numpy")
def _drive_fast_lane(F, q, dc0, cc0, h, c, tick):
    """Lane ``q``'s controller sample (if ``tick``) and drive step inside one sector
    (:func:`drive_fast`, an eccentric lane with its torque constants from ``_O_KTE`` and
    ``_O_KTM``, plus the lane's cogging torque, 0.0 without cogging as in the scalar kernel);
    a lane whose step is not such a step is marked for :func:`drive_step_general`.

    The ramp divides once (``one_division``): the scalar kernel's bits while the bus voltage
    exceeds the pair's back-EMF and resistive drop; a step where it does not (not reached
    inside the bounds) is marked too, so the general path computes it the scalar way."""
    if tick:
        cc = CtrlConsts(F[_O_KPOS + q], cc0.w_max, cc0.kpv, cc0.kiv, cc0.t_max, cc0.dtc,
                        cc0.amps_per_nm)
        i_ref, integ = ace_update(c, F[_O_FB + q], F[_O_WM + q], F[_O_INTEG + q], cc)
        F[_O_IREF + q] = i_ref
        F[_O_INTEG + q] = integ
    else:
        i_ref = F[_O_IREF + q]
    ecc = F[_O_ECC + q] != 0.0
    kt = F[_O_KTE + q] if ecc else F[_O_KT + q]
    kt_mid = F[_O_KTM + q] if ecc else kt
    cur = F[_O_CUR + q]
    fast, cur1, t_mean, t_start, t_end, t_rip, i_eq = drive_fast(
        cur, F[_O_TRT0 + q], F[_O_TRLEN + q], F[_O_THLO + q], kt, kt_mid, F[_O_RP + q],
        F[_O_IL + q], i_ref, F[_O_THM + q], F[_O_WM + q], dc0, True)
    back = kt * F[_O_WM + q] + F[_O_RP + q] * cur   # as drive_fast computes it
    fast &= (back < dc0.v_dc) & (-dc0.v_dc < back)
    t_cog = F[_O_TCOG + q]
    F[_O_DSLOW + q] = 0.0 if fast else 1.0
    F[_O_CUR + q] = cur1 if fast else cur
    F[_O_TRT0 + q] = F[_O_TRT0 + q] - h if fast else F[_O_TRT0 + q]
    F[_O_TM + q] = t_mean + t_cog
    F[_O_TM0 + q] = t_start + t_cog
    F[_O_TM1 + q] = t_end + t_cog
    F[_O_TRIP + q] = t_rip
    F[_O_IEQ + q] = i_eq


@njit(cache=True, inline="always", error_model="numpy")
def _lane_mech_consts(F, q, mc0):
    """Lane ``q``'s mechanics constants: lane 0's where no fault or lane effect changes them,
    the lane's own from ``F`` where one does (what :func:`mech_fast` reads; reading them
    per lane costs a tier-4 group nothing measurable, and one loop compiles faster than
    two)."""
    return MechConsts(mc0.tau, mc0.jm, mc0.ju, F[_O_K + q], mc0.c, F[_O_CM + q], F[_O_KA + q],
                      mc0.cu, mc0.fst, F[_O_FDYN + q], F[_O_HALF + q], mc0.w_stick,
                      mc0.th_stop, mc0.k_stop, mc0.c_stop, mc0.h, F[_O_BC + q], F[_O_GH + q],
                      F[_O_I11 + q], F[_O_I12 + q], F[_O_I22 + q], mc0.i_u_stuck,
                      F[_O_IMF + q], F[_O_IUF + q], F[_O_I11H + q], F[_O_I12H + q],
                      F[_O_IMFH + q])


@njit(cache=True, inline="always", error_model="numpy")
def _mech_fast_lane(F, q, mc):
    """Lane ``q``'s sliding mechanics (:func:`mech_fast`) under constants ``mc``; a lane
    whose step is not such a step is marked for :func:`mech_step_general`."""
    fast, th_m1, wm1, th_u1, wu1, m_thm, m_wm, m_thu = mech_fast(
        F[_O_THM + q], F[_O_WM + q], F[_O_THU + q], F[_O_WU + q], F[_O_TM + q], 0.0,
        F[_O_HALF + q], F[_O_FDYN + q], mc)
    F[_O_MSLOW + q] = 0.0 if fast else 1.0
    F[_O_THM + q] = th_m1 if fast else F[_O_THM + q]
    F[_O_WM + q] = wm1 if fast else F[_O_WM + q]
    F[_O_THU + q] = th_u1 if fast else F[_O_THU + q]
    F[_O_WU + q] = wu1 if fast else F[_O_WU + q]
    # a window sum starts at +0 and so is never -0: adding 0.0 leaves it exact
    F[_O_A0 + q] += m_thu if fast else 0.0
    F[_O_A1 + q] += m_thm if fast else 0.0
    F[_O_A2 + q] += m_wm if fast else 0.0
    F[_O_A3 + q] += F[_O_IEQ + q] if fast else 0.0


@njit(parallel=True, cache=True, error_model="numpy")
def lanes_parallel(p, X, E, groups, cmd, cmd_start, n_out, out_start, ticks_out, steps_tick,
                   dt, out, ok):
    """:func:`lane_group` over the rows of ``groups`` (n_groups, LANES), in parallel."""
    for g in prange(groups.shape[0]):
        lane_group(p, X, E, groups[g], cmd, cmd_start, n_out, out_start, ticks_out, steps_tick,
                   dt, out, ok)


@njit(cache=True, error_model="numpy")
def lanes_serial(p, X, E, groups, cmd, cmd_start, n_out, out_start, ticks_out, steps_tick,
                 dt, out, ok):
    """As :func:`lanes_parallel`, on the calling thread."""
    for g in range(groups.shape[0]):
        lane_group(p, X, E, groups[g], cmd, cmd_start, n_out, out_start, ticks_out, steps_tick,
                   dt, out, ok)


def lane_groups(rows: np.ndarray) -> np.ndarray:
    """Candidate indices ``rows`` in groups of ``LANES`` (n_groups, LANES); the last group is
    filled up by repeating its last candidate."""
    rows = np.asarray(rows, dtype=np.int64)
    n_groups = -(-rows.size // LANES)
    padded = np.concatenate([rows, np.full(n_groups * LANES - rows.size, rows[-1])])
    return padded.reshape(n_groups, LANES)
