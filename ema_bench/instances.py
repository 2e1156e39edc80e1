"""Measured traces for true faults, a track and a seed, wrapped in a
:class:`~ema_bench.problem.Problem` by :func:`make_problem` (the vector path: a suite's case
key goes through :func:`ema_bench.suites.problem.make_problem`, the package's
``ema_bench.make_problem``, which looks the case up and comes here with its truth)."""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence

import numpy as np

from .effects import EFFECT_INDEX, effects_to_dict, effects_vector
from .faults import check_faults, faults_to_dict
from .monitor import simulate_monitor
from .objective import KNOWN_TESTS, ProblemError, signal_mask
from .params import DEFAULT_PARAMS, EMAParams
from .physics.sensors import measure
from .problem import Problem
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
                tests: tuple[TestSpec, ...], params: EMAParams = DEFAULT_PARAMS) -> Traces:
    """Measured traces of the twin track: the monitor model (``params``: its model version)
    at faults ``x`` with effects ``e``, through the sensors (noise and ADC; one child of
    ``seed`` per test)."""
    outputs, ok = simulate_monitor(x[None, :], e[None, :], tests=tests, params=params)
    if not ok[0]:
        raise SimulationError(f"monitor model diverged at the true faults {faults_to_dict(x)}")
    data = {t: measure(v[0], np.random.default_rng(c))
            for (t, v), c in zip(outputs.items(), children(seed, len(outputs)))}
    return Traces(data=data, meta={"model": "monitor", "faults": faults_to_dict(x),
                                   "effects": effects_to_dict(e), "noise": True, "adc": True})


def make_problem(
    truth: Mapping[str, float] | np.ndarray,
    *,
    track: str = "reference",
    seed: SeedLike = 0,
    budget: int = 1000,
    normalise: bool = True,
    effects: Mapping[str, float] | None = None,
    augment: Sequence[str] = (),
    tests: Sequence[str] | None = None,
    start: np.ndarray | None = None,
    prior: bool = True,
    score_effects: bool = False,
    signals: Sequence[str] | None = None,
    label: str = "custom",
    params: EMAParams = DEFAULT_PARAMS,
) -> Problem:
    """The problem of true faults ``truth`` (a mapping or an array): measured traces made on
    ``track`` with the run node ``seed``'s ``noise`` stream, ``label`` its public case label.
    The other parameters are those of :func:`ema_bench.suites.problem.make_problem` (the
    package's ``ema_bench.make_problem``, which checks them and comes here); ``params``: the
    monitor's (the fitness's and the twin data's), the reference data do not depend on
    them."""
    keep = signal_mask(signals)   # an unknown signal fails before any simulation
    s_noise = stream(as_seed_sequence(seed), "noise")
    truth = check_faults(truth)
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
        measured = twin_traces(truth, e, s_noise, specs, params)
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
                   _meta=meta, params=params)
