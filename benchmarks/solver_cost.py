"""CPU seconds of one run of each zoo solver per tier of suite emafdi-v2: what a board costs.

One run per solver on the first instance of each tier (condition ``prior``, twin track, the
suite's budget for the tier, solver seed 0), timed with ``time.process_time`` around
``run_solver`` in one process (the instance's data and the kernels are loaded before the
first timed run, so every solver pays only its own work).  CPU time beside wall time and the
load average after each run: a board's cost is the sum of the CPU column times its runs
(docs/suite-v2.md, "The committed board: cost and plan").

    python benchmarks/solver_cost.py [--tiers 4,7,12] [--solvers cmaes,powell] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import time

from ema_bench.registry import available_solvers, run_solver
from ema_bench.suites.problem import make_problem
from ema_bench.suites.v2 import budget, case_key, instance_names


def zoo() -> list[str]:
    """The solvers this project ships (not third-party plugins)."""
    return [n for n, i in available_solvers().items()
            if i.func.__module__.split(".")[0] == "ema_bench_solvers"]


def solver_cost(tier: int, solver: str) -> dict[str, float]:
    """CPU and wall seconds of one run of ``solver`` on ``tier``'s first instance."""
    case = case_key(instance_names(tier)[0], "prior")
    p = make_problem(case, track="twin", seed=0, budget=budget(tier))
    c, w = time.process_time(), time.perf_counter()
    run_solver(solver, p, seed=0)
    return {"cpu_s": time.process_time() - c, "wall_s": time.perf_counter() - w,
            "evaluations": p.evaluations, "load": os.getloadavg()[0]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tiers", default="4,7,12")
    ap.add_argument("--solvers", default=None, help="comma-separated (default: the zoo)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    solvers = a.solvers.split(",") if a.solvers else zoo()
    out: dict[str, dict[str, dict[str, float]]] = {}
    for t in (int(x) for x in a.tiers.split(",")):
        warm = make_problem(case_key(instance_names(t)[0], "prior"), track="twin", seed=0,
                            budget=20)
        run_solver("random", warm, seed=1)   # data made, kernels loaded: not timed
        out[str(t)] = {}
        for s in solvers:
            out[str(t)][s] = r = solver_cost(t, s)
            if not a.json:
                print(f"tier {t:>2} {s:16s} {r['cpu_s']:7.1f} CPU-s {r['wall_s']:7.1f} s wall "
                      f"(load {r['load']:.1f})", flush=True)
        if not a.json:
            print(f"tier {t:>2} all {len(solvers)}: "
                  f"{sum(r['cpu_s'] for r in out[str(t)].values()):.0f} CPU-s")
    if a.json:
        print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
