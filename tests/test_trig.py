"""The monitor's polynomial sine and cosine (``ema_bench.physics.trig``) against libm, and the
eccentric torque constant built on them against the textbook formula."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from ema_bench.physics.averaged_drive import kt_eccentric
from ema_bench.physics.trig import poly_sin, poly_sincos


@njit   # no cache: numba would write it beside the tests (and into an sdist built from them)
def _grid(xs):
    s = np.empty_like(xs)
    c = np.empty_like(xs)
    s1 = np.empty_like(xs)
    for i in range(xs.size):
        s[i], c[i] = poly_sincos(xs[i])
        s1[i] = poly_sin(xs[i])
    return s, c, s1


@pytest.mark.parametrize("half_width", [math.pi, 2000.0, 1e5])
def test_within_two_ulp_of_libm_on_a_dense_grid(half_width):
    """Two million points (plus the quadrant boundaries k pi/4 and their neighbours) in
    [-w, w]: every sine and cosine within 2.3e-16 of libm's, within 2 ulp of it where its
    value exceeds 1e-9, and within 1e-25 near the zeros k pi/2 (the bounds ``trig``'s
    docstring states); the model's arguments stay under 1,620 rad."""
    xs = np.linspace(-half_width, half_width, 2_000_001)
    k = np.arange(-int(half_width / (math.pi / 4)), int(half_width / (math.pi / 4)) + 1)
    edges = k * (math.pi / 4)
    xs = np.concatenate([xs, edges, np.nextafter(edges, np.inf), np.nextafter(edges, -np.inf)])
    s, c, s1 = _grid(xs)
    ref_s, ref_c = np.sin(xs), np.cos(xs)
    assert np.abs(s - ref_s).max() <= 2.3e-16
    assert np.abs(c - ref_c).max() <= 2.3e-16
    for mine, ref in ((s, ref_s), (c, ref_c)):
        err = np.abs(mine - ref)
        big = np.abs(ref) > 1e-9   # in units in the last place of libm's value
        assert (err[big] <= 2 * np.spacing(np.abs(ref[big]))).all()
        assert err[~big].max(initial=0.0) <= 1e-25   # the reduction's error near a zero
    assert np.array_equal(s, s1)   # poly_sin is poly_sincos's sine, bit for bit


def test_exact_values_and_non_finite_arguments():
    s, c, _ = _grid(np.array([0.0, math.pi / 2, -math.pi / 2, math.inf, -math.inf, math.nan]))
    assert s[0] == 0.0 and c[0] == 1.0
    assert s[1] == 1.0 and abs(c[1]) < 1e-16 and s[2] == -1.0
    assert np.isnan(s[3:]).all() and np.isnan(c[3:]).all()   # as libm: nan, never a number


#: Conducting (positive, negative) phases of the six sectors (0 = a, 1 = b, 2 = c).
_PAIRS = ((0, 1), (0, 2), (1, 2), (1, 0), (2, 0), (2, 1))


@pytest.mark.parametrize("sec", range(6))
def test_eccentric_torque_constant_is_the_textbook_formula(sec):
    """``ke (n_x (1 + zeta cos(th - phi_x)) + n_y (1 + zeta cos(th - phi_y)))`` with libm's
    cosine and phi = 0, 2 pi/3, 4 pi/3 for phases a, b, c (phase a's turns ``na``), for int
    and float sectors alike: within 1e-15 relative.  A wrong phase, sign or turn fraction
    is off by about ``zeta``."""
    ke, na, zeta = 0.05, 0.8, 0.05
    x, y = _PAIRS[sec]
    phi = (0.0, 2 * math.pi / 3, 4 * math.pi / 3)
    for th in np.linspace(-140.0, 140.0, 1001):
        want = ke * ((na if x == 0 else 1.0) * (1.0 + zeta * math.cos(th - phi[x]))
                     + (na if y == 0 else 1.0) * (1.0 + zeta * math.cos(th - phi[y])))
        got = kt_eccentric(sec, th, ke, na, zeta)
        assert got == kt_eccentric(float(sec), th, ke, na, zeta)
        assert got == pytest.approx(want, rel=1e-15, abs=0.0)
