"""Replay of run records (``ema-bench validate --replay K``): re-run the registered solver at
the record's identity and compare what it did.

A record's evidence shows that its vectors have the fitness it states, not *when* they were
found: a solver that peeks at memory it was not given (the problem behind its view, the
caller's frame), or a submitter who moves a hit earlier, produces a record whose trajectory
the registered solver does not reproduce at that identity (root seed, seed, budget).  Replay
builds the instance as the leaderboard did, drops its truth (:meth:`~ema_bench.problem.
Problem.without_truth`: a solver that found the truth in memory during the leaderboard run
finds none now, so its trajectory changes), runs the solver through ``run_solver`` (so it
gets the :class:`~ema_bench.problem.SolverView` only) and compares: the evaluation count, the
trace (every point, evaluation index exactly, fitness to :data:`REPLAY_RTOL`), the ``best_at``
values, the final vector and, for schema-2 records, every trajectory vector.

Bit-for-bit replay needs the BLAS kernel the record was made with: OpenBLAS dispatches on the
CPU (SkylakeX kernels with AVX-512, Haswell ones without), and the finite-difference solvers
(lbfgsb, least-squares) amplify the last-bit differences into another path.  The manifest
records the kernel (``blas``); replay under another one names both in its finding, and
``OPENBLAS_CORETYPE=Haswell`` (or ``Zen``, ``SkylakeX``) replays under the record's.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..faults import FAULT_NAMES
from ..manifest import blas_kernel
from ..registry import run_solver
from ..suites.problem import make_problem
from .run_store import is_error
from .tasks import Task

#: Relative agreement of a replayed fitness or vector with the record's (the runs are
#: deterministic; this leaves room for another CPU's floating-point rounding only).
REPLAY_RTOL = 1e-6
#: The seed of the default sample of records to replay.
REPLAY_SEED = 29


@dataclass(frozen=True)
class ReplayResult:
    key: str
    finding: str | None     # None: reproduced
    wall_s: float


def sample(records: list[dict], k: int | None, seed: int = REPLAY_SEED,
           keys: set[str] | None = None) -> list[dict]:
    """``k`` records drawn without replacement with ``seed`` (all of them for None), in
    file order, or (``keys``) the records so named; error records are left out (there is
    nothing to reproduce)."""
    pool = [r for r in records if not is_error(r) and (keys is None or r.get("key") in keys)]
    if k is None or k >= len(pool):
        return pool
    pick = np.random.default_rng(seed).choice(len(pool), size=k, replace=False)
    return [pool[i] for i in sorted(pick)]


def compare(record: dict, history: dict[str, np.ndarray], x: np.ndarray) -> str | None:
    """The first difference between a record and its replay (``history``: the replayed
    problem's log; ``x``: its final vector), None when reproduced."""
    n = int(history["fitness"].size)
    if n != record["evaluations"]:
        return f"evaluations: recorded {record['evaluations']}, replayed {n}"
    best = history["best"]
    for e, f in record["trace"]:
        if not 1 <= e <= n or not math.isclose(f, best[e - 1], rel_tol=REPLAY_RTOL):
            got = float(best[e - 1]) if 1 <= e <= n else None
            return f"trace at evaluation {e}: recorded {f!r}, replayed {got!r}"
    for b, f in record.get("best_at", []):
        if not 1 <= b <= n or not math.isclose(f, best[b - 1], rel_tol=REPLAY_RTOL):
            return f"best_at {b}: recorded {f!r}, replayed {best[min(b, n) - 1]!r}"
    mine = [record["x"][k] for k in FAULT_NAMES]
    if not np.allclose(mine, x[:len(mine)], rtol=REPLAY_RTOL, atol=0.0):
        return f"x: recorded {mine}, replayed {[float(v) for v in x[:len(mine)]]}"
    for e, _, v in record.get("trajectory") or []:
        if not 1 <= e <= n or not np.allclose(v, history["x"][e - 1], rtol=REPLAY_RTOL,
                                               atol=0.0):
            return f"trajectory vector at evaluation {e}: not reproduced"
    return None


def replay(records: list[dict], k: int | None = None, seed: int = REPLAY_SEED,
           keys: set[str] | None = None) -> list[ReplayResult]:
    """Replay ``k`` sampled records (all for None; only those named ``keys``); one result
    each."""
    out = []
    for r in sample(records, k, seed, keys):
        t0 = time.perf_counter()
        task = Task(r["solver"], r["case"], r["track"], int(r["seed"]), int(r["budget"]),
                    int(r.get("root_seed", 0)))
        try:
            # the truthful problem is freed at once: while the solver runs, no truth of a
            # non-public instance is in memory to be read
            problem = make_problem(task.case, track=task.track, seed=task.node(),
                                   budget=task.budget).without_truth()
            res = run_solver(task.solver, problem, task.budget, seed=task.node())
            finding = compare(r, problem.history(), res.x)
        except Exception as exc:   # a solver that cannot be replayed is a finding, not a crash
            finding = f"replay failed: {type(exc).__name__}: {exc}"
        made = (r.get("manifest") or {}).get("blas")
        if finding and made != blas_kernel():
            finding += (f" (made under BLAS kernel {made or 'unrecorded'}, replayed under "
                        f"{blas_kernel()}: OPENBLAS_CORETYPE picks the kernel)")
        out.append(ReplayResult(r.get("key", "?"), finding, time.perf_counter() - t0))
    return out
