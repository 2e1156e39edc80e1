"""Cost of one evaluation per tier of suite emafdi-v2: evaluations per CPU second, tiers 7
and 12 against tier 4 (issue 33's targets: tier 7 >= 0.77 x tier 4; tier 12 asked for the
same, which the libm calls of eccentricity and cogging rule out: see docs/suite-v2.md).

The tiers are timed the way a solver meets them: ``objective.evaluate`` (monitor model and
fitness) of batches of candidates drawn uniformly in the tier's box (so a tier-7 candidate
carries a non-zero sensor offset, current gain and feedback delay, a tier-12 one every plant
effect too), on the twin track of a tier's first instance.  Rounds interleave the tiers (a
burst of load from elsewhere hits them alike); every figure is the median over rounds, CPU
time beside wall time, the load average before and after.  One numba thread unless
``NUMBA_NUM_THREADS`` says otherwise.

    NUMBA_NUM_THREADS=1 python benchmarks/tier_cost.py [--batch 32] [--rounds 9] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time

import numpy as np

from ema_bench.suites.problem import make_problem
from ema_bench.suites.v2 import case_key, instance_names


def _timed(fn) -> tuple[float, float]:
    c, w = time.process_time(), time.perf_counter()
    fn()
    return time.perf_counter() - w, time.process_time() - c


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--tiers", default="4,7,12")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    tiers = [int(t) for t in a.tiers.split(",")]
    loads = [os.getloadavg()[0]]
    rng = np.random.default_rng(0)
    setups = {}
    for t in tiers:
        p = make_problem(case_key(instance_names(t)[0], "prior"), track="twin", seed=0, budget=1)
        U = rng.random((a.batch, p.dim))
        X = p.space.check(p.from_unit(U))
        p.objective.evaluate(X)   # compile / load the kernels first
        setups[t] = (p.objective, X)
    cpu: dict[int, list[float]] = {t: [] for t in tiers}
    wall: dict[int, list[float]] = {t: [] for t in tiers}
    for _ in range(a.rounds):
        for t in tiers:
            obj, X = setups[t]
            w, c = _timed(lambda obj=obj, X=X: obj.evaluate(X))
            cpu[t].append(a.batch / c)
            wall[t].append(a.batch / w)
    loads.append(os.getloadavg()[0])
    out = {"batch": a.batch, "rounds": a.rounds,
           "numba_threads": int(os.environ.get("NUMBA_NUM_THREADS", "0")) or None,
           "evals_per_cpu_s": {str(t): statistics.median(cpu[t]) for t in tiers},
           "evals_per_wall_s": {str(t): statistics.median(wall[t]) for t in tiers},
           "load_avg": loads}
    base = out["evals_per_cpu_s"]["4"] if 4 in tiers else None
    if base:
        out["ratio_to_tier4_cpu"] = {str(t): out["evals_per_cpu_s"][str(t)] / base
                                     for t in tiers}
    if a.json:
        print(json.dumps(out, indent=1))
        return
    for t in tiers:
        r = out.get("ratio_to_tier4_cpu", {}).get(str(t))
        print(f"tier {t:>2}: {out['evals_per_cpu_s'][str(t)]:8.1f} evals/CPU-s "
              f"{out['evals_per_wall_s'][str(t)]:8.1f} evals/wall-s"
              + ("" if r is None else f"  ({r:.2f} x tier 4)"))
    print(f"load average before/after: {loads[0]:.2f} / {loads[1]:.2f}")


if __name__ == "__main__":
    main()
