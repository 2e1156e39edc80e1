"""Checks of third-party run records before they join a leaderboard (``ema-bench validate``).

``validate`` re-derives, it never trusts.  A record is accepted when it is of this suite and
model version, carries a complete manifest, stayed within its budget, its evidence is well
formed (evaluation indices increasing from 1 within the evaluations and the budget, fitness
decreasing), every vector its figures rest on re-evaluates to the fitness it states, and
every derived figure it claims (success, ``evals_to_success``, accuracy, range errors,
fitness and parameter targets and their first hits, ``best_at``, ``f*``, the truth) agrees
with the re-derivation (:mod:`.derive`) from those vectors and the instance's truth.  Any
disagreement refuses the record with one line naming the field and both values.  Legacy
records (schema 1) carry no trajectory vectors: their claims are checked against the bounds
their trace and final vector allow, and what those cannot prove
(:data:`LEGACY_UNVERIFIABLE`) is verified by replay (:mod:`.replay`).  A submission is complete when
every solver covers every (non-sanity) instance of the suite on each track it enters, for the
same seeds.  docs/submitting-results.md describes the whole path.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from ..faults import FAULT_NAMES, N_FAULTS, NOMINAL, faults_to_dict
from ..instances import TRACKS
from ..manifest import REQUIRED_MANIFEST_KEYS
from ..problem import MAX_BUDGET
from ..records import RECORD_SCHEMA, schema, seed_scheme
from ..scoring import SUCCESS_RANGE_ERROR, range_error
from ..seeding import SEED_SCHEMES, run_seed
from ..suites import DEFAULT, SUITES, find, is_case, suite_of
from ..suites.problem import make_problem
from ..suites.targets import (
    BUDGET_CHECKPOINTS,
    FITNESS_PRECISIONS,
    PARAMETER_TARGETS,
    fitness_targets,
    precision_key,
)
from ..trace_cache import COMPATIBLE_VERSIONS, MODEL_VERSION, is_comparable
from .derive import DerivationError, Derived, best_known_of, derive, frame_of, params_of, truth_of
from .run_store import IDENTITY_FIELDS, is_error

#: A fitness this far (in units of the instance's f*-to-nominal gap) below the suite's
#: best-known f* is a claim to confirm, not a record to accept.
BEST_KNOWN_SLACK = 1e-4

#: Relative agreement required between a reported and a re-evaluated fitness (the kernels
#: are deterministic; this leaves room for another CPU's floating-point rounding only).
FITNESS_RTOL = 1e-6
#: Relative agreement of a claimed accuracy or range error with the re-derived one (the same
#: formula on the same numbers: only JSON's round trip may differ).
FIGURE_RTOL = 1e-9
REQUIRED_FIELDS = (*IDENTITY_FIELDS, "suite", "model_version", "manifest", "x", "fitness",
                   "evaluations", "trace", "targets")
#: Fields that carry a score: an error record carries none of them (or only False / None,
#: as legacy error records do).
SCORE_FIELDS = ("success", "evals_to_success", "accuracy", "range_error", "targets",
                "best_at", "trajectory", "fitness", "x")
#: What a legacy record (schema 1, no trajectory vectors) cannot prove: ``validate`` checks
#: these claims against bounds only; replay verifies them.
LEGACY_UNVERIFIABLE = ("targets.parameters first-hit evaluations before the final vector was "
                       "found (scored as the last improvement)", "evals_to_success (likewise)")


@dataclass(frozen=True)
class Finding:
    """One reason to refuse a record (or the submission: ``key`` is ``"*"``)."""

    key: str
    problem: str

    def __str__(self) -> str:
        return f"{self.key}: {self.problem}"


def _claim(field: str, claimed: object, derived: object) -> str:
    """The one-line refusal of a claim: the field and both values."""
    return f"{field}: claimed {claimed!r}, re-derived {derived!r}"


def check_record(r: dict, reevaluate: bool = True) -> list[str]:
    """What is wrong with one record (empty: nothing)."""
    if not isinstance(r, dict):
        return [f"not a record: {type(r).__name__}"]
    missing = [f for f in (IDENTITY_FIELDS if is_error(r) else REQUIRED_FIELDS) if f not in r]
    if schema(r) >= 2 and not is_error(r) and "trajectory" not in r:
        missing.append("trajectory")
    if missing:
        return [f"missing field(s) {missing}"]
    bad = []
    if r.get("suite") != suite_of(r["case"]).id:
        bad.append(f"suite version {r.get('suite')!r}, expected {suite_of(r['case']).id!r}")
    current = suite_of(r["case"]).model_version
    if not is_comparable(str(r.get("model_version")), current):
        bad.append(f"model version {r.get('model_version')!r}, expected {current!r}" + (
            f" (or a compatible {', '.join(map(repr, COMPATIBLE_VERSIONS))})"
            if current == MODEL_VERSION else ""))
    if schema(r) not in (1, RECORD_SCHEMA):
        bad.append(f"record schema {r.get('schema')!r}, expected {RECORD_SCHEMA} (or legacy)")
    if type(seed_scheme(r)) is not int or seed_scheme(r) not in SEED_SCHEMES:
        bad.append(f"seed scheme {seed_scheme(r)!r}, expected one of {sorted(SEED_SCHEMES)}")
    if r["track"] not in TRACKS or not is_case(r["case"]):
        return bad + [f"not an instance of suite {' or '.join(SUITES)}: case {r['case']!r}, "
                      f"track {r['track']!r} (instances: {', '.join(DEFAULT.case_order())}, "
                      f"or instance@condition; tracks: {', '.join(TRACKS)})"]
    if is_error(r):
        scored = [f for f in SCORE_FIELDS if r.get(f) not in (None, False)]
        return bad + ([f"error record carries a score: {f}={r[f]!r}" for f in scored[:1]])
    man = r["manifest"] if isinstance(r["manifest"], dict) else {}
    lacking = [k for k in REQUIRED_MANIFEST_KEYS if k not in man]
    if lacking:
        bad.append(f"manifest lacks {lacking}")
    if not 1 <= r["evaluations"] <= r["budget"]:
        bad.append(f"{r['evaluations']} evaluations with a budget of {r['budget']}")
    ev = _check_evidence(r) or _check_no_prior(r)
    if ev:
        return bad + ev
    try:
        d = derive(r)
    except DerivationError as exc:
        return bad + [str(exc)]
    bad += _check_claims(r, d)
    if reevaluate and not bad:
        bad += _reevaluate(r, d)
    return bad


def _check_no_prior(r: dict) -> list[str]:
    """A v2 run without prior whose evidence holds the nominal vector: the solver was not
    handed it, so it took it from elsewhere (``ema_bench.faults.NOMINAL``).  The first
    evaluation is always in the trajectory, so a start there is always caught (a later,
    non-improving visit is not evidence the record keeps)."""
    if schema(r) < 2 or find(r["case"]).prior:
        return []
    for p in r["trajectory"]:
        if np.array_equal(np.asarray(p[2][:N_FAULTS], dtype=float), NOMINAL):
            return [f"evaluation {p[0]} is the nominal vector, which a run without prior is "
                    "not given"]
    return []


def _check_evidence(r: dict) -> list[str]:
    """The trace (and trajectory) are well formed: indices increasing from 1 within the
    evaluations and the budget, fitness non-increasing, ending at the reported fitness."""
    tr = r["trace"]
    if not isinstance(tr, list) or not tr or not all(
            isinstance(p, list) and len(p) == 2 for p in tr):
        return ["empty or malformed trace"]
    out = _check_points("trace", [p[0] for p in tr], [p[1] for p in tr], r, strict=False)
    if out:
        return out
    if schema(r) < 2:
        return []
    tj = r["trajectory"]
    if not isinstance(tj, list) or not tj or not all(
            isinstance(p, list) and len(p) == 3 and isinstance(p[2], list) for p in tj):
        return ["empty or malformed trajectory"]
    out = _check_points("trajectory", [p[0] for p in tj], [p[1] for p in tj], r, strict=True)
    if out:
        return out
    dims = {len(p[2]) for p in tj}
    need = max(N_FAULTS, frame_of(r)[0].size)     # every parameter the instance searches
    if len(dims) != 1 or dims.pop() < need:
        return [f"trajectory vectors of lengths {sorted({len(p[2]) for p in tj})}, the "
                f"instance's of at least {need}"]
    if not all(type(v) in (int, float) for p in tj for v in p[2]):
        return ["trajectory: vector entries must be numbers"]
    proj = [[p[0], p[1]] for p in tj]
    if tr != proj and tr != [*proj, [r["evaluations"], tj[-1][1]]]:
        return ["trace: not the trajectory's evaluations and fitness (and the last "
                "evaluation)"]
    final = dict(zip(FAULT_NAMES, tj[-1][2][:N_FAULTS]))
    if not isinstance(r["x"], dict) or any(r["x"].get(n) != final[n] for n in FAULT_NAMES):
        return [_claim("x", r["x"], final)]
    return []


def _check_points(name: str, ev: list, f: list, r: dict, strict: bool) -> list[str]:
    if not all(isinstance(e, int) and not isinstance(e, bool) for e in ev) or not all(
            isinstance(v, int | float) and math.isfinite(v) for v in f):
        return [f"{name}: evaluations must be integers and fitness finite numbers"]
    if ev[0] != 1:
        return [f"{name}: starts at evaluation {ev[0]}, not 1 (the first evaluation is "
                "always an improvement)"]
    if any(b <= a for a, b in zip(ev, ev[1:])):
        i = next(i for i, (a, b) in enumerate(zip(ev, ev[1:])) if b <= a)
        return [f"{name}: evaluations not increasing ({ev[i]} then {ev[i + 1]})"]
    if ev[-1] > r["evaluations"] or ev[-1] > r["budget"]:
        return [f"{name}: evaluation {ev[-1]} beyond the run's {r['evaluations']} evaluations "
                f"(budget {r['budget']})"]
    if any((b >= a if strict else b > a) for a, b in zip(f, f[1:])):
        return [f"{name}: best-so-far fitness does not decrease"]
    if not math.isclose(f[-1], r["fitness"], rel_tol=FITNESS_RTOL):
        return [_claim("fitness", r["fitness"], f[-1]) + f" (the {name}'s best)"]
    return []


def _check_claims(r: dict, d: Derived) -> list[str]:
    """Every claimed figure against its re-derivation (legacy: against the bounds its
    evidence allows)."""
    bad = []
    if r.get("success") != d.success:
        bad.append(_claim("success", r.get("success"), d.success))
    for field, derived in (("accuracy", d.accuracy), ("range_error", d.range_error)):
        claimed = r.get(field)
        if not isinstance(claimed, dict) or any(
                not _close(claimed.get(n), derived[n]) for n in FAULT_NAMES):
            bad.append(_claim(field, claimed, derived))
    t = r["targets"] if isinstance(r["targets"], dict) else {}
    known = best_known_of(r)
    if known is not None:
        for k in ("f_star", "f_nominal"):
            if t.get(k) != known[k]:
                bad.append(_claim(f"targets.{k}", t.get(k), known[k]) + " (the suite's)")
        if r["fitness"] < known["f_star"] - BEST_KNOWN_SLACK * (
                known["f_nominal"] - known["f_star"]):
            bad.append(f"fitness {r['fitness']:.10g} beats the suite's best known "
                       f"{known['f_star']:.10g}: confirm it (re-evaluation) and report it")
    truth = r.get("truth")
    true = truth_of(r)
    if truth is not None and (not isinstance(truth, dict) or not np.allclose(
            [truth.get(n, np.nan) for n in FAULT_NAMES], true, rtol=1e-12)):
        bad.append(_claim("truth", truth, faults_to_dict(true)))
    if d.schema >= 2:
        bad += _exact_claims(r, t, d)
    else:
        bad += _legacy_claims(r, t, d)
    return bad


def _close(a: object, b: float | None) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return isinstance(a, int | float) and math.isclose(a, b, rel_tol=FIGURE_RTOL,
                                                      abs_tol=1e-12)


def _exact_claims(r: dict, t: dict, d: Derived) -> list[str]:
    claims = (("evals_to_success", r.get("evals_to_success"), d.evals_to_success),
              ("targets.fitness", t.get("fitness"), d.fitness_hits),
              ("targets.parameters", t.get("parameters"), d.parameter_hits),
              ("best_at", r.get("best_at"), d.best_at))
    return [_claim(field, claimed, derived) for field, claimed, derived in claims
            if claimed != derived]


def _legacy_claims(r: dict, t: dict, d: Derived) -> list[str]:
    """A legacy record's claims against what its trace and final vector allow: a hit no
    earlier than the last trace point above the target and no later than the first at or
    below it; a parameter hit no later than where the final vector was found if that vector
    is within the target, and (the best-so-far point having moved on since) strictly
    earlier otherwise."""
    bad = []
    ev = [p[0] for p in r["trace"]]
    fit = [p[1] for p in r["trace"]]
    if d.fitness_hits is None:
        if t.get("fitness") is not None:
            bad.append(_claim("targets.fitness", t.get("fitness"), None) + " (no f* here)")
    else:
        claimed = t.get("fitness") if isinstance(t.get("fitness"), dict) else {}
        levels = dict(zip(map(precision_key, FITNESS_PRECISIONS),
                          fitness_targets(d.f_star, d.f_nominal)))
        for k, lv in levels.items():
            h = claimed.get(k)
            above = [e for e, f in zip(ev, fit) if f > lv]
            lo = above[-1] + 1 if above else 1
            hi = d.fitness_hits[k]
            ok = (h is None and hi is None) or (
                h is not None and hi is not None and lo <= h <= hi)
            if not ok:
                want = hi if hi is None or lo == hi else f"{lo}..{hi}"
                bad.append(_claim(f"targets.fitness.{k}", h, want) + " (from the trace)")
    claimed_p = t.get("parameters") if isinstance(t.get("parameters"), dict) else {}
    last = d.last_improvement
    prev = None
    for p in PARAMETER_TARGETS:    # coarse to fine: a finer target is hit no earlier
        k = precision_key(p)
        h, within = claimed_p.get(k), d.parameter_hits[k] is not None
        if h is not None and (not isinstance(h, int) or not 1 <= h <= r["evaluations"]):
            bad.append(_claim(f"targets.parameters.{k}", h, f"1..{r['evaluations']}"))
            continue
        if within and (h is None or h > last):
            bad.append(_claim(f"targets.parameters.{k}", h, f"1..{last}") +
                       " (the final vector is within the target)")
        elif not within and h is not None and h >= last:
            bad.append(_claim(f"targets.parameters.{k}", h, f"None or 1..{last - 1}") +
                       " (the final vector, found at evaluation " + f"{last}, is not within "
                       "the target)")
        elif h is not None and prev is not None and (prev[1] is None or h < prev[1]):
            bad.append(_claim(f"targets.parameters.{k}", h, f">= {prev[1]}") +
                       f" (a finer target than {prev[0]})")
        prev = (k, h)
    e2s = r.get("evals_to_success")
    if e2s != (claimed_p.get(precision_key(SUCCESS_RANGE_ERROR)) if d.success else None):
        bad.append(_claim("evals_to_success", e2s, "targets.parameters.0.01" if d.success
                          else None))
    bad += _legacy_best_at(r, ev, fit)
    return bad


def _legacy_best_at(r: dict, ev: list[int], fit: list[float]) -> list[str]:
    """Each claimed ``best_at`` value lies between the trace's best at the last point at or
    before the checkpoint and at the next point (exact when a trace point is there)."""
    claimed = r.get("best_at")
    want = [b for b in BUDGET_CHECKPOINTS if b <= r["evaluations"]]
    if not isinstance(claimed, list) or [p[0] if isinstance(p, list) and p else None
                                         for p in claimed] != want:
        return [_claim("best_at checkpoints", claimed, want)]
    for b, f in claimed:
        i = max(j for j, e in enumerate(ev) if e <= b)
        hi = fit[i]
        lo = hi if ev[i] == b or i + 1 == len(ev) else fit[i + 1]
        if not isinstance(f, int | float) or not lo <= f <= hi:
            return [_claim(f"best_at.{b}", f, hi if lo == hi else f"{lo}..{hi}") +
                    " (from the trace)"]
    return []


def _reevaluate(r: dict, d: Derived) -> list[str]:
    """Re-evaluate every vector the derivation used: the whole trajectory (schema 2), or
    the final vector and the start (legacy: the trace's first point at evaluation 1 is the
    start point when their fitness agree, which fixes the parameter hits at 1); and the
    truth, for ``fitness_at_truth``."""
    # the largest budget: no record's evidence is refused for want of one (a trajectory
    # holds at most the record's budget of points)
    # on the record's own model version (a compatible one: check_record refused others)
    problem = make_problem(r["case"], track=r["track"],
                           seed=run_seed(r["root_seed"], r["seed"]), budget=MAX_BUDGET,
                           params=params_of(r))
    if d.schema >= 2:
        tj = r["trajectory"]
        X, claimed, ev = np.array([p[2] for p in tj], float), [p[1] for p in tj], \
            [p[0] for p in tj]
    else:
        X = np.array([[r["x"][n] for n in FAULT_NAMES], problem.start[:N_FAULTS]])
        claimed, ev = [r["fitness"], None], [r["evaluations"], 1]
    if X.shape[1] != problem.dim:
        return [f"vectors of dimension {X.shape[1]}, the problem's is {problem.dim}"]
    if r.get("fitness_at_truth") is not None:   # the model-form bias the paper tables print
        g = problem.fitness_at_truth()
        if not math.isclose(g, r["fitness_at_truth"], rel_tol=FITNESS_RTOL):
            return [_claim("fitness_at_truth", r["fitness_at_truth"], g)]
    try:
        f = problem.evaluate(X)
    except ValueError as exc:
        return [f"reported vector cannot be evaluated: {exc}"]
    for e, c, g in zip(ev, claimed, f):
        if c is not None and not math.isclose(g, c, rel_tol=FITNESS_RTOL):
            return [_claim(f"fitness at evaluation {e}", c, float(g)) + " (re-evaluated "
                    "from its vector)"]
    if d.schema < 2 and math.isclose(f[1], r["trace"][0][1], rel_tol=FITNESS_RTOL):
        # the first evaluation was the start point: the hits at evaluation 1 are known
        worst = float(np.max(range_error(X[1], truth_of(r))))
        claimed_p = r["targets"].get("parameters") or {}
        for p in PARAMETER_TARGETS:
            k = precision_key(p)
            if (claimed_p.get(k) == 1) != (worst <= p):
                return [_claim(f"targets.parameters.{k}", claimed_p.get(k),
                               1 if worst <= p else "> 1") + " (evaluation 1 was the start "
                        "point)"]
    return []


def check_complete(records: list[dict], per_tier: int | None = None) -> list[Finding]:
    """Every solver must cover every non-sanity suite instance, on each track it enters,
    for the same seeds as its other runs (leaving out hard instances is not allowed).
    ``per_tier`` (emafdi-v2): the first N instances of each tier, in the suite's order (a
    board declared with ``--per-tier N``: the subset is fixed before any run, not chosen)."""
    have: dict[tuple[str, str], set[tuple[str, int]]] = defaultdict(set)
    for r in records:
        if "solver" in r and "track" in r:
            have[(r["solver"], r["track"])].add((r["case"], r["seed"]))
    out = []
    for (solver, track), runs in sorted(have.items()):
        seeds = sorted({s for _, s in runs})
        # per suite entered: the cases it asks of the instances entered (v2: every
        # instance of each (tier, condition))
        entered = [i for i in map(find, dict.fromkeys(c for c, _ in runs)) if i is not None]
        cases = [c for s in dict.fromkeys(i.suite for i in entered)
                 for c in s.complete_cases([i for i in entered if i.suite is s], per_tier)]
        lacking = [f"{c}/{s}" for c in cases for s in seeds if (c, s) not in runs]
        if lacking:
            out.append(Finding("*", f"{solver} on the {track} track lacks {len(lacking)} runs "
                                    f"of the suite (e.g. {', '.join(lacking[:5])})"))
    return out


def validate(records: list[dict], reevaluate: bool = True, complete: bool = True,
             per_tier: int | None = None) -> list[Finding]:
    """Every reason to refuse ``records`` (empty: accepted); ``per_tier``: see
    :func:`check_complete`."""
    found = [Finding(str(r.get("key", f"record {i}")), p)
             for i, r in enumerate(records) for p in check_record(r, reevaluate)]
    return found + (check_complete(records, per_tier) if complete else [])
