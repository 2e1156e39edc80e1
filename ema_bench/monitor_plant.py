"""The monitor plant: per-candidate constants, rest state and one 50 microsecond step.

The blocks the integrator (:mod:`ema_bench.physics.integrator`) runs for the monitor model, in
a leaf module of their own so that both batched kernels, the scalar one of
:mod:`ema_bench.monitor` and the lock-step lanes of :mod:`ema_bench.monitor_lanes`, import
them without importing each other.
"""

from __future__ import annotations

from numba import njit

from .faults import F_BLK, F_FST, F_NA
from .params import P_PP
from .physics.averaged_drive import drive_consts, drive_step, sector_index
from .physics.effect_terms import cogging_torque, plant_terms
from .physics.extra_terms import extra_torques, loop_voltage, term_consts
from .physics.load import hinge_extra
from .physics.mechanics import mech_consts, mech_step


@njit(cache=True, error_model="numpy")
def monitor_consts(p, x, e, dt):
    """Per-candidate constants of the monitor plant (drive, mechanics, effects)."""
    zeta, v_dc, r_scale, ks_scale, c_visc, k_aero, cog, quad, hfric = plant_terms(e, p)
    dc = drive_consts(p, x[F_NA], zeta, r_scale, v_dc, dt)
    mc = mech_consts(p, x[F_FST], x[F_BLK], c_visc, k_aero, ks_scale, dt)
    on, c, inv_kt, v_on = term_consts(e, p)
    return dc, mc, cog, p[P_PP], quad, hfric, on, c, inv_kt, v_on


@njit(cache=True, error_model="numpy")
def monitor_init(pc):
    """Drive state at rest: no current, the sector of angle 0, no commutation in progress."""
    return 0.0, sector_index(0.0, pc[3]), -1.0, 0.0, 0.0, 0.0, 0.0


@njit(cache=True, inline="always", error_model="numpy")
def monitor_step(th_m, w_m, th_u, w_u, ps, i_ref, pc):
    """One 50 microsecond step of the monitor plant (see :mod:`ema_bench.physics.integrator`)."""
    dc, mc, cog, pp, quad, hfric, on, c, inv_kt, v_on = pc
    cur, m, tr_t0, tr_len, kt_from, kt_to, tr_cr = ps
    # the current loop's dictionary terms at the step start's pair current (0 V: off)
    v_x = loop_voltage(cur, w_m, th_m, pp, c) if v_on else 0.0
    (cur, m, tr_t0, tr_len, kt_from, kt_to, tr_cr, t_mean, t_start, t_end, t_rip,
     i_eq) = drive_step(cur, m, tr_t0, tr_len, kt_from, kt_to, tr_cr, i_ref, th_m, w_m, dc,
                        v_x)
    t_cog = cogging_torque(cog, th_m + 0.5 * dc.h * w_m, pp, dc.libm)
    t_ext = hinge_extra(w_u, quad, hfric)
    if on:   # dictionary terms (diagnosis only): nothing changes without them
        t_m_x, t_u_x = extra_torques(th_m, w_m, th_u, w_u, t_mean * inv_kt, pp, c)
        t_cog += t_m_x
        t_ext += t_u_x
    th_m, w_m, th_u, w_u, m_thm, m_wm, m_thu = mech_step(
        th_m, w_m, th_u, w_u, t_mean + t_cog, t_start + t_cog, t_end + t_cog, t_rip,
        t_ext, mc)
    return (th_m, w_m, th_u, w_u, (cur, m, tr_t0, tr_len, kt_from, kt_to, tr_cr), m_thu, m_thm,
            m_wm, i_eq)
