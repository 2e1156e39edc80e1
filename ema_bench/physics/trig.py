"""The monitor's sine and cosine: range reduction and two short polynomials, no libm call.

Why not ``math.sin``: numba compiles it to a scalar libm call (about 20 ns) that LLVM cannot
vectorise, and a tier-12 candidate of suite emafdi-v2 makes five of them a 50 us step
(cogging, and the eccentric torque constant at the step start and mid-step): they made a
tier-12 evaluation five times the cost of a tier-4 one.  These functions are branch-free
arithmetic (``floor``, multiplies, adds and selects), which the lanes kernel
(:mod:`ema_bench.monitor_lanes`) vectorises with the rest of the drive, and which the C twin
(``benchmarks/c/monitor.c``: ``poly_sin``, ``poly_sincos``) repeats operation for operation, so
the scalar kernel, the lanes and C stay bit-identical.

Method (Cody and Waite's reduction, FreeBSD's ``k_sin.c``/``k_cos.c`` kernels):

* ``n = floor(x 2/pi + 1/2)``, ``r = ((x - n P1) - n P2) - n P3`` with ``pi/2 = P1 + P2 + P3 +
  O(1e-31)``, each ``Pi`` of 33 significant bits, so every ``n Pi`` is exact for
  ``|n| < 2**20`` and ``|r| <= pi/4`` carries one rounding;
* the minimax polynomials of ``sin`` (degree 13) and ``cos`` (degree 14) on ``[-pi/4, pi/4]``
  (errors below 2**-58 of the kernels alone);
* the quadrant ``n mod 4`` picks ``+-sin r`` or ``+-cos r``.

Accuracy: within 2.2e-16 of ``math.sin``/``math.cos`` (absolute; their results lie in
[-1, 1]), and within 2 ulp of them where the value exceeds 1e-9 (near the zeros ``k pi/2``
the absolute error is the reduction's, below 1e-25), for ``|x| <= 2**20 pi/2`` (1.6e6 rad).
The model's arguments are motor angles, at most the end stops' 0.45 rad times the reducer's
300 (135 rad), times 12 for cogging (1,620 rad): inside by three orders of magnitude
(``tests/test_trig.py`` checks the bounds on dense grids to 1e5 rad).  Beyond 1.6e6 rad the
result is meaningless (at 1e300 it overflows), where no stable simulation goes; ``inf`` and
``nan`` give ``nan``, as libm does.  A 2e-16 error in a torque constant's eccentric factor
or in a cogging torque is ten orders of magnitude below the sensors' quantisation
(:mod:`ema_bench.physics.sensors`): the trigonometry is not the model's limit, only its cost.
Model version 2 (the parameter ``libm_trig``, ``params.model_params("2")``) keeps libm's calls
at these functions' call sites, so the records made on it replay to the bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# pi/2 in three 33-bit parts (fdlibm's pio2_1, pio2_2, pio2_3)
_P1 = 1.57079632673412561417e+00
_P2 = 6.07710050630396597660e-11
_P3 = 2.02226624871116645580e-21
_TWO_OVER_PI = 6.36619772367581382433e-01
# sin r = r + r^3 (S1 + r^2 (S2 + ... )), |r| <= pi/4 (FreeBSD k_sin.c)
_S1 = -1.66666666666666324348e-01
_S2 = 8.33333333332248946124e-03
_S3 = -1.98412698298579493134e-04
_S4 = 2.75573137070700676789e-06
_S5 = -2.50507602534068634195e-08
_S6 = 1.58969099521155010221e-10
# cos r = 1 - r^2/2 + r^4 (C1 + r^2 (C2 + ...)), |r| <= pi/4 (FreeBSD k_cos.c)
_C1 = 4.16666666666666019037e-02
_C2 = -1.38888888888741095749e-03
_C3 = 2.48015872894767294178e-05
_C4 = -2.75573143513906633035e-07
_C5 = 2.08757232129817482790e-09
_C6 = -1.13596475577881948265e-11


@njit(cache=True, inline="always", error_model="numpy")
def _reduce(x):
    """``(q, s, c)``: with ``x = n pi/2 + r``, ``q = n mod 4`` (0.0 .. 3.0) and the kernels'
    ``s = sin r``, ``c = cos r``."""
    n = np.floor(x * _TWO_OVER_PI + 0.5)
    r = ((x - n * _P1) - n * _P2) - n * _P3
    q = n - 4.0 * np.floor(n * 0.25)
    z = r * r
    s = r + (z * r) * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))))
    hz = 0.5 * z
    w = 1.0 - hz
    c = w + (((1.0 - w) - hz)
             + (z * z) * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6))))))
    return q, s, c


@njit(cache=True, inline="always", error_model="numpy")
def poly_sincos(x):
    """``(sin x, cos x)`` (``x`` in rad) from one reduction, within 2 ulp for
    ``|x| <= 1.6e6``, branch-free (module doc)."""
    q, s, c = _reduce(x)
    swap = (q == 1.0) | (q == 3.0)
    a = c if swap else s
    b = s if swap else c
    return (-a if q >= 2.0 else a), (-b if (q == 1.0) | (q == 2.0) else b)


@njit(cache=True, inline="always", error_model="numpy")
def poly_sin(x):
    """``sin x``: :func:`poly_sincos`'s sine (the compiler drops the unused cosine)."""
    return poly_sincos(x)[0]
