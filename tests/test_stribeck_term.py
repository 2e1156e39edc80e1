"""The dictionary's Stribeck form (issue 46, the outside-library Stribeck miss): a smoothed
sign fading with the motor speed, in the motor torque balance, the form of the reference's
Stribeck physics, which neither the Fst fault nor ``tanh(w_m / 3)`` has."""

from __future__ import annotations

import numpy as np
import pytest

from ema_bench.diagnosis.blind_categories import EXPECTED_TERMS
from ema_bench.diagnosis.discovery import describe
from ema_bench.physics.extra_terms import extra_torques, stribeck
from ema_bench.terms import N_TERMS, TERM_INDEX, term


@pytest.mark.parametrize("w_m", [-40.0, -6.0, -0.7, 0.0, 2.5, 9.0, 30.0, 75.0])
def test_the_stribeck_term_is_the_decaying_smoothed_sign_at_the_motor(w_m):
    """A unit coefficient gives ``exp(-(w_m/30)^2) tanh(w_m/3)`` (written out here) in the
    motor balance only, at low speeds where it differs from ``tanh(w_m / 3)`` and at speed
    where it has faded; with ``-F`` it is the reference's Stribeck torque of peak ``F``."""
    c = np.zeros(N_TERMS)
    c[TERM_INDEX["motor_stribeck"]] = 1.0
    state = (0.4, w_m, 0.05, w_m / 300.0, 3.0, 2.0)
    motor, surface = extra_torques(*state, c)
    want = np.exp(-(w_m / 30.0) ** 2) * np.tanh(w_m / 3.0)
    assert motor == pytest.approx(want, rel=1e-12, abs=1e-300) and surface == 0.0
    c[TERM_INDEX["motor_stribeck"]] = -0.082
    assert extra_torques(*state, c)[0] == pytest.approx(-stribeck(0.082, w_m), rel=1e-12,
                                                        abs=1e-300)


def test_the_stribeck_physics_is_right_when_named_by_its_form():
    """The blind suite judges the outside-library Stribeck case on this term (equation and
    form), not on the constant-level smoothed sign, and the verdict writes the form out."""
    assert EXPECTED_TERMS["stribeck_friction"] == "motor_stribeck"
    t = term("motor_stribeck")
    assert t.equation == "motor" and t.unit == "N m" and t.bound == pytest.approx(0.5)
    assert describe("motor_stribeck", -0.08, [-0.09, -0.07]) == (
        "unnamed term in the motor torque balance: c exp(-(w_m / 30)^2) tanh(w_m / 3), "
        "c = -0.08 [-0.09, -0.07] N m")
