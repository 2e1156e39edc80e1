"""CMA-ES (pycma) with IPOP restarts, in the normalised box [0, 1]^dim.

The first run starts at ``problem.start`` (the nominal vector unless the problem was given a
warm start) with ``sigma0 = 0.3`` and pycma's default population (``4 + floor(3 ln 4) = 8``
for the four faults); its ``BoundTransform`` keeps every candidate inside ``[0, 1]``.  A
whole generation is one ``problem.evaluate`` call.  When a run stops on its own termination
criteria (tolfun, tolx, stagnation, ...) and budget remains, it restarts IPOP-style: twice the
population, from a uniformly random point of the box.  The start itself is scored first (one
evaluation), so a warm start is never lost.

Budget: pycma would overshoot ``maxfevals`` by up to a population, so the last generation is
truncated to what the problem has left (the first ``k`` candidates are evaluated, then the
search stops without a partial ``tell``).

``bipop-cmaes``: pycma's own BIPOP-CMA-ES (``cma.fmin2(..., restarts=9, bipop=True)``, Hansen
2009): after the first run (pycma's default population, from the problem's start) it
alternates IPOP's doubling populations with runs of small populations and a random initial
step ``sigma0 x 0.01^U`` while their summed evaluations stay below the large runs'; every
restart starts from a uniform random point of the box (``x0`` a callable, as pycma
recommends) and pycma increments its seed per restart.  A generation is one batched call
(``parallel_objective``); the generation that would pass the budget is truncated as above
and the search unwinds out of pycma.
"""

from __future__ import annotations

import time

import numpy as np

from ema_bench.registry import SolveResult, finish, register_solver

from ._common import (
    StopSolver,
    children,
    evaluate_unit,
    global_numpy_rng,
    import_cma,
    int_seed,
    quiet,
    start_unit,
)

SIGMA0 = 0.3
POPSIZE = None  # None: pycma's default, 4 + floor(3 ln n) = 8 for n = 4
IPOP_FACTOR = 2
MAX_RESTARTS = 9


@register_solver("cmaes", description="CMA-ES (pycma) from nominal, sigma0 0.3, IPOP restarts",
                 library="cma", scope="global")
def solve(problem, budget: int, seed: np.random.SeedSequence) -> SolveResult:
    cma = import_cma()

    t0 = time.perf_counter()
    s_x0, *s_runs = children(seed, MAX_RESTARTS + 2)
    rng = np.random.default_rng(s_x0)
    popsize = POPSIZE or 4 + int(3 * np.log(problem.dim))
    x0 = start_unit(problem, seed)   # drawn from the seed on a problem without prior
    stops: list[str] = []
    stop_reason = "budget"
    evaluate_unit(problem, x0[None, :])  # CMA-ES samples around x0 but never scores it
    with global_numpy_rng(), quiet(UserWarning, RuntimeWarning):
        for run in range(MAX_RESTARTS + 1):
            if problem.remaining < 1:
                break
            if run:
                popsize *= IPOP_FACTOR
                x0 = rng.random(problem.dim)
            opts = {"bounds": [0.0, 1.0], "popsize": popsize, "seed": int_seed(s_runs[run]),
                    "maxfevals": problem.remaining, "verbose": -9, "verb_log": 0,
                    "verb_disp": 0}
            es = cma.CMAEvolutionStrategy(x0, SIGMA0, opts)
            while not es.stop() and problem.remaining > 0:
                X = es.ask()
                k = min(len(X), problem.remaining)
                f = evaluate_unit(problem, np.asarray(X[:k]))
                if k < len(X):
                    break  # budget spent mid-generation: no partial tell
                es.tell(X, f.tolist())
            stops.append(",".join(es.stop()) or "budget")
            if problem.remaining == 0:
                break
        else:
            stop_reason = "restarts"
    return finish(problem, "cmaes", stop_reason, t0, libraries=("cma",),
                  restarts=max(len(stops) - 1, 0), run_stops=stops, sigma0=SIGMA0)


#: pycma's IPOP restarts of the large populations (small-population runs come on top).
BIPOP_RESTARTS = 9


@register_solver("bipop-cmaes", description="BIPOP-CMA-ES (pycma fmin2, bipop=True), sigma0 "
                 "0.3, restarts from random points", library="cma", scope="global")
def solve_bipop(problem, budget: int, seed: np.random.SeedSequence) -> SolveResult:
    cma = import_cma()

    t0 = time.perf_counter()
    s_x0, s_cma = children(seed, 2)
    rng = np.random.default_rng(s_x0)
    first = [start_unit(problem, seed)]

    def x0() -> np.ndarray:
        """The problem's start first, then uniform points of the box (one per restart)."""
        return first.pop() if first else rng.random(problem.dim)

    def batch(X: list) -> list[float]:
        k = min(len(X), problem.remaining)
        f = evaluate_unit(problem, np.asarray(X[:k])) if k else np.empty(0)
        if k < len(X):
            raise StopSolver   # budget spent mid-generation: unwind out of pycma
        return f.tolist()

    evaluate_unit(problem, first[0][None, :])   # pycma never scores x0 itself
    opts = {"bounds": [0.0, 1.0], "seed": int_seed(s_cma), "maxfevals": problem.remaining,
            "verbose": -9, "verb_log": 0, "verb_disp": 0}
    stop_reason, runs = "budget", 0
    with global_numpy_rng(), quiet(UserWarning, RuntimeWarning):
        try:
            _, es = cma.fmin2(None, x0, SIGMA0, opts, parallel_objective=batch,
                              restarts={"maxrestarts": BIPOP_RESTARTS,
                                        "maxfevals": problem.remaining},
                              bipop=True, eval_initial_x=False)
            runs = len(es.all_stoppings) - 1
            stop_reason = "budget" if problem.remaining == 0 else "restarts"
        except StopSolver:
            pass
    return finish(problem, "bipop-cmaes", stop_reason, t0, libraries=("cma",),
                  runs=runs, sigma0=SIGMA0)
