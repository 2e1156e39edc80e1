"""External load on the surface: aerodynamic hinge moment.

Linear hinge moment ``-K_aero theta_u - C_u w_u`` (aerodynamic spring and damping of the surface,
DESIGN section 8).  The spring keeps the reducer loaded on one side of its backlash.
"""

from __future__ import annotations

from numba import njit

from ..params import P_CU, P_KAERO


@njit(cache=True)
def hinge_moment(theta_u, w_u, p, k_extra):
    """Aerodynamic hinge moment on the surface, N m.

    ``k_extra`` (N m/rad) adds to the hinge-moment spring (the ``aero_spring`` effect).
    """
    return -(p[P_KAERO] + k_extra) * theta_u - p[P_CU] * w_u
