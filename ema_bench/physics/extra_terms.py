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

from ..effects import E_DEADTIME, E_KPOS, E_KTSAT, E_RESOLVER2, E_STRIBECK, E_TERM0
from ..params import P_KE
from ..terms import (
    EMF_ORDER,
    N_TERMS,
    SIGN_CURRENT,
    SIGN_SPEED_MOTOR,
    SIGN_SPEED_SURFACE,
    STIFFNESS_ANGLE,
    STRIBECK_SPEED,
    T_CURRENT0,
    T_SENSOR0,
)
from .trig import poly_sincos


@njit(cache=True, error_model="numpy")
def term_consts(e, p):
    """``(on, c, 1/K_t, v_on)``: whether any torque term is on, the coefficients (a view of
    the effects vector ``e``, :data:`~ema_bench.terms.TERMS` order), the inverse of the
    nominal torque constant ``2 Ke`` (A/N m; the terms' current is the drive's torque over
    it, signed, where the recorded ``i_eq`` is a magnitude) and whether any current-loop
    term is on (:func:`loop_voltage`)."""
    c = e[E_TERM0:E_TERM0 + N_TERMS]
    return (_any(c, 0, T_CURRENT0), c, 1.0 / (2.0 * p[P_KE]),
            _any(c, T_CURRENT0, T_SENSOR0))


@njit(cache=True, inline="always", error_model="numpy")
def _any(c, lo, hi):
    """Whether any of ``c[lo:hi]`` is non-zero."""
    for k in range(lo, hi):
        if c[k] != 0.0:
            return True
    return False


@njit(cache=True, inline="always", error_model="numpy")
def loop_voltage(i, w_m, th_m, pp, c):
    """The current loop's dictionary terms (slots ``T_CURRENT0`` on), V: the voltage added to
    the conducting pair's ``L di/dt = v - R i - e``.

    ``i``: the pair current (A, signed), ``w_m``, ``th_m``: motor speed (rad/s) and angle
    (rad), ``pp``: pole pairs; the terms ``tanh(i / 0.5)``, ``i |i|`` and ``w_m`` times the
    sine and cosine of the six-step harmonic ``6 pp th_m``."""
    s6, c6 = poly_sincos(EMF_ORDER * pp * th_m)
    k = T_CURRENT0
    return (c[k] * math.tanh(i / SIGN_CURRENT) + c[k + 1] * (i * abs(i))
            + c[k + 2] * (w_m * s6) + c[k + 3] * (w_m * c6))


@njit(cache=True, error_model="numpy")
def sensor_consts(e):
    """The sensors' dictionary terms (slots ``T_SENSOR0`` on): ``(angle_on, position_on,
    current_on, c)``, whether any term of the motor-angle, the surface-position and the
    current sensor is on, and the coefficients (``e``'s, TERMS order; the reference's
    outside-library resolver harmonic, :data:`~ema_bench.effects.E_RESOLVER2`, added to
    the ``sin(2 th_m)`` slot: the same error)."""
    c = e[E_TERM0:E_TERM0 + N_TERMS]
    k = T_SENSOR0
    if e[E_RESOLVER2] != 0.0:   # the outside-library resolver harmonic: a sin(2 th_m)
        c = c.copy()
        c[k + 2] += e[E_RESOLVER2]
    return _any(c, k, k + 4), _any(c, k + 4, k + 6), _any(c, k + 6, k + 7), c


@njit(cache=True, inline="always", error_model="numpy")
def angle_error(th_m, c):
    """The motor-angle sensor's error at angle ``th_m`` (rad), rad, and its slope
    ``d error / d th_m`` (-): the resolver's first and second harmonics.  The measured speed
    is the measured angle's rate, ``w_m (1 + slope)``."""
    s1, c1 = poly_sincos(th_m)
    s2, c2 = poly_sincos(2.0 * th_m)
    k = T_SENSOR0
    err = c[k] * s1 + c[k + 1] * c1 + c[k + 2] * s2 + c[k + 3] * c2
    slope = c[k] * c1 - c[k + 1] * s1 + 2.0 * (c[k + 2] * c2 - c[k + 3] * s2)
    return err, slope


@njit(cache=True, inline="always", error_model="numpy")
def position_error(th_u, c):
    """The surface-position sensor's error at ``th_u`` (rad), rad: ``th_u^2`` and
    ``th_u |th_u|`` (a potentiometer's or an LVDT's curvature)."""
    k = T_SENSOR0 + 4
    return c[k] * (th_u * th_u) + c[k + 1] * (th_u * abs(th_u))


@njit(cache=True, inline="always", error_model="numpy")
def current_error(i, c):
    """The current sensor's error at ``i`` (A, signed), A: ``i |i|`` (a saturating sensor)."""
    return c[T_SENSOR0 + 6] * (i * abs(i))


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
    """The reference-only physics outside the library (:data:`~ema_bench.effects.OUTSIDE`)
    in the torque balances: ``(F_s, k_pos, k_sat)``, the Stribeck peak (N m), the stiffness
    loss at full level and the torque constant's fall per ampere (1/A); 0 = off."""
    return e[E_STRIBECK], e[E_KPOS], e[E_KTSAT]


@njit(cache=True, error_model="numpy")
def outside_loop_consts(e):
    """The reference-only physics outside the library in the current loop and the sensors:
    ``(V_dt, a_2)``, the inverter's dead-time voltage (V) and the resolver's second-harmonic
    error (rad); 0 = off."""
    return e[E_DEADTIME], e[E_RESOLVER2]


@njit(cache=True, inline="always", error_model="numpy")
def dead_time_voltage(v_dt, i):
    """The voltage error of a phase leg carrying ``i`` (A) in an inverter with dead time:
    ``-V_dt tanh(i / 0.5)``, V (during the dead time the diodes clamp the phase to the rail
    that keeps its current flowing, so the leg's mean voltage lags the command against the
    current's sign)."""
    return -v_dt * math.tanh(i / SIGN_CURRENT)


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
