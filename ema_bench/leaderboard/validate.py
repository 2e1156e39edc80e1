"""Checks of third-party run records before they join a leaderboard (``ema-bench validate``).

A record is accepted when it is of this suite and model version, carries a complete manifest,
stayed within its budget, is consistent with itself (trace, targets, truth) and, re-evaluated
here, its reported best vector has the fitness it reports.  A submission is complete when
every solver covers every (non-sanity) instance of the suite on each track it enters, for the
same seeds.  docs/submitting-results.md describes the whole path.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from ..faults import FAULT_NAMES
from ..instances import TRACKS, make_problem
from ..manifest import REQUIRED_MANIFEST_KEYS
from ..seeding import run_seed
from ..suite import (
    FITNESS_PRECISIONS,
    PARAMETER_TARGETS,
    SANITY_CASES,
    SUITE_ID,
    best_known,
    instance_faults,
    instance_names,
    is_instance,
    precision_key,
)
from ..trace_cache import MODEL_VERSION
from .store import IDENTITY_FIELDS, is_error

#: Relative agreement required between a reported and a re-evaluated fitness (the kernels
#: are deterministic; this leaves room for another CPU's floating-point rounding only).
FITNESS_RTOL = 1e-6
REQUIRED_FIELDS = (*IDENTITY_FIELDS, "suite", "model_version", "manifest", "x", "fitness",
                   "evaluations", "trace", "targets")


@dataclass(frozen=True)
class Finding:
    """One reason to refuse a record (or the submission: ``key`` is ``"*"``)."""

    key: str
    problem: str

    def __str__(self) -> str:
        return f"{self.key}: {self.problem}"


def check_record(r: dict, reevaluate: bool = True) -> list[str]:
    """What is wrong with one record (empty: nothing)."""
    missing = [f for f in (IDENTITY_FIELDS if is_error(r) else REQUIRED_FIELDS) if f not in r]
    if missing:
        return [f"missing field(s) {missing}"]
    bad = []
    if r.get("suite") != SUITE_ID:
        bad.append(f"suite version {r.get('suite')!r}, expected {SUITE_ID!r}")
    if str(r.get("model_version")) != MODEL_VERSION:
        bad.append(f"model version {r.get('model_version')!r}, expected {MODEL_VERSION!r}")
    if r["track"] not in TRACKS or not is_instance(r["case"]):
        return bad + [f"not an instance of suite {SUITE_ID}: case {r['case']!r}, track "
                      f"{r['track']!r} (instances: {', '.join(instance_names())}; tracks: "
                      f"{', '.join(TRACKS)})"]
    if is_error(r):
        return bad
    man = r["manifest"] if isinstance(r["manifest"], dict) else {}
    lacking = [k for k in REQUIRED_MANIFEST_KEYS if k not in man]
    if lacking:
        bad.append(f"manifest lacks {lacking}")
    if not 1 <= r["evaluations"] <= r["budget"]:
        bad.append(f"{r['evaluations']} evaluations with a budget of {r['budget']}")
    bad += _check_trace(r) + _check_targets(r)
    if reevaluate and not bad:
        bad += _reevaluate(r)
    return bad


def _check_trace(r: dict) -> list[str]:
    tr = r["trace"]
    if not tr:
        return ["empty trace"]
    ev = [p[0] for p in tr]
    best = [p[1] for p in tr]
    if any(b <= a for a, b in zip(ev, ev[1:])) or ev[-1] > r["evaluations"]:
        return ["trace evaluations are not increasing within the run's evaluations"]
    if any(b > a for a, b in zip(best, best[1:])):
        return ["trace best-so-far fitness increases"]
    if not math.isclose(best[-1], r["fitness"], rel_tol=FITNESS_RTOL):
        return [f"reported fitness {r['fitness']:.10g} is not the trace's best "
                f"{best[-1]:.10g}"]
    return []


def _check_targets(r: dict) -> list[str]:
    t = r["targets"] or {}
    bad = []
    for kind, levels in (("fitness", FITNESS_PRECISIONS), ("parameters", PARAMETER_TARGETS)):
        hits = t.get(kind)
        if hits is None:
            continue
        seq = [hits.get(precision_key(p)) for p in levels]
        if any(h is not None and not 1 <= h <= r["evaluations"] for h in seq):
            bad.append(f"{kind} target reached outside the run's evaluations: {hits}")
        if kind == "fitness":   # a finer target cannot be reached before a coarser one
            reached = [h for h in seq if h is not None]
            if reached != sorted(reached) or (None in seq and
                                              seq.index(None) < len(reached)):
                bad.append(f"fitness targets reached out of order: {hits}")
    known = best_known(r["case"], r["track"], r["seed"], r["root_seed"])
    if known is not None and t.get("f_star") != known["f_star"]:
        bad.append(f"f* {t.get('f_star')!r} is not the suite's {known['f_star']!r}")
    if known is not None and r["fitness"] < known["f_star"] - 1e-4 * (
            known["f_nominal"] - known["f_star"]):
        bad.append(f"fitness {r['fitness']:.10g} beats the suite's best known "
                   f"{known['f_star']:.10g}: confirm it (re-evaluation) and report it")
    truth = r.get("truth")
    if truth is not None and not np.allclose([truth[n] for n in FAULT_NAMES],
                                             instance_faults(r["case"]), rtol=1e-12):
        bad.append(f"truth {truth} is not instance {r['case']}'s")
    return bad


def _reevaluate(r: dict) -> list[str]:
    problem = make_problem(r["case"], track=r["track"],
                           seed=run_seed(r["root_seed"], r["seed"]), budget=1)
    x = np.array([r["x"][n] for n in FAULT_NAMES])
    try:
        f = float(problem.evaluate(x))
    except ValueError as exc:
        return [f"reported vector cannot be evaluated: {exc}"]
    if not math.isclose(f, r["fitness"], rel_tol=FITNESS_RTOL):
        return [f"reported fitness {r['fitness']:.10g} does not match its vector "
                f"(re-evaluated: {f:.10g})"]
    return []


def check_complete(records: list[dict]) -> list[Finding]:
    """Every solver must cover every non-sanity suite instance, on each track it enters,
    for the same seeds as its other runs (leaving out hard instances is not allowed)."""
    cases = [c for c in instance_names() if c not in SANITY_CASES]
    have: dict[tuple[str, str], set[tuple[str, int]]] = defaultdict(set)
    for r in records:
        if "solver" in r and "track" in r:
            have[(r["solver"], r["track"])].add((r["case"], r["seed"]))
    out = []
    for (solver, track), runs in sorted(have.items()):
        seeds = sorted({s for _, s in runs})
        lacking = [f"{c}/{s}" for c in cases for s in seeds if (c, s) not in runs]
        if lacking:
            out.append(Finding("*", f"{solver} on the {track} track lacks {len(lacking)} runs "
                                    f"of the suite (e.g. {', '.join(lacking[:5])})"))
    return out


def validate(records: list[dict], reevaluate: bool = True, complete: bool = True
             ) -> list[Finding]:
    """Every reason to refuse ``records`` (empty: accepted)."""
    found = [Finding(str(r.get("key", f"record {i}")), p)
             for i, r in enumerate(records) for p in check_record(r, reevaluate)]
    return found + (check_complete(records) if complete else [])
