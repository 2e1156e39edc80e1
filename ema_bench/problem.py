"""The identification problem: what every solver is scored on.

A :class:`Problem` wraps an :class:`~ema_bench.objective.Objective` (the measured traces and
the fitness) with a hard budget, a log of every evaluation and the hidden true fault vector
(only :meth:`Problem.score` uses it).  :func:`~ema_bench.instances.make_problem` builds the
benchmark's instances.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping, Sequence

import numpy as np

from .faults import FaultError, check_faults, faults_to_dict
from .objective import (  # noqa: F401  (re-exported: the problem's vocabulary)
    KNOWN_TESTS,
    N_FAULTS,
    PENALTY,
    Objective,
    ProblemError,
    SearchSpace,
    fitness_from_outputs,
    signal_scales,
)
from .scoring import (  # noqa: F401
    SUCCESS_RANGE_ERROR,
    Score,
    parameter_hits,
    score,
    successes,
)
from .traces import SIGNALS, Traces

log = logging.getLogger(__name__)


#: The largest evaluation budget a problem accepts: about 12 days of single evaluations at
#: 1 ms; a larger number is a typo, not an experiment.
MAX_BUDGET = 10**9

# evaluations the log holds before it first grows (then it doubles, up to the budget)
_LOG_CHUNK = 4096


def check_budget(budget: object) -> int:
    """The budget as an int; ProblemError unless ``1 <= budget <= MAX_BUDGET``."""
    if isinstance(budget, bool) or not isinstance(budget, int | np.integer) or budget < 1:
        raise ProblemError(f"budget must be a positive integer, got {budget!r}")
    if budget > MAX_BUDGET:
        raise ProblemError(f"budget {budget} is beyond the maximum of {MAX_BUDGET:.0e} "
                           "evaluations (about 12 days at 1 ms each)")
    return int(budget)


class BudgetExhausted(RuntimeError):
    """The evaluation would exceed the problem's budget; nothing was scored."""


class Problem:
    """A fault-identification instance with a hard evaluation budget.

    Build it with :func:`make_problem`.  Public attributes describe the search space
    (``names``, ``units``, ``lower``, ``upper``, ``nominal``, ``dim``) and the data
    (``measured``); the true vector is not among them.

    Parameters
    ----------
    measured : Traces
        The traces to fit (the observation).
    budget : int
        Maximum number of candidate evaluations (each row of a batch counts one).
    normalise : bool
        Per-output normalised fitness (default) or the raw sum of squared errors, which
        reproduces the paper's Na/Fst valley (Figure 5).
    monitor_effects : array (N_EFFECTS,), optional
        Effects switched on in the *monitor* model for every candidate (``make_problem``'s
        ``effects`` switch effects on in the model that makes the data).
    augment : sequence of str
        Library effects whose parameters become extra search dimensions after the four
        faults (an augmented monitor: zero = off, so it contains the base model).
    start : array (dim,), optional
        Where solvers begin (their first point): a warm start, e.g. a previous fit.
        Default: the nominal (healthy) vector.
    sample_weights : mapping, optional
        Per-sample weight multipliers of the fitness (:class:`~ema_bench.objective.Objective`).
    """

    def __init__(self, measured: Traces, budget: int, *, normalise: bool = True,
                 monitor_effects: np.ndarray | None = None, augment: Sequence[str] = (),
                 start: np.ndarray | None = None,
                 sample_weights: Mapping[str, np.ndarray] | None = None,
                 label: str = "measured",
                 track: str = "measured", _truth: np.ndarray | None = None,
                 _meta: Mapping[str, object] | None = None) -> None:
        budget = check_budget(budget)
        self.space = SearchSpace.of(augment)
        self.objective = Objective(measured, self.space, normalise=normalise,
                                   effects=monitor_effects, sample_weights=sample_weights)
        self.names: tuple[str, ...] = self.space.names
        self.units: dict[str, str] = self.space.units
        self.lower, self.upper, self.nominal = self.space.lower, self.space.upper, \
            self.space.nominal
        self.dim = self.space.dim
        self.augment = self.space.augment
        self.start = self.nominal if start is None else self._check_batch(
            np.asarray(start, dtype=float)[None, :])[0]
        self.start.flags.writeable = False
        self.budget = int(budget)
        self.normalise = bool(normalise)
        self.label = label
        self.track = track
        self.measured = measured
        self.meta = dict(_meta or {})
        self.__truth = None if _truth is None else check_faults(_truth).copy()
        self._count = 0
        self._failures = 0
        # the evaluation log grows with use (a huge budget costs nothing up front)
        self._X = np.empty((min(self.budget, _LOG_CHUNK), self.dim))
        self._f = np.empty(self._X.shape[0])
        self._t = np.empty(self._X.shape[0])
        self._t0 = time.perf_counter()

    def __repr__(self) -> str:
        return (f"Problem({self.label!r}, track={self.track!r}, evaluations="
                f"{self._count}/{self.budget}, normalise={self.normalise})")

    # --- budget -------------------------------------------------------------------------
    @property
    def evaluations(self) -> int:
        """Evaluations scored so far (the only count that matters)."""
        return self._count

    @property
    def remaining(self) -> int:
        return self.budget - self._count

    @property
    def failures(self) -> int:
        """Evaluations whose simulation failed and scored ``PENALTY``."""
        return self._failures

    def limit(self, n: int) -> None:
        """Allow at most ``n`` more evaluations (the budget can shrink, never grow)."""
        if int(n) < 0:
            raise ProblemError(f"limit needs n >= 0, got {n}")
        self.budget = min(self.budget, self._count + int(n))

    def _reserve(self, n: int) -> None:
        if n > self.remaining:
            raise BudgetExhausted(
                f"{n} evaluation(s) requested with {self.remaining} of {self.budget} left")

    # --- evaluation ---------------------------------------------------------------------
    def _check_batch(self, X: np.ndarray) -> np.ndarray:
        return self.space.check(X)

    def to_unit(self, X: np.ndarray) -> np.ndarray:
        """Physical vector(s) -> the normalised box [0, 1]^dim of this problem."""
        return self.space.to_unit(X)

    def from_unit(self, U: np.ndarray) -> np.ndarray:
        """Normalised box [0, 1]^dim -> physical vector(s) of this problem."""
        return self.space.from_unit(U)

    def simulate(self, X: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """Monitor outputs for a batch, without counting (for plots and reports, never for
        search: solvers must go through :meth:`evaluate` or :meth:`residuals`)."""
        return self.objective.outputs(self._check_batch(np.atleast_2d(X)))

    def _fitness(self, X: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        f, outputs, failed = self.objective.evaluate(X)
        if failed.any():
            self._failures += int(failed.sum())
            for x in X[failed][:3]:
                log.warning("simulation failed at %s: scored penalty %g", faults_to_dict(x),
                            PENALTY)
        return f, outputs

    def _record(self, X: np.ndarray, f: np.ndarray) -> None:
        i, n = self._count, X.shape[0]
        if i + n > self._f.size:
            cap = min(self.budget, max(2 * self._f.size, i + n))
            self._X = np.resize(self._X, (cap, self.dim))  # copies; the tail is overwritten
            self._f = np.resize(self._f, cap)
            self._t = np.resize(self._t, cap)
        self._X[i:i + n] = X
        self._f[i:i + n] = f
        self._t[i:i + n] = time.perf_counter() - self._t0
        self._count += n

    def evaluate(self, X: np.ndarray) -> np.ndarray | float:
        """Fitness of candidate fault vectors (lower is better).

        Parameters
        ----------
        X : array, shape (n, dim) or (dim,)
            Physical vectors (``names`` order, ``units``), inside ``[lower, upper]``.

        Returns
        -------
        ndarray (n,) or float
            Normalised (or raw) sum of mean squared output errors; ``PENALTY`` for a failed
            simulation.

        Raises
        ------
        BudgetExhausted
            If the batch would exceed the budget (nothing is scored then).
        ProblemError
            Wrong shape, NaN, or out-of-bounds vectors.
        """
        arr = np.asarray(X, dtype=float)
        single = arr.ndim == 1
        f, _ = self.evaluate_outputs(arr[None, :] if single else arr)
        return float(f[0]) if single else f

    def evaluate_outputs(self, X: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """:meth:`evaluate` of a batch (n, dim) that also returns the monitor outputs it
        computed (test -> (n, n_samples, 4)): one simulation, counted once."""
        X2 = self._check_batch(X)
        if X2.shape[0] == 0:
            return np.empty(0), {t.name: np.empty((0, t.n_samples(), len(SIGNALS)))
                                 for t in self.objective.tests}
        self._reserve(X2.shape[0])
        f, outputs = self._fitness(X2)
        self._record(X2, f)
        return f, outputs

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """Weighted residual vector of one candidate: ``sum(r**2) == evaluate(x)``.

        Counts one evaluation.  For least-squares methods; layout: test by test, signal by
        signal, sample by sample (:meth:`~ema_bench.objective.Objective.residuals`)."""
        f, outputs = self.evaluate_outputs(np.asarray(x, dtype=float)[None, :])
        return self.objective.residuals(outputs, f)[0]

    @property
    def n_residuals(self) -> int:
        return self.objective.n_residuals

    # --- log ----------------------------------------------------------------------------
    def history(self) -> dict[str, np.ndarray]:
        """Every evaluation so far: ``index``, ``x`` (n, 4), ``fitness``, ``best`` (best so
        far), ``wall_s`` (since the problem was built)."""
        n = self._count
        f = self._f[:n].copy()
        return {"index": np.arange(n), "x": self._X[:n].copy(), "fitness": f,
                "best": np.minimum.accumulate(f) if n else f, "wall_s": self._t[:n].copy()}

    @property
    def best(self) -> tuple[np.ndarray, float]:
        """Best vector and fitness evaluated so far (``nominal, inf`` before any)."""
        if self._count == 0:
            return self.nominal.copy(), float("inf")
        i = int(np.argmin(self._f[:self._count]))
        return self._X[i].copy(), float(self._f[i])

    # --- scoring (not for solvers) ------------------------------------------------------
    @property
    def has_truth(self) -> bool:
        return self.__truth is not None

    def score(self, x: np.ndarray) -> Score:
        """Accuracy of an estimate against the hidden truth (for the scorer)."""
        if self.__truth is None:
            raise ProblemError("the true faults of measured data are unknown: no score")
        try:
            est = check_faults(np.asarray(x, dtype=float)[:N_FAULTS])
        except FaultError as exc:
            raise ProblemError(str(exc)) from None
        return score(est, self.__truth)

    def first_success(self) -> int | None:
        """Evaluations spent until the best-so-far point first succeeded (1-based), or None.

        A vector succeeds when every parameter is within 1 % of its range of the truth; it is
        judged at the point the solver would report at that moment (the lowest fitness so
        far), not at any evaluated point (scorer-only, like :meth:`score`)."""
        return self.parameter_hits((SUCCESS_RANGE_ERROR,))[0]

    def parameter_hits(self, levels: Sequence[float]) -> list[int | None]:
        """Per level, the evaluation (1-based) from which the best-so-far point first lies
        within ``level`` of every fault's range of the truth, or None (scorer-only)."""
        if self.__truth is None:
            raise ProblemError("the true faults of measured data are unknown")
        n = self._count
        return parameter_hits(self._X[:n], self._f[:n], self.__truth, levels)

    def first_success_wall_s(self) -> float | None:
        """Wall seconds from building the problem to its first successful evaluation, or None
        (scorer-only, like :meth:`first_success`)."""
        first = self.first_success()
        return None if first is None else float(self._t[first - 1])

    def first_success_clock(self) -> float | None:
        """``time.perf_counter()`` reading at the first successful evaluation, or None.  On
        Linux that clock is system-wide, so another process can subtract its own launch time
        (``ema-bench bench`` does, for the cold time to success)."""
        wall = self.first_success_wall_s()
        return None if wall is None else self._t0 + wall

    def fitness_at_truth(self) -> float:
        """Fitness of the true vector (not counted; for reports of the model-form bias)."""
        if self.__truth is None:
            raise ProblemError("the true faults of measured data are unknown")
        x = np.r_[self.__truth, np.zeros(self.dim - len(self.__truth))]
        f, _ = self._fitness(x[None, :])
        return float(f[0])


