"""The one shape of every suite version: a :class:`Suite` and the :class:`Instance` a run's
case key names.

A suite version is one module (``v1.py``, ``v2.py``) that builds one :class:`Suite` value:
its id, how it looks a case up, its best-known table, which parameters its parameter targets
judge, its IOH numbering and the cases a complete submission covers.  Every consumer (run
records, the re-derivation, validation, reports, exports, the environments, the command
line) asks the :class:`Instance` (``ema_bench.suites.instance(case)``), never the version.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from importlib.resources.abc import Traversable

import numpy as np

from ..faults import N_FAULTS
from ..params import EMAParams, model_params
from .targets import FITNESS_PRECISIONS, SUITE_MODEL_VERSION


@dataclass(frozen=True, eq=False)
class Instance:
    """One case of a suite: the problem a run on it solves and how the run is judged.

    Parameters
    ----------
    case : str
        The run records' case key (``small``, ``t7-s03@no-prior``).
    name : str
        The instance within its suite (``small``, ``t7-s03``).
    suite : Suite
        The suite version it belongs to.
    names : tuple of str
        The searched parameters: the faults, then any effects fitted with them.
    truth, lower, upper : ndarray
        Every searched parameter's true value and bounds (physical units).
    effects : mapping
        The effects switched on (non-zero) in the model that makes the data.
    tests, signals : tuple of str or None
        The protocol tests that make the data and the outputs the fitness weighs (None: the
        standard step and sine; all four outputs).
    prior : bool
        Whether the solver is handed the nominal vector and starts there.
    budget : int
        The suite's evaluation budget for the instance.
    ranked : bool
        False for a sanity case (the healthy actuator), outside the aggregate scores.
    group : tuple of (int, str) or None
        (dimension, condition) on a board scored by group; None: scored per instance.
    paper_case : str
        The case the paper tables know it by: the paper case whose problem this is, data
        and all (``small@prior`` -> ``small``), else its case key.
    ioh_function : str
        The IOH function's name before ``@track``.
    """

    case: str
    name: str
    suite: Suite
    names: tuple[str, ...]
    truth: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    effects: Mapping[str, float] = field(default_factory=dict)
    tests: tuple[str, ...] | None = None
    signals: tuple[str, ...] | None = None
    prior: bool = True
    budget: int = 5000
    ranked: bool = True
    group: tuple[int, str] | None = None
    paper_case: str = ""
    ioh_function: str = ""

    def __post_init__(self) -> None:
        # the registry caches instances: their arrays are read-only copies
        for name in ("truth", "lower", "upper"):
            arr = np.array(getattr(self, name), dtype=float)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def dim(self) -> int:
        """The number of searched parameters."""
        return len(self.names)

    @property
    def ranges(self) -> np.ndarray:
        """Every searched parameter's range (physical units)."""
        return self.upper - self.lower

    @property
    def augment(self) -> tuple[str, ...]:
        """The effects fitted with the faults."""
        return self.names[N_FAULTS:]

    def best_known(self, track: str, seed: int, root_seed: int = 0,
                   model_version: str | None = None) -> dict | None:
        """The best-known entry (``f_star``, ``f_nominal``, ``x_star``) of a run on this
        instance, or None where the suite has no fixed target.  ``model_version``: that of
        the record being judged (None: this installation's); a compatible earlier version
        (:data:`~ema_bench.trace_cache.COMPATIBLE_VERSIONS`) is judged on the entries it was
        made against, where the table keeps them (``superseded``)."""
        return self.suite.best_known(self, track, seed, root_seed, model_version)

    def judged(self, track: str) -> np.ndarray | None:
        """Which parameters carry parameter targets on ``track`` (None: all)."""
        return self.suite.judged(self, track)

    def frame(self, track: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Truth, target scales and judged mask (None: all) of the parameters the parameter
        targets and the success rule judge on ``track``: level ``L`` holds where every
        judged parameter lies within ``L x scale`` of the truth.  The scales are the ranges,
        or in a suite with noise-allowed targets (:attr:`Suite.target_scales`) the scale it
        gives."""
        scale = None if self.suite.target_scales is None else \
            self.suite.target_scales(self, track)
        return self.truth, self.ranges if scale is None else scale, self.judged(track)

    @property
    def model_version(self) -> str:
        """The model version of its suite: the monitor its fitness and twin data run."""
        return self.suite.model_version

    @property
    def params(self) -> EMAParams:
        """The monitor's parameters of :attr:`model_version`
        (:func:`~ema_bench.params.model_params`)."""
        return model_params(self.suite.model_version)

    @property
    def fitness_precisions(self) -> tuple[float, ...]:
        """The precisions ``p`` of the fitness targets ``f* + p (f_nominal - f*)``."""
        return self.suite.fitness_precisions

    def ioh_instance(self, seed: int) -> int:
        """The IOH instance id of run ``seed`` on this instance (ValueError beyond the ids
        the suite numbers)."""
        return self.suite.ioh_instance(self, seed)


@dataclass(frozen=True)
class Selection:
    """The part of a suite a command covers, as its options give it (None: the suite's
    default): named cases or groups (a suite without tiers), or tiers x conditions and the
    first ``per_tier`` instances of each (a suite with tiers); ``quick``: the small CI
    preset.  A suite refuses (SuiteError) the options it does not take."""

    cases: Sequence[str] | None = None
    tiers: Sequence[str] | None = None
    conditions: Sequence[str] | None = None
    per_tier: int | None = None
    quick: bool = False


@dataclass(frozen=True)
class CaseBudgets:
    """A sweep's budget that depends on the case: ``budgets(case)`` evaluations, said
    ``label`` (``1250 x tier``)."""

    budgets: Mapping[str, int]
    label: str

    def __call__(self, case: str) -> int:
        return self.budgets[case]

    def __str__(self) -> str:
        return self.label


@dataclass(frozen=True)
class Suite:
    """One suite version (see the module docstring); every field but ``id`` and ``grouped``
    is a function of the version's module.

    Parameters
    ----------
    id : str
        The version (``emafdi-v1``), in every record of it.
    lookup : callable
        ``(name, condition or None) -> Instance`` of a case of this suite, None when the key
        is not of its form or names none of its instances; SuiteError for a key of its form
        it refuses (an unknown condition, one not offered on the instance).
    best_known : callable
        ``(instance, track, seed, root_seed, model_version or None) -> entry or None``.
    judged : callable
        ``(instance, track) -> mask or None``: the parameters that carry parameter targets.
    ioh_instance : callable
        ``(instance, seed) -> int``.
    ioh_functions : callable
        ``() -> names`` of the IOH functions, in order (before ``@track``).
    complete_cases : callable
        ``(instances entered, per_tier) -> case keys`` a complete submission covers.
    case_order : callable
        ``() -> case names``: the order of the suite's tables.
    sweep_cases : callable
        ``(Selection) -> case keys`` of a sweep (``ema-bench leaderboard``).
    sweep_budget : callable
        ``(cases, budget or None, per-dimension budget or None, quick) -> budget``: an int,
        or :class:`CaseBudgets` (evaluations per case).
    target_keys : callable
        ``(Selection, seeds or None, tracks or None) -> keys or None`` whose best-known
        entries ``ema-bench targets`` computes (None: every key of the suite's table).
    targets_file : callable
        ``() -> path`` of the best-known table shipped with the package.
    grouped : bool
        Its board is scored per (dimension, condition) group as well as overall.
    clean_fits : bool
        Its best-known entries carry a clean-data fit, from which the reference track's
        judged parameters are chosen (``ema-bench targets`` computes it).
    target_scales : callable or None
        ``(instance, track) -> scales or None``: each searched parameter's target scale
        (physical units; level ``L`` of the parameter ladder is ``L x scale``); None: the
        ranges (emafdi-v3: the noise-allowed tolerances).
    fitness_precisions : tuple of float
        The fitness ladder's precisions (default :data:`~.targets.FITNESS_PRECISIONS`).
    split_ecdf : bool
        Its board also draws the ECDFs of fitness and of parameter targets apart (a dense
        fitness ladder would otherwise outweigh the three parameter targets).
    tier_cases : callable or None
        ``(tier or None, condition or None, instance name or None) -> case keys`` of a tier
        under a condition (its environment's episodes, ``gymnasium.make(..., tier=7)``);
        None: the suite has no tiers.
    model_version : str
        The model version its problems run on (:func:`~ema_bench.params.model_params`: the
        monitor of its fitness and of its twin-track data), its best-known tables and its
        run records are labelled with (emafdi-v1, v2: 3; emafdi-v3: 4).
    """

    id: str
    lookup: Callable[[str, str | None], Instance | None]
    best_known: Callable[[Instance, str, int, int, str | None], dict | None]
    judged: Callable[[Instance, str], np.ndarray | None]
    ioh_instance: Callable[[Instance, int], int]
    ioh_functions: Callable[[], Sequence[str]]
    complete_cases: Callable[[Sequence[Instance], int | None], list[str]]
    case_order: Callable[[], Sequence[str]]
    sweep_cases: Callable[[Selection], list[str]]
    sweep_budget: Callable[[Sequence[str], int | None, int | None, bool], int | CaseBudgets]
    target_keys: Callable[[Selection, int | None, Sequence[str] | None], list[str] | None]
    targets_file: Callable[[], Traversable]
    grouped: bool = False
    clean_fits: bool = False
    target_scales: Callable[[Instance, str], np.ndarray | None] | None = None
    fitness_precisions: tuple[float, ...] = FITNESS_PRECISIONS
    split_ecdf: bool = False
    tier_cases: Callable[[int | str | None, str | None, object], list[str]] | None = None
    model_version: str = SUITE_MODEL_VERSION
