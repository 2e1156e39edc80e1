"""The term dictionary (:mod:`ema_bench.terms`) and the outside-library physics inside the
integrators.

Both plants (:mod:`ema_bench.monitor_plant`, :mod:`ema_bench.reference`) read the dictionary's
coefficients through :func:`term_consts` once per candidate and, only when one is on, add
:func:`extra_torques` to the motor torque and to the explicit surface torque of the step, so
a term means the same thing in the model that makes data and in the model that fits it, and
with every term off no operation changes (the outputs stay bit for bit what they were).
"""

from __future__ import annotations

import math

from numba import njit

from ..effects import E_KPOS, E_KTSAT, E_STRIBECK, E_TERM0
from ..params import P_KE
from ..terms import (
    N_TERMS,
    SIGN_SPEED_MOTOR,
    SIGN_SPEED_SURFACE,
    STIFFNESS_ANGLE,
    STRIBECK_SPEED,
)
from .trig import poly_sincos


@njit(cache=True, error_model="numpy")
def term_consts(e, p):
    """``(on, c, 1/K_t)``: whether any dictionary term is on, the coefficients (a view of the
    effects vector ``e``, :data:`~ema_bench.terms.TERMS` order) and the inverse of the
    nominal torque constant ``2 Ke`` (A/N m; the terms' current is the drive's torque over
    it, signed, where the recorded ``i_eq`` is a magnitude)."""
    c = e[E_TERM0:E_TERM0 + N_TERMS]
    on = False
    for v in c:
        if v != 0.0:
            on = True
    return on, c, 1.0 / (2.0 * p[P_KE])


@njit(cache=True, inline="always", error_model="numpy")
def extra_torques(th_m, w_m, th_u, w_u, i, pp, c):
    """The dictionary's torques at the step-start state, N m: ``(motor, surface)``.

    ``th_m``, ``w_m``: motor angle (rad) and speed (rad/s); ``th_u``, ``w_u``: the surface's;
    ``i``: the drive's torque current (A, signed: its step-mean torque over the nominal
    torque constant); ``pp``: pole pairs (the electrical angle is
    ``pp th_m``); ``c``: the coefficients (:data:`~ema_bench.terms.TERMS` order: each term's
    basis function times its coefficient, summed per equation; the Stribeck form, slot 19,
    is added last so that the other terms' sums keep their rounding)."""
    s1, c1 = poly_sincos(th_m)
    se, ce = poly_sincos(pp * th_m)
    s2, c2 = poly_sincos(2.0 * pp * th_m)
    motor = (c[0] * (w_m * w_m) + c[1] * (w_m * abs(w_m))
             + c[2] * math.tanh(w_m / SIGN_SPEED_MOTOR) + c[3] * i + c[4] * (i * i)
             + c[5] * (i * abs(i)) + c[6] * s1 + c[7] * c1 + c[8] * se + c[9] * ce
             + c[10] * s2 + c[11] * c2
             + c[19] * (stribeck_decay(w_m) * math.tanh(w_m / SIGN_SPEED_MOTOR)))
    surface = (c[12] * w_u + c[13] * (th_u * th_u) + c[14] * (th_u * w_u) + c[15] * (w_u * w_u)
               + c[16] * (th_u * abs(th_u)) + c[17] * (w_u * abs(w_u))
               + c[18] * math.tanh(w_u / SIGN_SPEED_SURFACE))
    return motor, surface


@njit(cache=True, error_model="numpy")
def outside_consts(e):
    """The reference-only physics outside the library (:data:`~ema_bench.effects.OUTSIDE`):
    ``(F_s, k_pos, k_sat)``, the Stribeck peak (N m), the stiffness loss at full level and
    the torque constant's fall per ampere (1/A); 0 = off."""
    return e[E_STRIBECK], e[E_KPOS], e[E_KTSAT]


@njit(cache=True, inline="always", error_model="numpy")
def stribeck_decay(w_m):
    """The Stribeck curve's decay with the motor speed ``w_m`` (rad/s): ``exp(-(w_m/w_s)^2)``."""
    v = w_m / STRIBECK_SPEED
    return math.exp(-(v * v))


@njit(cache=True, inline="always", error_model="numpy")
def stribeck(f_s, w_m):
    """The Stribeck peak of the motor's dry friction at speed ``w_m`` (rad/s), N m, opposing
    the motion: ``F_s exp(-(w_m/w_s)^2) tanh(w_m/w_0)``."""
    return f_s * stribeck_decay(w_m) * math.tanh(w_m / SIGN_SPEED_MOTOR)


@njit(cache=True, inline="always", error_model="numpy")
def stiffness_level(th_u):
    """The transmission stiffness loss's level at surface angle ``th_u`` (rad), 0..1 in 256
    steps: ``min((th_u / angle)^2, 1)`` rounded down."""
    v = th_u / STIFFNESS_ANGLE
    return math.floor(min(v * v, 1.0) * 256.0) / 256.0
