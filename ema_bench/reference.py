"""The reference model: the detailed EMA that plays the real actuator.

Three-phase BLDC with hysteresis current control at a 1 microsecond step, sampled controller,
2-DOF mechanics with backlash and friction, sensors.  It runs once per episode to make the
"measured" traces.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from numba import njit

from .effects import (
    E_ECC,
    E_VISC,
    MAX_DELAY_SAMPLES,
    N_EFFECTS,
    effects_to_dict,
    effects_vector,
)
from .faults import check_faults, faults_to_dict
from .params import DEFAULT_PARAMS, EMAParams
from .physics.ace import ace_update, delayed_feedback
from .physics.bldc import bldc_step
from .physics.effect_terms import cogging_torque, effect_terms
from .physics.load import hinge_moment
from .physics.mechanics import mech_step
from .physics.sensors import measure
from .protocol import STANDARD_TESTS, TestSpec, steps_per
from .seeding import SeedLike, children, seed_repr
from .traces import OUTPUT_DT, Traces


@njit(cache=True)
def reference_kernel(p, x, e, cmd, n_out, steps_out, steps_ctrl, dt, out):
    """Integrate one test; write window means of the 4 outputs into ``out`` (n_out, 4).

    Returns False if the state became non-finite (the caller scores that as a failure)."""
    na, fst, blk, gprop = x[0], x[1], x[2], x[3]
    offset, gain, v_dc, r_scale, ks_scale, n_delay = effect_terms(e, p)
    buf = np.zeros(MAX_DELAY_SAMPLES + 1)
    th_m = w_m = th_u = w_u = 0.0
    ia = ib = ic = 0.0
    sa = sb = sc = 0
    i_ref = integ = 0.0
    k_ctrl = 0
    countdown = 0
    for k in range(n_out):
        a0 = a1 = a2 = a3 = 0.0
        for _ in range(steps_out):
            if countdown == 0:
                fb = delayed_feedback(buf, k_ctrl, th_u + offset, n_delay)
                i_ref, integ = ace_update(cmd[k_ctrl], fb, w_m, integ, gprop, p)
                k_ctrl += 1
                countdown = steps_ctrl
            countdown -= 1
            ia, ib, ic, sa, sb, sc, t_m = bldc_step(ia, ib, ic, sa, sb, sc, i_ref, th_m, w_m,
                                                    na, e[E_ECC], r_scale, v_dc, p, dt)
            t_m += cogging_torque(e, th_m, p)
            t_load = hinge_moment(th_u, w_u, p, e)
            th_m, w_m, th_u, w_u, _ = mech_step(th_m, w_m, th_u, w_u, t_m, t_load, fst, blk,
                                                e[E_VISC], ks_scale, p, dt)
            a0 += th_u
            a1 += th_m
            a2 += w_m
            a3 += abs(ia) + abs(ib) + abs(ic)
        out[k, 0] = a0 / steps_out + offset
        out[k, 1] = a1 / steps_out
        out[k, 2] = a2 / steps_out
        out[k, 3] = gain * 0.5 * a3 / steps_out
        if not (math.isfinite(a0) and math.isfinite(a2) and math.isfinite(a3)):
            return False
    return True


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
    steps_out = steps_per(OUTPUT_DT, dt)
    steps_ctrl = steps_per(params.dt_ctrl, dt)
    kids = children(seed, len(tests)) if noise else [None] * len(tests)
    data = {}
    for spec, kid in zip(tests, kids):
        out = np.empty((spec.n_samples(), 4))
        cmd = spec.command_at_samples(params.dt_ctrl)
        ok = reference_kernel(p, x, e, cmd, out.shape[0], steps_out, steps_ctrl, dt, out)
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

