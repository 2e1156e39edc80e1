"""What the switchable effects (:mod:`ema_bench.effects`) change inside the integrators.

Both the reference and the monitor read an effects vector through these functions, once per
candidate, so an effect means the same thing in the model that makes data and in the model that
fits it.  The per-step blocks then take plain scalars.
"""

from __future__ import annotations

import math

from numba import njit

from ..effects import (
    E_AERO,
    E_COG,
    E_DELAY,
    E_ECC,
    E_GEAR,
    E_HFRIC,
    E_IGAIN,
    E_OFFSET,
    E_QDAMP,
    E_RRISE,
    E_VISC,
    E_VSAG,
)
from ..params import P_DTC, P_VDC
from .trig import poly_sin


@njit(cache=True, error_model="numpy")
def sensor_terms(e, p):
    """Effects on the sensors and the controller.

    Returns
    -------
    offset : float
        rad, surface-position sensor offset (in the loop and in the record).
    gain : float
        gain of the recorded current channel.
    delay : float
        position-feedback delay in controller samples (fractional).
    """
    return e[E_OFFSET], 1.0 + e[E_IGAIN], e[E_DELAY] / p[P_DTC]


@njit(cache=True, error_model="numpy")
def plant_terms(e, p):
    """Effects on the drive, the motor and the mechanics.

    Returns
    -------
    zeta : float
        static rotor eccentricity.
    v_dc : float
        V, bus voltage after sag.
    r_scale, ks_scale : float
        multipliers of the winding resistance and of the transmission stiffness.
    c_m_extra, k_aero_extra : float
        N m s/rad extra motor viscous friction; N m/rad extra hinge spring.
    cogging : float
        N m, cogging torque amplitude.
    quad_damping, hinge_friction : float
        decoys: N m s^2/rad^2, N m.
    """
    return (e[E_ECC], p[P_VDC] * (1.0 - e[E_VSAG]), 1.0 + e[E_RRISE], 1.0 - e[E_GEAR],
            e[E_VISC], e[E_AERO], e[E_COG], e[E_QDAMP], e[E_HFRIC])


@njit(cache=True, inline="always", error_model="numpy")
def cogging_wave(amplitude, th_m, pole_pairs):
    """Cogging torque (N m) at motor angle ``th_m`` (rad), amplitude ``amplitude`` (N m): 6
    periods per pole pair and turn (the 12-slot, 4-pole motor).  Branch-free (the sine is
    :func:`~ema_bench.physics.trig.poly_sin`), so the lanes vectorise it; an amplitude of 0
    gives a signed zero, which :func:`cogging_torque` replaces by +0."""
    return amplitude * poly_sin(6.0 * pole_pairs * th_m)


@njit(cache=True, inline="always", error_model="numpy")
def cogging_torque(amplitude, th_m, pole_pairs, libm):
    """Cogging torque (N m) at motor angle ``th_m`` (rad): :func:`cogging_wave`, exactly
    +0.0 without cogging (no sine computed); with ``libm`` (model version 2, the parameter
    ``libm_trig``) libm's sine, as that version computed it."""
    if amplitude == 0.0:
        return 0.0
    if libm:
        return amplitude * math.sin(6.0 * pole_pairs * th_m)
    return cogging_wave(amplitude, th_m, pole_pairs)
