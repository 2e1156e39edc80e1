"""The one integrator skeleton of both models: controller tick, plant steps, window outputs.

The reference model (:mod:`ema_bench.reference`) and the monitor model
(:mod:`ema_bench.monitor`) differ only in their *plant*: the drive (three-phase hysteresis or
its averaged pair) and the step (1 or 50 microseconds).  Everything around the plant, the
sampled controller with zero-order hold, the sensor effects in the loop and the 1 ms window
means of the recorded outputs, is this function, so the two models cannot drift apart.

A plant is three compiled functions passed in as arguments; each model's kernel inlines the
skeleton (``inline="always"``), so the plant's calls are direct calls the compiler can inline
and the kernels stay cacheable:

``plant_consts(p, x, e, dt) -> pc``
    per-candidate constants from the parameter array ``p``, the fault vector ``x`` and the
    effects vector ``e``, for step ``dt`` (s);
``plant_init(pc) -> ps``
    the plant's own state (the drive's) at rest;
``plant_step(th_m, w_m, th_u, w_u, ps, i_ref, pc) -> (th_m, w_m, th_u, w_u, ps, mean_th_u,
mean_th_m, mean_w_m, mean_i_eq)``
    one step under the current reference ``i_ref`` (A), returning the new mechanical state,
    the new plant state and the step means of the four recorded signals.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..effects import MAX_DELAY_SAMPLES
from ..faults import F_GPROP
from .ace import ace_consts, ace_update, delayed_feedback
from .effect_terms import sensor_terms
from .extra_terms import angle_error, current_error, position_error, sensor_consts


@njit(cache=True, inline="always", error_model="numpy")
def integrate(plant_consts, plant_init, plant_step, p, x, e, cmd, n_out, ticks_out,
              steps_tick, dt, out):
    """Integrate one candidate on one test; window means of the outputs into ``out``.

    Parameters
    ----------
    plant_consts, plant_init, plant_step
        The plant (see the module docstring).
    p : ndarray
        Parameter array (:mod:`ema_bench.params`).
    x : ndarray (4,)
        Fault vector ``Na, Fst, BLK, Gprop``.
    e : ndarray (N_EFFECTS,)
        Effects vector.
    cmd : ndarray
        rad, surface command at every controller sample.
    n_out : int
        Output windows (1 ms each).
    ticks_out, steps_tick : int
        Controller samples per window, plant steps per controller sample.
    dt : float
        s, plant step.
    out : ndarray (n_out, 4)
        Surface position (rad), motor angle (rad), motor speed (rad/s), equivalent current
        (A): each window's mean.

    Returns
    -------
    bool
        False if the state became non-finite (the caller scores that as a failure).
    """
    pc = plant_consts(p, x, e, dt)
    cc = ace_consts(p, x[F_GPROP])
    offset, gain, delay = sensor_terms(e, p)
    # the sensors' dictionary terms (and the resolver's outside-library harmonic): each
    # branch is taken only when one is on, so without them nothing changes
    s_ang, s_pos, s_cur, sc = sensor_consts(e)
    buf = np.empty(MAX_DELAY_SAMPLES + 1)
    ps = plant_init(pc)
    th_m = w_m = th_u = w_u = 0.0
    integ = 0.0
    k_ctrl = 0
    scale = 1.0 / (ticks_out * steps_tick)
    for k in range(n_out):
        a0 = a1 = a2 = a3 = 0.0
        for _ in range(ticks_out):
            fb = th_u + offset   # the loop sees the same (offset) position sensor
            if s_pos:
                fb += position_error(th_u, sc)
            if delay > 0.0:
                fb = delayed_feedback(buf, k_ctrl, fb, delay)
            w_fb = w_m
            if s_ang:   # the speed feedback is the measured angle's rate
                w_fb = w_m * (1.0 + angle_error(th_m, sc)[1])
            i_ref, integ = ace_update(cmd[k_ctrl], fb, w_fb, integ, cc)
            if s_cur:   # the drive holds its sensor's reading at i_ref: i + err(i) = i_ref
                i_ref -= current_error(i_ref, sc)
            k_ctrl += 1
            for _ in range(steps_tick):
                th_m, w_m, th_u, w_u, ps, m0, m1, m2, m3 = plant_step(th_m, w_m, th_u, w_u,
                                                                      ps, i_ref, pc)
                a0 += m0
                a1 += m1
                a2 += m2
                a3 += m3
                if s_ang:   # the recorded angle and speed: the resolver's, step by step
                    err, slope = angle_error(m1, sc)
                    a1 += err
                    a2 += m2 * slope
        out[k, 0] = a0 * scale + offset
        out[k, 1] = a1 * scale
        out[k, 2] = a2 * scale
        out[k, 3] = gain * a3 * scale
        if s_pos:   # on the window mean (the surface moves < 3 mrad in a window)
            out[k, 0] += position_error(a0 * scale, sc)
        if s_cur:
            out[k, 3] += gain * current_error(a3 * scale, sc)
        if not (math.isfinite(a0) and math.isfinite(a1) and math.isfinite(a2)
                and math.isfinite(a3)):
            return False
    return True
