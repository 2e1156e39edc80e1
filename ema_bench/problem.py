"""The identification problem: what every solver is scored on.

A :class:`Problem` holds the measured traces (from the reference model, the monitor itself on
the *twin* track, or a file), evaluates batches of candidate fault vectors with the monitor
model, counts every evaluation against a hard budget, logs them, and hides the true fault
vector from solvers (only :meth:`Problem.score` uses it).
"""

from __future__ import annotations

import functools
import logging
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .effects import EFFECT_NAMES, EFFECTS, LIBRARY, N_EFFECTS, effects_vector
from .faults import (
    CASES,
    FAULT_NAMES,
    FAULT_UNITS,
    LOWER,
    NOMINAL,
    UPPER,
    FaultError,
    check_faults,
    faults_to_dict,
    random_faults,
)
from .monitor import simulate_monitor
from .params import DEFAULT_PARAMS
from .physics.sensors import SENSORS, measure
from .protocol import HOLDOUT_TESTS, STANDARD_TESTS, TestSpec
from .reference import SimulationError, simulate_reference
from .seeding import SeedLike, as_seed_sequence, children
from .trace_cache import cache_key, cached_traces, expected_shapes
from .traces import OUTPUT_DT, SIGNALS, Traces

log = logging.getLogger(__name__)

TRACKS = ("reference", "twin")
KNOWN_TESTS: dict[str, TestSpec] = {s.name: s for s in STANDARD_TESTS + HOLDOUT_TESTS}
# failed simulations score this; valid fitness values are clipped below it
PENALTY = 1e12
_VALID_CAP = 1e11
SUCCESS_RANGE_ERROR = 0.01  # a run succeeds when every parameter is within 1 % of its range


class BudgetExhausted(RuntimeError):
    """The evaluation would exceed the problem's budget; nothing was scored."""


class ProblemError(ValueError):
    """A problem that cannot be built or a request it cannot serve."""


@dataclass(frozen=True)
class Score:
    """How close an estimate is to the truth (for the scorer, not for solvers)."""

    x: dict[str, float]
    truth: dict[str, float]
    accuracy: dict[str, float | None]   # paper formula, %, None where true = 0 and est != 0
    range_error: dict[str, float]       # |est - true| / (upper - lower)
    success: bool                       # every range error <= 1 %

    def as_dict(self) -> dict[str, object]:
        return {"x": self.x, "truth": self.truth, "accuracy": self.accuracy,
                "range_error": self.range_error, "success": self.success}


def paper_accuracy(est: np.ndarray, true: np.ndarray) -> list[float | None]:
    """The paper's ``100 (1 - |est - true| / |true|)`` per parameter, in %.

    Where the true value is 0 the formula is undefined: 100 if the estimate is exactly 0,
    else ``None`` (use the range-normalised error there)."""
    out: list[float | None] = []
    for e, t in zip(est, true):
        if t == 0.0:
            out.append(100.0 if e == 0.0 else None)
        else:
            out.append(float(100.0 * (1.0 - abs(e - t) / abs(t))))
    return out


def range_error(est: np.ndarray, true: np.ndarray) -> np.ndarray:
    """``|est - true| / (upper - lower)`` per parameter (defined when the truth is 0)."""
    return np.abs(np.asarray(est, float) - np.asarray(true, float)) / (UPPER - LOWER)


def signal_scales(traces: Traces) -> dict[str, np.ndarray]:
    """Normalising scale of each measured output: its range, floored at 10 ADC steps so that
    a flat signal cannot blow the fitness up."""
    floor = np.array([10.0 * s.lsb for s in SENSORS])
    return {t: np.maximum(np.ptp(traces.data[t], axis=0), floor) for t in traces.tests}


def fitness_from_outputs(outputs: Mapping[str, np.ndarray], measured: Traces,
                         weights: Mapping[str, np.ndarray]) -> np.ndarray:
    """Sum over tests and signals of ``weight * mean((model - measured)^2)``.

    ``outputs[test]`` has shape (n, n_samples, 4); returns shape (n,)."""
    n = next(iter(outputs.values())).shape[0]
    f = np.zeros(n)
    for test in measured.tests:
        d = outputs[test] - measured.data[test][None, :, :]
        f += np.einsum("nsk,k->n", d * d, weights[test]) / d.shape[1]
    return f


@functools.lru_cache(maxsize=32)
def _reference_traces(x: tuple, e: tuple, seed_entropy: int, spawn_key: tuple,
                      tests: tuple[TestSpec, ...]) -> Traces:
    """Measured reference traces, cached in memory and on disk (:mod:`~ema_bench.trace_cache`)."""
    ss = np.random.SeedSequence(seed_entropy, spawn_key=spawn_key)
    key = cache_key(x=x, e=e, entropy=seed_entropy, spawn_key=spawn_key,
                    tests=[repr(t) for t in tests],
                    params=DEFAULT_PARAMS.to_array().tolist())
    return cached_traces(lambda: simulate_reference(np.array(x), np.array(e), seed=ss,
                                                    tests=tests), key, expected_shapes(tests))


def _twin_traces(x: np.ndarray, e: np.ndarray, seed: np.random.SeedSequence,
                 tests: tuple[TestSpec, ...]) -> Traces:
    outputs, ok = simulate_monitor(x[None, :], e[None, :], tests=tests)
    if not ok[0]:
        raise SimulationError(f"monitor model diverged at the true faults {faults_to_dict(x)}")
    data = {t: measure(v[0], np.random.default_rng(c))
            for (t, v), c in zip(outputs.items(), children(seed, len(outputs)))}
    return Traces(data=data, meta={"model": "monitor", "noise": True, "adc": True})


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
    effects : array (N_EFFECTS,), optional
        Effects switched on in the monitor model for every candidate.
    augment : sequence of str
        Library effects whose parameters become extra search dimensions after the four
        faults (an augmented monitor: zero = off, so it contains the base model).
    start : array (dim,), optional
        Where solvers begin (their first point): a warm start, e.g. a previous fit.
        Default: the nominal (healthy) vector.
    """

    def __init__(self, measured: Traces, budget: int, *, normalise: bool = True,
                 effects: np.ndarray | None = None, augment: Sequence[str] = (),
                 start: np.ndarray | None = None,
                 label: str = "measured",
                 track: str = "measured", _truth: np.ndarray | None = None,
                 _meta: Mapping[str, object] | None = None) -> None:
        if not isinstance(budget, int | np.integer) or budget < 1:
            raise ProblemError(f"budget must be a positive integer, got {budget!r}")
        if not np.isclose(measured.dt, OUTPUT_DT, rtol=1e-9, atol=0.0):
            raise ProblemError(f"measured traces are sampled at {1 / measured.dt:g} Hz; the "
                               f"monitor model outputs {1 / OUTPUT_DT:g} Hz (load finer data "
                               f"with load_traces, which block-averages it to that rate)")
        unknown = [t for t in measured.tests if t not in KNOWN_TESTS]
        if unknown:
            raise ProblemError(f"measured traces hold unknown test(s) {unknown}; the monitor "
                               f"model knows {list(KNOWN_TESTS)}")
        for t in measured.tests:
            expected = KNOWN_TESTS[t].n_samples(measured.dt)
            if measured.n_samples(t) != expected:
                raise ProblemError(f"test {t!r} has {measured.n_samples(t)} samples at "
                                   f"{1 / measured.dt:g} Hz, the protocol expects {expected}")
        augment = tuple(augment)
        bad = [n for n in augment if n not in LIBRARY]
        if bad or len(set(augment)) != len(augment):
            raise ProblemError(f"augment takes distinct library effects {list(LIBRARY)}, "
                               f"got {list(augment)}")
        specs = [EFFECTS[EFFECT_NAMES.index(n)] for n in augment]
        self.names: tuple[str, ...] = FAULT_NAMES + augment
        self.units: dict[str, str] = {**FAULT_UNITS, **{e.name: e.unit for e in specs}}
        self.lower = np.r_[LOWER, [e.lower for e in specs]]
        self.upper = np.r_[UPPER, [e.upper for e in specs]]
        self.nominal = np.r_[NOMINAL, np.zeros(len(specs))]
        for a in (self.lower, self.upper, self.nominal):
            a.flags.writeable = False
        self.dim = len(self.names)
        self.augment = augment
        self.start = self.nominal if start is None else self._check_batch(
            np.asarray(start, dtype=float)[None, :])[0]
        self.start.flags.writeable = False
        self._aug_idx = np.array([EFFECT_NAMES.index(n) for n in augment], dtype=int)
        self.budget = int(budget)
        self.normalise = bool(normalise)
        self.label = label
        self.track = track
        self.measured = measured
        self.meta = dict(_meta or {})
        self._tests = tuple(KNOWN_TESTS[t] for t in measured.tests)
        self._effects = np.zeros(N_EFFECTS) if effects is None else np.asarray(effects, float)
        if self._effects.shape != (N_EFFECTS,):
            raise ProblemError(f"effects must have shape ({N_EFFECTS},)")
        scales = signal_scales(measured)
        self._weights = {t: (1.0 / scales[t] ** 2 if normalise else np.ones(len(SIGNALS)))
                         for t in measured.tests}
        self._n_resid = sum(measured.data[t].size for t in measured.tests)
        self.__truth = None if _truth is None else check_faults(_truth).copy()
        self._count = 0
        self._failures = 0
        self._X = np.empty((self.budget, self.dim))
        self._f = np.empty(self.budget)
        self._t = np.empty(self.budget)
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
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[1] != self.dim:
            raise ProblemError(f"expected a batch of shape (n, {self.dim}) for parameters "
                               f"{list(self.names)}, got {X.shape}")
        try:
            faults = check_faults(X[:, :4], batch=True)
        except FaultError as exc:
            raise ProblemError(str(exc)) from None
        extra = X[:, 4:]
        slack = 1e-9 * (self.upper[4:] - self.lower[4:])
        bad = ~np.isfinite(extra) | (extra < self.lower[4:] - slack) | \
            (extra > self.upper[4:] + slack)
        if bad.any():
            i, j = np.argwhere(bad)[0]
            raise ProblemError(f"effect {self.augment[j]}={extra[i, j]:g} in row {i} is not "
                               f"finite or outside [{self.lower[4 + j]:g}, "
                               f"{self.upper[4 + j]:g}]")
        return np.hstack([faults, np.clip(extra, self.lower[4:], self.upper[4:])])

    def _effects_for(self, X: np.ndarray) -> np.ndarray:
        """Effects vector of every candidate: the fixed ones plus the augmented columns."""
        E = np.tile(self._effects, (X.shape[0], 1))
        E[:, self._aug_idx] = X[:, 4:]
        return E

    def to_unit(self, X: np.ndarray) -> np.ndarray:
        """Physical vector(s) -> the normalised box [0, 1]^dim of this problem."""
        return (np.asarray(X, dtype=float) - self.lower) / (self.upper - self.lower)

    def from_unit(self, U: np.ndarray) -> np.ndarray:
        """Normalised box [0, 1]^dim -> physical vector(s) of this problem."""
        return self.lower + np.asarray(U, dtype=float) * (self.upper - self.lower)

    def simulate(self, X: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """Monitor outputs for a batch, without counting (for plots and reports, never for
        search: solvers must go through :meth:`evaluate` or :meth:`residuals`)."""
        X = self._check_batch(np.atleast_2d(np.asarray(X, dtype=float)))
        return simulate_monitor(X[:, :4], self._effects_for(X), tests=self._tests,
                                check=False)

    def _fitness(self, X: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        outputs, ok = simulate_monitor(X[:, :4], self._effects_for(X), tests=self._tests,
                                       check=False)
        with np.errstate(over="ignore", invalid="ignore"):
            f = fitness_from_outputs(outputs, self.measured, self._weights)
        bad = ~ok | ~np.isfinite(f)
        if bad.any():
            self._failures += int(bad.sum())
            for x in X[bad][:3]:
                log.warning("simulation failed at %s: scored penalty %g", faults_to_dict(x),
                            PENALTY)
        f = np.where(bad, PENALTY, np.minimum(f, _VALID_CAP))
        return f, outputs

    def _record(self, X: np.ndarray, f: np.ndarray) -> None:
        i, n = self._count, X.shape[0]
        self._X[i:i + n] = X
        self._f[i:i + n] = f
        self._t[i:i + n] = time.perf_counter() - self._t0
        self._count += n

    def evaluate(self, X: np.ndarray) -> np.ndarray | float:
        """Fitness of candidate fault vectors (lower is better).

        Parameters
        ----------
        X : array, shape (n, 4) or (4,)
            Physical fault vectors (``names`` order, ``units``), inside ``[lower, upper]``.

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
        X2 = self._check_batch(arr[None, :] if single else arr)
        if X2.shape[0] == 0:
            return np.empty(0)
        self._reserve(X2.shape[0])
        f, _ = self._fitness(X2)
        self._record(X2, f)
        return float(f[0]) if single else f

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """Weighted residual vector of one candidate: ``sum(r**2) == evaluate(x)``.

        Counts one evaluation.  For least-squares methods."""
        X2 = self._check_batch(np.asarray(x, dtype=float)[None, :])
        self._reserve(1)
        f, outputs = self._fitness(X2)
        self._record(X2, f)
        if f[0] >= PENALTY:
            return np.full(self._n_resid, np.sqrt(PENALTY / self._n_resid))
        parts = []
        for t in self.measured.tests:
            d = outputs[t][0] - self.measured.data[t]
            parts.append((d * np.sqrt(self._weights[t] / d.shape[0])).ravel())
        r = np.concatenate(parts)
        raw = float(r @ r)
        # keep sum(r**2) == evaluate(x) where the fitness was capped
        return r * np.sqrt(f[0] / raw) if raw > f[0] > 0.0 else r

    @property
    def n_residuals(self) -> int:
        return self._n_resid

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
            est = check_faults(np.asarray(x, dtype=float)[:4])
        except FaultError as exc:
            raise ProblemError(str(exc)) from None
        err = range_error(est, self.__truth)
        return Score(x=faults_to_dict(est), truth=faults_to_dict(self.__truth),
                     accuracy=dict(zip(FAULT_NAMES, paper_accuracy(est, self.__truth))),
                     range_error=dict(zip(FAULT_NAMES, map(float, err))),
                     success=bool(np.all(err <= SUCCESS_RANGE_ERROR)))

    def first_success(self) -> int | None:
        """Evaluations spent until the first successful vector (1-based count), or None.

        A vector succeeds when every parameter is within 1 % of its range of the truth
        (scorer-only, like :meth:`score`)."""
        if self.__truth is None:
            raise ProblemError("the true faults of measured data are unknown")
        err = range_error(self._X[:self._count, :4], self.__truth)
        hits = np.flatnonzero(np.all(err <= SUCCESS_RANGE_ERROR, axis=1))
        return int(hits[0]) + 1 if hits.size else None

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
        x = np.r_[self.__truth, np.zeros(self.dim - 4)]
        f, _ = self._fitness(x[None, :])
        return float(f[0])


def make_problem(
    case: str | Mapping[str, float] | np.ndarray | None = "small",
    *,
    track: str = "reference",
    seed: SeedLike = 0,
    budget: int = 1000,
    normalise: bool = True,
    heterogeneity: float = 1.0,
    effects: Mapping[str, float] | None = None,
    measured: Traces | None = None,
    augment: Sequence[str] = (),
    tests: Sequence[str] | None = None,
    start: np.ndarray | None = None,
) -> Problem:
    """Build an identification problem.

    Parameters
    ----------
    case : str, mapping or array
        A paper case (``nominal``, ``small``, ``full``, ``random``), ``"seeded"`` for a random
        instance drawn from ``seed`` with ``heterogeneity``, or explicit true faults.
    track : {"reference", "twin"}
        ``reference``: measured traces come from the detailed reference model (model-form
        mismatch, as in the paper); ``twin``: from the monitor model itself plus sensor noise
        (a pure optimisation problem whose optimum is the truth).
    seed : int or SeedSequence
        Root seed: spawns the instance draw and the sensor noise.
    budget : int
        Hard evaluation budget.
    normalise : bool
        Normalised (default) or raw fitness.
    effects : mapping, optional
        Effects switched on in the *reference* model that makes the data (unmodelled physics).
    measured : Traces, optional
        Fit these traces instead (file data); ``case`` and ``track`` are then ignored and
        there is no truth to score against.
    augment : sequence of str
        Library effects fitted with the faults (see :class:`Problem`).
    tests : sequence of str, optional
        Protocol tests that make the data (default: the standard step and sine; add
        ``"sine2"`` for held-out validation).
    start : array, optional
        Warm start for solvers (see :class:`Problem`).
    """
    if measured is not None:
        if not isinstance(measured, Traces):
            raise ProblemError("measured must be a Traces (see ema_bench.load_traces)")
        return Problem(measured, budget, normalise=normalise, augment=augment, start=start,
                       label=str(measured.meta.get("source", "measured")), track="measured",
                       _meta={"source": measured.meta.get("source")})
    if track not in TRACKS:
        raise ProblemError(f"unknown track {track!r}; known: {list(TRACKS)}")
    ss = as_seed_sequence(seed)
    s_instance, s_noise = children(ss, 2)
    if isinstance(case, str) and case == "seeded":
        truth, label = random_faults(s_instance, heterogeneity), f"seeded(h={heterogeneity:g})"
    elif isinstance(case, str):
        if case not in CASES:
            raise ProblemError(f"unknown case {case!r}; known: {list(CASES)} or 'seeded'")
        truth, label = CASES[case].x, case
    elif case is None:
        raise ProblemError("give a case, or measured traces")
    else:
        try:
            truth, label = check_faults(case), "custom"
        except FaultError as exc:
            raise ProblemError(str(exc)) from None
    e = effects_vector(effects)
    names = tuple(tests) if tests is not None else tuple(s.name for s in STANDARD_TESTS)
    unknown = [n for n in names if n not in KNOWN_TESTS]
    if unknown or not names:
        raise ProblemError(f"unknown test(s) {unknown}; known: {list(KNOWN_TESTS)}")
    specs = tuple(KNOWN_TESTS[n] for n in names)
    if track == "reference":
        measured = _reference_traces(tuple(truth), tuple(e), int(s_noise.entropy),
                                     tuple(s_noise.spawn_key), specs).with_meta(faults=None)
    else:
        measured = _twin_traces(truth, e, s_noise, specs)
    # public: nothing a solver could use to recover the truth (no seed, no effects)
    meta = {"case": label, "track": track}
    return Problem(measured, budget, normalise=normalise, label=label, track=track,
                   augment=augment, start=start, _truth=truth, _meta=meta)
