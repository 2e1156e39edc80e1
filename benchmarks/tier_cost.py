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
    python benchmarks/tier_cost.py --breakdown [--batch 16] [--rounds 9]

``--breakdown``: where tier 12's extra time goes.  The monitor kernel alone (one thread, no
fitness) on the same tier-12 candidates with each of their effects set to zero in turn, and
eccentricity and cogging together, in the lanes and in the scalar kernel (a solver that
evaluates one candidate at a time runs the latter), against tier 4's candidates; and the
objective's time beside the kernel's (fitness and batch set-up).  Times are per candidate,
medians over interleaved rounds.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time

from ema_bench.bench import one_thread, tier_rates, tier_setups
from ema_bench.effects import EFFECT_INDEX
from ema_bench.monitor import simulate_monitor


def breakdown(batch: int, rounds: int) -> dict[str, dict[str, float]]:
    """kernel -> variant -> CPU ms per candidate (see the module doc)."""
    setups = tier_setups(batch)
    (obj4, X4), (obj12, X12) = setups[4], setups[12]
    E12 = obj12.space.effects_for(X12, obj12.effects)
    variants = {"tier 4": (X4[:, :4], None), "tier 12": (X12[:, :4], E12)}
    zeroed = [(name,) for name in obj12.space.augment] + [("eccentricity", "cogging")]
    for names in zeroed:
        E = E12.copy()
        E[:, [EFFECT_INDEX[n] for n in names]] = 0.0
        variants["tier 12 without " + " and ".join(names)] = (X12[:, :4], E)
    variants["tier 12, faults only"] = (X12[:, :4], None)
    calls = {}
    for kernel, lanes in (("lanes", None), ("scalar", False)):
        for label, (X, E) in variants.items():
            calls[kernel, label] = (lambda X=X, E=E, lanes=lanes: simulate_monitor(
                X, E, tests=obj12.tests, parallel=False, check=False, lanes=lanes))
    calls["objective", "tier 4"] = lambda: obj4.evaluate(X4)
    calls["objective", "tier 12"] = lambda: obj12.evaluate(X12)
    cpu: dict[tuple[str, str], list[float]] = {k: [] for k in calls}
    with one_thread():
        for fn in calls.values():
            fn()   # compile or load first
        for _ in range(rounds):
            for key, fn in calls.items():
                c = time.process_time()
                fn()
                cpu[key].append(time.process_time() - c)
    out: dict[str, dict[str, float]] = {}
    for (kernel, label), v in cpu.items():
        out.setdefault(kernel, {})[label] = 1e3 * statistics.median(v) / batch
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--breakdown", action="store_true",
                    help="tier 12's time with each effect set to zero (module doc)")
    a = ap.parse_args()
    loads = [os.getloadavg()[0]]
    if a.breakdown:
        ms = breakdown(a.batch, a.rounds)
        loads.append(os.getloadavg()[0])
        if a.json:
            print(json.dumps({"batch": a.batch, "rounds": a.rounds, "cpu_ms_per_candidate": ms,
                              "load_avg": loads}, indent=1))
            return
        for kernel, rows in ms.items():
            base = rows["tier 4"]
            for label, v in rows.items():
                print(f"{kernel:9s} {label:42s} {v:7.3f} ms  ({base / v:.2f} x tier 4's rate)")
        print(f"load average before/after: {loads[0]:.2f} / {loads[1]:.2f}")
        return
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
