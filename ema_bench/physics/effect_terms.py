"""What the switchable effects (:mod:`ema_bench.effects`) change inside the integrators.

Both the reference and the monitor integrator derive the same terms from an effects vector,
so an effect means the same thing in the model that makes data and in the model that fits it.
"""

from __future__ import annotations

import math

from numba import njit

from ..effects import E_COG, E_DELAY, E_GEAR, E_IGAIN, E_OFFSET, E_RRISE, E_VSAG
from ..params import P_DTC, P_PP, P_VDC


@njit(cache=True)
def effect_terms(e, p):
    """Scalars of an effects vector ``e``.

    Returns
    -------
    offset : float
        rad, surface-position sensor offset (in the loop and in the record).
    gain : float
        gain of the recorded current channel.
    v_dc : float
        V, bus voltage after sag.
    r_scale, ks_scale : float
        multipliers of the winding resistance and of the transmission stiffness.
    delay : float
        position-feedback delay in controller samples (fractional).
    """
    return (e[E_OFFSET], 1.0 + e[E_IGAIN], p[P_VDC] * (1.0 - e[E_VSAG]), 1.0 + e[E_RRISE],
            1.0 - e[E_GEAR], e[E_DELAY] / p[P_DTC])


@njit(cache=True)
def cogging_torque(e, th_m, p):
    """Cogging torque (N m) at motor angle ``th_m``: 6 periods per pole pair and turn (the
    12-slot, 4-pole motor), amplitude the ``cogging`` effect."""
    if e[E_COG] == 0.0:
        return 0.0
    return e[E_COG] * math.sin(6.0 * p[P_PP] * th_m)
