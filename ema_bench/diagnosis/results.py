"""What the missing-physics workflow (:mod:`.workflow`) is given and what it returns: its
settings, the fits, assessments and trials it makes, and the diagnosis."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from ..effects import EFFECT_NAMES, N_EFFECTS
from ..faults import FAULT_NAMES
from ..objective import N_FAULTS
from ..seeding import SEED_SCHEME
from .acquisition import Acquisition
from .verdict import (
    Discrepancy,
    discrepancy,
)

TRAIN = ("step", "sine")
HOLDOUT = ("sine2",)


class DiagnosisError(ValueError):
    """Traces the workflow cannot use (e.g. no held-out test)."""


@dataclass(frozen=True)
class Settings:
    solver: str = "cmaes"
    budget: int = 3000          # evaluations per fit
    n_boot: int = 40            # bootstrap replicates
    # robust deviations beyond which a statistic is anomalous: null cases reach ~9 at high
    # friction (model-form gap), effects at their detection threshold >= 50
    z_max: float = 10.0
    # candidates fitted jointly per round: the linearised score misranks strongly nonlinear
    # effects (a 1 ms delay ranked 4th behind aero_spring), so fit more than the top few
    top_k: int = 6
    min_score: float = 50.0     # screening score (chi2, 1 dof) worth a joint fit
    accept_closed: float = 0.7  # share of the discrepancy a set must close to be named
    partial_closed: float = 0.3  # ... to be flagged as the nearest, partial explanation
    max_effects: int = 3        # largest set of physical effects named at once
    max_acquisition: int = 2    # largest set of acquisition faults named at once
    # acquisition faults (best screened, each a joint fit) tried as singles, and on top of a
    # grown set: they cost a physics fit each, their screening costs none
    acq_top_k: int = 2
    pair_pool: int = 4          # best singles (training fit) whose pairs are fitted jointly
    grow_k: int = 3             # re-screened effects tried on top of an accepted set
    # each effect beyond the first must close this much more of the discrepancy than the
    # set without it (the price of a parameter)
    pair_penalty: float = 0.15
    # a set grown beyond the pairs must close this share of what its parent leaves (judged
    # against the parent, each addition also beating the held-out noise band, its interval
    # excluding zero): a third effect may close little of the base discrepancy but most of
    # what two left
    grow_closed: float = 0.3
    # how each fit's solver seed comes from its stream (seeding.SEED_SCHEMES): 2, a one-way
    # hash; 1 reproduces the committed blind suites, made before the hash
    seed_scheme: int = SEED_SCHEME
    # terms no library holds (:mod:`.discovery`), searched when no library set closes the
    # discrepancy: the sparse selection keeps terms explaining this share of the residual's
    # fitted part, at most ``term_top_k`` of them are fitted alone (the linearised selection
    # misranks strongly nonlinear physics: a torque constant 25 % down at 15 A ranked the
    # right i |i| fourth), and at most ``max_terms`` named at once
    discover: bool = True
    term_threshold: float = 0.1
    term_top_k: int = 5
    max_terms: int = 2


@dataclass
class Fit:
    """A fitted (possibly augmented) monitor model and its outputs on every test."""

    augment: tuple[str, ...]
    x: np.ndarray                 # faults then augmented effect values (physical)
    fitness: float                # training fitness
    outputs: dict[str, np.ndarray]  # test -> (n, 4) the record the model predicts
    evaluations: int
    # acquisition faults the model carries (applied to ``raw``, the monitor's own outputs)
    acquisition: tuple[Acquisition, ...] = ()
    raw: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    acq_intervals: dict[str, list[float]] = field(default_factory=dict)

    @property
    def names(self) -> tuple[str, ...]:
        """Every suspect the model carries: physical effects and acquisition faults."""
        return tuple(sorted(self.augment + tuple(a.name for a in self.acquisition)))

    @property
    def key(self) -> str:
        return "+".join(self.names)

    @property
    def values(self) -> dict[str, float]:
        """Fitted value of every suspect (its unit)."""
        return {**self.effects, **{a.name: a.value for a in self.acquisition}}

    @property
    def faults(self) -> dict[str, float]:
        return dict(zip(FAULT_NAMES, map(float, self.x[:N_FAULTS])))

    @property
    def effects(self) -> dict[str, float]:
        return dict(zip(self.augment, map(float, self.x[N_FAULTS:])))

    def effects_vector(self) -> np.ndarray:
        e = np.zeros(N_EFFECTS)
        for n, v in self.effects.items():
            e[EFFECT_NAMES.index(n)] = v
        return e


@dataclass
class Assessment:
    """What the model plus noise explains, and where the data leave it."""

    flagged: list[tuple[str, float, float]]  # (feature, value, z)
    holdout_fitness: float
    holdout_floor: float          # median bootstrap held-out fitness
    holdout_z: float
    holdout_threshold: float      # fitness the model plus noise reaches at worst

    @property
    def discrepancy(self) -> Discrepancy:
        return discrepancy(self.holdout_fitness, self.holdout_floor, self.holdout_threshold,
                           self.flagged)

    @property
    def detected(self) -> bool:
        return self.discrepancy.detected


@dataclass
class Trial:
    """One candidate set of effects fitted jointly with the faults, and how it was judged."""

    effects: tuple[str, ...]        # every effect of the model fitted
    added: tuple[str, ...]          # those added to the model it is judged against
    against: str                    # that model: "base" or a set's name
    values: dict[str, float]        # fitted values of ``effects``, their units
    intervals: dict[str, list[float]]  # 95 % intervals of ``added`` (empty: not computed)
    judged_on: str                  # "held-out" | "statistics"
    closed: float                   # share of the judged discrepancy closed
    closed_total: float             # ... of the base model's discrepancy
    holdout_fitness: tuple[float, float]   # before, after
    train_fitness: tuple[float, float]
    severity: tuple[float, float]   # flagged statistics' severity before, after
    still_detected: bool            # the model with the set still leaves the envelopes
    score: float                    # screening score of the added effects (sum)
    accepted: bool
    reason: str = ""
    partial: bool = False

    @property
    def name(self) -> str:
        return "+".join(self.effects)


@dataclass
class EffectFinding:
    """A named effect: its value and interval, and what the named set closed."""

    name: str
    params: dict[str, float]
    interval: list[float]
    gap_before: float
    gap_after: float
    gap_closed: float
    partial: bool = False     # named, but the augmented model still leaves the envelopes


@dataclass
class AcquisitionFinding:
    """A named fault of the acquisition chain: its value and interval (the channel's unit,
    :data:`~ema_bench.diagnosis.acquisition.KINDS`) and a phrase saying what it is."""

    name: str
    kind: str
    channel: str
    value: float
    interval: list[float]
    description: str
    partial: bool = False


@dataclass
class TermFinding:
    """A named term no library holds (:mod:`.discovery`): its equation, basis function,
    coefficient and interval, and what the named set closed."""

    name: str
    equation: str             # a key of ema_bench.terms.EQUATIONS
    form: str                 # the basis function the coefficient multiplies
    unit: str
    coefficient: float
    interval: list[float]
    description: str
    gap_before: float
    gap_after: float
    gap_closed: float
    partial: bool = False


@dataclass
class Diagnosis:
    # "none" | "effect" (a physical effect named, acquisition faults perhaps beside it) |
    # "acquisition" (only faults of the recording named) | "term" (terms no library holds
    # named, :mod:`.discovery`) | "unexplained"
    verdict: str
    effects: list[EffectFinding]
    candidates: list[Trial]           # every candidate set fitted, accepted or not
    faults: dict[str, dict[str, float]]
    gap: dict[str, object]            # the discrepancy before and after (one computation)
    flagged: list[tuple[str, float, float]]
    screening: list[dict[str, float]]
    evaluations: int
    fits: dict[str, Fit] = field(default_factory=dict, repr=False)
    message: str = ""
    flagged_after: list[tuple[str, float, float]] = field(default_factory=list)
    acquisition: list[AcquisitionFinding] = field(default_factory=list)
    terms: list[TermFinding] = field(default_factory=list)

    @property
    def named(self) -> list[str]:
        """Everything named: physical effects, then acquisition faults."""
        return [e.name for e in self.effects] + [a.name for a in self.acquisition]

    @property
    def final(self) -> Fit:
        """The model the verdict rests on: with the named suspects and terms, else the base
        fit (heavy-tailed noise is carried by every fit, the base one included, never a
        set's member)."""
        names = [n for n in self.named if not n.startswith("heavy_tailed(")]
        names += [t.name for t in self.terms]
        return self.fits["+".join(sorted(names))] if names else self.fits["base"]

    def as_dict(self) -> dict[str, object]:
        return {
            "verdict": self.verdict, "message": self.message,
            "effects": [asdict(f) for f in self.effects],
            "acquisition": [asdict(f) for f in self.acquisition],
            "terms": [asdict(f) for f in self.terms],
            "candidates": [{**asdict(t), "name": t.name} for t in self.candidates],
            "faults": self.faults, "gap": self.gap,
            "flagged": [{"feature": n, "value": v, "z": z} for n, v, z in self.flagged[:20]],
            "flagged_after": [{"feature": n, "value": v, "z": z}
                              for n, v, z in self.flagged_after[:20]],
            "screening": self.screening, "evaluations": self.evaluations,
        }
