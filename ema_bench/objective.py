"""The objective of the identification: the one place the fitness is defined.

A :class:`SearchSpace` says what is searched: the four faults, optionally followed by library
effects fitted with them (an *augmented* monitor), with names, units, bounds, the nominal
vector, the validity check and the maps to and from the unit box.  An :class:`Objective` says
what is minimised: it owns the weighting of the outputs (:func:`signal_weights`), runs the
monitor model once per batch and returns the fitness *and* the outputs, and lays residuals out
in one order (:meth:`Objective.residuals`).  :class:`~ema_bench.problem.Problem` wraps an
objective with the budget, the log and the hidden truth; the environment, the diagnosis
workflow and the calibration use the objective directly, so none rebuilds it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .effects import EFFECT_NAMES, EFFECTS, LIBRARY, N_EFFECTS
from .faults import (  # noqa: F401  (N_FAULTS re-exported with the search space)
    FAULT_NAMES,
    FAULT_UNITS,
    LOWER,
    N_FAULTS,
    NOMINAL,
    UPPER,
    FaultError,
    check_faults,
)
from .monitor import simulate_monitor
from .params import DEFAULT_PARAMS, EMAParams
from .physics.sensors import SENSORS
from .protocol import HOLDOUT_TESTS, STANDARD_TESTS, TestSpec
from .terms import TERM_NAMES
from .traces import OUTPUT_DT, SIGNALS, Traces

#: Fitness of a failed simulation; valid values are clipped below ``VALID_CAP``.
PENALTY = 1e12
VALID_CAP = 1e11
KNOWN_TESTS: dict[str, TestSpec] = {s.name: s for s in STANDARD_TESTS + HOLDOUT_TESTS}


class ProblemError(ValueError):
    """A problem (or objective, or search space) that cannot be built, or a request it cannot
    serve: wrong shapes, NaN, out-of-bounds vectors, unknown names."""


# --- the weighting -------------------------------------------------------------------------
def signal_scales(traces: Traces) -> dict[str, np.ndarray]:
    """Normalising scale of each measured output: its range, floored at 10 ADC steps so that
    a flat signal cannot blow the fitness up."""
    floor = np.array([10.0 * s.lsb for s in SENSORS])
    return {t: np.maximum(np.ptp(traces.data[t], axis=0), floor) for t in traces.tests}


def signal_weights(measured: Traces, normalise: bool = True) -> dict[str, np.ndarray]:
    """Weight of each test's four outputs: ``1 / scale**2`` (normalised fitness), or 1 (the
    raw sum of squared errors that shows the paper's Na/Fst valley)."""
    if not normalise:
        return {t: np.ones(len(SIGNALS)) for t in measured.tests}
    return {t: 1.0 / s**2 for t, s in signal_scales(measured).items()}


def fitness_from_outputs(outputs: Mapping[str, np.ndarray], measured: Traces,
                         weights: Mapping[str, np.ndarray]) -> np.ndarray:
    """Sum over tests and signals of ``weight * mean((model - measured)^2)``.

    ``outputs[test]`` has shape (n, n_samples, 4); ``weights[test]`` is (4,) per signal, or
    (n_samples, 4) per sample; returns shape (n,)."""
    n = next(iter(outputs.values())).shape[0]
    f = np.zeros(n)
    for test in measured.tests:
        d = outputs[test] - measured.data[test][None, :, :]
        w = weights[test]
        f += np.einsum("nsk,k->n" if w.ndim == 1 else "nsk,sk->n", d * d, w) / d.shape[1]
    return f


# --- what is searched ----------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class SearchSpace:
    """The searched parameters: the faults, then the ``augment`` library effects.

    Build it with :meth:`of`.  ``lower``, ``upper`` and ``nominal`` are read-only arrays in
    ``names`` order (``nominal`` is None in a space :meth:`without_prior`); ``units`` maps
    each name to its unit."""

    names: tuple[str, ...]
    units: dict[str, str]
    lower: np.ndarray
    upper: np.ndarray
    nominal: np.ndarray | None
    augment: tuple[str, ...]

    @classmethod
    def of(cls, augment: Sequence[str] = ()) -> SearchSpace:
        """The faults plus the named library effects or dictionary terms
        (:mod:`ema_bench.terms`; zero = off, so the augmented monitor contains the base
        model)."""
        augment = tuple(augment)
        bad = [n for n in augment if n not in LIBRARY and n not in TERM_NAMES]
        if bad or len(set(augment)) != len(augment):
            raise ProblemError(f"augment takes distinct library effects {list(LIBRARY)} "
                               f"(or dictionary terms), got {list(augment)}")
        specs = [EFFECTS[EFFECT_NAMES.index(n)] for n in augment]
        arrays = (np.r_[LOWER, [e.lower for e in specs]], np.r_[UPPER, [e.upper for e in specs]],
                  np.r_[NOMINAL, np.zeros(len(specs))])
        for a in arrays:
            a.flags.writeable = False
        return cls(FAULT_NAMES + augment, {**FAULT_UNITS, **{e.name: e.unit for e in specs}},
                   *arrays, augment)

    def without_prior(self) -> SearchSpace:
        """The same space with bounds only: no nominal vector (the no-prior condition of
        suite ``emafdi-v2``)."""
        return SearchSpace(self.names, dict(self.units), self.lower, self.upper, None,
                           self.augment)

    @property
    def dim(self) -> int:
        return len(self.names)

    def check(self, X: np.ndarray) -> np.ndarray:
        """A validated copy of the batch ``X`` (n, dim): finite and inside the bounds (effect
        columns within 1e-9 of their range are clipped in); :class:`ProblemError` otherwise."""
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[1] != self.dim:
            raise ProblemError(f"expected a batch of shape (n, {self.dim}) for parameters "
                               f"{list(self.names)}, got {X.shape}")
        try:
            faults = check_faults(X[:, :N_FAULTS], batch=True)
        except FaultError as exc:
            raise ProblemError(str(exc)) from None
        lo, hi = self.lower[N_FAULTS:], self.upper[N_FAULTS:]
        extra = X[:, N_FAULTS:]
        slack = 1e-9 * (hi - lo)
        bad = ~np.isfinite(extra) | (extra < lo - slack) | (extra > hi + slack)
        if bad.any():
            i, j = np.argwhere(bad)[0]
            raise ProblemError(f"effect {self.augment[j]}={extra[i, j]:g} in row {i} is not "
                               f"finite or outside [{lo[j]:g}, {hi[j]:g}]")
        return np.hstack([faults, np.clip(extra, lo, hi)])

    def effects_for(self, X: np.ndarray, base: np.ndarray | None = None) -> np.ndarray:
        """Effects vector of every candidate (n, N_EFFECTS): ``base`` plus the augmented
        columns of ``X``."""
        E = np.zeros((X.shape[0], N_EFFECTS)) if base is None else np.tile(base, (len(X), 1))
        for j, name in enumerate(self.augment):
            E[:, EFFECT_NAMES.index(name)] = X[:, N_FAULTS + j]
        return E

    def to_unit(self, X: np.ndarray) -> np.ndarray:
        """Physical vector(s) -> the normalised box [0, 1]^dim."""
        return (np.asarray(X, dtype=float) - self.lower) / (self.upper - self.lower)

    def from_unit(self, U: np.ndarray) -> np.ndarray:
        """Normalised box [0, 1]^dim -> physical vector(s)."""
        return self.lower + np.asarray(U, dtype=float) * (self.upper - self.lower)


# --- what is minimised ---------------------------------------------------------------------
def check_measured(measured: Traces) -> tuple[TestSpec, ...]:
    """The protocol tests of ``measured``; :class:`ProblemError` if the monitor cannot
    simulate them at the traces' rate and length."""
    if not isinstance(measured, Traces):
        raise ProblemError("measured must be a Traces (see ema_bench.load_traces)")
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
    return tuple(KNOWN_TESTS[t] for t in measured.tests)


def signal_mask(signals: Sequence[str] | None) -> np.ndarray:
    """Weight multiplier (4,) per output, ``SIGNALS`` order: 1 for each of ``signals`` (all
    for None), 0 for the others (an information condition of suite ``emafdi-v2``: the
    fitness sees fewer signals); :class:`ProblemError` for an unknown or empty selection."""
    if signals is None:
        return np.ones(len(SIGNALS))
    signals = tuple(signals)
    bad = [n for n in signals if n not in SIGNALS]
    if bad or not signals or len(set(signals)) != len(signals):
        raise ProblemError(f"signals takes distinct outputs of {list(SIGNALS)}, got "
                           f"{list(signals)}")
    return np.array([float(n in signals) for n in SIGNALS])


def _sample_weights(sample_weights: Mapping[str, np.ndarray], test: str,
                    shape: tuple[int, ...]) -> np.ndarray:
    """The checked per-sample weight multipliers of one test."""
    if test not in sample_weights:
        raise ProblemError(f"sample_weights has no entry for test {test!r}")
    w = np.asarray(sample_weights[test], dtype=float)
    if w.shape != shape or not np.all(np.isfinite(w)) or np.any(w < 0.0):
        raise ProblemError(f"sample_weights[{test!r}] must be finite, >= 0 and of shape "
                           f"{shape}, got shape {w.shape}")
    return w


class Objective:
    """The fitness of candidates against measured traces (lower is better).

    Parameters
    ----------
    measured : Traces
        The traces to fit.
    space : SearchSpace, optional
        What is searched (default: the four faults).
    normalise : bool
        Normalised (default) or raw fitness (:func:`signal_weights`).
    effects : array (N_EFFECTS,), optional
        Effects switched on in the monitor for every candidate.
    sample_weights : mapping, optional
        Per test, an (n_samples, 4) multiplier of each sample's weight (e.g. 0 where a
        sample carries no information the model can match); default 1 everywhere.
    params : EMAParams, optional
        The monitor's parameters (default ``DEFAULT_PARAMS``, model version 3;
        :func:`ema_bench.params.model_params` gives another version's).

    Notes
    -----
    Residual layout (:meth:`residuals`, the environment's observations): test by test, signal
    by signal, sample by sample, as :meth:`~ema_bench.traces.Traces.stacked`.
    """

    def __init__(self, measured: Traces, space: SearchSpace | None = None, *,
                 normalise: bool = True, effects: np.ndarray | None = None,
                 sample_weights: Mapping[str, np.ndarray] | None = None,
                 signals: Sequence[str] | None = None,
                 params: EMAParams = DEFAULT_PARAMS) -> None:
        self.tests = check_measured(measured)
        self.params = params
        self.measured = measured
        self.space = space or SearchSpace.of()
        self.normalise = bool(normalise)
        self.effects = np.zeros(N_EFFECTS) if effects is None else np.asarray(effects, float)
        if self.effects.shape != (N_EFFECTS,):
            raise ProblemError(f"effects must have shape ({N_EFFECTS},)")
        self.mask = signal_mask(signals)
        self.mask.flags.writeable = False
        self.signals = tuple(n for n, m in zip(SIGNALS, self.mask) if m)
        self.weights = {t: w * self.mask for t, w in signal_weights(measured, normalise).items()}
        if sample_weights is not None:
            self.weights = {t: w[None, :] * _sample_weights(sample_weights, t,
                                                            measured.data[t].shape)
                            for t, w in self.weights.items()}
        # sqrt(weight / n_samples) per residual element, stacked layout (signal by signal)
        self._factors = np.concatenate([
            np.sqrt(np.broadcast_to(self.weights[t], measured.data[t].shape).T.ravel()
                    / measured.n_samples(t)) for t in measured.tests])
        self._stacked = measured.stacked()
        # which output (SIGNALS order) each stacked element is
        self._signal = np.concatenate([np.repeat(np.arange(len(SIGNALS)),
                                                 measured.n_samples(t)) for t in measured.tests])
        for a in (self._factors, self._stacked, self._signal):
            a.flags.writeable = False

    @property
    def n_residuals(self) -> int:
        return self._stacked.size

    @property
    def data(self) -> np.ndarray:
        """The measured traces in the stacked layout, shape (n_residuals,), canonical units."""
        return self._stacked

    @property
    def factors(self) -> np.ndarray:
        """Residual factor of each stacked element, ``sqrt(weight / n_samples)``: the
        fitness is ``sum((factors * (model - data))**2)``."""
        return self._factors

    @property
    def signal_index(self) -> np.ndarray:
        """Index into ``SIGNALS`` (and ``SENSORS``) of each stacked element."""
        return self._signal

    def outputs(self, X: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """Monitor outputs of a validated batch (test -> (n, n_samples, 4)) and the
        success flags of the simulations."""
        return simulate_monitor(X[:, :N_FAULTS], self.space.effects_for(X, self.effects),
                                tests=self.tests, params=self.params, check=False)

    def evaluate(self, X: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
        """Fitness (n,), outputs and the failed mask of a validated batch: one monitor call.

        A failed (non-finite) simulation scores :data:`PENALTY`; valid values are clipped to
        :data:`VALID_CAP`, so a failure always ranks last."""
        outputs, ok = self.outputs(X)
        with np.errstate(over="ignore", invalid="ignore"):
            f = fitness_from_outputs(outputs, self.measured, self.weights)
        failed = ~ok | ~np.isfinite(f)
        return np.where(failed, PENALTY, np.minimum(f, VALID_CAP)), outputs, failed

    def stack(self, outputs: Mapping[str, np.ndarray]) -> np.ndarray:
        """Outputs (test -> (n, n_samples, 4)) in the stacked layout, shape (n, n_residuals)."""
        return np.concatenate([np.swapaxes(outputs[t.name], 1, 2).reshape(
            outputs[t.name].shape[0], -1) for t in self.tests], axis=1)

    def residuals(self, outputs: Mapping[str, np.ndarray], fitness: np.ndarray) -> np.ndarray:
        """Weighted residuals (n, n_residuals), stacked layout, with ``sum(r**2) == fitness``
        row by row (rescaled where the fitness was capped; a failed row is the uniform vector
        of that sum)."""
        r = (self.stack(outputs) - self._stacked[None, :]) * self._factors[None, :]
        fitness = np.asarray(fitness, dtype=float)
        with np.errstate(over="ignore", invalid="ignore"):
            raw = np.einsum("ij,ij->i", r, r)
        failed = fitness >= PENALTY
        capped = ~failed & (raw > fitness) & (fitness > 0.0)
        r[capped] *= np.sqrt(fitness[capped] / raw[capped])[:, None]
        r[failed] = np.sqrt(PENALTY / r.shape[1])
        return r
