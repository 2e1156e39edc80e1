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
records the kernel (``blas``), and each record is replayed under its own: the records made
under this process's kernel here, those of another OpenBLAS kernel in a child process started
with ``OPENBLAS_CORETYPE`` set to it (OpenBLAS picks its kernel once, when it loads, and the
workers are forked from a server that loaded it), where the CPU can run that kernel (the
AVX-512 ones need ``avx512f``).  A record whose kernel cannot be had here is still replayed,
and a finding names both kernels.

The solver never runs in this process: each sampled record's run goes to a fresh worker
process (:mod:`.replay_worker`, the sweep engine's ``isolated`` executor, forked from a server
that imported the package and loaded its kernels once, :mod:`.replay_server`), which gets the
truthless instance, the budget, the run node and the record's seed scheme (the solver's seed
is derived from the node by it, as in the run), never the record, and sends back the
problem's log and its count of model evaluations; the comparison happens here.  The sample
is drawn from fresh entropy unless a seed is given (:mod:`ema_bench.sampling`), so nobody
can tell beforehand which records will be replayed.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..escape import terminal
from ..faults import FAULT_NAMES
from ..manifest import blas_kernel
from ..records import seed_scheme
from ..sampling import sample_indices
from ..suites.problem import make_problem
from ..sweep.executors import Job, execute
from .derive import params_of
from .replay_worker import replay_job
from .run_store import is_error
from .tasks import Task

#: What the fork server of the workers imports (trusted code only, never a plugin): the
#: package's modules and kernels, once (:mod:`.replay_server`); each worker is a fork of it.
SERVER_PRELOAD = ("ema_bench.leaderboard.replay_server",)

#: Relative agreement of a replayed fitness or vector with the record's (the runs are
#: deterministic; this leaves room for another CPU's floating-point rounding only).
REPLAY_RTOL = 1e-6


@dataclass(frozen=True)
class ReplayResult:
    key: str
    finding: str | None     # None: reproduced
    wall_s: float


def sample(records: list[dict], k: int | None, seed: int,
           keys: set[str] | None = None) -> list[dict]:
    """``k`` records drawn without replacement with ``seed`` (all of them for None), in
    file order, or (``keys``) the records so named; error records are left out (there is
    nothing to reproduce)."""
    pool = [r for r in records if not is_error(r) and (keys is None or r.get("key") in keys)]
    return [pool[i] for i in sample_indices(len(pool), k, seed)]


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
            return f"best_at {b}: recorded {f!r}, replayed {float(best[min(b, n) - 1])!r}"
    mine = [record["x"][k] for k in FAULT_NAMES]
    if not np.allclose(mine, x[:len(mine)], rtol=REPLAY_RTOL, atol=0.0):
        return f"x: recorded {mine}, replayed {[float(v) for v in x[:len(mine)]]}"
    for e, _, v in record.get("trajectory") or []:
        if not 1 <= e <= n or not np.allclose(v, history["x"][e - 1], rtol=REPLAY_RTOL,
                                               atol=0.0):
            return f"trajectory vector at evaluation {e}: not reproduced"
    return None


def _job(i: int, r: dict) -> Job:
    """The worker's task: what a solver may see of the record's run, never the record; the
    problem is built on the record's own model version (:func:`~.derive.params_of`: a
    version-2 record on libm's trigonometry), so a run replays on the model it was made on."""
    task = Task(r["solver"], r["case"], r["track"], int(r["seed"]), int(r["budget"]),
                int(r.get("root_seed", 0)))
    # the truthful problem is dropped here: the worker receives the truthless one only
    problem = make_problem(task.case, track=task.track, seed=task.node(), budget=task.budget,
                           params=params_of(r)).without_truth()
    return Job(str(i), i, (task.solver, problem, task.budget, task.node(), seed_scheme(r)))


def _finding(r: dict, out: dict) -> str | None:
    hist = {"fitness": np.asarray(out["fitness"]), "best": np.asarray(out["best"]),
            "x": np.asarray(out["x_hist"])}
    finding = compare(r, hist, np.asarray(out["x"]))
    if finding is None and out["model_evaluations"] > out["evaluations"]:
        finding = (f"the replayed run made {out['model_evaluations']} model evaluations, "
                   f"{out['evaluations']} of them counted: a solver that evaluates the model "
                   "outside its budget")
    return finding


#: OpenBLAS kernels that need AVX-512 (the others in the manifests need AVX2 at most).
AVX512_KERNELS = frozenset({"SkylakeX", "Cooperlake", "SapphireRapids"})


def _cpu_runs(kernel: str) -> bool:
    """Whether this CPU can run OpenBLAS ``kernel`` (forcing one it cannot is a crash)."""
    if kernel not in AVX512_KERNELS:
        return True
    try:
        return "avx512f" in Path("/proc/cpuinfo").read_text().split()
    except OSError:
        return False


def _elsewhere(r: dict, here: str | None) -> str | None:
    """The OpenBLAS kernel ``r`` was made under, where this process (kernel ``here``) also
    runs OpenBLAS, under another kernel that this CPU can run (the record is then replayed
    in a child process under it), else None."""
    made = str((r.get("manifest") or {}).get("blas") or "")
    lib, _, kernel = made.partition(" ")
    mine = lib == "openblas" and (here or "").startswith("openblas ")
    # isalnum: the label goes into the child's environment, so nothing but a name
    return kernel if mine and made != here and kernel.isalnum() and _cpu_runs(kernel) else None


def _replay_under(kernel: str, picked: list[dict], workers: int | None
                  ) -> list[ReplayResult]:
    """Replay ``picked`` in a child process whose OpenBLAS loads ``kernel``."""
    env = {**os.environ, "OPENBLAS_CORETYPE": kernel}
    proc = subprocess.run([sys.executable, "-m", "ema_bench.leaderboard.replay", str(workers or 0)],
                          input=json.dumps(picked), capture_output=True, text=True, env=env)
    if proc.returncode:
        tail = terminal(proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else "")
        return [ReplayResult(_name(r), f"replay failed under BLAS kernel {kernel}: {tail}", 0.0)
                for r in picked]
    return [ReplayResult(**d) for d in json.loads(proc.stdout.strip().splitlines()[-1])]


def replay(records: list[dict], k: int | None, seed: int, keys: set[str] | None = None,
           workers: int | None = None, *, kernels: bool = True) -> list[ReplayResult]:
    """Replay ``k`` records sampled with ``seed`` (all for None; only those named ``keys``),
    each in a fresh worker process (at most ``workers`` at a time), each under the BLAS
    kernel it was made with where this CPU has it (``kernels``; module docstring); one
    result each, in sample order."""
    picked = sample(records, k, seed, keys)
    found: dict[int, ReplayResult] = {}
    if kernels:
        away: dict[str, list[int]] = {}
        here = blas_kernel()
        for i, r in enumerate(picked):
            if (kernel := _elsewhere(r, here)) is not None:
                away.setdefault(kernel, []).append(i)
        for kernel, idx in away.items():
            for i, res in zip(idx, _replay_under(kernel, [picked[i] for i in idx], workers)):
                found[i] = res
    jobs = []
    for i, r in enumerate(picked):
        if i in found:
            continue
        if not _installed(str(r["solver"])):
            found[i] = ReplayResult(_name(r), f"not replayable: solver {_name(r['solver'])!r} "
                                    "is not an installed plugin (an adapter's run, e.g. SciPy "
                                    "through ema_bench.adapters, has no registered solver to "
                                    "re-run): install its package, or do not --replay it", 0.0)
            continue
        try:
            jobs.append(_job(i, r))
        except Exception as exc:   # a record whose instance cannot be built is a finding
            found[i] = ReplayResult(_name(r), f"replay failed: {type(exc).__name__}: {exc}",
                                    0.0)
    workers = workers or max(1, min(len(jobs), os.cpu_count() or 1))
    for o in execute(jobs, replay_job, "isolated", workers, preload=SERVER_PRELOAD) \
            if jobs else ():
        i = o.task.identity
        r = picked[i]
        if o.failure is not None:
            # a solver that cannot be replayed is a finding, not a crash
            finding, wall = f"replay failed: {o.failure.line()}", o.failure.wall_s
        else:
            finding, wall = _finding(r, o.records[0]), o.records[0]["wall_s"]
        made = (r.get("manifest") or {}).get("blas")
        if finding and made != blas_kernel():
            finding += (f" (made under BLAS kernel {made or 'unrecorded'}, replayed under "
                        f"{blas_kernel()}: OPENBLAS_CORETYPE picks the kernel)")
        found[i] = ReplayResult(_name(r), finding, wall)
    return [found[i] for i in sorted(found)]


def _name(r: object) -> str:
    return terminal(r.get("key", "?") if isinstance(r, dict) else r)


def _installed(solver: str) -> bool:
    """Whether an entry point names ``solver`` (read from the metadata: nothing imported)."""
    import importlib.metadata

    from ..registry import ENTRY_POINT_GROUP

    return bool(importlib.metadata.entry_points(group=ENTRY_POINT_GROUP, name=solver))


if __name__ == "__main__":
    # the child of _replay_under: records on stdin, results on stdout, under the kernel its
    # OPENBLAS_CORETYPE chose (never forwarded again: kernels=False)
    _out = replay(json.loads(sys.stdin.read()), None, 0, workers=int(sys.argv[1]) or None,
                  kernels=False)
    print(json.dumps([asdict(x) for x in _out]))
