"""One adapter run: the suite instance's Problem and the run record it produces.

The record is made exactly as the leaderboard makes it (:func:`~ema_bench.records.run_record`
of the problem's own log, with the instance, noise and solver streams of the run node
:func:`~ema_bench.seeding.run_seed` ``(root_seed, seed)``): a run made through an adapter and
one made by ``ema-bench leaderboard`` are the same kind of record, and both pass
``ema-bench validate``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..leaderboard.tasks import Task
from ..problem import Problem, SolverView
from ..records import run_record
from ..registry import finish
from ..seeding import solver_seed


@dataclass
class AdapterRun:
    """A suite instance opened for an outside optimiser.

    Parameters
    ----------
    solver : str
        The name the run is recorded under (e.g. ``scipy-nelder-mead``, ``pymoo-de``).
    case, track : str
        Suite instance (``small``, ``s03``, ...) and track (``reference`` or ``twin``).
    seed : int
        Noise seed (the leaderboard's row seed).
    budget : int
        Evaluations (each row of a batch counts one); the problem refuses more.
    root_seed : int
        Root of the seed tree (the leaderboard's ``--root-seed``).
    library : str
        The distribution(s) the algorithm comes from, comma-separated (recorded with their
        versions).
    """

    solver: str
    case: str = "small"
    track: str = "reference"
    seed: int = 0
    budget: int = 1000
    root_seed: int = 0
    library: str = ""
    _problem: Problem = field(init=False, repr=False)
    _t0: float = field(init=False, default=0.0)

    def __post_init__(self) -> None:
        from ..suites.problem import make_problem

        self._task = Task(self.solver, self.case, self.track, int(self.seed), int(self.budget),
                          int(self.root_seed))
        self._t0 = time.perf_counter()
        self._problem = make_problem(self.case, track=self.track, seed=self._task.node(),
                                     budget=self.budget)
        self._view = self._problem.view()

    @property
    def problem(self) -> SolverView:
        """What the outside library may reach: the problem's solver view (the counted
        evaluation, bounds, budget, data), never the truth or a score (the record is made
        from the scorer's problem, which stays private to this run)."""
        return self._view

    def node(self) -> np.random.SeedSequence:
        """The run node (``run_seed(root_seed, seed)``): what ``run_solver`` takes as the
        seed of a registered solver run on this problem."""
        return self._task.node()

    def solver_seed(self) -> int:
        """A 32-bit seed for the library's own generator, from the seed every registered
        solver gets (:func:`~ema_bench.seeding.solver_seed`: a one-way hash of the run node,
        which gives nothing of its instance and noise streams away)."""
        return int(solver_seed(self.node()).generate_state(1)[0])

    def record(self, stop_reason: str = "budget", **extra: Any) -> dict[str, Any]:
        """The run's record: the problem's best vector and count, never the library's."""
        libs = tuple(d for d in self.library.split(",") if d)
        result = finish(self._problem, self.solver, stop_reason, self._t0, libraries=libs,
                        **extra)
        return run_record(self._problem, result, case=self.case, track=self.track,
                          seed=self.seed, budget=self.budget, root_seed=self.root_seed,
                          wall_s=time.perf_counter() - self._t0, info=self.library)


def append_record(path: str | Path, record: dict[str, Any]) -> None:
    """Append ``record`` to a ``runs.jsonl`` (the leaderboard's store: one run once, locked
    against concurrent writers)."""
    from ..leaderboard.run_store import RunStore

    with RunStore(Path(path)) as store:
        store.append(record)


def evaluate_unit(problem: SolverView, U: np.ndarray) -> np.ndarray:
    """Fitness of unit-box points ``U`` (n, dim), clipped into the box first (a library's
    bound handling may step 1 ulp outside), as one batched, counted evaluation."""
    U = np.clip(np.atleast_2d(np.asarray(U, dtype=float)), 0.0, 1.0)
    return np.asarray(problem.evaluate(problem.from_unit(U)), dtype=float)
