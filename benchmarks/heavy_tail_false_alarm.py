"""False alarms of the heavy-tailed noise test (issue 46, item 2), measured.

For ``--instances`` random fault vectors, a noisy reference record with no effect and one
with each drawable library effect at 4x its detection threshold (capped at its bound), the
monitor at the true faults without the effect standing for the base fit (its misfit is the
effect's whole signature, more than a fit leaves): the tail share of every channel
(:func:`ema_bench.diagnosis.tails.tail_shares`) and whether the test chooses heavy-tailed
noise (:func:`~ema_bench.diagnosis.tails.detect`).  The false-alarm rate is the share of
records where it does; the margin, the largest second-largest channel share against the
1 % the test needs on two channels.

    python benchmarks/heavy_tail_false_alarm.py --instances 10 \\
        --json benchmarks/results/heavy_tail_false_alarm.json
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np

from ema_bench.diagnosis import tails
from ema_bench.diagnosis.blind import DRAWABLE, TESTS
from ema_bench.diagnosis.fitting import simulate
from ema_bench.diagnosis.results import TRAIN
from ema_bench.effects import EFFECT_INDEX, EFFECTS
from ema_bench.faults import random_faults
from ema_bench.reference import simulate_reference
from ema_bench.seeding import stream

NAMES = tuple(t.name for t in TESTS)


def measure(instances: int, seed: int) -> dict:
    rows = []
    for i in range(instances):
        x = random_faults(stream(seed, "instance", i), 1.0)
        model = {t: v[0] for t, v in simulate(x, (), NAMES).items()}
        for name in (None, *DRAWABLE):
            spec = EFFECTS[EFFECT_INDEX[name]] if name else None
            effects = {name: min(4.0 * spec.detect, spec.upper)} if name else {}
            rec = simulate_reference(x, effects, tests=TESTS, seed=stream(seed, "noise", i))
            ones = {t: np.ones_like(v) for t, v in rec.data.items()}
            shares = tails.tail_shares(model, rec.data, ones, TRAIN)
            rows.append({"instance": i, "effect": name, "shares": shares,
                         "chosen": tails.detect(model, rec.data, ones, TRAIN) is not None})
        print(f"instance {i} done", file=sys.stderr, flush=True)
    second = [sorted(r["shares"].values())[-2] for r in rows]
    return {"rows": rows, "records": len(rows), "false_alarms": sum(r["chosen"] for r in rows),
            "largest_second_share": max(second),
            "largest_share": {c: max(r["shares"][c] for r in rows) for c in rows[0]["shares"]},
            "needed": {"share": tails.TAIL_SHARE, "channels": tails.TAIL_CHANNELS}}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--instances", type=int, default=10)
    p.add_argument("--seed", type=int, default=46)
    p.add_argument("--json", default=None)
    a = p.parse_args(argv)
    t0 = time.process_time()
    res = measure(a.instances, a.seed)
    res.update(instances=a.instances, seed=a.seed, cpu_s=time.process_time() - t0)
    print(json.dumps({k: v for k, v in res.items() if k != "rows"}, indent=1,
                     default=lambda v: None if isinstance(v, float) and math.isnan(v) else v))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
