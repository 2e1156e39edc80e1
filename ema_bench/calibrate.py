"""Calibration of the monitor's one drive constant, ``kt_factor``.

The monitor's single-phase pair model assumes the ideal torque ``Kt I``; the three-phase
bridge of the reference loses a little torque at every commutation (the outgoing phase's
current decays while the incoming one rises).  Left out, that deficit biases the fitted ``Na``
0.6-0.7 % low on the reference track, healthy actuator included.  It is a property of the
drive, not of a fault, so it is fitted once on the healthy actuator (clean reference traces,
faults known) as an engineer would calibrate a monitor on a new unit.

Run ``python -m ema_bench.calibrate`` to reproduce the shipped value.
"""

from __future__ import annotations

import json

import numpy as np
from scipy.optimize import minimize_scalar

from .faults import CASES
from .monitor import simulate_monitor
from .params import DEFAULT_PARAMS, EMAParams
from .problem import fitness_from_outputs, signal_scales
from .reference import simulate_reference


def calibrate_kt_factor(case: str = "nominal", params: EMAParams = DEFAULT_PARAMS,
                        bounds: tuple[float, float] = (0.98, 1.01)) -> dict[str, float]:
    """Fit ``kt_factor`` so the monitor matches clean reference traces at the known faults.

    Returns the fitted value and the fitness at it and at 1 (no correction)."""
    x = CASES[case].x
    ref = simulate_reference(x, params=params, noise=False, adc=False)
    weights = {t: 1.0 / s**2 for t, s in signal_scales(ref).items()}

    def fitness(k: float) -> float:
        out, _ = simulate_monitor(x[None, :], params=params.replace(kt_factor=k))
        return float(fitness_from_outputs(out, ref, weights)[0])

    res = minimize_scalar(fitness, bounds=bounds, method="bounded", options={"xatol": 1e-6})
    return {"case": case, "kt_factor": float(np.round(res.x, 5)), "fitness": float(res.fun),
            "fitness_uncorrected": fitness(1.0)}


if __name__ == "__main__":  # pragma: no cover
    print(json.dumps([calibrate_kt_factor(c) for c in CASES], indent=1))
