"""Detection thresholds of the acquisition-chain faults, measured (issue 46, item 2).

For each kind on each channel the blind suite draws it on, and each magnitude of a grid, the
fault is applied (:mod:`ema_bench.diagnosis.decoys`) to noisy reference-model records of
``--instances`` random fault vectors (no physical effect), and counted **found** when both

- the workflow's detection fires at the true physics: the monitor model at the true faults,
  assessed against its bootstrap envelopes (:func:`~ema_bench.diagnosis.fitting.assess`:
  the held-out fitness above its threshold or a training statistic outside), and
- the acquisition screen at those outputs ranks that fault first among the 24 candidates,
  with a score of at least ``Settings().min_score``.

The threshold of a kind is the smallest grid magnitude from which every draw of every
channel is found, at it and at every larger magnitude (the effects' ``detect``: the
value the workflow detects and names reliably).  The true physics stands for the base fit:
a fit that absorbs part of the fault makes the threshold a lower bound of the workflow's.

    python benchmarks/acquisition_thresholds.py --instances 3 \\
        --json benchmarks/results/acquisition_thresholds.json

(3 instances: 271 CPU-s.)
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from ema_bench.diagnosis import acquisition as acq
from ema_bench.diagnosis import decoys
from ema_bench.diagnosis.blind import TESTS
from ema_bench.diagnosis.fitting import assess, simulate
from ema_bench.diagnosis.results import TRAIN, Fit, Settings
from ema_bench.diagnosis.sized import CHANNELS, channel_sd, stuck_start
from ema_bench.diagnosis.stiction import stick_weights
from ema_bench.faults import random_faults
from ema_bench.objective import signal_weights
from ema_bench.reference import simulate_reference
from ema_bench.seeding import stream

NAMES = tuple(t.name for t in TESTS)


#: kind -> (magnitude grid in the kind's detect unit, outliers: spike height in noise sd;
#: decoy parameters), on each channel the blind suite draws the kind on (sized.CHANNELS)
GRID = {
    "lowpass": ((2.5e-4, 5e-4, 7.5e-4, 1e-3, 1.5e-3, 2e-3, 3e-3),
                lambda c, m, r: {"signal": c, "tau": m}),
    "time_shift": ((1, 2, 3), lambda c, m, r: {"signal": c, "samples": m}),
    "drift": ((1.0, 2.0, 3.0, 5.0, 7.0, 10.0, 15.0),
              lambda c, m, r: {"signal": c, "rate": m * channel_sd(c) * r.choice((-1, 1))}),
    "mains_hum": ((0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0),
                  lambda c, m, r: {"signal": c, "amplitude": m * channel_sd(c), "freq": 400.0,
                                   "phase": float(r.uniform(0, 2 * np.pi))}),
    "outliers": ((6.0, 8.0, 10.0, 12.0, 16.0, 20.0),
                 lambda c, m, r: {"signal": c, "size": m * channel_sd(c), "fraction": 0.005,
                                  "seed": int(r.integers(2**31))}),
    "stuck": ((0.03, 0.05, 0.1, 0.2), lambda c, m, r: {"signal": c, "start": stuck_start(m)}),
}


def found(record, truth: Fit, name: str, settings: Settings) -> tuple[bool, float]:
    """Whether the fault ``name`` in ``record`` is detected and screened first at the true
    physics, and its screening score."""
    sw = stick_weights(record)
    w = {t: v[None, :] * sw[t] for t, v in signal_weights(record).items()}
    status, _ = assess(record, truth, w, settings, 0)
    best = acq.screen(truth.raw, record.data, sw, TRAIN)[0]
    score = best.score if best.fault.name == name else 0.0
    return bool(status.detected and score >= settings.min_score), float(score)


def measure(instances: int, seed: int) -> dict:
    settings = Settings()
    rows = []
    for i in range(instances):
        x = random_faults(stream(seed, "instance", i), 1.0)
        clean = simulate_reference(x, {}, tests=TESTS, seed=stream(seed, "noise", i))
        out = {t: v[0] for t, v in simulate(x, (), NAMES).items()}
        truth = Fit((), x, 0.0, out, 0, (), out)
        rng = np.random.default_rng(stream(seed, "acquisition", i))
        for kind, (grid, params) in GRID.items():
            for c in CHANNELS[kind]:
                for m in grid:
                    rec = decoys.apply(kind, clean, params(c, m, rng))
                    ok, score = found(rec, truth, f"{kind}({c})", settings)
                    rows.append({"instance": i, "kind": kind, "channel": c, "magnitude": m,
                                 "found": ok, "score": score})
        print(f"instance {i} done", file=sys.stderr, flush=True)
    return {"rows": rows, "thresholds": thresholds(rows)}


def thresholds(rows: list[dict]) -> dict[str, float | None]:
    """Per kind: the smallest grid magnitude from which every draw is found (``None``: not
    even the largest)."""
    out = {}
    for kind, (grid, _) in GRID.items():
        ok = [all(r["found"] for r in rows if r["kind"] == kind and r["magnitude"] == m)
              for m in grid]
        first = None
        for j in range(len(grid) - 1, -1, -1):
            if not ok[j]:
                break
            first = grid[j]
        out[kind] = first
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--instances", type=int, default=3)
    p.add_argument("--seed", type=int, default=46)
    p.add_argument("--json", default=None)
    a = p.parse_args(argv)
    t0 = time.process_time()
    res = measure(a.instances, a.seed)
    res.update(instances=a.instances, seed=a.seed, cpu_s=time.process_time() - t0)
    print(json.dumps(res["thresholds"], indent=1))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
