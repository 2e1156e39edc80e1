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

from ..faults import N_FAULTS, NOMINAL, random_faults
from ..instances import check_settings as check_vector_settings
from ..instances import make_problem as vector_problem
from ..objective import ProblemError
from ..problem import Problem
from ..seeding import SeedLike, as_seed_sequence, stream
from ..traces import Traces
from . import find, instance
from .targets import SuiteError

#: The case of a random instance drawn from each run's seed (no suite instance).
SEEDED = "seeded"


def check_settings(case: object = "small", track: str = "reference", budget: object = 1,
                   heterogeneity: float = 1.0) -> None:
    """The checks of :func:`make_problem`'s settings, for callers that must fail early (the
    environment at construction, the command line before any work): ProblemError."""
    if isinstance(case, str):
        # a key a suite refuses (an unknown condition) raises its SuiteError here
        if case != SEEDED and find(case) is None:
            try:
                instance(case)
            except SuiteError as exc:
                raise ProblemError(str(exc)) from None
        case = NOMINAL   # a case key is valid: check the rest
    check_vector_settings(case, track, budget, heterogeneity)


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
    budget : int or None
        Hard evaluation budget; None: the case's suite budget
        (:attr:`~ema_bench.suites.base.Instance.budget`; v2: 1250 x the tier).
    track, seed, normalise, effects, measured, augment, tests, start,
    sample_weights, prior, score_effects, signals
        As :func:`ema_bench.instances.make_problem` (``seed``: the run node, whose
        ``noise`` stream draws the sensor noise).
    heterogeneity : float
        In [0, 1]: how far a ``seeded`` case's faults spread (1: the whole box).
    """
    options = dict(track=track, seed=seed, budget=budget, normalise=normalise,
                   heterogeneity=heterogeneity, measured=measured, start=start,
                   sample_weights=sample_weights)
    if measured is not None or not isinstance(case, str):
        return vector_problem(case, effects=effects, augment=augment, tests=tests,
                              prior=prior, score_effects=score_effects, signals=signals,
                              **options)
    check_settings(case, track, 1 if budget is None else budget, heterogeneity)
    if case == SEEDED:
        truth = random_faults(stream(as_seed_sequence(seed), "instance"), heterogeneity)
        return vector_problem(truth, effects=effects, augment=augment, tests=tests,
                              prior=prior, score_effects=score_effects, signals=signals,
                              label=f"seeded(h={heterogeneity:g})", **options)
    inst = instance(case)
    options["budget"] = inst.budget if budget is None else budget
    if start is not None and not inst.prior:
        raise ProblemError(f"case {case!r} gives no prior: no start")
    return vector_problem(inst.truth[:N_FAULTS],
                          effects=inst.effects or None if effects is None else effects,
                          augment=tuple(augment) or inst.augment,
                          tests=inst.tests if tests is None else tests,
                          prior=prior and inst.prior,
                          score_effects=score_effects or bool(inst.augment),
                          signals=inst.signals if signals is None else signals,
                          label=inst.case, **options)
