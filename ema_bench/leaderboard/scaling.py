"""An emafdi-v2 board by tier and condition: the ranking of each (tier, condition), ERT to the
1 % parameter target against dimension, global vs local search without a prior, saturation.

Every figure comes from :mod:`.anytime` (ECDF areas, hits, ERT and their bootstrap intervals,
re-derived from each record's evidence), never re-implemented here: this module only groups
the records.  Whether a solver is a global or a local search is the ``scope`` it declares
where it is registered (:data:`ema_bench.registry.SCOPES`), never a list kept here.
"""

from __future__ import annotations

import functools
import math
from collections import defaultdict
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from ..suites import find, instance
from ..suites.targets import precision_key
from ..suites.v2 import CONDITIONS, instance_names
from .anytime import AnytimeScore, anytime_score, group_seed, hits, mean_ci, run_area

#: The target of the scaling plot and of the global-vs-local success rates: the best-so-far
#: point within 1 % of range of every judged parameter.
P_TARGET = f"p{precision_key(0.01)}"
#: The saturation check compares the best solver with the one ranked here (1-based).
FIFTH = 5


def group_of(record: dict) -> tuple[int, str]:
    """The (tier, condition) of a record of a grouped suite
    (:attr:`~ema_bench.suites.base.Instance.group`)."""
    return instance(record["case"]).group


def group_label(tier: int, cond: str) -> str:
    """The ``cases`` label of a (tier, condition) score (``t7@no-prior``): no instance is
    named so."""
    return f"t{tier}@{cond}"


def _order(key: tuple[int, str]) -> tuple[int, int]:
    return key[0], list(CONDITIONS).index(key[1])


def groups(records: list[dict]) -> dict[tuple[str, int, str], list[dict]]:
    """(track, tier, condition) -> the records of that group, tiers ascending, conditions
    in the suite's order (records of a suite scored per instance are left out)."""
    out: dict[tuple[str, int, str], list[dict]] = defaultdict(list)
    for r in records:
        inst = find(r["case"])
        if inst is not None and inst.group is not None:
            out[(r["track"], *inst.group)].append(r)
    return dict(sorted(out.items(), key=lambda kv: (kv[0][0], *_order(kv[0][1:]))))


def group_scores(records: list[dict]) -> list[AnytimeScore]:
    """The anytime score of every solver on every (track, tier, condition) of the board
    (``cases`` = :func:`group_label`), ranked by ECDF area within each group."""
    out = []
    for (track, tier, cond), recs in groups(records).items():
        by: dict[str, list[dict]] = defaultdict(list)
        for r in recs:
            by[r["solver"]].append(r)
        label = group_label(tier, cond)
        out += sorted((anytime_score(track, s, label, rs) for s, rs in by.items()),
                      key=lambda s: (-np.nan_to_num(s.area[0], nan=-1.0), s.solver))
    return out


def split_label(label: str) -> tuple[int, str]:
    """(tier, condition) of a :func:`group_label`."""
    tier, _, cond = label.partition("@")
    return int(tier[1:]), cond


# --- ERT against dimension (the COCO scaling plot) -------------------------------------------
@dataclass(frozen=True)
class ScalingPoint:
    """ERT to :data:`P_TARGET` of one solver on one (track, tier, condition)."""

    track: str
    solver: str
    condition: str
    dim: int
    ert: tuple[float, float, float]   # evaluations: value, 95 % interval (inf: never reached)
    hits: int                         # runs that reached the target
    runs: int


def scaling_points(scores: list[AnytimeScore]) -> list[ScalingPoint]:
    """One point per (track, solver, condition, tier) of :func:`group_scores`: the ERT and
    hit rate the anytime score computed (:func:`.anytime.ert_ci`)."""
    out = []
    for s in scores:
        tier, cond = split_label(s.cases)
        e = s.ert.get(P_TARGET, (math.inf,) * 3)
        rate = s.hit_rate.get(P_TARGET, 0.0)
        out.append(ScalingPoint(s.track, s.solver, cond, tier, e, round(rate * s.runs),
                                s.runs))
    return out


# --- global vs local without a prior ---------------------------------------------------------
def registered_scopes(solvers: list[str]) -> dict[str, str]:
    """Each solver's declared scope (``unclassified`` for one that is not registered here),
    read in a worker process of its own: the plugins' import code never runs where the
    scores are computed, and what comes back is only a known scope name.  Asked once per
    set of solvers and process (a report asks it for every table and page that groups
    solvers by scope; each ask starts a process that imports the zoo)."""
    return dict(_scopes(tuple(solvers)))


@functools.lru_cache(maxsize=32)
def _scopes(solvers: tuple[str, ...]) -> tuple[tuple[str, str], ...]:
    from ..registry import SCOPES
    from ..sweep.executors import Job, execute
    from .replay_worker import scopes_job

    (o,) = execute([Job("scopes", "scopes", list(solvers))], scopes_job, "isolated", 1)
    got = o.records[0] if o.failure is None else {}
    return tuple((s, got.get(s) if got.get(s) in SCOPES else "unclassified") for s in solvers)


@dataclass(frozen=True)
class GlobalLocal:
    """The global against the local solvers of one (track, tier, condition), paired per
    (instance, seed): on each pair, the mean over each group's solvers of their runs' ECDF
    area (and of reaching :data:`P_TARGET`); differences global - local with 95 % bootstrap
    intervals over the pairs (:func:`.anytime.mean_ci`)."""

    track: str
    tier: int
    condition: str
    global_solvers: tuple[str, ...]
    local_solvers: tuple[str, ...]
    pairs: int                        # (instance, seed) pairs every solver of both ran
    global_hits: int                  # runs of the global solvers that reached P_TARGET
    global_runs: int
    local_hits: int
    local_runs: int
    global_area: float
    local_area: float
    area_diff: tuple[float, float, float]
    rate_diff: tuple[float, float, float]
    best_global: tuple[str, float]    # the group's solver with the largest mean area
    best_local: tuple[str, float]
    others: tuple[str, ...] = ()      # the group's other solvers (baselines, unclassified)

    @property
    def verdict(self) -> str:
        """``global``, ``local`` (the group whose area interval lies above 0), or ``none``."""
        _, lo, hi = self.area_diff
        if lo > 0:
            return "global"
        if hi < 0:
            return "local"
        return "none"


def global_vs_local(records: list[dict], condition: str = "no-prior",
                    scope_of: Callable[[list[str]], Mapping[str, str]] = registered_scopes
                    ) -> list[GlobalLocal]:
    """:class:`GlobalLocal` of every (track, tier) of the board under ``condition`` that has
    at least one global and one local solver (scopes: ``scope_of(solver names)``, by default
    as registered).  Only the (instance, seed) pairs that every compared solver ran count:
    a board missing one solver's bad runs cannot tilt the comparison."""
    out = []
    for (track, tier, cond), recs in groups(records).items():
        if cond != condition:
            continue
        scopes = scope_of(sorted({r["solver"] for r in recs}))
        glob = tuple(s for s, k in sorted(scopes.items()) if k == "global")
        loc = tuple(s for s, k in sorted(scopes.items()) if k == "local")
        if not glob or not loc:
            continue
        runs: dict[tuple[str, int], dict[str, dict]] = defaultdict(dict)
        for r in recs:
            runs[(r["case"], int(r["seed"]))][r["solver"]] = r
        pairs = [p for p in sorted(runs) if set(glob + loc) <= set(runs[p])]
        if not pairs:
            continue
        area = {(p, s): run_area(runs[p][s]) for p in pairs for s in glob + loc}
        hit = {(p, s): hits(runs[p][s]).get(P_TARGET) is not None
               for p in pairs for s in glob + loc}

        def mean_over(group, table, p):
            return math.fsum(float(table[(p, s)]) for s in group) / len(group)

        d_area = [mean_over(glob, area, p) - mean_over(loc, area, p) for p in pairs]
        d_rate = [mean_over(glob, hit, p) - mean_over(loc, hit, p) for p in pairs]
        label = group_label(tier, cond)
        solver_area = {s: math.fsum(area[(p, s)] for p in pairs) / len(pairs)
                       for s in glob + loc}
        out.append(GlobalLocal(
            track, tier, cond, glob, loc, len(pairs),
            sum(hit[(p, s)] for p in pairs for s in glob), len(pairs) * len(glob),
            sum(hit[(p, s)] for p in pairs for s in loc), len(pairs) * len(loc),
            math.fsum(solver_area[s] for s in glob) / len(glob),
            math.fsum(solver_area[s] for s in loc) / len(loc),
            mean_ci(d_area, group_seed(track, "global-local", label, "area")),
            mean_ci(d_rate, group_seed(track, "global-local", label, P_TARGET)),
            max(((s, solver_area[s]) for s in glob), key=lambda t: (t[1], t[0])),
            max(((s, solver_area[s]) for s in loc), key=lambda t: (t[1], t[0])),
            tuple(s for s, k in sorted(scopes.items()) if k not in ("global", "local"))))
    return out


def _signed(v: tuple[float, float, float]) -> str:
    # one pair has no bootstrap interval (NaN bounds): "-" as in the table, never "+nan"
    lo, hi = (f"{b:+.3f}" if math.isfinite(b) else "-" for b in v[1:])
    return f"{v[0]:+.3f} [{lo}, {hi}]"


def _tiers(rows: list[GlobalLocal]) -> str:
    names = [str(r.tier) for r in rows]
    text = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    return ("tier " if len(names) == 1 else "tiers ") + text


def answer(rows: list[GlobalLocal], track: str) -> str:
    """The paper's claim (global methods beat local ones without a prior) answered in one
    sentence from the numbers of ``track``'s rows."""
    mine = [r for r in rows if r.track == track]
    if not mine:
        return (f"{track} track: no tier has both a global and a local solver on every "
                "(instance, seed) pair: the claim is not tested.")
    cond = mine[0].condition
    parts = []
    for who, text in (("global", "global methods beat local ones"),
                      ("local", "local methods beat global ones"),
                      ("none", "the two groups are not separated")):
        sel = [r for r in mine if r.verdict == who]
        if sel:
            diffs = "; ".join(f"{_signed(r.area_diff)} over {r.pairs} pairs" for r in sel)
            parts.append(f"{text} on {_tiers(sel)} (ECDF-area difference global - local "
                         f"{diffs})")
    return (f"Without a prior ({cond}, {track} track), " + ", ".join(parts)
            + ": 95 % bootstrap intervals over (instance, seed) pairs, each pair the mean of "
              "each group's solvers.")


# --- saturation ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Reach:
    """How many instances of one (track, tier, condition) a solver reached :data:`P_TARGET`
    on, in at least one run and in every run."""

    solver: str
    any_run: int
    every_run: int
    instances: int


def reach(records: list[dict]) -> dict[tuple[str, int, str], list[Reach]]:
    """(track, tier, condition) -> every solver's :class:`Reach`, the most instances first."""
    out = {}
    for key, recs in groups(records).items():
        by: dict[str, dict[str, list[bool]]] = defaultdict(lambda: defaultdict(list))
        for r in recs:
            by[r["solver"]][r["case"]].append(hits(r).get(P_TARGET) is not None)
        n = len({r["case"] for r in recs})
        rows = [Reach(s, sum(map(any, per.values())), sum(map(all, per.values())), n)
                for s, per in by.items()]
        out[key] = sorted(rows, key=lambda x: (-x.any_run, -x.every_run, x.solver))
    return out


def separated(scores: list[AnytimeScore], rank: int = FIFTH) -> dict[tuple[str, int, str],
                                                                     bool | None]:
    """(track, tier, condition) -> whether the best solver's ECDF-area interval lies wholly
    above the one ranked ``rank`` (None: fewer solvers)."""
    by: dict[tuple[str, int, str], list[AnytimeScore]] = defaultdict(list)
    for s in scores:
        by[(s.track, *split_label(s.cases))].append(s)
    out: dict[tuple[str, int, str], bool | None] = {}
    for key, ss in by.items():
        ranked = sorted(ss, key=lambda s: (-np.nan_to_num(s.area[0], nan=-1.0), s.solver))
        out[key] = None if len(ranked) < rank else bool(ranked[0].area[1]
                                                        > ranked[rank - 1].area[2])
    return out


@dataclass(frozen=True)
class TierSeparation:
    """Best and ``rank``-th solver of one tier, their ECDF areas pooled over every condition
    of the tier the board has (mean, 95 % bootstrap interval over runs)."""

    tier: int
    best: str
    best_area: tuple[float, float, float]
    nth: str
    nth_area: tuple[float, float, float]

    @property
    def disjoint(self) -> bool:
        return bool(self.best_area[1] > self.nth_area[2])


def pooled_separation(records: list[dict], track: str,
                      rank: int = FIFTH) -> dict[int, TierSeparation | None]:
    """Tier -> best vs ``rank``-th solver on ``track``, each solver's runs of all the tier's
    conditions pooled (the issue's "on at least two tiers" read per tier; None: fewer
    solvers).  The areas come from :func:`.anytime.run_area`, the intervals from
    :func:`.anytime.mean_ci` seeded by (track, solver, ``t<tier>``)."""
    by: dict[int, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    for (tr, tier, _), recs in groups(records).items():
        if tr == track:
            for r in recs:
                by[tier][r["solver"]].append(run_area(r))
    out: dict[int, TierSeparation | None] = {}
    for tier, per in sorted(by.items()):
        areas = {s: mean_ci(v, group_seed(track, s, f"t{tier}")) for s, v in per.items()}
        ranked = sorted(areas, key=lambda s: (-np.nan_to_num(areas[s][0], nan=-1.0), s))
        out[tier] = None if len(ranked) < rank else TierSeparation(
            tier, ranked[0], areas[ranked[0]], ranked[rank - 1], areas[ranked[rank - 1]])
    return out


def saturation_lines(records: list[dict], scores: list[AnytimeScore], track: str,
                     rank: int = FIFTH, name: Callable[[str], str] = str) -> list[str]:
    """The issue's saturation check on ``track``, as report lines: on the highest tier,
    whether any solver reaches :data:`P_TARGET` on every instance (in at least one run: the
    strict reading), and the tiers whose best and ``rank``-th solvers' ECDF-area intervals
    are disjoint under every condition the board has of them, then pooled over the
    tier's conditions (:func:`pooled_separation`).  ``name`` formats a solver's
    name (:func:`~ema_bench.escape.markdown` for Markdown: names come from plugins)."""
    r = {k: v for k, v in reach(records).items() if k[0] == track}
    if not r:
        return []
    top = max(t for _, t, _ in r)
    per_cond = []
    saturated = False
    held = 0
    for (_, t, cond), rows in r.items():
        if t != top or not rows:
            continue
        b = rows[0]
        held = max(held, b.instances)
        full = [name(x.solver) for x in rows if x.any_run == x.instances]
        saturated |= bool(full)
        per_cond.append(f"{cond}: best {name(b.solver)}, {b.any_run} of {b.instances} instances "
                        f"in at least one run, {b.every_run} in every run"
                        + (f", every instance: {', '.join(full)}" if full else ""))
    # a board lacking instances could look saturated on the ones it has: say so, once
    suite_n = len(instance_names(top))
    lines = [f"Highest tier ({top}): "
             + ("SATURATED, a solver reaches the 1 % parameter target on every instance"
                if saturated else "no solver reaches the 1 % parameter target on every "
                                  "instance")
             + (f" (only {held} of the tier's {suite_n} instances on this board)"
                if held < suite_n else "")
             + f". {'; '.join(per_cond)}."]
    sep = {k: v for k, v in separated(scores, rank).items() if k[0] == track}
    tiers = sorted({t for _, t, _ in sep})
    detail, disjoint = [], []
    for t in tiers:
        conds = {c: v for (_, tt, c), v in sep.items() if tt == t}
        if all(v is not None for v in conds.values()) and all(conds.values()):
            disjoint.append(t)
        detail.append(f"tier {t}: " + ", ".join(
            f"{c} {'n/a' if v is None else 'yes' if v else 'no'}" for c, v in conds.items()))
    nth = {1: "st", 2: "nd", 3: "rd"}.get(rank if rank < 20 else rank % 10, "th")
    lines.append(f"Best and {rank}{nth} solver's ECDF-area intervals disjoint under every "
                 f"condition on {len(disjoint)} tier(s)"
                 + (f" ({', '.join(map(str, disjoint))})" if disjoint else "")
                 + f" (target: at least two; {'; '.join(detail)}; n/a: fewer than {rank} "
                   "solvers).")
    pooled = pooled_separation(records, track, rank)
    parts = [f"tier {t}: n/a" if p is None else
             f"tier {t}: {name(p.best)} {_interval(p.best_area)} vs {name(p.nth)} "
             f"{_interval(p.nth_area)}, {'yes' if p.disjoint else 'no'}"
             for t, p in pooled.items()]
    hit = [t for t, p in pooled.items() if p is not None and p.disjoint]
    lines.append(f"Pooled over each tier's conditions, best and {rank}{nth} solver's ECDF-area "
                 f"intervals disjoint on {len(hit)} tier(s)"
                 + (f" ({', '.join(map(str, hit))})" if hit else "")
                 + f" (target: at least two; {'; '.join(parts)}).")
    return lines


def _interval(v: tuple[float, float, float]) -> str:
    return f"{v[0]:.3f} [{v[1]:.3f}, {v[2]:.3f}]"
