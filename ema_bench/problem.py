"""The identification problem: what every solver is scored on.

A :class:`Problem` wraps an :class:`~ema_bench.objective.Objective` (the measured traces and
the fitness) with a hard budget, a log of every evaluation (:class:`EvaluationLog`) and the
hidden true fault vector (only the scoring methods use it).  Solvers never get the problem:
``run_solver`` hands them its :class:`SolverView`, which shares the budget and the log and
holds nothing that leads to the truth (docs/submitting-results.md, "Threat model").
:func:`~ema_bench.instances.make_problem` builds the benchmark's instances.
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
from .params import DEFAULT_PARAMS, EMAParams
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


class EvaluationLog:
    """The counted side of a problem: the objective, the budget and the log of every
    evaluation.  It holds no truth: the :class:`SolverView` a solver gets wraps this and
    nothing else, while the :class:`Problem` (the scorer's object) holds it beside the truth.
    """

    def __init__(self, objective: Objective, space: SearchSpace, budget: int) -> None:
        self.objective, self.space = objective, space
        self.dim = space.dim
        self.budget = int(budget)
        self.count = 0
        self.failures = 0
        # the evaluation log grows with use (a huge budget costs nothing up front)
        self.X = np.empty((min(self.budget, _LOG_CHUNK), self.dim))
        self.f = np.empty(self.X.shape[0])
        self.t = np.empty(self.X.shape[0])
        self.t0 = time.perf_counter()

    @property
    def remaining(self) -> int:
        return self.budget - self.count

    def limit(self, n: int) -> None:
        if int(n) < 0:
            raise ProblemError(f"limit needs n >= 0, got {n}")
        self.budget = min(self.budget, self.count + int(n))

    def fitness(self, X: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Uncounted fitness of a checked batch (counting is :meth:`evaluate_outputs`'s)."""
        f, outputs, failed = self.objective.evaluate(X)
        if failed.any():
            self.failures += int(failed.sum())
            for x in X[failed][:3]:
                log.warning("simulation failed at %s: scored penalty %g", faults_to_dict(x),
                            PENALTY)
        return f, outputs

    def _record(self, X: np.ndarray, f: np.ndarray) -> None:
        i, n = self.count, X.shape[0]
        if i + n > self.f.size:
            cap = min(self.budget, max(2 * self.f.size, i + n))
            self.X = np.resize(self.X, (cap, self.dim))  # copies; the tail is overwritten
            self.f = np.resize(self.f, cap)
            self.t = np.resize(self.t, cap)
        self.X[i:i + n] = X
        self.f[i:i + n] = f
        self.t[i:i + n] = time.perf_counter() - self.t0
        self.count += n

    def evaluate_outputs(self, X: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        X2 = self.space.check(X)
        if X2.shape[0] == 0:
            return np.empty(0), {t.name: np.empty((0, t.n_samples(), len(SIGNALS)))
                                 for t in self.objective.tests}
        if X2.shape[0] > self.remaining:
            raise BudgetExhausted(f"{X2.shape[0]} evaluation(s) requested with "
                                  f"{self.remaining} of {self.budget} left")
        f, outputs = self.fitness(X2)
        self._record(X2, f)
        return f, outputs

    def history(self) -> dict[str, np.ndarray]:
        n = self.count
        f = self.f[:n].copy()
        return {"index": np.arange(n), "x": self.X[:n].copy(), "fitness": f,
                "best": np.minimum.accumulate(f) if n else f, "wall_s": self.t[:n].copy()}

    def best(self, nominal: np.ndarray | None) -> tuple[np.ndarray, float]:
        if self.count == 0:   # nothing evaluated: the nominal, or the box centre without one
            mid = 0.5 * (self.space.lower + self.space.upper)
            return (mid if nominal is None else nominal.copy()), float("inf")
        i = int(np.argmin(self.f[:self.count]))
        return self.X[i].copy(), float(self.f[i])


class _Counted:
    """What a solver and the scorer's problem share: the search space and the counted
    evaluation, both through an :class:`EvaluationLog` (``self._log``)."""

    _log: EvaluationLog
    space: SearchSpace

    @property
    def evaluations(self) -> int:
        """Evaluations scored so far (the only count that matters)."""
        return self._log.count

    @property
    def remaining(self) -> int:
        """Evaluations left in the budget."""
        return self._log.remaining

    @property
    def budget(self) -> int:
        """The evaluation budget (it can shrink, never grow)."""
        return self._log.budget

    @property
    def failures(self) -> int:
        """Evaluations whose simulation failed and scored ``PENALTY``."""
        return self._log.failures

    @property
    def n_residuals(self) -> int:
        return self._log.objective.n_residuals

    def to_unit(self, X: np.ndarray) -> np.ndarray:
        """Physical vector(s) -> the normalised box [0, 1]^dim of this problem."""
        return self.space.to_unit(X)

    def from_unit(self, U: np.ndarray) -> np.ndarray:
        """Normalised box [0, 1]^dim -> physical vector(s) of this problem."""
        return self.space.from_unit(U)

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
        return self._log.evaluate_outputs(X)

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """Weighted residual vector of one candidate (``x`` (dim,): ``sum(r**2) ==
        evaluate(x)``), or of a batch (``x`` (n, dim): an (n, n_residuals) array, rows in
        order, the same bits as one call each).

        Counts one evaluation per candidate.  For least-squares methods; layout: test by
        test, signal by signal, sample by sample
        (:meth:`~ema_bench.objective.Objective.residuals`)."""
        arr = np.asarray(x, dtype=float)
        single = arr.ndim == 1
        f, outputs = self.evaluate_outputs(arr[None, :] if single else arr)
        r = self._log.objective.residuals(outputs, f)
        return r[0] if single else r

    def history(self) -> dict[str, np.ndarray]:
        """Every evaluation so far: ``index``, ``x`` (n, dim), ``fitness``, ``best`` (best
        so far), ``wall_s`` (since the problem was built)."""
        return self._log.history()

    @property
    def best(self) -> tuple[np.ndarray, float]:
        """Best vector and fitness evaluated so far (``nominal, inf`` before any; the centre
        of the box on a problem without prior)."""
        return self._log.best(self.space.nominal)


class SolverView(_Counted):
    """What a solver is given: everything it needs to search, nothing that leads to the truth.

    Built by :meth:`Problem.view` (``run_solver`` passes it to the solver).  It holds the
    search space, the observation (``measured``, whose metadata names no fault) and the
    problem's :class:`EvaluationLog`, never the :class:`Problem`: no attribute, method or
    object reachable from it yields the true faults, a score, a success flag or the fitness
    at the truth.  On a problem without prior (``prior=False``) ``nominal`` and ``start`` are
    None and its search space holds bounds only: a solver draws its own start.  Evaluations
    through it count against the same budget and land in the same log as the problem's,
    which the scorer reads after the solver returns.
    """

    __slots__ = ("_log", "space", "names", "units", "lower", "upper", "nominal", "dim",
                 "augment", "start", "normalise", "measured")

    def __init__(self, log_: EvaluationLog, space: SearchSpace, start: np.ndarray,
                 normalise: bool, measured: Traces) -> None:
        self._log, self.space = log_, space
        self.names, self.units = space.names, space.units
        self.lower, self.upper, self.nominal = space.lower, space.upper, space.nominal
        self.dim, self.augment = space.dim, space.augment
        self.start, self.normalise, self.measured = start, normalise, measured

    def __repr__(self) -> str:
        return (f"SolverView(evaluations={self.evaluations}/{self.budget}, "
                f"dim={self.dim})")


def _check_truth(truth: np.ndarray, space: SearchSpace) -> np.ndarray:
    """The hidden truth: the four faults, or (suite ``emafdi-v2``'s higher tiers) every
    searched parameter, faults then the augmented effects' true values."""
    truth = np.asarray(truth, dtype=float)
    if truth.shape == (N_FAULTS,):
        return check_faults(truth).copy()
    if truth.shape != (space.dim,):
        raise ProblemError(f"the truth must have {N_FAULTS} or {space.dim} values, got "
                           f"shape {truth.shape}")
    return space.check(truth[None, :])[0]


class Problem(_Counted):
    """A fault-identification instance with a hard evaluation budget.

    Build it with :func:`make_problem`.  Public attributes describe the search space
    (``names``, ``units``, ``lower``, ``upper``, ``nominal``, ``dim``) and the data
    (``measured``); the true vector is not among them.  A problem is the scorer's object (it
    scores against the truth); solvers get its :meth:`view`.

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
    signals : sequence of str, optional
        The outputs the fitness weighs (default all; :class:`~ema_bench.objective.Objective`).
    prior : bool
        False: the no-prior condition of suite ``emafdi-v2``: ``nominal`` and ``start`` are
        None here and in the solver's view, whose search space has bounds only (solvers
        that need a start draw it from their own seeded stream).
    params : EMAParams
        The monitor's parameters: its model version (:func:`ema_bench.params.model_params`).
    """

    def __init__(self, measured: Traces, budget: int, *, normalise: bool = True,
                 monitor_effects: np.ndarray | None = None, augment: Sequence[str] = (),
                 start: np.ndarray | None = None,
                 sample_weights: Mapping[str, np.ndarray] | None = None,
                 signals: Sequence[str] | None = None,
                 prior: bool = True, label: str = "measured",
                 track: str = "measured", _truth: np.ndarray | None = None,
                 _meta: Mapping[str, object] | None = None,
                 params: EMAParams = DEFAULT_PARAMS) -> None:
        budget = check_budget(budget)
        self.space = SearchSpace.of(augment)
        if not prior:
            if start is not None:
                raise ProblemError("a problem without prior takes no start")
            self.space = self.space.without_prior()
        self.objective = Objective(measured, self.space, normalise=normalise,
                                   effects=monitor_effects, sample_weights=sample_weights,
                                   signals=signals, params=params)
        self.names: tuple[str, ...] = self.space.names
        self.units: dict[str, str] = self.space.units
        self.lower, self.upper, self.nominal = self.space.lower, self.space.upper, \
            self.space.nominal
        self.dim = self.space.dim
        self.augment = self.space.augment
        self.start = self.nominal if start is None else self.space.check(
            np.asarray(start, dtype=float)[None, :])[0]
        if self.start is not None:
            self.start.flags.writeable = False
        self.prior = bool(prior)
        self.normalise = bool(normalise)
        self.label = label
        self.track = track
        self.measured = measured
        self.meta = dict(_meta or {})
        self.__truth = None if _truth is None else _check_truth(_truth, self.space)
        self._log = EvaluationLog(self.objective, self.space, budget)

    def __repr__(self) -> str:
        return (f"Problem({self.label!r}, track={self.track!r}, evaluations="
                f"{self.evaluations}/{self.budget}, normalise={self.normalise})")

    def without_truth(self) -> Problem:
        """This problem without its truth: the same data, search space and budget, a fresh
        log, no score.  Replay runs a solver on it after the truthful problem is gone, so a
        solver that reads memory it was not given finds no truth there."""
        blind = object.__new__(Problem)
        blind.__dict__.update(self.__dict__)
        blind.__truth = None
        blind.meta = dict(self.meta)
        blind._log = EvaluationLog(self.objective, self.space, self.budget)
        return blind

    @property
    def objective(self) -> Objective:
        """The objective every evaluation of this problem (and of its view) computes."""
        return self._objective

    @objective.setter
    def objective(self, objective: Objective) -> None:
        # a stand-in objective (e.g. the diagnosis' model carrying acquisition faults) is
        # allowed before the first evaluation only: the log's count and best stay one
        # objective's
        if getattr(self, "_log", None) is not None:
            if self._log.count:
                raise ProblemError("the objective of a problem can only be replaced before "
                                   f"its first evaluation ({self._log.count} made)")
            self._log.objective = objective
        self._objective = objective

    def view(self) -> SolverView:
        """The solver's view of this problem: shares its budget and log, holds no truth."""
        return SolverView(self._log, self.space, self.start, self.normalise, self.measured)

    def limit(self, n: int) -> None:
        """Allow at most ``n`` more evaluations (the budget can shrink, never grow)."""
        self._log.limit(n)

    def simulate(self, X: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """Monitor outputs for a batch, without counting (for plots and reports, never for
        search: solvers get a :class:`SolverView`, which has no uncounted evaluation)."""
        return self.objective.outputs(self.space.check(np.atleast_2d(X)))

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
        return score(est, self.__truth[:N_FAULTS])

    def first_success(self) -> int | None:
        """Evaluations spent until the best-so-far point first succeeded (1-based), or None.

        A vector succeeds when every parameter is within 1 % of its range of the truth; it is
        judged at the point the solver would report at that moment (the lowest fitness so
        far), not at any evaluated point (scorer-only, like :meth:`score`)."""
        return self.parameter_hits((SUCCESS_RANGE_ERROR,))[0]

    def parameter_hits(self, levels: Sequence[float], judged: np.ndarray | None = None,
                       scales: np.ndarray | None = None) -> list[int | None]:
        """Per level, the evaluation (1-based) from which the best-so-far point first lies
        within ``level`` of every judged parameter's range of the truth, or None
        (scorer-only).  The truth holds the faults, or every searched parameter (suite
        ``emafdi-v2``); ``judged`` masks the parameters without a parameter target;
        ``scales`` replaces the ranges (a suite's target scales, ``Instance.frame``)."""
        if self.__truth is None:
            raise ProblemError("the true faults of measured data are unknown")
        n = self._log.count
        return parameter_hits(self._log.X[:n], self._log.f[:n], self.__truth, levels,
                              ranges=self.space.upper - self.space.lower
                              if scales is None else scales, judged=judged)

    def truth_size(self) -> int:
        """How many values the hidden truth has: 4 (the faults) or ``dim`` (scorer-only)."""
        return 0 if self.__truth is None else len(self.__truth)

    def first_success_wall_s(self) -> float | None:
        """Wall seconds from building the problem to its first successful evaluation, or None
        (scorer-only, like :meth:`first_success`)."""
        first = self.first_success()
        return None if first is None else float(self._log.t[first - 1])

    def first_success_clock(self) -> float | None:
        """``time.perf_counter()`` reading at the first successful evaluation, or None.  On
        Linux that clock is system-wide, so another process can subtract its own launch time
        (``ema-bench bench`` does, for the cold time to success)."""
        wall = self.first_success_wall_s()
        return None if wall is None else self._log.t0 + wall

    def fitness_at_truth(self) -> float:
        """Fitness of the true vector (not counted; for reports of the model-form bias)."""
        if self.__truth is None:
            raise ProblemError("the true faults of measured data are unknown")
        x = np.r_[self.__truth, np.zeros(self.dim - len(self.__truth))]  # effects off
        f, _ = self._log.fitness(x[None, :])
        return float(f[0])


