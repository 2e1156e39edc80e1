"""Hand-built schema-2 run records for the scoring tests: a trajectory of points (evaluation,
fitness, vector) chosen by hand, on a real suite instance (its truth and shipped ``f*``).

The claims of a record (``success``, ``targets``, ``best_at``, ...) are filled in from the
re-derivation so that the record is self-consistent; the tests assert hand-computed values
of the scores, which never read those claims.
"""

from __future__ import annotations

import functools
import json

import numpy as np

from ema_bench.faults import FAULT_NAMES, LOWER, UPPER, faults_to_dict
from ema_bench.leaderboard.derive import derive
from ema_bench.leaderboard.tasks import Task, run_task
from ema_bench.manifest import manifest
from ema_bench.records import RECORD_SCHEMA
from ema_bench.seeding import SEED_SCHEME
from ema_bench.suites.v1 import SUITE_ID, best_known, instance_faults
from ema_bench.trace_cache import MODEL_VERSION

F_KEYS = ("0.1", "0.01", "0.001", "0.0001")
P_KEYS = ("0.1", "0.03", "0.01")


def vector(case: str, err: float, fault: str = "Na") -> list[float]:
    """A vector whose largest range error to ``case``'s truth is ``err`` (on ``fault``)."""
    x = instance_faults(case).astype(float).copy()
    i = FAULT_NAMES.index(fault)
    step = err * (UPPER[i] - LOWER[i])
    x[i] = x[i] + step if x[i] + step <= UPPER[i] else x[i] - step
    return [float(v) for v in x]


def level(case: str, track: str, seed: int, p: float) -> float:
    """The fitness at precision ``p`` of the instance's f*-to-nominal gap."""
    k = best_known(case, track, seed)
    return k["f_star"] + p * (k["f_nominal"] - k["f_star"])


def record(points, solver: str = "a", case: str = "small", track: str = "twin",
           seed: int = 0, budget: int = 100, evaluations: int | None = None,
           status: str | None = None, root_seed: int = 0) -> dict:
    """A schema-2 record of ``points`` ``[(evaluation, fitness, vector)]`` (an error record
    with ``status``)."""
    base = {"key": f"{solver}|{case}|{track}|{seed}", "solver": solver, "case": case,
            "track": track, "seed": seed, "budget": budget, "root_seed": root_seed,
            "model_version": MODEL_VERSION, "suite": SUITE_ID}
    if status:
        return {**base, "status": status, "error_type": "RuntimeError", "error": "boom",
                "wall_s": 0.0}
    pts = [[int(e), float(f), [float(v) for v in x]] for e, f, x in points]
    r = {**base, "schema": RECORD_SCHEMA, "seed_scheme": SEED_SCHEME, "manifest": manifest([]),
         "evaluations": evaluations or budget, "trajectory": pts,
         "trace": [[p[0], p[1]] for p in pts], "fitness": pts[-1][1],
         "x": faults_to_dict(np.array(pts[-1][2])), "wall_s": 1.0, "stop_reason": "budget"}
    if r["trace"][-1][0] != r["evaluations"]:
        r["trace"].append([r["evaluations"], pts[-1][1]])
    d = derive(r)
    r.update(success=d.success, evals_to_success=d.evals_to_success, accuracy=d.accuracy,
             range_error=d.range_error, best_at=d.best_at,
             truth=faults_to_dict(instance_faults(case)),
             targets={"fitness": d.fitness_hits, "parameters": d.parameter_hits,
                      **({"f_star": d.f_star, "f_nominal": d.f_nominal}
                         if d.f_star is not None else {})})
    return r


def from_hits(f_hits=(None,) * 4, p_hits=(None,) * 3, budget: int = 100, **kw) -> dict:
    """A record whose fitness targets (1e-1 .. 1e-4) and parameter targets (10, 3, 1 %) are
    first reached at the given evaluations (None: never); ``f_hits`` are ignored on an
    instance without ``f*`` (the sanity case)."""
    case, track, seed = kw.get("case", "small"), kw.get("track", "twin"), kw.get("seed", 0)
    if best_known(case, track, seed) is None:
        f_hits = (None,) * 4
    events = sorted({1, *(h for h in (*f_hits, *p_hits) if h is not None)})
    pts = []
    for k, e in enumerate(events):
        f_done = [p for p, h in zip((1e-1, 1e-2, 1e-3, 1e-4), f_hits) if h is not None and h <= e]
        p_done = [p for p, h in zip((0.1, 0.03, 0.01), p_hits) if h is not None and h <= e]
        q = (0.5 * min(f_done) if f_done else 0.5) * (1 - 1e-6 * k)   # strictly decreasing
        fit = level(case, track, seed, q) if best_known(case, track, seed) else 1.0 + q
        pts.append((e, fit, vector(case, 0.5 * min(p_done) if p_done else 0.3)))
    return record(pts, budget=budget, **kw)


def real_run(solver: str, case: str, track: str, seed: int, budget: int) -> dict:
    """The record of a real run (``run_task``), made once per process; each call returns a
    fresh copy (read back from JSON, as from a file).  Under mutmut the child forked for each
    mutant inherits the runs the clean test run made instead of making them again (they were
    most of a mutant's test time in tests/test_validate.py, test_integrity.py, test_judge.py).
    """
    return json.loads(_real_run(solver, case, track, seed, budget))


@functools.cache
def _real_run(solver: str, case: str, track: str, seed: int, budget: int) -> str:
    return json.dumps(run_task(Task(solver, case, track, seed, budget)))
