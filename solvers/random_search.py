"""Random-search baseline: ``problem.start`` (the nominal vector unless warm-started), then
Latin-hypercube batches of 256.

Each batch is a fresh Latin hypercube of the normalised box (scipy ``qmc.LatinHypercube``,
seeded) evaluated in one ``problem.evaluate`` call; the last batch is cut to the budget.
"""

from __future__ import annotations

import time

import numpy as np

from ema_bench.registry import SolveResult, finish, register_solver

from ._common import child, evaluate_unit, lhs, start_unit

BATCH = 256


@register_solver("random", description="random search: nominal, then Latin-hypercube batches "
                 "of 256", library="scipy", scope="baseline")
def solve(problem, budget: int, seed: np.random.SeedSequence) -> SolveResult:
    t0 = time.perf_counter()
    batches = 0
    while problem.remaining > 0:
        k = min(BATCH, problem.remaining)
        U = lhs(child(seed, batches), k, problem.dim)
        if batches == 0 and problem.start is not None:   # without prior: all random
            U[0] = start_unit(problem)
        evaluate_unit(problem, U)
        batches += 1
    return finish(problem, "random", "budget", t0, libraries=("scipy",), batches=batches)
