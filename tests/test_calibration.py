"""The monitor needs no drive calibration: fitted on clean reference traces at the known
faults, its torque-constant multiplier comes out at the shipped value 1 on every case.

Before the integration fix it came out at 0.9971 (healthy) and moved with the faults, which
biased the fitted coil fraction by 1-3 % of its range; a monitor that drifts from the
reference again (a wrong window mean, a lost commutation term) moves it by more than 2e-4.
"""

import pytest

from ema_bench.monitor_bias import calibrate_kt_factor
from ema_bench.params import DEFAULT_PARAMS


def test_shipped_drive_constant_is_one():
    assert DEFAULT_PARAMS.kt_factor == 1.0


@pytest.mark.parametrize("case", ["nominal", "small", "full"])
def test_drive_constant_fits_to_one_on_every_case(case):
    res = calibrate_kt_factor(case)
    assert res["kt_factor"] == pytest.approx(1.0, abs=2e-4)
    # and the shipped value is as good as the fitted one
    assert res["fitness_shipped"] <= 1.5 * res["fitness"] + 1e-9
