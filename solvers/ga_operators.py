"""MATLAB ``ga`` operators as small pure functions (for the paper's GA,
``ema_bench_solvers.paper_ga``).

Each function reproduces one of MATLAB's Global Optimization Toolbox operators used by the
paper (Dalla Vedova et al. 2016): the population split of ``stepGA``, ``fitscalingrank``,
``selectionstochunif``, ``crossoverheuristic``, the step-size rule and the direction set of
``mutationadaptfeasible``, and the default ``'averageChange'`` stall test.  They work on numpy
arrays in a box (the solver uses the normalised box ``[0, 1]^4``: the fault scales differ by
five orders of magnitude, so the box-relative steps of ``mutationadaptfeasible`` only make
sense there) and take the random generator as an argument, so each one can be tested against
a hand-computed case.

DEAP has none of these: no rank scaling, no adaptive feasible mutation, and its
``tools.selStochasticUniversalSampling`` lays out the *raw* fitness values on the wheel, which
is wrong when minimising (a worse, larger score gets a larger slice) and undefined for
negative scores.  It also draws from Python's global ``random``.  Do not use it here.
"""

from __future__ import annotations

import math

import numpy as np

EPS = float(np.finfo(float).eps)
#: ``mutationadaptfeasible``'s step-size floor, ``sqrt(eps)``
MIN_STEP = math.sqrt(EPS)
#: MATLAB's default ``ConstraintTolerance`` (1e-3), the "bound is active" tolerance
ACTIVE_TOL = 1e-3


# --- population split (stepGA) ----------------------------------------------------------------
def default_elite_count(pop_size: int) -> int:
    """MATLAB's default ``EliteCount``: ``ceil(0.05 * PopulationSize)``."""
    return math.ceil(0.05 * pop_size)


def offspring_counts(pop_size: int, elite_count: int | None = None,
                     crossover_fraction: float = 0.8) -> tuple[int, int, int]:
    """``(elites, crossover children, mutants)`` of one generation, as in MATLAB's ``stepGA``.

    ``nXover = round(CrossoverFraction * (N - elites))`` (MATLAB rounds halves away from zero),
    the rest are mutants.  N = 100 gives (5, 76, 19); N = 50 gives (3, 38, 9).
    """
    if pop_size < 1:
        raise ValueError(f"population size must be positive, got {pop_size}")
    if not 0.0 <= crossover_fraction <= 1.0:
        raise ValueError(f"crossover fraction must lie in [0, 1], got {crossover_fraction}")
    elites = default_elite_count(pop_size) if elite_count is None else int(elite_count)
    if not 0 <= elites <= pop_size:
        raise ValueError(f"elite count must lie in [0, {pop_size}], got {elites}")
    rest = pop_size - elites
    n_xover = int(math.floor(crossover_fraction * rest + 0.5))
    return elites, n_xover, rest - n_xover


def parents_needed(n_xover: int, n_mutants: int) -> int:
    """``nParents = 2 * nXover + nMutants`` (two parents per crossover child, one per mutant)."""
    return 2 * n_xover + n_mutants


# --- fitness scaling (fitscalingrank) ---------------------------------------------------------
def rank_scaling(scores: np.ndarray, n_parents: int) -> np.ndarray:
    """``fitscalingrank``: the i-th best raw score (i = 1, 2, ...) gets ``1/sqrt(i)``, then all
    are scaled so that the expectations sum to ``n_parents``.

    Lower scores are better (minimisation).  Ties are ranked in index order (MATLAB's ``sort``
    is stable).  Returns the expectation of each individual, in the input order.
    """
    s = np.asarray(scores, dtype=float).ravel()
    order = np.argsort(s, kind="stable")
    raw = np.empty_like(s)
    raw[order] = 1.0 / np.sqrt(np.arange(1, s.size + 1))
    return n_parents * raw / raw.sum()


# --- selection (selectionstochunif) -----------------------------------------------------------
def stochastic_uniform(expectation: np.ndarray, n_parents: int,
                       rng: np.random.Generator | None = None,
                       start: float | None = None) -> np.ndarray:
    """``selectionstochunif``: indices of ``n_parents`` parents.

    The expectations are laid out end to end on a line of length ``total``; pointers are placed
    at ``start + k * step``, ``step = total / n_parents``, ``k = 0 .. n_parents-1``, with one
    random ``start`` in ``[0, step)`` (or the given one, for tests); each pointer picks the
    individual whose segment it falls in (MATLAB: the first ``j`` with
    ``position < cumsum(expectation)(j)``).

    The result is in wheel order, as MATLAB's function returns it; MATLAB's ``stepGA`` (not the
    selection function) then shuffles the parents with ``randperm`` "to prevent locality
    effects" before pairing them for crossover -- the solver does that shuffle.
    """
    e = np.asarray(expectation, dtype=float).ravel()
    if n_parents < 1:
        return np.empty(0, dtype=np.intp)
    if np.any(e < 0) or e.sum() <= 0:
        raise ValueError("expectations must be non-negative with a positive sum")
    wheel = np.cumsum(e)
    total = wheel[-1]
    step = total / n_parents
    if start is None:
        if rng is None:
            raise ValueError("give a random generator or a start offset")
        start = rng.random() * step
    elif not 0.0 <= start < step:
        raise ValueError(f"start must lie in [0, {step}), got {start}")
    pointers = start + step * np.arange(n_parents)
    idx = np.searchsorted(wheel, pointers, side="right")
    # round-off can push the last pointer onto the end of the wheel
    return np.minimum(idx, e.size - 1).astype(np.intp)


# --- crossover (crossoverheuristic) -----------------------------------------------------------
def heuristic_crossover(parent1: np.ndarray, parent2: np.ndarray, score1: np.ndarray,
                        score2: np.ndarray, *, ratio: float = 1.2, lower: np.ndarray | float = 0.0,
                        upper: np.ndarray | float = 1.0, rng: np.random.Generator | None = None,
                        fallback: str = "random", alpha: np.ndarray | None = None) -> np.ndarray:
    """``crossoverheuristic``: ``child = worse + ratio * (better - worse)`` for each pair.

    ``parent1``, ``parent2`` are ``(n, d)`` (or ``(d,)``) arrays, ``score1``, ``score2`` their
    raw scores; ``better`` is the parent with the lower score (``parent2`` on a tie, as in
    MATLAB's ``if score1 < score2 ... else ...``).  With ``ratio = 1.2`` the child lies a
    little beyond the better parent, on the line from the worse one.

    Feasible fallback for a child outside ``[lower, upper]``:

    * ``"random"`` (default, MATLAB's): replace it by a random convex combination of its two
      parents, ``alpha * parent1 + (1 - alpha) * parent2``, ``alpha ~ U(0, 1)`` (``alpha`` may
      be given per pair for tests).  Feasible by construction in a box (clipped against
      round-off only).
    * ``"clip"``: clip it to the box.
    """
    p1 = np.atleast_2d(np.asarray(parent1, dtype=float))
    p2 = np.atleast_2d(np.asarray(parent2, dtype=float))
    s1 = np.asarray(score1, dtype=float).reshape(-1)
    s2 = np.asarray(score2, dtype=float).reshape(-1)
    first_better = (s1 < s2)[:, None]
    better = np.where(first_better, p1, p2)
    worse = np.where(first_better, p2, p1)
    child = worse + ratio * (better - worse)
    lo = np.broadcast_to(np.asarray(lower, dtype=float), child.shape[1:])
    hi = np.broadcast_to(np.asarray(upper, dtype=float), child.shape[1:])
    bad = np.any((child < lo) | (child > hi), axis=1)
    if bad.any():
        if fallback == "random":
            if alpha is None:
                if rng is None:
                    raise ValueError("the random fallback needs a random generator (or alpha)")
                a = rng.random(int(bad.sum()))
            else:
                a = np.broadcast_to(np.asarray(alpha, dtype=float).reshape(-1),
                                    (child.shape[0],))[bad]
            a = a[:, None]
            child[bad] = a * p1[bad] + (1.0 - a) * p2[bad]
        elif fallback != "clip":
            raise ValueError(f"unknown fallback {fallback!r}; use 'random' or 'clip'")
        child = np.clip(child, lo, hi)
    return child[0] if np.ndim(parent1) == 1 else child


# --- mutation (mutationadaptfeasible) ---------------------------------------------------------
def adapt_step(step: float, improved: bool, *, factor: float = 4.0, max_step: float = 1.0,
               min_step: float = MIN_STEP) -> float:
    """``mutationadaptfeasible``'s step-size rule, applied once per generation.

    After a generation that improved the best score the step grows ``factor`` times (capped at
    ``max_step`` = 1, the box size); otherwise it shrinks ``factor`` times (floored at
    ``min_step = sqrt(eps)``).  MATLAB starts from 1 and holds it for the first two
    generations (the solver does that).
    """
    if improved:
        return min(max_step, step * factor)
    return max(min_step, step / factor)


def mads_basis(dim: int, step: float, rng: np.random.Generator) -> np.ndarray:
    """A random basis for the mesh size ``step``, as MATLAB's ``uncondirections`` (LTMADS).

    Columns are the basis directions.  Lower-triangular: diagonal ``+-1/sqrt(step)`` (random
    signs), strictly-lower entries random integers ``round((p + 1) U - 0.5)`` (``0`` to about ``p``)
    with ``p = 1/sqrt(step)``; rows and columns permuted by one random permutation.  So the
    mutation ``step * direction`` moves about ``sqrt(step)`` per coordinate.  ``[B, -B]`` is a
    positive spanning set.
    """
    p = 1.0 / math.sqrt(step)
    # MATLAB's round((p + 1) U - 0.5), U ~ U[0, 1): rounding halves up, that is floor((p + 1) U)
    lower_t = np.tril(np.floor((p + 1.0) * rng.random((dim, dim))), -1)
    diag = p * np.where(rng.random(dim) < 0.5, -1.0, 1.0)
    basis = lower_t + np.diag(diag)
    order = rng.permutation(dim)
    return basis[np.ix_(order, order)]


def active_bound_directions(x: np.ndarray, lower: np.ndarray | float = 0.0,
                            upper: np.ndarray | float = 1.0, tol: float = ACTIVE_TOL
                            ) -> np.ndarray:
    """Unit coordinate directions (columns) of the bounds active at ``x`` (MATLAB's
    ``boxdirections`` tangent cone): coordinate ``i`` where ``|x_i - lower_i| <= tol`` or
    ``|x_i - upper_i| <= tol``.  Shape ``(d, n_active)``."""
    x = np.asarray(x, dtype=float)
    active = (np.abs(x - lower) <= tol) | (np.abs(x - upper) <= tol)
    return np.eye(x.size)[:, active]


def max_feasible_length(x: np.ndarray, directions: np.ndarray, lower: np.ndarray | float,
                        upper: np.ndarray | float) -> np.ndarray:
    """Largest ``t >= 0`` with ``lower <= x + t * d <= upper`` for each direction ``d`` (the
    columns of ``directions``, shape ``(dim, k)``, or one ``(dim,)`` direction); ``inf`` where
    ``d`` is 0."""
    x = np.asarray(x, dtype=float)[:, None]
    D = np.asarray(directions, dtype=float)
    single = D.ndim == 1
    D = D[:, None] if single else D
    lo = np.broadcast_to(np.asarray(lower, dtype=float), x.shape[:1])[:, None]
    hi = np.broadcast_to(np.asarray(upper, dtype=float), x.shape[:1])[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        room = np.where(D > 0, (hi - x) / D, np.where(D < 0, (lo - x) / D, np.inf))
    t = np.maximum(0.0, room.min(axis=0))
    return t[0] if single else t


def adaptive_feasible_mutation(parents: np.ndarray, step: float, rng: np.random.Generator, *,
                               lower: np.ndarray | float = 0.0, upper: np.ndarray | float = 1.0,
                               tol: float = ACTIVE_TOL, fallback: str = "shrink",
                               max_halvings: int = 60) -> np.ndarray:
    """``mutationadaptfeasible`` for a box: one mutant per parent row.

    For each parent ``x``: directions ``[B, -B, T, -T]`` with ``B`` a fresh random MADS basis
    (:func:`mads_basis`) and ``T`` the active-bound directions
    (:func:`active_bound_directions`), tried in random order; the mutant is
    ``x + step * direction`` for the first direction that stays inside the box (MATLAB).

    Where none is feasible at the full step (in the unit box no interior point has a feasible
    full step when ``step`` = 1, MATLAB's starting value):

    * ``"shrink"`` (default): halve the step, trying the same random order of directions
      again, until one fits (at most ``max_halvings`` times), so that a mutant always moves
      (what MathWorks' patent on the operator, US7660773B1, describes);
    * ``"copy"``: the mutant is a copy of its parent (an alternative kept for comparison).

    Children are inside ``[lower, upper]`` (clipped against round-off).
    """
    if fallback not in ("shrink", "copy"):
        raise ValueError(f"unknown fallback {fallback!r}; use 'shrink' or 'copy'")
    X = np.atleast_2d(np.asarray(parents, dtype=float))
    lo = np.broadcast_to(np.asarray(lower, dtype=float), X.shape[1:])
    hi = np.broadcast_to(np.asarray(upper, dtype=float), X.shape[1:])
    out = X.copy()
    halvings = max_halvings if fallback == "shrink" else 0
    for i, x in enumerate(X):
        basis = mads_basis(x.size, step, rng)
        tangent = active_bound_directions(x, lo, hi, tol)
        dirs = np.concatenate([basis, -basis, tangent, -tangent], axis=1)
        dirs = dirs[:, rng.permutation(dirs.shape[1])]
        reach = max_feasible_length(x, dirs, lo, hi)
        t = step
        for _ in range(halvings + 1):
            ok = np.flatnonzero(reach >= t)
            if ok.size:
                out[i] = x + t * dirs[:, ok[0]]
                break
            t *= 0.5
    return np.clip(out, lo, hi)


# --- stopping (ga's default StallTest 'averageChange') ----------------------------------------
def stalled(best_history: np.ndarray, stall_generations: int = 50,
            function_tolerance: float = 1e-6, floor: float = 0.0) -> bool:
    """``ga``'s stall test: the average relative change of the best score over the last
    ``W = stall_generations`` generations is at most ``function_tolerance``.

    ``best_history[g]`` is the best score after generation ``g`` (``g = 0``: the initial
    population).  Stalled when::

        |best[g - W] - best[g]| / (W * max(floor, |best[g]|)) <= function_tolerance

    MATLAB (option ``StallTest = 'averageChange'``, its default) uses ``floor = 1``, which
    turns the test into an *absolute* change for scores below 1.  Our fitness (a sum of
    normalised mean squared errors) is about 1e-4 near the optimum, where that absolute test
    (5e-5 over 50 generations, the size of the noise floor itself) stops runs that are still
    converging; so the default here is ``floor = 0``, a truly relative change as MATLAB's
    documentation words it.  ``floor = 1`` reproduces MATLAB's code.  Never stalled before
    ``W`` generations have run; a zero best score with no change counts as stalled.
    """
    b = np.asarray(best_history, dtype=float)
    w = int(stall_generations)
    if w < 1 or b.size <= w:
        return False
    new, old = b[-1], b[-1 - w]
    if not (np.isfinite(new) and np.isfinite(old)):
        return False
    change = abs(old - new)
    scale = w * max(float(floor), abs(new))
    if scale == 0.0:
        return change == 0.0
    return change / scale <= function_tolerance
