"""Identifiability report of every tier of suite emafdi-v2 on the twin track (docs/suite-v2.md).

For each instance of a tier, the Laplace intervals at the truth (no polish, no calibration:
the noise-whitened Jacobian of the tests, :mod:`ema_bench.uncertainty`) under the standard
tests and under the step test alone; per parameter the widest 95 % interval over the
tier's instances (in % of range), the instances where it is non-identifiable (interval wider
than 5 % of range) and the confounded pairs (|r| > 0.9).  Each condition's problem carries
its own objective (tests and output weights: ``surface-current`` weighs ``theta_u`` and
``i_eq`` only), so the interval's Jacobian sees exactly what its fitness sees.

    python benchmarks/v2_identifiability.py [--tiers 7,12] [--per-tier 20] \
        [--conditions prior,step-only,surface-current] > report.md
"""

from __future__ import annotations

import argparse
import time
from collections import Counter

import numpy as np

from ema_bench.instances import make_problem
from ema_bench.seeding import run_seed
from ema_bench.suites.v2 import CONDITIONS, TIERS, instance, instance_names
from ema_bench.uncertainty.methods import intervals


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tiers", default=",".join(str(t) for t in TIERS))
    ap.add_argument("--per-tier", type=int, default=20)
    # no-prior shares prior's objective: the same intervals
    ap.add_argument("--conditions", default="prior,step-only,surface-current")
    a = ap.parse_args()
    t0, c0 = time.perf_counter(), time.process_time()
    for d in (int(t) for t in a.tiers.split(",")):
        names = instance_names(d)[:a.per_tier]
        for cond in a.conditions.split(","):
            c = CONDITIONS[cond]
            widths, nonid, conf = [], Counter(), Counter()
            for n in names:
                # a condition with less information is offered on some tiers only: build
                # it through make_problem, with the condition's tests and outputs
                inst = instance(n)
                p = make_problem(inst.faults, track="twin", seed=run_seed(0, 0), budget=1,
                                 effects={k: v for k, v in inst.effects.items() if v},
                                 augment=TIERS[d].effects, tests=c.tests, signals=c.signals)
                iv = intervals(p.objective, inst.truth, method="laplace", track="twin",
                               polish=False, calibrate=False)
                widths.append(iv.width_percent())
                nonid.update(iv.identifiability["non_identifiable"])
                conf.update("/".join(c["pair"]) for c in iv.identifiability["confounded"])
            w = np.max(widths, axis=0)
            print(f"\n### Tier {d}, {cond} ({len(names)} instances)\n")
            print("| parameter | widest 95 % interval, % of range | median | "
                  "non-identifiable on |")
            print("|---|---|---|---|")
            for j, name in enumerate(TIERS[d].names):
                print(f"| {name} | {w[j]:.2f} | {np.median(np.array(widths)[:, j]):.2f} | "
                      f"{nonid.get(name, 0)} of {len(names)} |")
            print(f"\nconfounded pairs (|r| > 0.9; instances): "
                  f"{dict(conf) if conf else 'none'}", flush=True)
    print(f"\n(wall {time.perf_counter() - t0:.0f} s, CPU {time.process_time() - c0:.0f} s)")


if __name__ == "__main__":
    main()
