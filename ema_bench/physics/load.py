"""External load on the surface: aerodynamic hinge moment.

Linear hinge moment ``-K_aero theta_u - C_u w_u`` (aerodynamic spring and damping of the surface,
DESIGN section 8).  The spring keeps the reducer loaded on one side of its backlash.
"""

from __future__ import annotations

import math

from numba import njit

from ..effects import E_AERO, E_HFRIC, E_QDAMP
from ..params import P_CU, P_KAERO

HINGE_FRICTION_SPEED = 0.01  # rad/s, smoothing of the hinge-friction sign


@njit(cache=True)
def hinge_moment(theta_u, w_u, p, e):
    """Hinge moment on the surface, N m: aerodynamic spring and damping, plus effects.

    Effects (``e``, :mod:`ema_bench.effects`): ``aero_spring`` adds to the spring (N m/rad);
    the decoys ``quadratic_damping`` (``-c w|w|``) and ``hinge_friction`` (smoothed Coulomb)
    lie outside the missing-physics library.
    """
    m = -(p[P_KAERO] + e[E_AERO]) * theta_u - p[P_CU] * w_u
    if e[E_QDAMP] != 0.0:
        m -= e[E_QDAMP] * w_u * abs(w_u)
    if e[E_HFRIC] != 0.0:
        m -= e[E_HFRIC] * math.tanh(w_u / HINGE_FRICTION_SPEED)
    return m
