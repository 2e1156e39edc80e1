"""The one problem factory: a case of any suite (or true faults) -> its
:class:`~ema_bench.problem.Problem`.

The case key is looked up in the registry (:func:`ema_bench.suites.instance`); the instance
sets the data (its truth, the effects on in the model that makes them, its tests and
outputs), the search space (the faults and the effects it fits) and what the solver is given
(the prior), and the problem is built on the vector path
(:func:`ema_bench.instances.make_problem`) labelled with the case key.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..faults import N_FAULTS, FaultError, check_faults, random_faults
from ..instances import TRACKS
from ..instances import make_problem as vector_problem
from ..objective import ProblemError
from ..params import DEFAULT_PARAMS, EMAParams
from ..problem import Problem, check_budget
from ..seeding import SeedLike, as_seed_sequence, stream
from ..traces import Traces
from . import find, instance
from .targets import SuiteError

#: The case of a random instance drawn from each run's seed (no suite instance).
SEEDED = "seeded"


def check_settings(case: object = "small", track: str = "reference", budget: object = 1,
                   heterogeneity: float = 1.0) -> None:
    """The checks of :func:`make_problem`'s settings, for callers that must fail early (the
    environment at construction, the command line before any work): ProblemError (a
    SuiteError for a case key a suite refuses, an unknown condition)."""
    check_budget(budget)
    if track not in TRACKS:
        raise ProblemError(f"unknown track {track!r}; known: {list(TRACKS)}")
    if not 0.0 <= float(heterogeneity) <= 1.0:
        raise ProblemError(f"heterogeneity must lie in [0, 1], got {heterogeneity!r}")
    if case is None:
        raise ProblemError("give a case, or measured traces")
    if isinstance(case, str):
        if case != SEEDED and find(case) is None:   # a key a suite refuses raised here
            try:
                instance(case)
            except SuiteError as exc:
                raise ProblemError(str(exc)) from None
        return
    try:
        check_faults(case)
    except FaultError as exc:
        raise ProblemError(f"bad case: {exc}") from None


def make_problem(
    case: str | Mapping[str, float] | np.ndarray | None = "small",
    *,
    track: str = "reference",
    seed: SeedLike = 0,
    budget: int | None = 1000,
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
    params: EMAParams | None = None,
) -> Problem:
    """Build an identification problem.

    Parameters
    ----------
    case : str, mapping or array
        A case of any suite (:mod:`ema_bench.suites`): a v1 instance (a paper case
        ``nominal``, ``small``, ``full``, ``random``, or ``s00`` .. ``s19``) or a v2 case
        ``instance@condition`` (``t12-s03@no-prior``: the tier's search space, the
        condition's data and prior); ``"seeded"`` for a random instance drawn from the
        ``instance`` stream of ``seed`` with ``heterogeneity``; or explicit true faults.  A
        case's own settings (effects, fitted effects, tests, outputs, prior) apply where the
        arguments below are left at their defaults.
    track : {"reference", "twin"}
        ``reference``: measured traces come from the detailed reference model (model-form
        mismatch, as in the paper); ``twin``: from the monitor model itself plus sensor noise
        (a pure optimisation problem whose optimum is the truth).
    seed : int or SeedSequence
        The run node (:func:`~ema_bench.seeding.run_seed`; an int is a node of its own):
        its ``instance`` stream draws a seeded case, its ``noise`` stream the sensor noise.
    budget : int or None
        Hard evaluation budget; None: the case's suite budget
        (:attr:`~ema_bench.suites.base.Instance.budget`; v2: 1250 x the tier).
    normalise : bool
        Normalised (default) or raw fitness.
    heterogeneity : float
        In [0, 1]: how far a ``seeded`` case's faults spread (1: the whole box).
    effects : mapping, optional
        Effects switched on in the model that makes the data (unmodelled physics).
    measured : Traces, optional
        Fit these traces instead (file data); ``case`` and ``track`` are then ignored and
        there is no truth to score against.
    augment : sequence of str
        Library effects fitted with the faults (see :class:`~ema_bench.problem.Problem`).
    tests : sequence of str, optional
        Protocol tests that make the data (default: the standard step and sine; add
        ``"sine2"`` for held-out validation).
    start : array, optional
        Warm start for solvers (see :class:`~ema_bench.problem.Problem`).
    sample_weights : mapping, optional
        Per test, (n_samples, 4) weight multipliers of ``measured``'s samples (only with
        ``measured``; see :class:`~ema_bench.objective.Objective`).
    prior : bool
        False: no nominal vector and no start for the solver.
    score_effects : bool
        The hidden truth holds the ``augment`` effects' true values after the faults, so
        parameter targets judge them too (suite ``emafdi-v2``'s higher tiers).
    signals : sequence of str, optional
        The outputs the fitness weighs (default all four; suite ``emafdi-v2``'s
        ``surface-current`` condition: ``theta_u``, ``i_eq``).  The others get weight 0 in
        the objective, and in synthetic data (a case and a track) their columns are zeros:
        the solver is not given what the condition withholds.
    params : EMAParams, optional
        Both models' parameters (the data maker's and the monitor's): default a case's
        suite's model version (:attr:`~ema_bench.suites.base.Instance.params`; emafdi-v3:
        model version 4), else :data:`~ema_bench.params.DEFAULT_PARAMS`;
        :func:`ema_bench.params.model_params` gives another's (replay re-runs a record on its
        own version's).
    """
    if measured is not None:
        if not isinstance(measured, Traces):
            raise ProblemError("measured must be a Traces (see ema_bench.load_traces)")
        return Problem(measured, budget, normalise=normalise, augment=augment, start=start,
                       sample_weights=sample_weights, signals=signals, prior=prior,
                       params=DEFAULT_PARAMS if params is None else params,
                       label=str(measured.meta.get("source", "measured")), track="measured",
                       _meta={"source": measured.meta.get("source")})
    if sample_weights is not None:
        raise ProblemError("sample_weights weigh given measured traces: pass measured too")
    inst = find(case) if isinstance(case, str) and case != SEEDED else None
    if budget is None and inst is not None:
        budget = inst.budget
    check_settings(case, track, budget, heterogeneity)
    options = dict(track=track, seed=seed, budget=budget, normalise=normalise, start=start)
    if inst is None:
        seeded = isinstance(case, str)   # "seeded": drawn from the node's instance stream
        truth = (random_faults(stream(as_seed_sequence(seed), "instance"), heterogeneity)
                 if seeded else case)
        return vector_problem(truth, effects=effects, augment=augment, tests=tests,
                              prior=prior, score_effects=score_effects, signals=signals,
                              params=DEFAULT_PARAMS if params is None else params,
                              label=f"seeded(h={heterogeneity:g})" if seeded else "custom",
                              **options)
    if start is not None and not inst.prior:
        raise ProblemError(f"case {case!r} gives no prior: no start")
    return vector_problem(inst.truth[:N_FAULTS],
                          effects=inst.effects or None if effects is None else effects,
                          augment=tuple(augment) or inst.augment,
                          tests=inst.tests if tests is None else tests,
                          prior=prior and inst.prior,
                          score_effects=score_effects or bool(inst.augment),
                          signals=inst.signals if signals is None else signals,
                          params=inst.params if params is None else params,
                          label=inst.case, **options)
