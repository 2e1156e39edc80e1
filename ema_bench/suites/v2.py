"""Suite ``emafdi-v2``: tiers of dimension, conditions, budgets that scale with dimension.

v1 (:mod:`~ema_bench.suites.v1`) is the paper's four-fault problem, now solved by every competent
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
tier ``d`` uses ``t<d>-s00`` ..  (:func:`instance_names`).  A run's case is
``<instance>@<condition>`` (``t7-s03@no-prior``; ``small@prior`` is tier 4).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from importlib.resources.abc import Traversable

import numpy as np

from ..effects import EFFECT_INDEX, EFFECTS
from ..faults import FAULT_NAMES, LOWER, UPPER
from ..seeding import child
from ..trace_cache import MODEL_VERSION
from . import v1
from .base import CaseBudgets, Instance, Selection, Suite
from .targets import (
    TARGET_ROOT_SEED,
    SuiteError,
    package_file,
    read_targets,
    target_key,
    user_entry,
)

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
    """One dimension of the suite: the faults plus ``effects`` (fitted, scored); its
    dimension follows from the fault and effect lists (a fifth fault moves every tier)."""

    effects: tuple[str, ...]
    description: str

    def __post_init__(self) -> None:
        unknown = [n for n in self.effects if n not in EFFECT_INDEX]
        if unknown:
            raise SuiteError(f"tier of unknown effect(s) {unknown}")

    @property
    def dim(self) -> int:
        return len(FAULT_NAMES) + len(self.effects)

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
    Tier((), "the paper's faults: v1's instances, unchanged"),
    Tier(SENSOR_EFFECTS, "faults + position-sensor offset, current-channel gain, feedback "
                         "delay"),
    Tier(SENSOR_EFFECTS + ("eccentricity", "viscous_friction", "aero_spring", "cogging",
                           "gear_stiffness"),
         "faults + every library effect the twin-track identifiability report keeps"),
)}
#: The faults-only tier (4): v1's instances and problems.
BASE_TIER = len(FAULT_NAMES)
CONDITIONS: dict[str, Condition] = {c.name: c for c in (
    Condition("prior", True, None, "nominal vector given, solvers start there (as v1)"),
    Condition("no-prior", False, None, "bounds only: solvers draw their own start"),
    # from the step alone the delay's interval exceeds 5 % of its range on 2 of tier 7's 20
    # instances, eccentricity's on tier 12 (docs/suite-v2.md): tier 4 only
    Condition("step-only", True, ("step",), "nominal given, the step test alone (less "
                                            "information)", tiers=(BASE_TIER,)),
    # the motor-side outputs theta_m, omega_m get weight 0 (and are zeroed in the data);
    # the tiers: benchmarks/v2_identifiability.py (docs/suite-v2.md)
    Condition("surface-current", True, None, "nominal given, the standard tests, surface "
              "position and equivalent current only (less information)", tiers=tuple(TIERS),
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
class TierInstance:
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
def tier_instances(dim: int) -> dict[str, TierInstance]:
    """The instances of a tier, name -> :class:`TierInstance`.

    Tier 4: v1's paper cases and seeded instances (sanity case ``nominal`` included), no
    effects.  Higher tiers: :data:`v1.N_SEEDED` instances ``t<d>-s00`` .., faults on a Latin
    hypercube over the fault box and effects from :func:`_effect_values`, all drawn from
    child ``dim`` of :data:`SUITE_SEED`."""
    t = tier(dim)
    if not t.effects:
        return {n: TierInstance(n, t.dim, v1.instance_faults(n), {}) for n in v1.instance_names()}
    from scipy.stats import qmc  # here: scipy.stats costs 0.5 s of every start-up

    ss = child(SUITE_SEED, t.dim)
    lhs = qmc.LatinHypercube(d=len(FAULT_NAMES), rng=np.random.default_rng(child(ss, 0)))
    X = qmc.scale(lhs.random(v1.N_SEEDED), LOWER, UPPER)
    rng = np.random.default_rng(child(ss, 1))
    return {f"t{t.dim}-s{i:02d}": TierInstance(f"t{t.dim}-s{i:02d}", t.dim, x,
                                           _effect_values(rng, t.effects))
            for i, x in enumerate(X)}


def instance_names(dim: int | str) -> tuple[str, ...]:
    """The ranked instances of a tier (tier 4: v1's, without the sanity case)."""
    return tuple(n for n in tier_instances(tier(dim).dim) if n not in v1.SANITY_CASES)


def instance(name: str, dim: int | str | None = None) -> TierInstance:
    """An instance by name (``t7-s03``; a v1 name is tier 4)."""
    if dim is None:
        head = name.partition("-")[0]
        dim = head[1:] if name.startswith("t") and "-" in name else BASE_TIER
    found = tier_instances(tier(dim).dim).get(name)
    if found is None:
        raise SuiteError(f"unknown tier-{dim} instance {name!r}; known: "
                         f"{list(tier_instances(tier(dim).dim))}")
    return found


def judged_parameters(truth: np.ndarray, x_star: np.ndarray,
                      ranges: np.ndarray) -> np.ndarray:
    """Which parameters carry parameter targets: those whose clean-data bias (``x_star``, the
    monitor's best fit to noise-free reference traces, against the truth: the model-form
    bias, :func:`ema_bench.monitor_bias.clean_bias` for the faults) is within
    :data:`MAX_TARGET_BIAS` of their range.  (A fit to noisy data adds the noise's scatter:
    on v1's shipped reference ``x*`` Na moves up to 0.8 % of range with the seed, while its
    clean-data bias is at most 0.27 %.)"""
    return np.abs(np.asarray(x_star) - np.asarray(truth)) / ranges <= MAX_TARGET_BIAS


# --- run keys: a v2 run's case is "<instance>@<condition>" ---------------------------------
#: Between an instance and its condition in a case key (the registry splits keys there).
CASE_SEP = "@"


def case_key(name: str, cond: str) -> str:
    """The case of a v2 run record (``t7-s03@no-prior``; ``small@prior`` is tier 4)."""
    return f"{name}{CASE_SEP}{cond}"


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


def tier_cases(dim: int | str, cond: str, name: object = None) -> list[str]:
    """The case keys of tier ``dim`` under ``cond`` (only instance ``name``'s where it is
    given); SuiteError for an unknown tier, condition or instance, or a condition the tier
    does not offer."""
    t, c = tier(dim), condition(cond)
    if not c.offered_on(t.dim):
        raise SuiteError(f"condition {cond!r} is offered on tiers {list(c.tiers)} only")
    names = instance_names(t.dim)
    if name is not None and name not in names:
        raise SuiteError(f"unknown tier-{t.dim} instance {name!r}; known: {list(names)}")
    return [case_key(n, c.name) for n in (names if name is None else (name,))]


#: The best-known table of the v2 cases v1's does not cover (``ema-bench targets --suite
#: emafdi-v2``); absent until it is computed in full (then those cases have no fitness
#: targets, and parameter targets judge every parameter).
TARGETS_FILE = "suite_targets_v2.json"
#: Noise seeds (root seed 0) per (instance, data, track) the table covers: the board runs at
#: most 5 seeds per case.
TARGET_SEEDS = 5
#: IOH: one function per condition, one dimension per tier; the IOH instance of a run is
#: this x the instance's position in its tier + the seed.
IOH_SEEDS = 1000
#: The reference-track entry whose clean-data fit picks the judged parameters (seed 0).
CLEAN_SEED = 0


def targets_path() -> Traversable:
    """Where the shipped v2 table is (the package's ``suite_targets_v2.json``)."""
    return package_file(TARGETS_FILE)


@functools.cache
def shipped_targets() -> dict:
    """The v2 best-known table shipped with the package (:func:`~ema_bench.suites.targets.
    read_targets`: empty entries when it is absent, SuiteError when it is mislabelled)."""
    return read_targets(targets_path(), SUITE_ID)


def target_condition(c: Condition) -> Condition:
    """The condition whose best-known entries ``c`` uses: the first with the prior and the
    same objective (tests and outputs; ``no-prior`` -> ``prior``)."""
    return next(o for o in CONDITIONS.values() if o.prior and o.objective_id == c.objective_id)


def judged_by_entry(inst: Instance, entry: Mapping[str, object]) -> np.ndarray | None:
    """:func:`judged_parameters` of a v2 case on the clean-data fit ``clean_x`` of a table
    entry (None without one)."""
    clean = entry.get("clean_x")
    if not isinstance(clean, Mapping):
        return None
    return judged_parameters(inst.truth, np.array([float(clean[n]) for n in inst.names]),
                             inst.ranges)


def target_keys(seeds: int = TARGET_SEEDS, tracks: Sequence[str] = ("reference", "twin"),
                tiers: Sequence[int] | None = None, conditions: Sequence[str] | None = None,
                per_tier: int | None = None) -> list[str]:
    """The ``case|track|seed`` keys whose best-known optimum v2 must ship (for
    :func:`ema_bench.suites.best_known.compute_targets`'s ``keys``): one per instance and
    objective (``prior`` stands for ``no-prior``, whose data and fitness are the same; each
    condition with less information for itself), none for tier 4 with full information
    (v1's entries hold) nor for the sanity case.  ``tiers``, ``conditions`` (any: each maps
    to its :func:`target_condition`) and ``per_tier`` (the first N instances) select a
    subset, for a partial regeneration."""
    dims = [tier(d).dim for d in (TIERS if tiers is None else tiers)]
    wanted = {target_condition(condition(n)).name for n in (conditions or CONDITIONS)}
    data_conds = [c for c in CONDITIONS.values() if c.prior and c.name in wanted]
    # seed by seed: a partial run covers every instance at seed 0 (whose reference entry
    # holds the clean-data fit) first
    return [target_key(case_key(n, c.name), tr, k)
            for k in range(seeds) for d in dims for c in data_conds
            if c.offered_on(d) and not (d == BASE_TIER and c.full_information)
            for n in instance_names(d)[:per_tier] for tr in tracks]


def target_case(inst: Instance) -> str:
    """The case key of a v2 case's best-known entries (``t7-s03@no-prior`` ->
    ``t7-s03@prior``)."""
    return case_key(inst.name, target_condition(condition(inst.group[1])).name)


def _v1_entries(inst: Instance) -> bool:
    """A tier-4 case with full information (``prior``, ``no-prior``) is v1's problem, data
    and all: v1's shipped entries hold (test_suite_v2 checks the fitness to the bit)."""
    return not inst.augment and condition(inst.group[1]).full_information


def _best_known(inst: Instance, track: str, seed: int, root_seed: int,
                model_version: str | None = None) -> dict | None:
    """v1's entry (:func:`_v1_entries`), else the entry of :func:`target_case` in
    ``suite_targets_v2.json`` (None while it is absent or lacks the key), at a root seed
    other than 0 a user table's (:func:`~ema_bench.suites.targets.user_entry`).  A record
    of an earlier compatible model version is judged on the entry it was made against where
    the table keeps one (``superseded``: tier 12's entries of model version 2, whose
    trigonometry version 3 replaced)."""
    if _v1_entries(inst):
        return v1.best_known(inst.name, track, seed, root_seed)
    key = target_key(target_case(inst), track, seed)
    if root_seed != TARGET_ROOT_SEED:   # a user table of that root seed, if one is named
        return user_entry(SUITE_ID, key, root_seed)
    table = shipped_targets()
    old = table.get("superseded", {}).get(str(model_version), {})
    return old[key] if model_version != MODEL_VERSION and key in old else \
        table["entries"].get(key)


def _judged(inst: Instance, track: str) -> np.ndarray | None:
    """Which parameters carry parameter targets on ``track``, or None (all of them).

    On the reference track: those :func:`judged_parameters` keeps on the instance's
    clean-data fit (``clean_x`` of its seed-0 reference entry in its suite's best-known
    table: v2's, or v3's own fits on model version 4; noise-free reference traces, same
    objective).  The twin track (no model-form bias), v1's problems (:func:`_v1_entries`:
    v1's clean-data fits exclude nothing, docs/suite-v2.md) and cases without a computed
    entry judge all."""
    if track != "reference" or _v1_entries(inst):
        return None
    entry = inst.best_known(track, CLEAN_SEED)
    return None if entry is None else judged_by_entry(inst, entry)


def _lookup(name: str, cond: str | None) -> Instance | None:
    """A v2 case is ``<instance>@<condition>``; SuiteError for an unknown condition or one
    the instance's tier does not offer."""
    if cond is None:
        return None
    try:
        found = instance(name)
    except SuiteError:
        return None
    t, c = tier(found.tier), condition(cond)
    if not c.offered_on(t.dim):
        raise SuiteError(f"condition {cond!r} is offered on tiers {list(c.tiers)} only: on "
                         f"tier {t.dim} it leaves parameters non-identifiable")
    lo = np.r_[LOWER, [EFFECTS[EFFECT_INDEX[n]].lower for n in t.effects]]
    hi = np.r_[UPPER, [EFFECTS[EFFECT_INDEX[n]].upper for n in t.effects]]
    case = case_key(name, c.name)
    return Instance(case=case, name=name, suite=SUITE, names=t.names, truth=found.truth,
                    lower=lo, upper=hi,
                    effects={k: v for k, v in found.effects.items() if v != 0.0},
                    tests=c.tests, signals=c.signals, prior=c.prior, budget=t.budget,
                    ranked=name not in v1.SANITY_CASES, group=(t.dim, c.name),
                    paper_case=name if t.dim == BASE_TIER and c.name == "prior" else case,
                    ioh_function=c.name)


def _ioh_instance(inst: Instance, seed: int) -> int:
    if seed >= IOH_SEEDS:
        raise ValueError(f"seed {seed} is beyond the {IOH_SEEDS} seeds per instance an "
                         f"{SUITE_ID} export numbers")
    return IOH_SEEDS * instance_names(inst.group[0]).index(inst.name) + seed


def _complete_cases(entered, per_tier: int | None) -> list[str]:
    """Every instance of each (tier, condition) entered (the first ``per_tier`` of each
    tier, in the suite's order: a board declared with ``--per-tier N``)."""
    return [case_key(n, cond) for d, cond in sorted({i.group for i in entered})
            for n in instance_names(d)[:per_tier]]


def selected_tiers(sel: Selection, suite: str = SUITE_ID) -> list[int] | None:
    """The tiers a selection of a suite with tiers names (None: all); SuiteError where it
    names cases instead."""
    if sel.cases:
        raise SuiteError(f"--suite {suite} picks its instances with --tiers, --conditions "
                         "and --per-tier, not --cases")
    # a tier that is not a number: a ValueError, one line on the command line
    return [int(t) for t in sel.tiers] if sel.tiers else None


def sweep_cases(sel: Selection, suite: str = SUITE_ID) -> list[str]:
    """Tiers x conditions (default all), the first ``per_tier`` instances of each (v2's
    names; ``suite`` names the suite in the error for a selection by --cases)."""
    return cases(selected_tiers(sel, suite) or list(TIERS), sel.conditions or list(CONDITIONS),
                 sel.per_tier)


def _sweep_budget(keys: Sequence[str], budget: int | None, per_dim: int | None,
                  quick: bool) -> int | CaseBudgets:
    """One fixed budget, else evaluations per searched dimension (the suite's: tier budgets)."""
    if budget is not None:
        return budget
    per = per_dim or BUDGET_PER_DIM
    return CaseBudgets({k: per * _lookup(*k.split(CASE_SEP, 1)).dim for k in keys},
                       f"{per} x tier")


def _target_keys(sel: Selection, seeds: int | None,
                 tracks: Sequence[str] | None) -> list[str]:
    """:func:`target_keys` of the tiers, conditions and instances selected."""
    from ..instances import TRACKS

    keys = target_keys(seeds or TARGET_SEEDS, tracks or TRACKS, selected_tiers(sel),
                       sel.conditions, sel.per_tier)
    if not keys:
        raise SuiteError("no v2 case there needs its own entries (tier 4 with full "
                         "information uses v1's table)")
    return keys


def _env_cases(dim: int | str | None, cond: str | None, name: object = None) -> list[str]:
    """An environment's episode cases: :func:`tier_cases`, by default of the faults-only tier
    under ``prior``."""
    return tier_cases(BASE_TIER if dim is None else dim, cond or "prior", name)


SUITE = Suite(id=SUITE_ID, lookup=_lookup, best_known=_best_known, judged=_judged,
              ioh_instance=_ioh_instance, ioh_functions=lambda: list(CONDITIONS),
              complete_cases=_complete_cases,
              case_order=lambda: cases(list(TIERS), list(CONDITIONS)),
              sweep_cases=sweep_cases, sweep_budget=_sweep_budget, target_keys=_target_keys,
              targets_file=lambda: targets_path(), grouped=True, clean_fits=True,
              tier_cases=_env_cases)
