"""The monitor's drive: the single-phase equivalent of the three-phase BLDC and its
hysteresis current control (:mod:`ema_bench.physics.bldc`), one step per controller sample.

* **Conducting pair.**  In each six-step sector two phases carry the current ``I``: phase x
  driven positive and y negative give ``T = (ke_x - ke_y) I`` with ``R_x + R_y`` and
  ``L_x + L_y``.  Averaged over the six sectors this is ``Kt = 2 Ke (Na + 2) / 3`` of DESIGN
  section 8; resolving the sector keeps the monitor right at standstill too.
* **Ideal current loop, limited by the bus voltage.**  The current moves towards its reference
  at the slope ``(+-V_dc - Kt w - R I) / L`` of the pair, then holds it (the analog hysteresis
  controller's ripple is symmetric about the reference, so its mean is the reference).  Torque
  and the recorded equivalent current use the exact step means of that ramp-and-hold path.
* **Commutation.**  When the rotor crosses a sector boundary inside the step, the outgoing
  phase's current decays while the incoming one rises, in ``t_tr = |I| (L_y + L_z) / V_dc`` (the
  continuing phase stays regulated; Carlson, Lajoie-Mazenc and Fagundes, IEEE Trans. Ind. Appl.
  28(3), 1992, for the equal-phase case).  Meanwhile the torque constant moves linearly from the
  old pair's to the new pair's (they differ when ``Na < 1``), and the outgoing phase's back-EMF,
  already ramping off its flat top, costs ``ke_y (p w / (pi / 6)) tau i_y`` of torque.  Left
  out, this speed- and current-dependent deficit (up to 0.4 % of torque at 750 rad/s, 20 A)
  was absorbed by a calibrated constant and biased the fitted ``Na`` by up to 1 % of its range.
  A crossing is predicted on the straight path ``th_m + h w_m``; one that the mechanics'
  trapezoidal path makes but the prediction misses (an accelerating rotor) shows at the next
  step's start.  Model version 3 switches the pair there without a transfer, a jump in the
  fitness decided at step resolution; version 4 (``locate_commutation``) starts the transfer
  where the crossing was, inside the last step (docs/landscape-atlas.md, "Kinds of jump").
* **Breakaway.**  The hysteresis ripple's peaks (half the band above the mean current) reach a
  stuck shaft's static friction level first: the mechanics are told that ripple torque.
"""

from __future__ import annotations

import math
from collections import namedtuple

from numba import njit

from ..params import P_HYST, P_KE, P_KTF, P_L, P_LIBM, P_LOCATE, P_PP, P_R
from .trig import poly_sincos

SIXTH = math.pi / 6.0
# cos and sin of phase b's eccentricity shift, 2 pi / 3 (phase c's, 4 pi / 3: the same cos, -sin)
_COS_120, _SIN_120 = -0.5, math.sqrt(3.0) / 2.0
# phases b's and c's shifts themselves (model version 2 takes libm's cos(th_m - phi))
_PHI_B, _PHI_C = 2.0 * math.pi / 3.0, 4.0 * math.pi / 3.0
# Six-step sectors s = 0..5 (from 30 electrical degrees) conduct a+b-, a+c-, b+c-, b+a-, c+a-,
# c+b-: phase a conducts unless s % 3 == 2.  Crossing s -> s+1 exchanges (outgoing, incoming)
# = (b, c), (a, b), (c, a) for s % 3 = 0, 1, 2; crossing s -> s-1 exchanges (a, c), (c, b),
# (b, a).  With phase a's turns Na and the others' 1, every sector quantity is one of two
# values, picked by a branch rather than a table (no arrays in the per-step constants).

DriveConsts = namedtuple("DriveConsts", (
    "kt_a", "kt_n", "r_a", "r_n", "il_a", "il_n", "ltr_a", "ltr_n", "na", "ke", "pp", "zeta",
    "v_dc", "ktf", "half_band", "h", "sector_width", "th_0", "locate", "libm"))
DriveConsts.__doc__ = "Per-candidate constants of :func:`drive_step` (see :func:`drive_consts`)."


@njit(cache=True, error_model="numpy")
def drive_consts(p, na, zeta, r_scale, v_dc, h):
    """Drive constants for one candidate: ``na`` healthy turn fraction of phase a, eccentricity
    ``zeta``, resistance multiplier ``r_scale``, bus voltage ``v_dc`` (V), step ``h`` (s).

    ``kt_*``, ``r_*``, ``il_*`` are the pair torque constant (N m/A), resistance (ohm) and
    inverse inductance (1/H) of a sector with phase a (``_a``) or without (``_n``); ``ltr_*``
    the commutation transfer time per ampere (s/A) of a crossing that exchanges phase a or not.
    """
    ke, el, r = p[P_KE], p[P_L], p[P_R] * r_scale
    return DriveConsts(ke * (na + 1.0), 2.0 * ke, r * (na + 1.0), 2.0 * r,
                       1.0 / (el * (na * na + 1.0)), 1.0 / (2.0 * el),
                       el * (na * na + 1.0) / v_dc, 2.0 * el / v_dc, na, ke, p[P_PP], zeta,
                       v_dc, p[P_KTF], 0.5 * p[P_HYST], h, 2.0 * SIXTH / p[P_PP],
                       SIXTH / p[P_PP], p[P_LOCATE] != 0.0, p[P_LIBM] != 0.0)


@njit(cache=True, inline="always", error_model="numpy")
def kt_eccentric(sec, th_m, ke, na, zeta):
    """Pair torque constant (N m/A) of sector ``sec`` (0..5, int or float) at motor angle
    ``th_m`` (rad) of a rotor with eccentricity ``zeta``: each conducting phase's constant
    ``ke`` (V s/rad) scaled by ``1 + zeta cos(th_m - phi_x)``, phase a's by its turn fraction
    ``na`` too.

    ``cos(th_m - phi) = cos th_m cos phi + sin th_m sin phi``: one sine-cosine pair
    (:func:`~ema_bench.physics.trig.poly_sincos`) serves both phases, within 4e-16 of libm's
    ``cos(th_m - phi)``.  Branch-free (the sector's phases by selects), so the lanes
    (:mod:`ema_bench.monitor_lanes`) run it vectorised and the scalar kernel through
    :func:`kt_at`: one expression, the same bits.  Sectors 0..5 conduct a+b-, a+c-, b+c-,
    b+a-, c+a-, c+b-."""
    s, c = poly_sincos(th_m)
    # phase x (positive): a in sectors 0-1, b in 2-3, c in 4-5; y (negative): b, c, c, a, a, b
    cx = 1.0 if sec < 2 else _COS_120
    sx = 0.0 if sec < 2 else (_SIN_120 if sec < 4 else -_SIN_120)
    nx = na if sec < 2 else 1.0
    y_is_a = (sec == 3) | (sec == 4)
    cy = 1.0 if y_is_a else _COS_120
    sy = 0.0 if y_is_a else (_SIN_120 if (sec == 0) | (sec == 5) else -_SIN_120)
    ny = na if y_is_a else 1.0
    return ke * (nx * (1.0 + zeta * (c * cx + s * sx)) + ny * (1.0 + zeta * (c * cy + s * sy)))


@njit(cache=True, inline="always", error_model="numpy")
def kt_eccentric_libm(sec, th_m, ke, na, zeta):
    """:func:`kt_eccentric` as model version 2 computed it (``libm_trig``): libm's
    ``cos(th_m - phi_x)`` for each conducting phase, the operations of that version in their
    order, so its records replay to the bit.  Scalar libm calls: the lanes run it, not
    vectorised."""
    phx = 0.0 if sec < 2 else (_PHI_B if sec < 4 else _PHI_C)
    nx = na if sec < 2 else 1.0
    y_is_a = (sec == 3) | (sec == 4)
    phy = 0.0 if y_is_a else (_PHI_B if (sec == 0) | (sec == 5) else _PHI_C)
    ny = na if y_is_a else 1.0
    return ke * (nx * (1.0 + zeta * math.cos(th_m - phx))
                 + ny * (1.0 + zeta * math.cos(th_m - phy)))


@njit(cache=True, inline="always", error_model="numpy")
def kt_eccentric_of(sec, th_m, dc):
    """The eccentric pair torque constant of the model version ``dc`` holds:
    :func:`kt_eccentric`, or :func:`kt_eccentric_libm` (``dc.libm``, version 2)."""
    if dc.libm:
        return kt_eccentric_libm(sec, th_m, dc.ke, dc.na, dc.zeta)
    return kt_eccentric(sec, th_m, dc.ke, dc.na, dc.zeta)


@njit(cache=True, inline="always", error_model="numpy")
def kt_at(sec, th_m, dc):
    """Pair torque constant of sector ``sec`` at motor angle ``th_m``: the sector's constant
    without eccentricity, else :func:`kt_eccentric_of`."""
    if dc.zeta == 0.0:
        return dc.kt_n if sec % 3 == 2 else dc.kt_a
    return kt_eccentric_of(sec, th_m, dc)


@njit(cache=True, inline="always", error_model="numpy")
def _ramp_integral(lo, hi, t_tr):
    """Integral of ``u (1 - u / t_tr)`` over ``[lo, hi]`` (the outgoing current times its
    back-EMF ramp, both linear in the time ``u`` since the crossing)."""
    return (0.5 * hi * hi - hi * hi * hi / (3.0 * t_tr)) - \
        (0.5 * lo * lo - lo * lo * lo / (3.0 * t_tr))


@njit(cache=True, inline="always", error_model="numpy")
def sector_index(th_m, pole_pairs):
    """Unwrapped six-step sector index at motor angle ``th_m`` (``index % 6`` is the sector)."""
    return int(math.floor((pole_pairs * th_m - SIXTH) / (2.0 * SIXTH)))


@njit(cache=True, inline="always", error_model="numpy")
def _ramp(cur, i_ref, back, il, v_dc, h, one_division):
    """The current's voltage-limited ramp towards ``i_ref``, then hold, over one step.

    ``back`` (V) is the pair's back-EMF plus resistive drop, ``il`` its inverse inductance.
    Returns the end current, the share ``f`` of the step spent ramping, and the step means of
    the current and of its magnitude (A).

    ``f`` is the change ``d`` over the span on its side (``d > 0`` only where the up-span is
    positive, ``d < 0`` only where the down-span is negative: the clamp sees to it), so
    ``0 <= f <= 1``.  ``one_division`` (a constant) picks how.  The scalar kernel: while the bus
    voltage exceeds ``back`` (always, inside the bounds), ``f`` is the larger of ``d / up`` and
    ``d / down`` by reciprocals, both off the step's critical path and with no branch on the
    ramp's direction, which flips at random from step to step (a select on it cost 14 %).  The
    lanes of :mod:`ema_bench.monitor_lanes`, which compute both sides of every branch anyway,
    select the span and divide once: the same ``f`` to the bit for ``d != 0`` (for ``d = 0``
    only the sign of a zero ``f`` may differ, which reaches no output), and within one
    rounding where the voltage runs out."""
    up = h * (v_dc - back) * il
    dn = h * (-v_dc - back) * il
    cur1 = i_ref
    if cur1 > cur + up:
        cur1 = cur + up
    elif cur1 < cur + dn:
        cur1 = cur + dn
    d = cur1 - cur
    if one_division:
        f = d * (1.0 / (up if d > 0.0 else dn))
    elif up > 0.0 and dn < 0.0:
        f = max(d * (1.0 / up), d * (1.0 / dn))
    elif d > 0.0:   # no voltage headroom (not reached inside the bounds)
        f = d / up
    elif d < 0.0:
        f = d / dn
    else:
        f = 0.0
    i_mean = cur1 - (0.5 * d) * f
    if cur * cur1 >= 0.0:
        ramp_abs = 0.5 * abs(cur + cur1)
    else:   # the ramp passes through zero
        ramp_abs = 0.5 * (cur * cur + cur1 * cur1) / abs(d)
    return cur1, f, i_mean, f * ramp_abs + (1.0 - f) * abs(cur1)


@njit(cache=True, inline="always", error_model="numpy")
def drive_step(cur, m, tr_t0, tr_len, kt_from, kt_to, tr_cr, i_ref, th_m, w_m, dc, v_x=0.0):
    """Advance the averaged drive by one step ``dc.h``.

    Parameters
    ----------
    cur : float
        A, pair current at the step start (signed).
    m : int
        Unwrapped sector index tracked so far.
    tr_t0, tr_len, kt_from, kt_to, tr_cr : float
        The commutation transfer in progress: its start (s, relative to this step's start),
        duration (s), torque constants before and after (N m/A) and its back-EMF-ramp
        coefficient (N m/s).
    i_ref : float
        A, current reference.
    th_m, w_m : float
        rad, rad/s: rotor angle and speed at the step start.
    dc : DriveConsts
    v_x : float
        V, a voltage added to the pair's loop ``L di/dt = v - R i - e + v_x`` (the
        dictionary's current-loop terms; 0 leaves every operation's result as it was).

    Returns
    -------
    cur, m, tr_t0, tr_len, kt_from, kt_to, tr_cr
        The drive state at the step end (``tr_t0`` relative to the next step).
    t_mean, t_start, t_end, t_ripple : float
        N m: step-mean torque, torque at the step start and end, ripple amplitude.
    i_eq : float
        A, step mean of ``|I|`` (the equivalent current).

    Most steps stay inside one sector with no commutation in progress; they take the short
    path here.  The others go to :func:`drive_step_general`, which does the same arithmetic
    for them plus the commutation.
    """
    th_lo, kt, r_pair, il = sector_consts(m, dc)
    kt_mid = kt
    if dc.zeta != 0.0:   # the torque constants at the step start and mid-step
        kt = kt_eccentric_of(m % 6, th_m, dc)
        kt_mid = kt_eccentric_of(m % 6, th_m + 0.5 * dc.h * w_m, dc)
    fast, cur1, t_mean, t_start, t_end, t_rip, i_eq = drive_fast(
        cur, tr_t0, tr_len, th_lo, kt, kt_mid, r_pair, il, i_ref, th_m, w_m, dc, False, v_x)
    if fast:
        return (cur1, m, tr_t0 - dc.h, tr_len, kt_from, kt_to, tr_cr, t_mean, t_start,
                t_end, t_rip, i_eq)
    return drive_step_general(cur, m, tr_t0, tr_len, kt_from, kt_to, tr_cr, i_ref, th_m, w_m,
                              dc, kt, kt_mid, v_x)


@njit(cache=True, inline="always", error_model="numpy")
def sector_consts(m, dc):
    """Lower sector boundary (rad) and the pair's torque constant (N m/A), resistance (ohm) and
    inverse inductance (1/H) of unwrapped sector ``m`` (no eccentricity)."""
    th_lo = dc.th_0 + dc.sector_width * m
    sec = m % 6
    if sec == 2 or sec == 5:   # the pair without phase a
        return th_lo, dc.kt_n, dc.r_n, dc.il_n
    return th_lo, dc.kt_a, dc.r_a, dc.il_a


@njit(cache=True, inline="always", error_model="numpy")
def drive_fast(cur, tr_t0, tr_len, th_lo, kt, kt_mid, r_pair, il, i_ref, th_m, w_m, dc,
               one_division, v_x=0.0):
    """The short path of :func:`drive_step`: a step inside one sector (lower boundary ``th_lo``,
    pair constants ``kt``, ``r_pair``, ``il``) with no commutation in progress.

    ``kt`` is the pair's torque constant at the step start (back-EMF, start torque) and
    ``kt_mid`` at mid-step (mean and end torque, ripple): the same constant without
    eccentricity; with it, :func:`kt_at` at ``th_m`` and at ``th_m + 0.5 h w_m``, as
    :func:`drive_step_general` takes them (the lanes use that; :func:`drive_step` sends an
    eccentric rotor to the general path).

    Returns ``fast`` (whether the step is such a step; the other values hold only then), the
    end current and the step's torques and equivalent current as :func:`drive_step`.  Free of
    branches that the compiler cannot turn into selects, so the lock-step lanes of
    :mod:`ema_bench.monitor_lanes` run it vectorised; ``dc`` supplies only fault-independent
    constants (step, sector width, bus voltage, torque factor, hysteresis band);
    ``one_division`` as :func:`_ramp`; ``v_x`` (V) as :func:`drive_step`."""
    h = dc.h
    th_hi = th_lo + dc.sector_width
    th_end = th_m + h * w_m
    fast = ((tr_t0 + tr_len <= 0.0) & (th_lo <= th_m) & (th_m < th_hi) & (th_lo <= th_end)
            & (th_end < th_hi))
    cur1, f, i_mean, i_eq = _ramp(cur, i_ref, kt * w_m + r_pair * cur - v_x, il, dc.v_dc, h,
                                  one_division)
    kf = dc.ktf * kt
    km = dc.ktf * kt_mid
    return fast, cur1, km * i_mean, kf * cur, km * cur1, abs(km) * dc.half_band, i_eq


@njit(cache=True, inline="always", error_model="numpy")
def _transfer(sec, up, th_b, i_tr, w_m, dc):
    """The commutation transfer of a crossing out of sector ``sec`` (0..5) upwards (``up``)
    or downwards at the boundary ``th_b`` (rad), current ``i_tr`` (A), speed ``w_m``
    (rad/s): the torque constants before and after (N m/A), its duration (s) and its
    back-EMF-ramp coefficient (N m/s)."""
    k3 = sec % 3
    if up:   # exchanges (b, c), (a, b), (c, a)
        ltr = dc.ltr_n if k3 == 0 else dc.ltr_a
        ny = dc.na if k3 == 1 else 1.0
        sec_to = (sec + 1) % 6
    else:    # exchanges (a, c), (c, b), (b, a)
        ltr = dc.ltr_n if k3 == 1 else dc.ltr_a
        ny = dc.na if k3 == 0 else 1.0
        sec_to = (sec + 5) % 6
    return (kt_at(sec, th_b, dc), kt_at(sec_to, th_b, dc), max(i_tr * ltr, 1e-12),
            ny * dc.ke * dc.pp * abs(w_m) / SIXTH * i_tr)


@njit(cache=True, error_model="numpy")
def drive_step_general(cur, m, tr_t0, tr_len, kt_from, kt_to, tr_cr, i_ref, th_m, w_m, dc,
                       kt_m0, kt_mid_m0, v_x=0.0):
    """:func:`drive_step` for every case: sector crossings, commutation transfers,
    eccentricity (not inlined: the hot loop stays small).

    ``kt_m0``, ``kt_mid_m0`` are the torque constants of sector ``m`` at ``th_m`` and at
    mid-step that the short path already computed (:func:`kt_at`'s values, the sector's
    constant without eccentricity): used while the step stays in sector ``m``, so an
    eccentric rotor's slow step does not compute its sines again."""
    h = dc.h
    m_in = m
    pp = dc.pp
    th_lo = dc.th_0 + dc.sector_width * m
    th_hi = th_lo + dc.sector_width
    if th_m >= th_hi or th_m < th_lo:   # a crossing the speed did not predict
        m0 = m
        m = sector_index(th_m, pp)
        th_lo = dc.th_0 + dc.sector_width * m
        th_hi = th_lo + dc.sector_width
        if dc.locate and m != m0:
            # Model version 4: the mechanics' trapezoidal path crossed a boundary that the
            # straight prediction ``th_m + h w_m`` of the last step missed (an accelerating
            # rotor); the commutation transfer starts where the crossing was, inside the
            # last step, instead of being dropped (a jump in the fitness, docs/
            # landscape-atlas.md).
            up = m > m0
            th_b = th_lo if up else th_hi
            tr_t0 = (th_b - th_m) / w_m if w_m != 0.0 else 0.0
            tr_t0 = tr_t0 if tr_t0 > -h else -h
            tr_t0 = tr_t0 if tr_t0 < 0.0 else 0.0
            kt_from, kt_to, tr_len, tr_cr = _transfer((m - 1 if up else m + 1) % 6, up,
                                                      th_b, abs(cur), w_m, dc)
    sec = m % 6
    with_a = sec % 3 != 2
    kt0 = kt_m0 if m == m_in else kt_at(sec, th_m, dc)
    r_pair = dc.r_a if with_a else dc.r_n
    il = dc.il_a if with_a else dc.il_n
    cur1, f, i_mean, i_eq = _ramp(cur, i_ref, kt0 * w_m + r_pair * cur - v_x, il, dc.v_dc, h,
                                  False)
    # a sector crossing inside the step starts a commutation transfer
    th_end = th_m + h * w_m
    if th_end >= th_hi or th_end < th_lo:
        up = th_end >= th_hi
        g = ((th_hi if up else th_lo) - th_m) / (h * w_m)
        th_b = th_hi if up else th_lo
        # the current at the crossing: on its ramp if it had not reached its end yet
        i_tr = abs(cur + (cur1 - cur) * (g if g < f else f) / f) if f > 0.0 else abs(cur1)
        kt_from, kt_to, tr_len, tr_cr = _transfer(sec, up, th_b, i_tr, w_m, dc)
        m += 1 if up else -1
        sec = m % 6
        tr_t0 = g * h
    deficit = 0.0
    if tr_t0 < h and tr_t0 + tr_len > 0.0:
        a = tr_t0 if tr_t0 > 0.0 else 0.0
        b = tr_t0 + tr_len if tr_t0 + tr_len < h else h
        fa = (a - tr_t0) / tr_len
        fb = (b - tr_t0) / tr_len
        dk = kt_to - kt_from
        kt_mean = (kt_from * a + (b - a) * (kt_from + dk * 0.5 * (fa + fb))
                   + kt_to * (h - b)) / h
        kt_start = kt_from + dk * fa if tr_t0 <= 0.0 else kt_from
        kt_end = kt_from + dk * fb if b < h else kt_to
        deficit = tr_cr * _ramp_integral(a - tr_t0, b - tr_t0, tr_len) / h
    else:
        kt_mean = kt0 if dc.zeta == 0.0 else (
            kt_mid_m0 if m == m_in else kt_at(sec, th_m + 0.5 * h * w_m, dc))
        kt_start = kt0
        kt_end = kt_mean
    ktf = dc.ktf
    t_mean = (ktf * kt_mean) * i_mean
    if deficit != 0.0:
        t_mean -= ktf * (deficit if i_mean > 0.0 else -deficit)
    return (cur1, m, tr_t0 - h, tr_len, kt_from, kt_to, tr_cr, t_mean,
            ktf * kt_start * cur, ktf * kt_end * cur1, ktf * abs(kt_end) * dc.half_band, i_eq)
