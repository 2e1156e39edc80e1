"""Solver registry: the built-in zoo and third-party solvers register the same way.

A solver is a function ``solve(problem, budget, seed) -> SolveResult`` decorated with
:func:`register_solver`, in a module named by an entry point of the group
``ema_bench.solvers``::

    # pyproject.toml of any package
    [project.entry-points."ema_bench.solvers"]
    my-solver = "my_package.my_module"

The zoo in ``solvers/`` is registered through ema-bench's own entry points exactly like that.
"""

from __future__ import annotations

import importlib.metadata
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .plugins import PluginRegistry
from .seeding import SEED_SCHEME, SeedLike, solver_seed

if TYPE_CHECKING:
    from .problem import Problem

ENTRY_POINT_GROUP = "ema_bench.solvers"


@dataclass(frozen=True)
class SolveResult:
    """What a solver returns (evaluations are the problem's count, never the solver's)."""

    solver: str
    x: np.ndarray
    fitness: float
    evaluations: int
    stop_reason: str
    wall_s: float
    library: dict[str, str] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)



SolveFn = Callable[["Problem", int, np.random.SeedSequence], SolveResult]

#: What kind of search a solver is, declared where it is registered (``scope=``) and shown by
#: ``ema-bench solvers``: the board's "global vs local without a prior" comparison reads it.
SCOPES = {
    "global": "searches the whole box (population, swarm, sampling model, restarts there)",
    "local": "improves from a start point (multi-start included)",
    "baseline": "no search model: a degenerate reference (random sampling), compared to "
                "neither group",
    "unclassified": "not declared (a plugin that names no scope): compared to neither group",
}


@dataclass(frozen=True)
class SolverInfo:
    name: str
    func: SolveFn
    description: str
    library: str  # distribution(s) the algorithm comes from, e.g. "cma" or "scipy"
    config: dict[str, Any] = field(default_factory=dict)  # keywords passed to func
    scope: str = "unclassified"   # a key of SCOPES: global or local search, or a baseline


class SolverError(LookupError):
    """Unknown solver name or a broken plugin."""


_SOLVERS: PluginRegistry[SolverInfo] = PluginRegistry(ENTRY_POINT_GROUP, "solver", SolverError,
                                                      lambda info: info.func)


def register_solver(name: str, /, *, description: str, library: str,
                    scope: str = "unclassified", **config: Any) -> Callable[[SolveFn], SolveFn]:
    """Decorator: make ``func`` available as solver ``name``.

    ``scope`` (a key of :data:`SCOPES`) says whether it is a global or a local search, or a
    baseline.  Keyword ``config`` is passed to ``func`` on every run: one function registers
    several configured variants (``register_solver("ng-de", ..., optimizer="TwoPointsDE")``)."""
    if scope not in SCOPES:
        raise SolverError(f"solver {name!r}: unknown scope {scope!r}; known: {list(SCOPES)}")

    def deco(func: SolveFn) -> SolveFn:
        _SOLVERS.add(name, SolverInfo(name, func, description, library, dict(config), scope))
        return func
    return deco


def available_solvers() -> dict[str, SolverInfo]:
    """Every registered solver, by name (sorted)."""
    return _SOLVERS.available()


def get_solver(name: str) -> SolverInfo:
    """The solver registered as ``name``, importing its plugin module only: running one
    solver must not pay for importing every library of the zoo (about 1 s); all of them when
    the name is unknown, for the error message."""
    return _SOLVERS.get(name)


def library_versions(*dists: str) -> dict[str, str]:
    """Installed versions of the named distributions (plus numpy and ema-bench)."""
    out = {}
    for d in ("ema-bench", "numpy", *dists):
        try:
            out[d] = importlib.metadata.version(d)
        except importlib.metadata.PackageNotFoundError:
            out[d] = "not installed"
    return out


def finish(problem: Problem, solver: str, stop_reason: str, t0: float,
           libraries: tuple[str, ...] = (), **extra: Any) -> SolveResult:
    """The result record from the problem's own log: its best vector and its count."""
    x, f = problem.best
    return SolveResult(solver=solver, x=x, fitness=f, evaluations=problem.evaluations,
                       stop_reason=stop_reason, wall_s=time.perf_counter() - t0,
                       library=library_versions(*libraries), extra=dict(extra))


def run_solver(name: str, problem: Problem, budget: int | None = None,
               seed: SeedLike = 0, seed_scheme: int = SEED_SCHEME) -> SolveResult:
    """Run a registered solver on ``problem`` and return its result.

    The solver's seed is :func:`~ema_bench.seeding.solver_seed` ``(seed, seed_scheme)``: a
    one-way hash of the run node ``seed`` (scheme 2), from which the solver cannot rebuild the
    node nor draw the instance and noise streams; scheme 1 (the spawned stream) replays the
    committed records made with it.

    The budget is the smaller of ``budget`` and what the problem has left; the problem's
    own counter enforces it, so a solver that overshoots is stopped, not trusted.  The
    returned vector is the best the problem has logged (a solver cannot report a vector it
    never evaluated), and ``evaluations`` is the problem's count.
    """
    from .problem import BudgetExhausted
    from .threads import blas_single_thread

    info = get_solver(name)
    budget = problem.remaining if budget is None else min(int(budget), problem.remaining)
    if budget < 1:
        raise SolverError(f"no budget left on {problem!r}")
    problem.limit(budget)
    t0 = time.perf_counter()
    try:
        # the solver gets a one-way seed of the run node (nothing of the node's instance and
        # noise streams) and the view (budget, log, space, data), never the problem's truth
        with blas_single_thread():   # small linear algebra: idle BLAS threads only spin
            res = info.func(problem.view(), budget, solver_seed(seed, seed_scheme),
                            **info.config)
        stop, extra, lib = res.stop_reason, res.extra, res.library
    except BudgetExhausted:
        stop, extra, lib = "budget", {}, library_versions(*info.library.split(","))
    x, f = problem.best
    return SolveResult(solver=name, x=x, fitness=f, evaluations=problem.evaluations,
                       stop_reason=stop, wall_s=time.perf_counter() - t0, library=lib,
                       extra=extra)
