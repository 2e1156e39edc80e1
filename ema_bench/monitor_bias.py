"""Check of the monitor's drive constant, ``kt_factor`` (a torque-constant multiplier).

Earlier monitors needed ``kt_factor`` = 0.9971, fitted on the healthy actuator: most of it was
their own 50 us integration error (end-of-step current applied as torque, sampled hysteresis in
the reference), the rest the commutation torque deficit of the three-phase bridge.  The monitor
now models both (step-mean current, commutation transfer), so the constant fitted on clean
reference traces at the known faults is 1.0000 +- 5e-5 on every case: nothing left to
calibrate, and ``kt_factor`` ships at 1.  This module reproduces that check; a fitted value
away from 1 means the monitor and the reference have drifted apart.

Run ``python -m ema_bench.monitor_bias`` to reproduce it.  :func:`clean_bias` measures the
monitor's model-form bias on the faults themselves (``benchmarks/clean_bias.py`` tabulates it).
"""

from __future__ import annotations

import json

import numpy as np
from scipy.optimize import minimize_scalar

from .faults import CASES
from .monitor import simulate_monitor
from .objective import Objective, fitness_from_outputs, signal_weights
from .params import DEFAULT_PARAMS, EMAParams
from .reference import simulate_reference


def calibrate_kt_factor(case: str = "nominal", params: EMAParams = DEFAULT_PARAMS,
                        bounds: tuple[float, float] = (0.99, 1.01)) -> dict[str, float]:
    """Fit ``kt_factor`` so the monitor matches clean reference traces at the known faults.

    Returns the fitted value and the fitness at it and at the shipped value."""
    x = CASES[case].x
    ref = simulate_reference(x, params=params, noise=False, adc=False)
    weights = signal_weights(ref)

    def fitness(k: float) -> float:
        out, _ = simulate_monitor(x[None, :], params=params.replace(kt_factor=k))
        return float(fitness_from_outputs(out, ref, weights)[0])

    res = minimize_scalar(fitness, bounds=bounds, method="bounded", options={"xatol": 1e-6})
    return {"case": case, "kt_factor": float(np.round(res.x, 5)), "fitness": float(res.fun),
            "fitness_shipped": fitness(params.kt_factor)}


def clean_bias(x_true: np.ndarray, evals: int = 6000, seed: int = 1,
               sigmas: tuple[float, ...] = (0.02, 0.002),
               params: EMAParams = DEFAULT_PARAMS) -> dict[str, object]:
    """The monitor's best fit to noise-free reference traces, polished from the truth.

    No solver can get closer to the truth than this point on clean data: its distance from
    the truth is the monitor's model-form bias.  One CMA-ES run per initial step in
    ``sigmas`` (fractions of each fault's range) starts at the truth; the best end point
    counts (the truth itself where nothing beats it).  Two steps, because some instances sit
    in valleys far narrower than 2 % of a range (high friction with a high loop gain: the
    stick-slip pattern of the hold phase changes within 1e-4 of the Gprop range), where a
    wide CMA-ES never samples a point as good as its start.  ``params``: the monitor's
    (another model version's, :func:`ema_bench.params.model_params`); the reference data
    always come from ``DEFAULT_PARAMS``.

    Returns
    -------
    dict
        ``range_error`` (4,): signed best-minus-truth in fractions of each range;
        ``fitness_truth``, ``fitness_best``.
    """
    import cma

    objective = Objective(simulate_reference(x_true, noise=False, adc=False), params=params)
    space = objective.space

    def fitness(U: np.ndarray) -> np.ndarray:
        return objective.evaluate(space.from_unit(np.clip(np.atleast_2d(U), 0.0, 1.0)))[0]

    u0 = space.to_unit(np.asarray(x_true, dtype=float))
    f0 = float(fitness(u0)[0])
    best_u, best_f = u0, f0
    for sigma in sigmas:
        es = cma.CMAEvolutionStrategy(u0, sigma, {
            "bounds": [0, 1], "popsize": 16, "verbose": -9, "seed": seed, "tolfun": 1e-14,
            "tolx": 5e-6 * sigma, "maxfevals": evals})
        while not es.stop():
            X = es.ask()
            es.tell(X, fitness(np.array(X)).tolist())
        if es.result.fbest < best_f:
            best_u, best_f = es.result.xbest, float(es.result.fbest)
    return {"range_error": best_u - u0, "fitness_truth": f0, "fitness_best": best_f}


if __name__ == "__main__":  # pragma: no cover
    print(json.dumps([calibrate_kt_factor(c) for c in CASES], indent=1))
