"""Helpers shared by the zoo solvers (not part of the solver API).

Every zoo solver searches the normalised box ``[0, 1]^dim`` (the physical fault scales differ
by five orders of magnitude; ``dim`` is 4, more for a problem augmented with effect
parameters) and maps candidates back with :meth:`Problem.from_unit` just before
:meth:`Problem.evaluate`.  Every random number comes from the ``SeedSequence`` the
solver was given, through :func:`child` (which, unlike ``SeedSequence.spawn``, does not
depend on how often the sequence was spawned before, so one seed object always gives one run,
and never replays the streams ``make_problem`` drew the instance and the noise from).
"""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Iterator

import numpy as np

from ema_bench.problem import Problem
from ema_bench.seeding import child, children  # noqa: F401  (the solvers' helpers)


class StopSolver(Exception):
    """Private signal: the budget is spent; unwind out of a library's optimisation loop."""


# A solver receives its own stream of the run node (run_solver derives it), so it may spawn
# freely: nothing it draws can replay the instance's or the noise's streams.


def int_seed(seed: np.random.SeedSequence) -> int:
    """A positive 31-bit integer seed for libraries that take one (pycma treats 0 as
    'seed from the clock', so 0 is never returned)."""
    return int(seed.generate_state(1, dtype=np.uint32)[0] % (2**31 - 2)) + 1


#: Child index of a solver's seed that draws its start on a problem without prior (far from
#: the small indices the solvers use for their own streams).
NO_PRIOR_START = 1 << 20


def start_unit(problem: Problem, seed: np.random.SeedSequence | None = None) -> np.ndarray:
    """The first point to try, in the normalised box: the problem's start (the nominal,
    healthy vector unless the caller gave a warm start); on a problem without prior
    (``start`` None, suite ``emafdi-v2``) a uniform point drawn from the solver's ``seed``."""
    if problem.start is None:
        if seed is None:
            raise ValueError("a problem without prior has no start: give the solver's seed")
        return np.random.default_rng(child(seed, NO_PRIOR_START)).random(problem.dim)
    return np.clip(problem.to_unit(problem.start), 0.0, 1.0)


def evaluate_unit(problem: Problem, U: np.ndarray) -> np.ndarray:
    """Fitness of a batch ``U`` (n, dim) of normalised candidates, in one problem call.

    Candidates are clipped into the box first (library round-off can leave them 1 ulp out;
    a NaN coordinate, which no library should propose, becomes the middle of the box rather
    than an error).  The caller keeps ``n <= problem.remaining``."""
    U = np.clip(np.nan_to_num(np.atleast_2d(np.asarray(U, dtype=float)), nan=0.5), 0.0, 1.0)
    return np.asarray(problem.evaluate(problem.from_unit(U)), dtype=float)


def import_cma():
    """``import cma`` without pycma's optional extras.

    pycma imports ``matplotlib.pyplot`` (for its plots) and ``scipy.stats`` (for its surrogate
    models) at import time, both inside ``try`` blocks with fallbacks: 1-1.5 s of its 2 s import,
    for nothing the CMA-ES core uses.  While cma is imported the two modules read as absent
    (holding the import lock, so no other thread's import sees that), then they are importable
    again as usual.  A no-op once cma is imported; modules already imported are left alone.
    """
    import importlib
    import sys

    if "cma" in sys.modules:
        return sys.modules["cma"]
    import _imp

    _imp.acquire_lock()
    blocked = [m for m in ("matplotlib", "matplotlib.pyplot", "scipy.stats")
               if m not in sys.modules]
    try:
        for m in blocked:
            sys.modules[m] = None   # type: ignore[assignment]  # import raises ImportError
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")   # "could not import matplotlib.pyplot"
            return importlib.import_module("cma")
    finally:
        for m in blocked:
            if sys.modules.get(m, 0) is None:
                del sys.modules[m]
        _imp.release_lock()


def scalar_objective(problem: Problem):
    """``f(u) -> float`` for one-at-a-time methods; raises :class:`StopSolver` instead of
    evaluating once the budget is spent."""
    def f(u: np.ndarray) -> float:
        if problem.remaining < 1:
            raise StopSolver
        return float(evaluate_unit(problem, np.asarray(u, dtype=float).reshape(1, -1))[0])
    return f


def lhs(seed: np.random.SeedSequence, n: int, dim: int) -> np.ndarray:
    """``n`` Latin-hypercube points in ``[0, 1]^dim``, seeded."""
    from scipy.stats import qmc  # here, not at import: scipy.stats costs 0.5-1 s

    return qmc.LatinHypercube(d=dim, rng=np.random.default_rng(seed)).random(n)


def start_points(problem: Problem, seed: np.random.SeedSequence,
                 batch: int = 32) -> Iterator[np.ndarray]:
    """Multi-start points: the problem's start (drawn from ``seed`` without prior), then
    Latin-hypercube points (batches of ``batch``, each a fresh Latin hypercube), without
    end."""
    yield start_unit(problem, seed)
    for i in range(1_000_000):
        yield from lhs(child(seed, i), batch, problem.dim)


def spend_rest(problem: Problem, seed: np.random.SeedSequence) -> int:
    """Spend a budget remainder too small for one more local start on Latin-hypercube probes
    (one batched call).  Returns the number of evaluations made."""
    k = problem.remaining
    if k > 0:
        evaluate_unit(problem, lhs(seed, k, problem.dim))
    return k


@contextlib.contextmanager
def global_numpy_rng() -> Iterator[None]:
    """Restore numpy's global RNG state afterwards (pycma seeds and draws from it)."""
    state = np.random.get_state()  # noqa: NPY002 (the legacy global state is the point)
    try:
        yield
    finally:
        np.random.set_state(state)  # noqa: NPY002


@contextlib.contextmanager
def quiet(*categories: type[Warning]) -> Iterator[None]:
    """Silence the given warning categories (library chatter that would spill to stderr)."""
    with warnings.catch_warnings():
        for c in categories:
            warnings.simplefilter("ignore", c)
        yield
