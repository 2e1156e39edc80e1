"""The claims of a grouped board, bootstrapped over instances with the runs nested inside.

The saturation check and the global-vs-local table (:mod:`.scaling`) put their intervals
over runs (or over (instance, seed) pairs): with one seed per instance and condition, the
runs of one instance under four conditions are not four independent draws of the suite.
Here every claim is re-asked the way a reviewer resamples a benchmark: per (track, tier)

- **best vs fifth** and **first vs second**: the solvers ranked by their mean ECDF area over
  every run of the tier (all its conditions pooled, as :func:`.scaling.pooled_separation`);
- **global vs local**: the solvers that declare ``scope="global"`` against those that
  declare ``"local"``, without a prior (``no-prior``), as :func:`.scaling.global_vs_local`;
- **best vs fifth, parameter targets**: the same ranking and claim on the parameter
  targets' area alone (where the runs have parameter targets): the fitness ladder's
  targets outnumber them, so the claims above mostly measure fitness;

each is the mean over instances of the per-instance mean of the paired difference (one
*cell* = one (condition, seed) run of an instance that every compared solver made; the
difference of the sides' mean ECDF areas on it).  Its 95 % interval is a two-level
bootstrap (:func:`nested_bootstrap`): instances drawn with replacement, then each drawn
instance's cells drawn with replacement.  A **leave-one-solver-out** line asks the claim
again without the top solver of its leading side (best vs fifth: without the best, the new
best against the new fifth; first vs second: the second against the third; global vs local:
without the leading group's best solver).  A claim is **fragile** when its instance
interval reaches 0 or the claim without that solver does, or either difference is below
:data:`NEGLIGIBLE` (statistically clear but too small to matter).  Where a tier's best and fifth
cannot be told apart by instance, :func:`separation_lines` says why in a sentence (how many
instances the fifth is level with or ahead on, or too few instances or solvers).
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..suites import instance
from .anytime import CONFIDENCE, group_seed, run_area
from .scaling import FIFTH, groups, registered_scopes

N_RESAMPLES = 2000
#: The smallest difference in mean ECDF area a claim may rest on (a region of practical
#: equivalence, Benavoli et al., JMLR 18(77), 2017).  Reaching one of a run's 24 targets (21
#: fitness, 3 parameter) with half the evaluations is worth ln 2 / ln B / 24 of area: 0.0030
#: at the largest budget, B = 15000.  Below it the two sides reach the same targets at
#: practically the same cost, however narrow the interval: two solvers that run the same
#: descent until a restart differ by 1e-4 (v3's cmaes and bipop-cmaes).
NEGLIGIBLE = 0.003
#: The suffix of the claim asked on the parameter targets alone.
PARAMETER = "parameter targets"
#: What the claims table shows (the report's and the page's note under it).
CLAIMS_NOTE = (
    "Each claim re-asked over the board's instances: per instance the mean over its "
    "(condition, seed) runs of the paired difference in ECDF area (side a - side b), "
    "the mean over instances, 95 % interval from a two-level bootstrap (instances, "
    "then each instance's runs, with replacement); best vs fifth and first vs second "
    "rank the solvers by mean area over the tier's conditions pooled (the parameter-"
    "targets claim by their area over parameter targets alone); global vs local "
    "is without a prior. Left out: the claim asked again without the top solver of "
    "its leading side. Fragile: either interval reaches 0, or either difference is under "
    f"{NEGLIGIBLE:g} of area (negligible: less than one target in 24 reached with half the "
    "evaluations).")


def nested_bootstrap(cells: Sequence[Sequence[float]], seed: int,
                     n: int = N_RESAMPLES) -> tuple[float, float, float]:
    """Mean over instances of each instance's mean cell value, and its 95 % percentile
    interval from ``n`` two-level resamples (instances with replacement, then each drawn
    instance's cells with replacement); nan bounds for fewer than two instances."""
    cells = [np.asarray(c, float) for c in cells if len(c)]
    if not cells:
        return math.nan, math.nan, math.nan
    est = math.fsum(float(c.mean()) for c in cells) / len(cells)
    k = len(cells)
    if k < 2:
        return est, math.nan, math.nan
    rng = np.random.default_rng(seed)
    pick = rng.integers(k, size=(n, k))       # the instances of each resample
    vals = np.empty((n, k))
    for i, c in enumerate(cells):              # the cells of every draw of instance i
        where = pick == i
        m = int(where.sum())
        if m:
            vals[where] = c[rng.integers(c.size, size=(m, c.size))].mean(axis=1)
    stat = vals.mean(axis=1)
    a = (1.0 - CONFIDENCE) / 2.0
    lo, hi = np.quantile(stat, [a, 1.0 - a])
    return est, float(lo), float(hi)


@dataclass(frozen=True)
class Claim:
    """One claim of one (track, tier), by instance: side ``a`` minus side ``b`` in mean ECDF
    area (``diff``: estimate, 95 % interval over instances), and the same without the
    solver ``without`` (``without_diff``; None where too few solvers remain).  ``ahead``:
    the instances on which side ``a``'s mean area is above side ``b``'s; ``areas``: each
    side's mean area over instances (the paired cells)."""

    track: str
    tier: int
    claim: str
    a: tuple[str, ...]
    b: tuple[str, ...]
    instances: int
    diff: tuple[float, float, float]
    without: str
    without_a: tuple[str, ...] = ()
    without_b: tuple[str, ...] = ()
    without_diff: tuple[float, float, float] | None = None
    ahead: int = 0
    areas: tuple[float, float] = (math.nan, math.nan)

    @property
    def holds(self) -> bool:
        """Side ``a`` ahead on instances: the interval lies above 0 and the difference is
        not negligible (:data:`NEGLIGIBLE`)."""
        return bool(self.diff[1] > 0 and self.diff[0] >= NEGLIGIBLE)

    @property
    def fragile(self) -> bool:
        """The interval reaches 0 (or is undefined), or the claim fails without the top
        solver (:attr:`verdict`)."""
        return self.verdict != "holds"

    @property
    def verdict(self) -> str:
        if not (math.isfinite(self.diff[1]) and self.diff[1] > 0):
            return "fragile: the interval over instances reaches 0"
        if self.diff[0] < NEGLIGIBLE:
            return f"fragile: negligible, {self.diff[0]:+.4f} is under {NEGLIGIBLE:g}"
        if self.without_diff is None:
            return "fragile: too few solvers to ask it without " + self.without
        if not self.without_diff[1] > 0:
            return f"fragile: without {self.without} the interval reaches 0"
        if self.without_diff[0] < NEGLIGIBLE:
            return (f"fragile: without {self.without} negligible, "
                    f"{self.without_diff[0]:+.4f} is under {NEGLIGIBLE:g}")
        return "holds"


def _cells(recs: list[dict], a: Sequence[str], b: Sequence[str], kinds: str = "fp"
           ) -> list[list[tuple[float, float]]]:
    """Per instance, the paired mean areas (of ``a``, of ``b``; over the targets of
    ``kinds``) of its cells that every solver of both sides ran."""
    runs: dict[str, dict[tuple[str, int], dict[str, float]]] = defaultdict(
        lambda: defaultdict(dict))
    for r in recs:
        inst = instance(r["case"])
        runs[inst.name][(inst.group[1], int(r["seed"]))][r["solver"]] = run_area(r, kinds)
    out = []
    for inst in sorted(runs):
        pairs = [(math.fsum(v[s] for s in a) / len(a), math.fsum(v[s] for s in b) / len(b))
                 for _, v in sorted(runs[inst].items()) if set(a) | set(b) <= set(v)]
        if pairs:
            out.append(pairs)
    return out


def _nth(rank: int) -> str:
    """``5th``, ``2nd``."""
    return str(rank) + {1: "st", 2: "nd", 3: "rd"}.get(rank, "th")


def _ranked(recs: list[dict], kinds: str = "fp") -> list[str]:
    per: dict[str, list[float]] = defaultdict(list)
    for r in recs:
        per[r["solver"]].append(run_area(r, kinds))
    mean = {s: math.fsum(v) / len(v) for s, v in per.items()}
    return sorted(mean, key=lambda s: (-np.nan_to_num(mean[s], nan=-1.0), s))


@dataclass(frozen=True)
class _Diff:
    """Side ``a`` - side ``b`` over instances: the estimate and its interval, and per
    instance the two sides' mean areas."""

    diff: tuple[float, float, float]
    means: tuple[tuple[float, float], ...]

    def claim(self, track, tier, what, a, b, without, wa=(), wb=(),
              wd: _Diff | None = None) -> Claim:
        n = len(self.means)
        areas = tuple(math.fsum(m[k] for m in self.means) / n if n else math.nan
                      for k in (0, 1))
        return Claim(track, tier, what, a, b, n, self.diff, without, wa, wb,
                     None if wd is None else wd.diff, sum(x > y for x, y in self.means),
                     areas)

    def flipped(self) -> _Diff:
        """Side ``b`` - side ``a``."""
        return _Diff((-self.diff[0], -self.diff[2], -self.diff[1]),
                     tuple((y, x) for x, y in self.means))


def _diff(track: str, tier: int, what: str, recs: list[dict], a, b, kinds: str = "fp"
          ) -> _Diff:
    cells = _cells(recs, a, b, kinds)
    seed = group_seed(track, "by-instance", tier, what, ",".join(a), ",".join(b))
    return _Diff(nested_bootstrap([[x - y for x, y in c] for c in cells], seed),
                 tuple((math.fsum(x for x, _ in c) / len(c), math.fsum(y for _, y in c) / len(c))
                       for c in cells))


def _ranking_claim(track, tier, what, recs, ranked, i, j, kinds: str = "fp") -> Claim | None:
    """``ranked[i]`` vs ``ranked[j]``, and without ``ranked[i]`` (the next pair down)."""
    if len(ranked) <= j:
        return None
    a, b = (ranked[i],), (ranked[j],)
    d = _diff(track, tier, what, recs, a, b, kinds)
    rest = ranked[:i] + ranked[i + 1:]
    if len(rest) <= j:
        return d.claim(track, tier, what, a, b, ranked[i])
    wa, wb = (rest[i],), (rest[j],)
    wd = _diff(track, tier, what, [r for r in recs if r["solver"] != ranked[i]], wa, wb,
               kinds)
    return d.claim(track, tier, what, a, b, ranked[i], wa, wb, wd)


def claims(records: list[dict], rank: int = FIFTH, condition: str = "no-prior",
           scope_of: Callable[[list[str]], Mapping[str, str]] = registered_scopes
           ) -> list[Claim]:
    """Every claim of the board by instance (see the module docstring), per track and tier:
    best vs ``rank``-th and first vs second over the tier's conditions pooled, then global
    vs local under ``condition`` (where both groups have solvers; scopes from
    ``scope_of``)."""
    by: dict[tuple[str, int], list[dict]] = defaultdict(list)
    for (track, tier, _), recs in groups(records).items():
        by[(track, tier)] += recs
    solvers = sorted({r["solver"] for r in records})
    scopes = scope_of(solvers) if solvers else {}
    out: list[Claim] = []
    for (track, tier), recs in by.items():
        ranked = _ranked(recs)
        for what, i, j in ((f"best vs {_nth(rank)}", 0, rank - 1), ("first vs second", 0, 1)):
            c = _ranking_claim(track, tier, what, recs, ranked, i, j)
            if c is not None:
                out.append(c)
        # the same on the parameter targets alone: the fitness ladder's targets outnumber
        # them (v3: 21 to 3), so the claim above mostly measures fitness
        if any(math.isfinite(run_area(r, "p")) for r in recs):
            c = _ranking_claim(track, tier, f"best vs {_nth(rank)}, {PARAMETER}", recs,
                               _ranked(recs, "p"), 0, rank - 1, "p")
            if c is not None:
                out.append(c)
        nop = [r for r in recs if instance(r["case"]).group[1] == condition]
        glob = tuple(s for s in _ranked(nop) if scopes.get(s) == "global")
        loc = tuple(s for s in _ranked(nop) if scopes.get(s) == "local")
        if not glob or not loc:
            continue
        what = f"global vs local, {condition}"
        d = _diff(track, tier, what, nop, glob, loc)
        top = glob[0] if d.diff[0] >= 0 else loc[0]      # the leading group's best solver
        wa = tuple(s for s in glob if s != top)
        wb = tuple(s for s in loc if s != top)
        wd = None
        if wa and wb:
            wd = _diff(track, tier, what, [r for r in nop if r["solver"] != top], wa, wb)
        # the claim's side a is the leading group: global if ahead, else local
        if d.diff[0] >= 0:
            out.append(d.claim(track, tier, what, glob, loc, top, wa, wb, wd))
        else:
            out.append(d.flipped().claim(
                track, tier, what.replace("global vs local", "local vs global"), loc, glob,
                top, wb, wa, None if wd is None else wd.flipped()))
    return out


def _ci(v: tuple[float, float, float] | None) -> str:
    if v is None:
        return "-"
    lo, hi = (f"{x:+.3f}" if math.isfinite(x) else "-" for x in v[1:])
    return f"{v[0]:+.3f} [{lo}, {hi}]"


def claim_rows(cs: list[Claim], track: str) -> list[dict[str, object]]:
    """The report's table of ``track``'s claims: text cells (solver names, escaped by the
    table writer) and ``(text, value)`` number cells."""
    def side(s: Sequence[str]) -> str:
        return ", ".join(s) if len(s) <= 3 else f"{s[0]} + {len(s) - 1} more"
    return [{"tier": c.tier, "claim": c.claim, "a": side(c.a), "b": side(c.b),
             "instances": c.instances,
             "area a - b [95 % CI over instances]": (_ci(c.diff), c.diff[0]),
             "left out": c.without,
             "then a / b": (f"{side(c.without_a)} / {side(c.without_b)}"
                            if c.without_diff else "-"),
             "then a - b": (_ci(c.without_diff), None if c.without_diff is None
                            else c.without_diff[0]),
             "verdict": c.verdict} for c in cs if c.track == track]


def fragile_line(cs: list[Claim], track: str, name: Callable[[str], str] = str) -> str:
    """One sentence: which of ``track``'s claims hold by instance and which are fragile
    (``name`` formats a solver's name: :func:`~ema_bench.escape.markdown` for Markdown)."""
    mine = [c for c in cs if c.track == track]
    if not mine:
        return "No claim to resample: fewer than two solvers per tier."
    held = [f"{c.claim} on tier {c.tier}" for c in mine if not c.fragile]
    weak = [f"{c.claim} on tier {c.tier} "
            f"({c.verdict.removeprefix('fragile: ').replace(c.without, name(c.without))})"
            for c in mine if c.fragile]
    return ("By instance: " + ("holds: " + "; ".join(held) if held else "no claim holds")
            + (". FRAGILE: " + "; ".join(weak) if weak else "") + ".")


#: Both sides' mean areas above this: the tier's targets are nearly all reached by both.
CEILING = 0.9


def separation_lines(cs: list[Claim], records: list[dict], track: str, rank: int = FIFTH,
                     name: Callable[[str], str] = str) -> list[str]:
    """Per tier of ``track`` in ``records``: whether its best and ``rank``-th solvers are
    separated by instance (claims ``cs``, :func:`claims` of ``records``), and where they are
    not, why, in a sentence (the issue's "or the report says plainly why a tier cannot
    separate them")."""
    nth = _nth(rank)
    tiers = sorted({t for tr, t, _ in groups(records) if tr == track})
    by = {c.tier: c for c in cs if c.track == track and c.claim == f"best vs {nth}"}
    out = []
    for t in tiers:
        c = by.get(t)
        if c is None:
            out.append(f"Tier {t}: fewer than {rank} solvers ran it; best vs {nth} is not "
                       "asked.")
            continue
        a, b = name(c.a[0]), name(c.b[0])
        if c.holds:
            out.append(f"Tier {t}: best ({a}) and {nth} ({b}) separated by instance, "
                       f"{_ci(c.diff)}; {a} ahead on {c.ahead} of {c.instances} instances.")
            continue
        why = (f"Tier {t} cannot separate its best ({a}, mean area {c.areas[0]:.3f}) and "
               f"{nth} ({b}, {c.areas[1]:.3f}) solvers by instance: ")
        if c.instances < 2:
            why += (f"the board has {c.instances} instance of it that both ran, and one "
                    "instance gives no interval over instances.")
        elif c.diff[1] > 0:
            why += (f"{a} is ahead, {_ci(c.diff)}, by less than {NEGLIGIBLE:g} of area: both "
                    "reach the same targets at practically the same cost.")
        else:
            why += (f"{b} is level with or ahead of {a} on {c.instances - c.ahead} of the "
                    f"{c.instances} instances, so the instances disagree and the interval "
                    f"over them, {_ci(c.diff)}, reaches 0")
            if min(c.areas) > CEILING:
                why += (f"; both reach nearly every target early (mean areas above "
                        f"{CEILING:g}): the tier's targets leave little room between them")
            why += "."
        out.append(why)
    return out
