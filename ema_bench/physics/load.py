"""External load on the surface: aerodynamic hinge moment.

Linear hinge moment ``-K_aero theta_u - C_u w_u`` (aerodynamic spring and damping of the surface,
DESIGN section 8).  The spring keeps the reducer loaded on one side of its backlash.  The linear
part is integrated implicitly by :func:`ema_bench.physics.mechanics.mech_step` (its constants
come from :func:`~ema_bench.physics.mechanics.mech_consts`, the ``aero_spring`` effect adding
to the spring); :func:`hinge_extra` holds the nonlinear terms, which enter explicitly.
"""

from __future__ import annotations

import math

from numba import njit

HINGE_FRICTION_SPEED = 0.01  # rad/s, smoothing of the hinge-friction sign


@njit(cache=True, inline="always", error_model="numpy")
def hinge_extra(w_u, quad_damping, hinge_friction):
    """Nonlinear hinge moment on the surface, N m: the decoy effects ``quadratic_damping``
    (``-c w |w|``, N m s^2/rad^2) and ``hinge_friction`` (smoothed Coulomb, N m), which lie
    outside the missing-physics library (0 = off)."""
    m = 0.0
    if quad_damping != 0.0:
        m -= quad_damping * w_u * abs(w_u)
    if hinge_friction != 0.0:
        m -= hinge_friction * math.tanh(w_u / HINGE_FRICTION_SPEED)
    return m
