"""Measured traces for true faults, a track and a seed, wrapped in a
:class:`~ema_bench.problem.Problem` by :func:`make_problem` (the vector path: a suite's case
key goes through :func:`ema_bench.suites.problem.make_problem`, the package's
``ema_bench.make_problem``, which looks the case up and comes here with its truth)."""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence

import numpy as np

from .effects import EFFECT_INDEX, effects_to_dict, effects_vector
from .faults import FaultError, check_faults, faults_to_dict
from .monitor import simulate_monitor
from .objective import KNOWN_TESTS, ProblemError, signal_mask
from .params import DEFAULT_PARAMS
from .physics.sensors import measure
from .problem import Problem, check_budget
from .protocol import STANDARD_TESTS, TestSpec
from .reference import SimulationError, simulate_reference
from .seeding import SeedLike, as_seed_sequence, children, stream
from .trace_cache import PUBLIC_META, cache_key, cached_traces, expected_shapes
from .traces import Traces

TRACKS = ("reference", "twin")


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


def twin_traces(x: np.ndarray, e: np.ndarray, seed: np.random.SeedSequence,
                tests: tuple[TestSpec, ...]) -> Traces:
    """Measured traces of the twin track: the monitor model at faults ``x`` with effects
    ``e``, through the sensors (noise and ADC; one child of ``seed`` per test)."""
    outputs, ok = simulate_monitor(x[None, :], e[None, :], tests=tests)
    if not ok[0]:
        raise SimulationError(f"monitor model diverged at the true faults {faults_to_dict(x)}")
    data = {t: measure(v[0], np.random.default_rng(c))
            for (t, v), c in zip(outputs.items(), children(seed, len(outputs)))}
    return Traces(data=data, meta={"model": "monitor", "faults": faults_to_dict(x),
                                   "effects": effects_to_dict(e), "noise": True, "adc": True})


def check_settings(case: object = None, track: str = "reference", budget: object = 1,
                   heterogeneity: float = 1.0) -> None:
    """The checks of :func:`make_problem`'s settings (``case``: true faults, a mapping or an
    array), for callers that must fail early: ProblemError.  A case key is checked by
    :func:`ema_bench.suites.problem.check_settings`, which comes here for the rest."""
    check_budget(budget)
    if track not in TRACKS:
        raise ProblemError(f"unknown track {track!r}; known: {list(TRACKS)}")
    if not 0.0 <= float(heterogeneity) <= 1.0:
        raise ProblemError(f"heterogeneity must lie in [0, 1], got {heterogeneity!r}")
    if case is None:
        raise ProblemError("give a case, or measured traces")
    try:
        check_faults(case)
    except FaultError as exc:
        raise ProblemError(f"bad case: {exc}") from None


def make_problem(
    case: Mapping[str, float] | np.ndarray | None = None,
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
    sample_weights: Mapping[str, np.ndarray] | None = None,
    prior: bool = True,
    score_effects: bool = False,
    signals: Sequence[str] | None = None,
    label: str = "custom",
) -> Problem:
    """Build an identification problem from true faults (the parameters are those of
    :func:`ema_bench.suites.problem.make_problem`, which takes a case key too).

    Parameters
    ----------
    case : mapping or array
        The true faults.
    track : {"reference", "twin"}
        ``reference``: measured traces come from the detailed reference model (model-form
        mismatch, as in the paper); ``twin``: from the monitor model itself plus sensor noise
        (a pure optimisation problem whose optimum is the truth).
    seed : int or SeedSequence
        The run node (:func:`~ema_bench.seeding.run_seed`; an int is a node of its own):
        its ``noise`` stream draws the sensor noise.
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
    sample_weights : mapping, optional
        Per test, (n_samples, 4) weight multipliers of ``measured``'s samples (only with
        ``measured``; see :class:`~ema_bench.objective.Objective`).
    prior : bool
        False: no nominal vector and no start for the solver (see :class:`Problem`).
    score_effects : bool
        The hidden truth holds the ``augment`` effects' true values after the faults, so
        parameter targets judge them too (suite ``emafdi-v2``'s higher tiers).
    signals : sequence of str, optional
        The outputs the fitness weighs (default all four; suite ``emafdi-v2``'s
        ``surface-current`` condition: ``theta_u``, ``i_eq``).  The others get weight 0 in
        the objective, and in synthetic data (a case and a track) their columns are zeros:
        the solver is not given what the condition withholds.
    label : str
        The problem's public case label (a case key, ``seeded(h=..)``).
    """
    if measured is not None:
        if not isinstance(measured, Traces):
            raise ProblemError("measured must be a Traces (see ema_bench.load_traces)")
        return Problem(measured, budget, normalise=normalise, augment=augment, start=start,
                       sample_weights=sample_weights, signals=signals, prior=prior,
                       label=str(measured.meta.get("source", "measured")), track="measured",
                       _meta={"source": measured.meta.get("source")})
    if sample_weights is not None:
        raise ProblemError("sample_weights weigh given measured traces: pass measured too")
    check_settings(case, track, budget, heterogeneity)
    keep = signal_mask(signals)   # an unknown signal fails before any simulation
    s_noise = stream(as_seed_sequence(seed), "noise")
    truth = check_faults(case)
    e = effects_vector(effects)
    names = tuple(tests) if tests is not None else tuple(s.name for s in STANDARD_TESTS)
    unknown = [n for n in names if n not in KNOWN_TESTS]
    if unknown or not names:
        raise ProblemError(f"unknown test(s) {unknown}; known: {list(KNOWN_TESTS)}")
    specs = tuple(KNOWN_TESTS[n] for n in names)
    if track == "reference":
        measured = _reference_traces(tuple(truth), tuple(e), int(s_noise.entropy),
                                     tuple(s_noise.spawn_key), specs)
    else:
        measured = twin_traces(truth, e, s_noise, specs)
    # the data makers record faults, effects and seeds; a solver sees none of them, nor the
    # outputs a condition withholds (zeroed: their weight is 0, the fitness is unchanged)
    measured = Traces({t: v * keep if signals is not None else v
                       for t, v in measured.data.items()}, dt=measured.dt,
                      meta={k: v for k, v in measured.meta.items() if k in PUBLIC_META})
    # public: nothing a solver could use to recover the truth (no seed, no effects)
    meta = {"case": label, "track": track}
    if score_effects:
        truth = np.r_[truth, [e[EFFECT_INDEX[n]] for n in augment]]
    return Problem(measured, budget, normalise=normalise, label=label, track=track,
                   augment=augment, start=start, prior=prior, signals=signals, _truth=truth,
                   _meta=meta)
