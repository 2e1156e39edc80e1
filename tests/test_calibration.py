"""The shipped monitor calibration is what the calibration procedure gives, and it helps."""

import pytest

from ema_bench.calibrate import calibrate_kt_factor
from ema_bench.params import DEFAULT_PARAMS


def test_shipped_kt_factor_matches_calibration_on_healthy_actuator():
    res = calibrate_kt_factor("nominal")
    assert res["kt_factor"] == pytest.approx(DEFAULT_PARAMS.kt_factor, abs=2e-4)
    assert res["fitness"] < 0.5 * res["fitness_uncorrected"]


@pytest.mark.parametrize("case", ["small", "full"])
def test_drive_constant_does_not_depend_on_the_faults(case):
    # a property of the drive: damaged actuators calibrate to the same value
    assert calibrate_kt_factor(case)["kt_factor"] == pytest.approx(DEFAULT_PARAMS.kt_factor,
                                                                   abs=5e-4)
