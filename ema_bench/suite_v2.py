"""Suite ``emafdi-v2``: tiers of dimension, conditions, budgets that scale with dimension.

v1 (:mod:`~ema_bench.suite`) is the paper's four-fault problem, now solved by every competent
method from the nominal start it hands out.  v2 keeps it as tier 4 and adds:

- **tiers** (:data:`TIERS`): tier 4 = v1's instances, unchanged (same names, truths, data,
  so v1's ``f*`` carry over bit for bit); tier 7 = the faults plus the three sensor and
  controller effects; tier 12 = the faults plus every library effect the identifiability
  report keeps (docs/suite-v2.md).  In a higher tier the truth draws a random subset of the
  tier's effects non-zero (:func:`tier_instances`) and the parameter targets judge every
  searched parameter, the effects included;
- **conditions** (:data:`CONDITIONS`): ``prior`` (the solver gets the nominal vector and
  starts there, as in v1), ``no-prior`` (bounds only: solvers draw their own start),
  ``step-only`` (less information: the step test alone, with the prior; tier 4 only,
  where it keeps every parameter identifiable) and ``surface-current`` (less information:
  the fitness weighs the surface position and the equivalent current only, with the
  prior; every tier);
- **budgets** ``BUDGET_PER_DIM x dim`` (5,000 at tier 4, v1's board budget).

The instances' names: tier 4 uses v1's (``small``, ``full``, ``random``, ``s00`` ..);
tier ``d`` uses ``t<d>-s00`` .. (:func:`instance_names`).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from importlib.resources.abc import Traversable

import numpy as np

from .effects import EFFECT_INDEX, EFFECTS, effects_to_dict
from .faults import FAULT_NAMES, LOWER, UPPER, faults_to_dict
from .seeding import SeedLike, child
from .suite import N_SEEDED, SANITY_CASES, SuiteError, instance_faults
from .suite import instance_names as v1_instance_names
from .traces import SIGNALS

SUITE_ID = "emafdi-v2"
#: Root of the draw of the higher tiers' instances (never changes within the suite version).
SUITE_SEED = 20261126
#: Evaluation budget per searched dimension (tier 4: 5,000, v1's board budget).
BUDGET_PER_DIM = 1250
#: Chance that each effect of a tier is non-zero in an instance's truth.
P_EFFECT_ON = 0.5
#: Parameter targets hold only on parameters whose clean-data bias on the reference track
#: (``x*`` of the best-known fit against the truth) is within this fraction of range.
MAX_TARGET_BIAS = 0.003


@dataclass(frozen=True)
class Tier:
    """One dimension of the suite: the four faults plus ``effects`` (fitted, scored)."""

    dim: int
    effects: tuple[str, ...]
    description: str

    def __post_init__(self) -> None:
        if self.dim != len(FAULT_NAMES) + len(self.effects):
            raise SuiteError(f"tier {self.dim} lists {len(self.effects)} effects")

    @property
    def names(self) -> tuple[str, ...]:
        return FAULT_NAMES + self.effects

    @property
    def budget(self) -> int:
        return BUDGET_PER_DIM * self.dim


@dataclass(frozen=True)
class Condition:
    """What the solver is given: the prior (nominal vector and start), the tests and the
    outputs the fitness weighs."""

    name: str
    prior: bool
    tests: tuple[str, ...] | None   # None: the standard step and sine
    description: str
    tiers: tuple[int, ...] = ()     # with less information: the tiers it keeps identifiable
    signals: tuple[str, ...] | None = None   # None: all four outputs (traces.SIGNALS)

    @property
    def full_information(self) -> bool:
        """The standard tests and every output (offered on every tier)."""
        return self.tests is None and self.signals is None

    def offered_on(self, dim: int) -> bool:
        """Whether the suite offers this condition on tier ``dim``: a condition with less
        information only where the identifiability report keeps every parameter."""
        return self.full_information or dim in self.tiers

    @property
    def objective_id(self) -> tuple[tuple[str, ...] | None, tuple[str, ...] | None]:
        """What makes the fitness (tests and outputs): conditions that share it share the
        data and the best-known optima (``prior`` and ``no-prior``)."""
        return self.tests, self.signals


# The effects of each tier (docs/suite-v2.md has the identifiability report that chose them).
#: The sensor and controller effects: cheap to fit (they run in the lanes), identifiable.
SENSOR_EFFECTS = ("sensor_offset", "current_gain", "delay")
TIERS: dict[int, Tier] = {t.dim: t for t in (
    Tier(4, (), "the paper's four faults: v1's instances, unchanged"),
    Tier(7, SENSOR_EFFECTS, "faults + position-sensor offset, current-channel gain, "
                            "feedback delay"),
    Tier(12, SENSOR_EFFECTS + ("eccentricity", "viscous_friction", "aero_spring", "cogging",
                               "gear_stiffness"),
         "faults + every library effect the twin-track identifiability report keeps"),
)}
CONDITIONS: dict[str, Condition] = {c.name: c for c in (
    Condition("prior", True, None, "nominal vector given, solvers start there (as v1)"),
    Condition("no-prior", False, None, "bounds only: solvers draw their own start"),
    # from the step alone the delay's interval exceeds 5 % of its range on 2 of tier 7's 20
    # instances, eccentricity's on tier 12 (docs/suite-v2.md): tier 4 only
    Condition("step-only", True, ("step",), "nominal given, the step test alone (less "
                                            "information)", tiers=(4,)),
    # the motor-side outputs theta_m, omega_m get weight 0 (and are zeroed in the data);
    # the tiers: benchmarks/v2_identifiability.py (docs/suite-v2.md)
    Condition("surface-current", True, None, "nominal given, the standard tests, surface "
              "position and equivalent current only (less information)", tiers=(4, 7, 12),
              signals=("theta_u", "i_eq")),
)}


def tier(dim: int | str) -> Tier:
    """The tier of dimension ``dim``; :class:`SuiteError` naming the known ones."""
    try:
        return TIERS[int(dim)]
    except (KeyError, ValueError, TypeError):
        raise SuiteError(f"unknown tier {dim!r}; known: {list(TIERS)}") from None


def condition(name: str) -> Condition:
    if name not in CONDITIONS:
        raise SuiteError(f"unknown condition {name!r}; known: {list(CONDITIONS)}")
    return CONDITIONS[name]


def budget(dim: int | str) -> int:
    """The evaluation budget of a tier: :data:`BUDGET_PER_DIM` x dim."""
    return tier(dim).budget


@dataclass(frozen=True)
class Instance:
    """A v2 instance: its name, tier, true faults and true effects (``name -> value``)."""

    name: str
    tier: int
    faults: np.ndarray
    effects: Mapping[str, float]

    @property
    def truth(self) -> np.ndarray:
        """Every searched parameter's true value, tier order (faults, then effects)."""
        return np.r_[self.faults, [self.effects.get(n, 0.0) for n in tier(self.tier).effects]]


def _effect_values(rng: np.random.Generator, names: Sequence[str]) -> dict[str, float]:
    """A random subset of ``names`` on (at least one), each at a magnitude between what the
    missing-physics workflow detects and its bound, either sign where the bounds allow."""
    on = rng.random(len(names)) < P_EFFECT_ON
    if not on.any():
        on[rng.integers(len(names))] = True
    out = {}
    for n, flag in zip(names, on):
        spec = EFFECTS[EFFECT_INDEX[n]]
        u, s = rng.random(), rng.random()
        if not flag:
            out[n] = 0.0
            continue
        side = spec.upper if (spec.lower >= 0.0 or s < 0.5) else spec.lower
        lo = min(spec.detect, abs(side))
        out[n] = float(np.sign(side) * (lo + u * (abs(side) - lo)))
    return out


@functools.cache
def tier_instances(dim: int) -> dict[str, Instance]:
    """The instances of a tier, name -> :class:`Instance`.

    Tier 4: v1's paper cases and seeded instances (sanity case ``nominal`` included), no
    effects.  Higher tiers: :data:`N_SEEDED` instances ``t<d>-s00`` .., faults on a Latin
    hypercube over the fault box and effects from :func:`_effect_values`, all drawn from
    child ``dim`` of :data:`SUITE_SEED`."""
    t = tier(dim)
    if not t.effects:
        return {n: Instance(n, t.dim, instance_faults(n), {}) for n in v1_instance_names()}
    from scipy.stats import qmc  # here: scipy.stats costs 0.5 s of every start-up

    ss = child(SUITE_SEED, t.dim)
    lhs = qmc.LatinHypercube(d=len(FAULT_NAMES), rng=np.random.default_rng(child(ss, 0)))
    X = qmc.scale(lhs.random(N_SEEDED), LOWER, UPPER)
    rng = np.random.default_rng(child(ss, 1))
    return {f"t{t.dim}-s{i:02d}": Instance(f"t{t.dim}-s{i:02d}", t.dim, x,
                                           _effect_values(rng, t.effects))
            for i, x in enumerate(X)}


def instance_names(dim: int | str) -> tuple[str, ...]:
    """The ranked instances of a tier (tier 4: v1's, without the sanity case)."""
    return tuple(n for n in tier_instances(tier(dim).dim) if n not in SANITY_CASES)


def instance(name: str, dim: int | str | None = None) -> Instance:
    """An instance by name (``t7-s03``; a v1 name is tier 4)."""
    if dim is None:
        head = name.partition("-")[0]
        dim = head[1:] if name.startswith("t") and "-" in name else 4
    found = tier_instances(tier(dim).dim).get(name)
    if found is None:
        raise SuiteError(f"unknown tier-{dim} instance {name!r}; known: "
                         f"{list(tier_instances(tier(dim).dim))}")
    return found


def make_v2_problem(name: str, *, cond: str = "prior", track: str = "reference",
                    seed: SeedLike = 0, budget: int | None = None,
                    start: np.ndarray | None = None):
    """The :class:`~ema_bench.problem.Problem` of a v2 instance under a condition.

    The data: the instance's faults with its effects switched on in the model that makes
    them (reference or twin), the condition's tests; the search space: the faults plus the
    tier's effects (an augmented monitor); the hidden truth: every searched parameter.  The
    budget defaults to the tier's (:func:`budget`).  ``start`` (a warm start, for the
    best-known polish) needs a condition with prior."""
    from .instances import make_problem

    inst = instance(name)
    c = condition(cond)
    t = tier(inst.tier)
    if not c.offered_on(t.dim):
        raise SuiteError(f"condition {cond!r} is offered on tiers {list(c.tiers)} only: on "
                         f"tier {t.dim} it leaves parameters non-identifiable")
    if start is not None and not c.prior:
        raise SuiteError(f"condition {cond!r} gives no prior: no start")
    problem = make_problem(inst.faults, track=track, seed=seed,
                           budget=t.budget if budget is None else budget,
                           effects={k: v for k, v in inst.effects.items() if v != 0.0},
                           augment=t.effects, tests=c.tests, start=start, prior=c.prior,
                           score_effects=bool(t.effects), signals=c.signals)
    problem.label = name
    problem.meta["case"] = name
    return problem


def judged_parameters(truth: np.ndarray, x_star: np.ndarray,
                      ranges: np.ndarray) -> np.ndarray:
    """Which parameters carry parameter targets: those whose clean-data bias (``x_star``, the
    monitor's best fit to noise-free reference traces, against the truth: the model-form
    bias, :func:`ema_bench.calibrate.clean_bias` for the faults) is within
    :data:`MAX_TARGET_BIAS` of their range.  (A fit to noisy data adds the noise's scatter:
    on v1's shipped reference ``x*`` Na moves up to 0.8 % of range with the seed, while its
    clean-data bias is at most 0.27 %.)"""
    return np.abs(np.asarray(x_star) - np.asarray(truth)) / ranges <= MAX_TARGET_BIAS


def describe() -> dict[str, object]:
    """The suite as JSON: tiers with their instances' truths, conditions, budgets."""
    return {"suite": SUITE_ID, "suite_seed": SUITE_SEED, "budget_per_dim": BUDGET_PER_DIM,
            "conditions": {c.name: {"prior": c.prior, "tests": c.tests or ["step", "sine"],
                                    "signals": list(c.signals or SIGNALS),
                                    "tiers": [d for d in TIERS if c.offered_on(d)],
                                    "description": c.description}
                           for c in CONDITIONS.values()},
            "tiers": {str(t.dim): {"effects": list(t.effects), "budget": t.budget,
                                   "description": t.description,
                                   "instances": {n: {**faults_to_dict(i.faults),
                                                     **effects_to_dict(np.array(
                                                         [i.effects.get(e.name, 0.0)
                                                          for e in EFFECTS]))}
                                                 for n, i in tier_instances(t.dim).items()}}
                      for t in TIERS.values()}}


# --- run keys: a v2 run's case is "<instance>@<condition>" ---------------------------------
CASE_SEP = "@"


def case_key(name: str, cond: str) -> str:
    """The case of a v2 run record (``t7-s03@no-prior``; ``small@prior`` is tier 4)."""
    return f"{name}{CASE_SEP}{cond}"


def parse_case(case: str) -> tuple[Instance, Condition]:
    """The instance and condition of a v2 case key; :class:`SuiteError` if it is not one."""
    name, sep, cond = str(case).partition(CASE_SEP)
    if not sep:
        raise SuiteError(f"{case!r} is not a {SUITE_ID} case (instance{CASE_SEP}condition)")
    return instance(name), condition(cond)


def is_v2_case(case: object) -> bool:
    try:
        parse_case(case)   # type: ignore[arg-type]
    except SuiteError:
        return False
    return True


def suite_of(case: object) -> str:
    """The suite a run's case belongs to: v2 for a v2 case key, else v1."""
    from .suite import SUITE_ID as V1

    return SUITE_ID if is_v2_case(case) else V1


def cases(tiers: Sequence[int], conditions: Sequence[str],
          per_tier: int | None = None) -> list[str]:
    """The v2 case keys of ``tiers`` x ``conditions`` (the first ``per_tier`` instances of
    each tier; default all), skipping a condition a tier does not offer."""
    out = []
    for d in tiers:
        t = tier(d)
        for cond in conditions:
            c = condition(cond)
            if not c.offered_on(t.dim):
                continue
            out += [case_key(n, c.name) for n in instance_names(t.dim)[:per_tier]]
    return out


def build_problem(case: str, *, track: str, seed: SeedLike, budget: int):
    """The problem of a run's case: a v2 case key, or anything
    :func:`~ema_bench.instances.make_problem` takes (v1)."""
    if is_v2_case(case):
        inst, c = parse_case(case)
        problem = make_v2_problem(inst.name, cond=c.name, track=track, seed=seed,
                                  budget=budget)
        problem.label = problem.meta["case"] = case
        return problem
    from .instances import make_problem

    return make_problem(case, track=track, seed=seed, budget=budget)


def scoring_frame(case: str) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """Names, truth and ranges (physical) of every parameter a v2 case's parameter targets
    judge: every searched parameter of its tier."""
    inst, _ = parse_case(case)
    t = tier(inst.tier)
    lo = np.r_[LOWER, [EFFECTS[EFFECT_INDEX[n]].lower for n in t.effects]]
    hi = np.r_[UPPER, [EFFECTS[EFFECT_INDEX[n]].upper for n in t.effects]]
    return t.names, inst.truth, hi - lo


#: The best-known table of the v2 cases v1's does not cover (``ema-bench targets --suite
#: emafdi-v2``); absent until it is computed in full (then those cases have no fitness
#: targets, and parameter targets judge every parameter).
TARGETS_FILE = "suite_targets_v2.json"
#: Noise seeds (root seed 0) per (instance, data, track) the table covers: the board runs at
#: most 5 seeds per case.
TARGET_SEEDS = 5
#: The reference-track entry whose clean-data fit picks the judged parameters (seed 0).
CLEAN_SEED = 0


def targets_path() -> Traversable:
    """Where the shipped v2 table is (the package's ``suite_targets_v2.json``)."""
    from importlib import resources

    return resources.files("ema_bench").joinpath(TARGETS_FILE)


@functools.cache
def shipped_targets() -> dict:
    """The v2 best-known table shipped with the package (:func:`ema_bench.suite.
    read_targets`: empty entries when it is absent, SuiteError when it is mislabelled)."""
    from .suite import read_targets

    return read_targets(targets_path(), SUITE_ID)


def target_condition(c: Condition) -> Condition:
    """The condition whose best-known entries ``c`` uses: the first with the prior and the
    same objective (tests and outputs; ``no-prior`` -> ``prior``)."""
    return next(o for o in CONDITIONS.values() if o.prior and o.objective_id == c.objective_id)


def target_case(case: str) -> str:
    """The case key of a v2 case's best-known entries (``t7-s03@no-prior`` ->
    ``t7-s03@prior``)."""
    inst, c = parse_case(case)
    return case_key(inst.name, target_condition(c).name)


def best_known_for(case: str, track: str, seed: int, root_seed: int = 0) -> dict | None:
    """The best-known entry (``f_star``, ``f_nominal``, ``x_star``) of a run's case, or None.

    A tier-4 case with full information (``prior``, ``no-prior``) is v1's problem, data
    and all: v1's shipped entry holds (test_suite_v2 checks the fitness to the bit).  Other
    v2 cases: the entry of :func:`target_case` in ``suite_targets_v2.json``
    (:func:`shipped_targets`; None while it is absent or lacks the key), or at a root seed
    other than 0 a user table's (:func:`ema_bench.suite.user_entry`); v1 cases:
    :func:`ema_bench.suite.best_known`."""
    from .suite import TARGET_ROOT_SEED, best_known, target_key, user_entry

    if not is_v2_case(case):
        return best_known(case, track, seed, root_seed)
    inst, c = parse_case(case)
    if inst.tier == 4 and c.full_information:
        return best_known(inst.name, track, seed, root_seed)
    key = target_key(target_case(case), track, seed)
    if root_seed != TARGET_ROOT_SEED:
        return user_entry(SUITE_ID, key, root_seed)
    return shipped_targets()["entries"].get(key)


def judged_for(case: str, track: str) -> np.ndarray | None:
    """Which of a v2 case's parameters (:func:`scoring_frame` order) carry parameter targets
    on ``track``, or None (all of them).

    On the reference track: those :func:`judged_parameters` keeps on the instance's
    clean-data fit (``clean_x`` of its seed-0 reference entry in the v2 table, noise-free
    reference traces, same objective).  The twin track (no model-form bias), tier 4 with
    full information (v1's clean-data fits exclude nothing: docs/suite-v2.md) and cases
    without a computed entry judge all."""
    from .suite import target_key

    inst, c = parse_case(case)
    if track != "reference" or (inst.tier == 4 and c.full_information):
        return None
    entry = shipped_targets()["entries"].get(target_key(target_case(case), track,
                                                        CLEAN_SEED))
    return None if entry is None else judged_by_entry(case, entry)


def judged_by_entry(case: str, entry: Mapping[str, object]) -> np.ndarray | None:
    """:func:`judged_parameters` of a v2 case on the clean-data fit ``clean_x`` of a table
    entry (None without one)."""
    clean = entry.get("clean_x")
    if not isinstance(clean, Mapping):
        return None
    names, truth, ranges = scoring_frame(case)
    return judged_parameters(truth, np.array([float(clean[n]) for n in names]), ranges)


def target_keys(seeds: int = TARGET_SEEDS, tracks: Sequence[str] = ("reference", "twin"),
                tiers: Sequence[int] | None = None, conditions: Sequence[str] | None = None,
                per_tier: int | None = None) -> list[str]:
    """The ``case|track|seed`` keys whose best-known optimum v2 must ship (for
    :func:`ema_bench.best_known.compute_targets`'s ``keys``): one per instance and
    objective (``prior`` stands for ``no-prior``, whose data and fitness are the same; each
    condition with less information for itself), none for tier 4 with full information
    (v1's entries hold) nor for the sanity case.  ``tiers``, ``conditions`` (any: each maps
    to its :func:`target_condition`) and ``per_tier`` (the first N instances) select a
    subset, for a partial regeneration."""
    from .suite import target_key

    dims = [tier(d).dim for d in (TIERS if tiers is None else tiers)]
    wanted = {target_condition(condition(n)).name for n in (conditions or CONDITIONS)}
    data_conds = [c for c in CONDITIONS.values() if c.prior and c.name in wanted]
    # seed by seed: a partial run covers every instance at seed 0 (whose reference entry
    # holds the clean-data fit) first
    return [target_key(case_key(n, c.name), tr, k)
            for k in range(seeds) for d in dims for c in data_conds
            if c.offered_on(d) and not (d == 4 and c.full_information)
            for n in instance_names(d)[:per_tier] for tr in tracks]
