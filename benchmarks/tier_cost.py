"""Cost of one evaluation per tier of suite emafdi-v2: evaluations per CPU second on one
thread, tiers 7 and 12 against tier 4 (issue 42's targets: tier 7 >= 0.9 x tier 4, tier 12
>= 0.8 x; docs/suite-v2.md, "The kernel keeps up").

The tiers are timed the way a solver meets them, by ``ema_bench.bench.tier_rates`` (the
figures ``ema-bench bench`` reports as ``tier_evals_per_cpu_s``): ``objective.evaluate``
(monitor model and fitness) of batches of candidates drawn uniformly in the tier's box, on the
twin track of a tier's first instance.  Rounds interleave the tiers (a burst of load from
elsewhere hits them alike); every figure is the median over rounds, CPU time beside wall time,
the load average before and after.

    python benchmarks/tier_cost.py [--batch 32] [--rounds 9] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics

from ema_bench.bench import tier_rates, tier_setups


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    loads = [os.getloadavg()[0]]
    setups = tier_setups(a.batch)
    rounds = [tier_rates(setups) for _ in range(a.rounds)]
    loads.append(os.getloadavg()[0])
    rates = {str(t): statistics.median(r[t] for r in rounds) for t in setups}
    out = {"batch": a.batch, "rounds": a.rounds, "evals_per_cpu_s": rates,
           "ratio_to_tier4_cpu": {t: v / rates["4"] for t, v in rates.items()},
           "load_avg": loads}
    if a.json:
        print(json.dumps(out, indent=1))
        return
    for t, v in rates.items():
        print(f"tier {t:>2}: {v:8.1f} evals/CPU-s  ({out['ratio_to_tier4_cpu'][t]:.2f} x tier 4)")
    print(f"load average before/after: {loads[0]:.2f} / {loads[1]:.2f}")


if __name__ == "__main__":
    main()
