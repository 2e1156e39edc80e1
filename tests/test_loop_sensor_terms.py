"""The current loop's and the sensors' dictionary terms (issue 46 item 4): their forms, where
each acts (the conducting pair's voltage in both drives; each sensor in the loop and in the
record), and the reference's dead time and resolver harmonic, against values written out or
integrated by hand here."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ema_bench.effects import EFFECT_INDEX, N_EFFECTS
from ema_bench.faults import NOMINAL
from ema_bench.monitor import simulate_monitor
from ema_bench.objective import KNOWN_TESTS
from ema_bench.params import DEFAULT_PARAMS
from ema_bench.physics.averaged_drive import drive_consts, drive_step, sector_index
from ema_bench.physics.bldc import bldc_consts, bldc_step
from ema_bench.physics.extra_terms import (
    angle_error,
    current_error,
    loop_voltage,
    position_error,
    sensor_consts,
)
from ema_bench.terms import EQUATIONS, N_TERMS, TERM_INDEX, TERMS

P = DEFAULT_PARAMS.to_array()
PAR = DEFAULT_PARAMS


def _unit(name: str) -> np.ndarray:
    c = np.zeros(N_TERMS)
    c[TERM_INDEX[name]] = 1.0
    return c


def test_each_current_loop_and_sensor_term_has_its_form_in_its_equation_only():
    """A unit coefficient gives the form written out here, in its own equation, and nothing
    in the others; the resolver's slope is the derivative of its error (a central
    difference)."""
    i, w_m, th_m, pp, th_u = -3.7, 212.0, 7.3, 2.0, -0.137
    forms = {"current_sign": math.tanh(i / 0.5), "current_i_abs": i * abs(i),
             "current_emf_sin": w_m * math.sin(6 * pp * th_m),
             "current_emf_cos": w_m * math.cos(6 * pp * th_m),
             "sensor_thm_sin": math.sin(th_m), "sensor_thm_cos": math.cos(th_m),
             "sensor_thm_sin2": math.sin(2 * th_m), "sensor_thm_cos2": math.cos(2 * th_m),
             "sensor_thu2": th_u ** 2, "sensor_thu_abs": th_u * abs(th_u),
             "sensor_i_abs": i * abs(i)}
    new = [t for t in TERMS if t.equation not in ("motor", "surface")]
    assert [t.name for t in new] == list(forms)
    for t in new:
        c = _unit(t.name)
        got = {"current": loop_voltage(i, w_m, th_m, pp, c),
               "motor_angle": angle_error(th_m, c)[0],
               "surface_position": position_error(th_u, c),
               "current_sensor": current_error(i, c)}
        assert got.pop(t.equation) == pytest.approx(forms[t.name], rel=1e-12, abs=1e-15)
        assert all(v == 0.0 for v in got.values()), t.name
        assert t.equation in EQUATIONS
        if t.equation == "motor_angle":
            d = 1e-6
            fd = (angle_error(th_m + d, c)[0] - angle_error(th_m - d, c)[0]) / (2 * d)
            assert angle_error(th_m, c)[1] == pytest.approx(fd, rel=1e-7, abs=1e-9)


def test_a_current_loop_voltage_moves_the_monitor_pairs_current_by_h_v_over_L():
    """From rest towards a far reference the averaged drive's pair current ramps at
    ``(V_dc + v) / (2 L)`` (no back-EMF, no current yet): a term's voltage ``v`` adds
    ``h v / (2 L)`` to the step's end current, with its sign."""
    h = 50e-6
    dc = drive_consts(P, 1.0, 0.0, 1.0, PAR.V_dc, h)
    th_m = 0.3   # inside sector 0 at 2 pole pairs (30..90 electrical degrees)
    m = sector_index(th_m, PAR.pole_pairs)
    assert m % 6 == 0
    end = {v: drive_step(0.0, m, -1.0, 0.0, 0.0, 0.0, 0.0, 60.0, th_m, 0.0, dc, v)[0]
           for v in (0.0, 10.0, -10.0)}
    assert end[0.0] == pytest.approx(h * PAR.V_dc / (2 * PAR.L), rel=1e-12)
    assert end[10.0] - end[0.0] == pytest.approx(h * 10.0 / (2 * PAR.L), rel=1e-9)
    assert end[-10.0] - end[0.0] == pytest.approx(-h * 10.0 / (2 * PAR.L), rel=1e-9)


def test_the_reference_pair_sees_the_terms_voltage_and_each_leg_its_dead_time():
    """Sector 0 (a+ b-), both legs driving up the current: over one microsecond the pair's
    current grows by ``dt (V_dc + v) / (2 L)``; a dead time ``V`` costs each leg
    ``V tanh(i / 0.5)`` against its current, ``2 V tanh(I / 0.5)`` on the pair: the
    dictionary's ``tanh(i / 0.5)`` with ``c = -2 V``."""
    dt, i0 = 1e-6, 3.0
    bc = bldc_consts(P, 1.0, 0.0, 1.0, PAR.V_dc)
    th_m = 0.3

    def pair_rise(v_pair, v_dt):
        ia = bldc_step(i0, -i0, 0.0, 1, -1, 0, 10.0, th_m, 0.0, bc, dt, v_pair, v_dt)[0]
        return ia - i0

    base = pair_rise(0.0, 0.0)
    assert base == pytest.approx(dt * (PAR.V_dc - 2 * PAR.R * i0) / (2 * PAR.L), rel=1e-9)
    assert pair_rise(10.0, 0.0) - base == pytest.approx(dt * 10.0 / (2 * PAR.L), rel=1e-6)
    want = dt * (-2 * 2.0 * math.tanh(i0 / 0.5)) / (2 * PAR.L)
    assert pair_rise(0.0, 2.0) - base == pytest.approx(want, rel=1e-6)


def _monitor(name: str | None, value: float = 0.0):
    E = np.zeros((1, N_EFFECTS))
    if name:
        E[0, EFFECT_INDEX[name]] = value
    out, ok = simulate_monitor(NOMINAL[None], E, tests=(KNOWN_TESTS["step"],), parallel=False)
    assert ok.all()
    return out["step"][0]


@pytest.fixture(scope="module")
def base():
    return _monitor(None)


def test_a_surface_position_sensor_error_is_held_by_the_loop_and_moves_the_motor(base):
    """The loop holds the *measured* position at the 0.3 rad step: the record shows the
    command as without the error, and the surface (so the motor, through the gear) stands
    ``c th^2`` short of it (``th + c th^2 = 0.3``, solved here): the term acts in the loop
    and in the record, as the library's ``sensor_offset`` does."""
    c = 0.04
    y = _monitor("sensor_thu2", c)
    cmd = 0.3
    th_true = (-1.0 + math.sqrt(1.0 + 4.0 * c * cmd)) / (2.0 * c)
    assert y[-1, 0] == pytest.approx(base[-1, 0], abs=2e-6)
    shift = (th_true - base[-1, 0]) / PAR.tau
    assert y[-1, 1] - base[-1, 1] == pytest.approx(shift, rel=0.01)


def test_a_resolver_harmonic_shows_in_the_recorded_angle_and_steers_the_loop(base):
    """At the hold the recorded motor angle is the rotor's plus ``a sin(2 th_m)`` (the rotor
    where the error-free run left it); while moving, the speed the loop feeds back is the
    measured angle's rate, so the surface's path itself changes (a record-only error would
    leave it as it was)."""
    a = 0.005
    y = _monitor("sensor_thm_sin2", a)
    th_m = base[-1, 1]
    assert y[-1, 1] - base[-1, 1] == pytest.approx(a * math.sin(2.0 * th_m), rel=0.02)
    assert np.abs(y[:, 0] - base[:, 0]).max() > 1e-6
    # the reference's outside-library harmonic is the same error in the same slot
    e = np.zeros(N_EFFECTS)
    e[EFFECT_INDEX["resolver_harmonic"]] = a
    assert np.array_equal(sensor_consts(e)[3], a * _unit("sensor_thm_sin2"))
    np.testing.assert_array_equal(_monitor("resolver_harmonic", a), y)


def test_a_current_sensor_error_is_in_the_record_and_in_the_drives_loop(base):
    """At the hold the recorded current is the drive's current plus ``c i^2`` (its equivalent
    current is a magnitude); and the drive regulates the sensor's reading, so the current it
    makes, and the motion, change while the loop moves the surface."""
    c = -0.01
    y = _monitor("sensor_i_abs", c)
    i = base[-1, 3]
    assert i > 0.5
    assert y[-1, 3] - base[-1, 3] == pytest.approx(c * i * i, rel=0.02)
    assert np.abs(y[:, 2] - base[:, 2]).max() > 1e-3


def test_a_current_loop_term_reaches_the_monitors_outputs(base):
    """The monitor passes the term's voltage to its drive (a term wired to nothing would
    leave every output as it was), and only there: the recorded position still follows the
    command."""
    y = _monitor("current_sign", -8.0)
    assert not np.array_equal(y, base)
    assert y[-1, 0] == pytest.approx(base[-1, 0], abs=1e-4)
