"""The unit of work: one solver on one (case, track, seed) instance, and how to run it."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..records import run_record
from ..registry import get_solver, run_solver
from ..seeding import run_seed
from ..suites import suite_of
from ..suites.problem import make_problem
from ..sweep.executors import Failure
from .run_store import IDENTITY_FIELDS


@dataclass(frozen=True)
class Task:
    """One run.  ``seed`` indexes the instance (noise, random cases): every solver sees the
    same instance for the same (case, track, seed)."""

    solver: str
    case: str
    track: str
    seed: int
    budget: int
    root_seed: int = 0

    @property
    def identity(self) -> tuple:
        """:func:`~ema_bench.leaderboard.run_store.run_identity` of this task's record."""
        return (self.solver, self.case, self.track, self.seed, self.budget, self.root_seed,
                suite_of(self.case).model_version)

    @property
    def key(self) -> str:
        return f"{self.solver}|{self.case}|{self.track}|{self.seed}"

    def node(self) -> np.random.SeedSequence:
        """The run node: instance, noise and solver streams all come from it (every solver
        sees the same instance; ``ema-bench solve --root-seed R --seed k`` replays it)."""
        return run_seed(self.root_seed, self.seed)


def make_tasks(solvers, cases, tracks, seeds: int, budget: int | Callable[[str], int],
               root_seed: int = 0, shard: tuple[int, int] = (0, 1)) -> list[Task]:
    """Every (solver, case, track, seed) run, in a fixed order; ``shard=(i, n)`` keeps the
    i-th of n interleaved slices (0-based) so n machines can share a sweep.  ``budget`` may
    be a function of the case (suite emafdi-v2: a multiple of the tier's dimension)."""
    i, n = shard
    if not (n >= 1 and 0 <= i < n):
        raise ValueError(f"shard must be i/n with 0 <= i < n, got {i}/{n}")
    for s in solvers:
        get_solver(s)  # unknown names fail before anything runs
    per_case = budget if callable(budget) else (lambda _case: budget)
    all_tasks = [Task(s, c, t, k, int(per_case(c)), root_seed)
                 for t in tracks for c in cases for s in solvers for k in range(seeds)]
    return all_tasks[i::n]


def run_task(task: Task) -> dict:
    """Run one task and return its JSON record (deterministic apart from ``wall_s``)."""
    t0 = time.perf_counter()
    problem = make_problem(task.case, track=task.track, seed=task.node(), budget=task.budget)
    result = run_solver(task.solver, problem, task.budget, seed=task.node())
    return run_record(problem, result, case=task.case, track=task.track, seed=task.seed,
                      budget=task.budget, root_seed=task.root_seed,
                      wall_s=time.perf_counter() - t0, info=get_solver(task.solver).library)


def failure_record(task: Task, failure: Failure) -> dict[str, Any]:
    """The record of a run that raised: its identity and the error, and no score (scores
    count it as an unsuccessful run at its budget; a score a record carries is not read).
    The ``on_error`` of the leaderboard's sweep."""
    return {"key": task.key, **{f: getattr(task, f) for f in IDENTITY_FIELDS},
            "model_version": suite_of(task.case).model_version, "suite": suite_of(task.case).id,
            "status": "error",
            "error_type": failure.error_type, "error": failure.error,
            "traceback": failure.traceback, "wall_s": failure.wall_s}


def error_record(task: Task, exc: BaseException, wall_s: float = 0.0) -> dict[str, Any]:
    """The :func:`failure_record` of a run that raised ``exc``."""
    return failure_record(task, Failure.of(exc, wall_s))
