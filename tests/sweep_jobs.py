"""Tiny real sweeps of the five long-running commands, for the fault-injection suite
(``tests/test_sweep_engine_faults.py``).

Usage: ``python tests/sweep_jobs.py COMMAND OUT WORKERS``; exit status as the command's.

Each job runs the command's own code on the sweep engine, only smaller:

- ``leaderboard``: ``ema-bench leaderboard`` (random solver, 4 seeds, budget 400);
- ``coverage``: ``ema-bench coverage`` (4 instances, differential evolution at 60 evaluations);
- ``track``: ``ema-bench campaign track`` on a 4-unit synthetic campaign (made once, under
  ``OUT/../campaign``) with ``slow-age``: the ``rul-age`` reference, 0.2 s per inspection;
- ``track-exit``: the same with ``exits-on-u001``, whose worker dies on unit ``u001``;
- ``blind``: ``ema-bench blind`` of 4 cases whose diagnosis (``blind.run_case``, a minute
  per case) is replaced by one that scores a perfect diagnosis after 0.5 s;
- ``targets``: ``ema-bench targets`` of 4 entries (``small``, ``full`` x both tracks, seed 0)
  with polishing stages of 20 to 30 evaluations (set when this file runs as a script, so its spawned
  workers polish alike; a test importing it sets them with ``monkeypatch``, as it replaces
  the blind diagnosis).

Module-level definitions only: spawned workers import this file again as their main module.
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from ema_bench.prognostics.tracking import Inspection, TrackStep, register_tracker
from ema_bench.suites import best_known

TINY_STAGES = (("least-squares", 20, "truth"), ("powell", 20, "previous"),
               ("cmaes", 30, "nominal"))
if __name__ in ("__main__", "__mp_main__"):   # this script and its spawned workers only
    best_known.STAGES = TINY_STAGES
UNITS, FLIGHTS = ("u000", "u001", "u002", "u003"), (0, 10, 20, 30)


@register_tracker("slow-age", description="test tracker: rul-age, 0.2 s per inspection")
def slow_age(campaign_info, seed):
    from ema_bench.faults import FAULT_NAMES, LOWER, NOMINAL, UPPER

    def step(insp: Inspection) -> TrackStep:
        time.sleep(0.2)
        return TrackStep(flight=insp.flight,
                         estimate={n: float(v) for n, v in zip(FAULT_NAMES, NOMINAL)},
                         low={n: float(v) for n, v in zip(FAULT_NAMES, LOWER)},
                         high={n: float(v) for n, v in zip(FAULT_NAMES, UPPER)},
                         rul=float(insp.flight), rul_low=0.0, rul_high=math.inf,
                         failing_fault=None, replace=insp.flight >= 20, evaluations=0)
    return step


@register_tracker("exits-on-u001", description="test tracker: slow-age that kills its "
                  "worker process on unit u001")
def exits_on_u001(campaign_info, seed):
    import os

    step = slow_age(campaign_info, seed)

    def exiting(insp: Inspection) -> TrackStep:
        if insp.unit == "u001":
            os._exit(3)
        return step(insp)
    return exiting


def slow_perfect_case(case, seed, settings):
    """A blind case's record after 0.5 s: a diagnosis naming the hidden effects exactly."""
    from types import SimpleNamespace

    from ema_bench.diagnosis.blind import case_record, score

    time.sleep(0.5)
    found = [SimpleNamespace(name=k, params={k: v}, interval=[v, v], partial=False)
             for k, v in case.effects.items()] if case.kind == "effect" else []
    verdict = "effect" if found else "unexplained" if case.kind == "decoy" else "none"
    d = SimpleNamespace(verdict=verdict, effects=found, gap={"partial": None})
    return {**case_record(case, seed), "verdict": verdict, "named": [e.name for e in found],
            "partial": None, "gap_closed": 1.0 if found else 0.0, "gap_before": 1.0,
            "gap_after": 0.0 if found else 1.0, "message": "", "evaluations": 0,
            **score(case, d), "wall_s": 0.0}


def campaign(root: Path) -> Path:
    """A 4-unit twin campaign of 4 inspections each (made once)."""
    from ema_bench.effects import N_EFFECTS
    from ema_bench.faults import NOMINAL
    from ema_bench.instances import twin_traces
    from ema_bench.prognostics.laws import THRESHOLDS
    from ema_bench.protocol import STANDARD_TESTS
    from ema_bench.seeding import child

    if (root / "manifest.json").exists():
        return root
    units = []
    for u, unit in enumerate(UNITS):
        (root / unit).mkdir(parents=True, exist_ok=True)
        items = []
        for i, f in enumerate(FLIGHTS):
            rel = f"{unit}/i{i:03d}.npz"
            x = np.array([1.0, NOMINAL[1] + 4e-3 * f, 0.001, 1e5])
            twin_traces(x, np.zeros(N_EFFECTS), child(7, 10 * u + i),
                        STANDARD_TESTS).save(root / rel)
            items.append({"index": i, "flight": f, "file": rel, "conditions": {
                "ambient_temp_C": 25.0, "winding_temp_C": 20.0,
                "flights_since_last": 10 if i else 0, "duty_since_last": 10.0 if i else 0.0}})
        units.append({"unit": unit, "inspections": items})
    manifest = {"format": "ema-bench-campaign", "version": 2, "name": "faults",
                "definition_version": 2, "track": "twin", "seed": 0, "split": "test",
                "inspection_every": 10, "tests": ["step", "sine"], "thresholds": THRESHOLDS,
                "laws": {}, "cut_rule": {"rule": "nearest-inspection-to-uniform-share",
                                         "stop": [0.5, 0.95]}, "units": units}
    tmp = root / "manifest.json.tmp"
    tmp.write_text(json.dumps(manifest))
    tmp.replace(root / "manifest.json")
    return root


def run(command: str, out: Path, workers: int) -> int:
    """Run the tiny sweep of ``command`` into ``out``; the command's exit status."""
    from ema_bench.cli import main

    w = ["--workers", str(workers)]
    if command == "leaderboard":
        return main(["leaderboard", "--solvers", "random", "--cases", "small", "--tracks",
                     "twin", "--seeds", "4", "--budget", "400", "--executor",
                     "serial" if workers == 1 else "processes", *w, "--no-plots",
                     "--quiet", "--out", str(out)])
    if command == "coverage":
        return main(["coverage", "--instances", "4", "--budget", "60", *w, "--quiet",
                     "--json", "--out", str(out)])
    if command == "track":
        return main(["campaign", "track", str(campaign(out.parent / "campaign")),
                     "--tracker", "slow-age", *w, "--quiet", "--json", "--out", str(out)])
    if command == "track-exit":
        return main(["campaign", "track", str(campaign(out.parent / "campaign")),
                     "--tracker", "exits-on-u001", *w, "--quiet", "--json", "--out", str(out)])
    if command == "blind":
        return main(["blind", "--cases", "4", "--seed", "5", *w, "--quiet", "--json",
                     "--out", str(out)])
    if command == "targets":
        out.mkdir(parents=True, exist_ok=True)
        return main(["targets", "--cases", "small,full", "--seeds", "1", "--tracks",
                     "reference,twin", *w, "--quiet", "--out", str(out / "targets.json")])
    raise SystemExit(f"unknown job {command!r}")


if __name__ in ("__main__", "__mp_main__"):   # this script and its spawned workers only
    from ema_bench.diagnosis import blind

    blind.run_case = slow_perfect_case

if __name__ == "__main__":
    sys.exit(run(sys.argv[1], Path(sys.argv[2]), int(sys.argv[3])))
