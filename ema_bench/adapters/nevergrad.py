"""nevergrad on the suite: an ``ExperimentFunction`` per instance and experiment plans in
``nevergrad.benchmark``'s registry, so ``python -m nevergrad.benchmark`` runs the suite.

:class:`EmaBenchFunction` is one suite instance (case, track, noise seed, root seed) as a
nevergrad ``ExperimentFunction`` over the unit box (``ng.p.Array`` bounded to ``[0, 1]^dim``,
starting at the nominal vector).  Each copy nevergrad's benchmark makes is a fresh run with its
own :class:`~ema_bench.problem.Problem` (budget, count, log).  When the experiment ends,
nevergrad asks for the loss of its recommendation (``evaluation_function``); that loss is the
best fitness the problem logged, which costs no evaluation (a recommendation nevergrad never
evaluated is not credited, as for every ema-bench solver), and the run's record, made as the
leaderboard makes it, is appended to ``$EMA_BENCH_RUNS`` (default ``ema_bench_runs.jsonl`` in
the working folder), ready for ``ema-bench validate`` and the board.

Plans: :func:`plan` lists the experiments of the suite (``full``: every ranked instance, both
tracks, 10 seeds, budget 5000, the leaderboard's sweep; ``quick``: the paper cases and
s00-s03, twin track, 2 seeds, budget 100, a smoke run) for the optimisers :data:`OPTIMIZERS`;
:mod:`ema_bench.adapters.nevergrad_plan` registers them in ``nevergrad.benchmark``'s registry
as ``ema_bench`` and ``ema_bench_quick``.  ``nevergrad.benchmark`` imports torch, torchvision
and OpenCV at start-up (its other experiments need them; ``pip install "nevergrad[benchmark]"``
or those three), so that command needs them; this module does not.
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import nevergrad as ng
import numpy as np
from nevergrad.functions import ExperimentFunction

from ema_bench.adapters.run import AdapterRun, append_record, evaluate_unit
from ema_bench.instances import TRACKS
from ema_bench.objective import SearchSpace
from ema_bench.suites.v1 import SANITY_CASES, instance_names

#: where each finished run's record is appended
RUNS_ENV = "EMA_BENCH_RUNS"
DEFAULT_RUNS = "ema_bench_runs.jsonl"
#: the optimisers the plans compare (nevergrad registry names)
OPTIMIZERS = ("NGOpt", "CMA", "TwoPointsDE", "PSO", "RandomSearch")


class EmaBenchFunction(ExperimentFunction):
    """One suite instance as a nevergrad ``ExperimentFunction`` (minimise; unit box).

    Parameters
    ----------
    case, track : str
        Suite instance and track.
    seed, root_seed : int
        Noise seed and root seed (the leaderboard's).
    budget : int
        The problem's evaluation budget (give the experiment the same).
    solver : str
        The name the run is recorded under (the plans use ``ngbench-<optimizer>``).
    """

    def __init__(self, case: str = "small", track: str = "twin", seed: int = 0,
                 budget: int = 1000, root_seed: int = 0, solver: str = "ngbench") -> None:
        self._spec = (solver, case, track, seed, budget, root_seed)
        self._run: AdapterRun | None = None
        space = SearchSpace.of(())
        param = ng.p.Array(init=np.clip(space.to_unit(space.nominal), 0, 1),
                           lower=0.0, upper=1.0).set_name("ema_unit")
        super().__init__(self._fitness, param)

    @property
    def run(self) -> AdapterRun:
        """The run, opened at first use: a plan lists thousands of functions (nevergrad
        counts them by listing them), and a problem's measured traces cost a simulation."""
        if self._run is None:
            self._run = AdapterRun(*self._spec, library="nevergrad")
        return self._run

    def _fitness(self, u: np.ndarray) -> float:
        return float(evaluate_unit(self.run.problem, u)[0])

    def evaluation_function(self, *recommendations: ng.p.Parameter) -> float:
        """The experiment's loss: the best fitness the problem logged (no evaluation spent);
        writes the run's record (once)."""
        if not getattr(self, "_recorded", False) and self.run.problem.evaluations:
            self._recorded = True
            stop = "budget" if self.run.problem.remaining == 0 else "stalled"
            append_record(os.environ.get(RUNS_ENV, DEFAULT_RUNS), self.run.record(stop))
        return float(self.run.problem.best[1])


#: plan name -> (instance group, tracks, seeds, budget)
PLANS: dict[str, tuple[str, tuple[str, ...], int, int]] = {
    "full": ("all", tuple(TRACKS), 10, 5000),
    "quick": ("quick", ("twin",), 2, 100),
}


def plan(name: str = "quick") -> Iterator[tuple[EmaBenchFunction, str, int]]:
    """The experiments of plan ``name`` (:data:`PLANS`): ``(function, optimizer, budget)``
    for each optimiser, track, ranked instance and seed (the sanity case is left out)."""
    group, tracks, seeds, budget = PLANS[name]
    for optimizer in OPTIMIZERS:
        for track in tracks:
            for case in instance_names(group):
                if case in SANITY_CASES:
                    continue
                for k in range(seeds):
                    yield (EmaBenchFunction(case, track, k, budget,
                                            solver=f"ngbench-{optimizer}"), optimizer, budget)
