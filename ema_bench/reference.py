"""The reference model: the detailed EMA that plays the real actuator.

Three-phase BLDC with analog hysteresis current control (switching located inside the step) at
a 1 microsecond step, the sampled controller, 2-DOF mechanics with backlash and friction, and
sensors.  The controller, the mechanics and the window outputs are the same compiled code as in
the monitor (:mod:`ema_bench.physics.integrator`).  It runs once per episode to make the
"measured" traces.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numba import njit

from .effects import N_EFFECTS, effects_to_dict, effects_vector
from .faults import F_BLK, F_FST, F_NA, check_faults, faults_to_dict
from .params import DEFAULT_PARAMS, P_LIBM, P_PP, EMAParams
from .physics.bldc import bldc_consts, bldc_step, commutation
from .physics.effect_terms import cogging_torque, plant_terms
from .physics.extra_terms import (
    extra_torques,
    loop_voltage,
    outside_consts,
    outside_loop_consts,
    stiffness_level,
    stribeck,
    term_consts,
)
from .physics.integrator import integrate
from .physics.load import hinge_extra
from .physics.mechanics import mech_consts, mech_step
from .physics.sensors import measure
from .protocol import STANDARD_TESTS, TestSpec, steps_per
from .seeding import SeedLike, children, seed_repr
from .traces import OUTPUT_DT, Traces


# --- the reference plant ------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def reference_consts(p, x, e, dt):
    """Per-candidate constants of the reference plant (three-phase drive, mechanics, effects)."""
    zeta, v_dc, r_scale, ks_scale, c_visc, k_aero, cog, quad, hfric = plant_terms(e, p)
    bc = bldc_consts(p, x[F_NA], zeta, r_scale, v_dc)
    mc = mech_consts(p, x[F_FST], x[F_BLK], c_visc, k_aero, ks_scale, dt)
    on, c, inv_kt, v_on = term_consts(e, p)
    # the outside-library physics (the monitor has none of it) and what a position-dependent
    # transmission stiffness recomputes the mechanics' constants from
    out = outside_consts(e)
    v_dt, _ = outside_loop_consts(e)   # (the resolver's error is a sensor's: integrator)
    return (bc, mc, cog, p[P_PP], quad, hfric, dt, on, c, inv_kt, out,
            (p, x[F_FST], x[F_BLK], c_visc, k_aero, ks_scale), p[P_LIBM] != 0.0, v_on, v_dt)


@njit(cache=True, error_model="numpy")
def reference_init(pc):
    """Drive state at rest: no phase current, every leg off; the mechanics' constants at
    stiffness level 0."""
    return 0.0, 0.0, 0.0, 0, 0, 0, pc[1], 0.0


@njit(cache=True, inline="always", error_model="numpy")
def reference_step(th_m, w_m, th_u, w_u, ps, i_ref, pc):
    """One 1 microsecond step of the reference plant (see
    :mod:`ema_bench.physics.integrator`)."""
    bc, _, cog, pp, quad, hfric, dt, on, c, inv_kt, (f_s, k_pos, k_sat), mk, libm, v_on, \
        v_dt = pc
    ia, ib, ic, sa, sb, sc, mc, level = ps
    v_pair = 0.0
    if v_on:   # the current loop's dictionary terms at the pair current
        ca, cb, cc = commutation(pp * th_m)
        v_pair = loop_voltage(0.5 * (ca * ia + cb * ib + cc * ic), w_m, th_m, pp, c)
    ia, ib, ic, sa, sb, sc, t_mean, t_start, t_end, i_eq = bldc_step(
        ia, ib, ic, sa, sb, sc, i_ref, th_m, w_m, bc, dt, v_pair, v_dt)
    if k_sat != 0.0:   # torque constant K_t (1 - k_sat |i|)
        f = 1.0 - k_sat * abs(i_eq)
        t_mean, t_start, t_end = t_mean * f, t_start * f, t_end * f
    t_cog = cogging_torque(cog, th_m + 0.5 * dt * w_m, pp, libm)
    t_ext = hinge_extra(w_u, quad, hfric)
    if on:
        t_m_x, t_u_x = extra_torques(th_m, w_m, th_u, w_u, t_mean * inv_kt, pp, c)
        t_cog += t_m_x
        t_ext += t_u_x
    if f_s != 0.0:
        t_cog -= stribeck(f_s, w_m)
    if k_pos != 0.0:
        # the stiffness in 256 levels of (th_u / angle)^2: the constants are recomputed
        # only when the surface crosses a level
        new = stiffness_level(th_u)
        if new != level:
            level = new
            mc = mech_consts(mk[0], mk[1], mk[2], mk[3], mk[4],
                             mk[5] * (1.0 - k_pos * level), dt)
    th_m, w_m, th_u, w_u, m_thm, m_wm, m_thu = mech_step(
        th_m, w_m, th_u, w_u, t_mean + t_cog, t_start + t_cog, t_end + t_cog, 0.0,
        t_ext, mc)
    return th_m, w_m, th_u, w_u, (ia, ib, ic, sa, sb, sc, mc, level), m_thu, m_thm, m_wm, i_eq


@njit(cache=True, error_model="numpy")
def reference_kernel(p, x, e, cmd, n_out, ticks_out, steps_tick, dt, out):
    """Integrate one test; window means of the 4 outputs into ``out`` (n_out, 4).

    Returns False if the state became non-finite."""
    return integrate(reference_consts, reference_init, reference_step, p, x, e, cmd, n_out,
                     ticks_out, steps_tick, dt, out)


class SimulationError(RuntimeError):
    """A simulation produced non-finite states."""


def simulate_reference(
    faults: np.ndarray | Mapping[str, float],
    effects: np.ndarray | Mapping[str, float] | None = None,
    *,
    tests: Sequence[TestSpec] = STANDARD_TESTS,
    params: EMAParams = DEFAULT_PARAMS,
    seed: SeedLike = None,
    noise: bool = True,
    adc: bool = True,
    dt: float | None = None,
) -> Traces:
    """Simulate the reference (detailed) EMA on the given tests.

    Parameters
    ----------
    faults : array (4,) or mapping
        True fault vector ``Na, Fst (N m), BLK (rad), Gprop (1/s)``.
    effects : array (N_EFFECTS,) or mapping, optional
        Switched-on effects (:mod:`ema_bench.effects`); off by default.
    seed : int or SeedSequence, optional
        Root of the sensor noise; each test gets its own spawned child.  ``None`` with
        ``noise=True`` raises, so noise is never unseeded.
    noise, adc : bool
        Apply sensor noise / ADC quantisation to the outputs.
    dt : float, optional
        Integration step (s); default ``params.dt_ref``.

    Returns
    -------
    Traces
        Window-averaged outputs at 1 kHz, one array (n, 4) per test.
    """
    x = check_faults(faults)
    e = effects if isinstance(effects, np.ndarray) else effects_vector(effects)
    if e.shape != (N_EFFECTS,):
        raise ValueError(f"effects vector must have shape ({N_EFFECTS},), got {e.shape}")
    if noise and seed is None:
        raise ValueError("sensor noise needs a seed (pass seed=..., or noise=False)")
    p = params.to_array()
    dt = params.dt_ref if dt is None else float(dt)
    ticks_out = steps_per(OUTPUT_DT, params.dt_ctrl)
    steps_tick = steps_per(params.dt_ctrl, dt)
    kids = children(seed, len(tests)) if noise else [None] * len(tests)
    data = {}
    for spec, kid in zip(tests, kids):
        out = np.empty((spec.n_samples(), 4))
        cmd = spec.command_at_samples(params.dt_ctrl)
        ok = reference_kernel(p, x, e, cmd, out.shape[0], ticks_out, steps_tick, dt, out)
        if not ok:
            raise SimulationError(f"reference model diverged on test {spec.name!r} at "
                                  f"faults {faults_to_dict(x)}")
        rng = np.random.default_rng(kid) if kid is not None else None
        data[spec.name] = measure(out, rng, noise=noise, adc=adc)
    meta = {"model": "reference", "faults": faults_to_dict(x),
            "effects": effects_to_dict(e),
            "seed": seed_repr(seed), "noise": noise, "adc": adc,
            "dt": dt}
    return Traces(data=data, dt=OUTPUT_DT, meta=meta)

