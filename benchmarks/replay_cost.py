"""CPU of ``validate --replay K``: each record in its own worker process against the same runs
in the verdict's process (issue 48's target: within 1.5x).

    python benchmarks/replay_cost.py [--runs leaderboards/runs.jsonl] [--k 12] [--seed 1]
        [--out benchmarks/results/replay_cost.txt]

Samples ``k`` records of the board with ``seed`` (:func:`ema_bench.leaderboard.replay.sample`),
then, interleaved, (a) the replay as ``validate`` runs it (:func:`~ema_bench.leaderboard.
replay.replay`: one fresh process per record, one at a time), CPU of this process and its
reaped children, and (b) the same runs in this process (``run_solver`` on the truthless
problem, what replay did before the worker), CPU of this process.  (a) then (b) then (a)
again, so neither order favours one; the load average is printed beside.  The kernels are
loaded (compiled, after an edit of the package) before, so that neither pays it.  ``--out``
writes the table to a file as well.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import time
from pathlib import Path


def _cpu() -> float:
    own = time.process_time()
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own + kids.ru_utime + kids.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", default="leaderboards/runs.jsonl")
    ap.add_argument("--k", type=int, default=12)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, help="also write the table here")
    args = ap.parse_args()
    _warm()

    from ema_bench.leaderboard.replay import _job, replay, sample
    from ema_bench.registry import run_solver

    records = [json.loads(line) for line in Path(args.runs).read_text().splitlines() if line]
    records = [r for r in records if "error" not in r]
    picked = sample(records, args.k, args.seed)

    def isolated() -> tuple[float, float, int]:
        c0, w0 = _cpu(), time.perf_counter()
        found = replay(records, args.k, args.seed, workers=1)
        return _cpu() - c0, time.perf_counter() - w0, sum(r.finding is None for r in found)

    def in_process() -> tuple[float, float, int]:
        c0, w0 = _cpu(), time.perf_counter()
        for i, r in enumerate(picked):
            solver, problem, budget, node, scheme = _job(i, r).data
            run_solver(solver, problem, budget, seed=node, seed_scheme=scheme)
        return _cpu() - c0, time.perf_counter() - w0, len(picked)

    load = os.getloadavg()[0]
    rows = [("workers", isolated()), ("in-process", in_process()), ("workers", isolated())]
    lines = [f"{args.k} records of {args.runs} (sample seed {args.seed}); load average "
             f"{load:.2f} at the start, {os.getloadavg()[0]:.2f} at the end"]
    for name, (cpu, wall, n) in rows:
        lines.append(f"  {name:10s} {cpu:7.1f} CPU-s {wall:7.1f} s wall  ({n} reproduced/run)")
    worker_cpu = (rows[0][1][0] + rows[2][1][0]) / 2
    lines.append(f"  ratio workers / in-process (CPU): {worker_cpu / rows[1][1][0]:.2f}")
    print("\n".join(lines))
    if args.out:
        args.out.write_text("\n".join([f"python benchmarks/replay_cost.py --k {args.k} "
                                        f"--seed {args.seed}", *lines]) + "\n")


def _warm() -> None:
    """Every monitor kernel (serial and parallel, scalar and lanes) loaded once, so that a
    cold numba cache is compiled here, not in the first pass timed."""
    import numpy as np

    from ema_bench.faults import NOMINAL
    from ema_bench.monitor import simulate_monitor

    X = np.tile(NOMINAL, (16, 1))
    for parallel in (False, True):
        for lanes in (False, True):
            simulate_monitor(X, parallel=parallel, lanes=lanes)


if __name__ == "__main__":
    main()
