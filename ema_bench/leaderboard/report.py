"""Tables: ``leaderboard_<track>.md`` / ``.csv`` (anytime scores, :mod:`.anytime`) and
``paper_tables.md`` (the paper's Tables 2-5 beside ours)."""

from __future__ import annotations

import csv
import json
import math
from collections import defaultdict
from importlib import resources
from pathlib import Path

import numpy as np

from ..escape import csv_value, markdown
from ..faults import CASES, FAULT_NAMES, FAULT_UNITS
from ..suites import board_suite, case_order, find
from . import by_instance, scaling
from .anytime import (
    FITNESS_TARGETS,
    AnytimeScore,
    SanityScore,
    anytime_scores,
    hits,
    sanity_scores,
)
from .derive import derived
from .scaling import GlobalLocal, ScalingPoint
from .scores import ALL, SolverScore


def _fmt(v: float, digits: int = 3) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    if isinstance(v, float) and math.isinf(v):
        return "inf"
    return f"{v:.{digits}g}"


def _ci(v: tuple[float, float, float], digits: int = 3) -> str:
    """``value [lo, hi]``."""
    return f"{_fmt(v[0], digits)} [{_fmt(v[1], digits)}, {_fmt(v[2], digits)}]"


#: The ERT columns of the ranking table (all of them are in the CSV).
ERT_COLUMNS = ("f0.01", "f0.0001", "p0.01")


def ranking_rows(scores: list[AnytimeScore], track: str, cases: str = ALL
                 ) -> list[dict[str, object]]:
    """The ranking table of a track (non-sanity instances; ``cases``: an emafdi-v2 tier and
    condition, :func:`.scaling.group_label`), rank by ECDF area: one dict per solver, display
    strings and the raw values for sorting (``(text, value)`` pairs)."""
    rows = []
    for rank, s in enumerate((s for s in scores if s.track == track and s.cases == cases), 1):
        b10, b = sorted(s.precision)[0], sorted(s.precision)[-1]
        row: dict[str, object] = {
            "rank": rank, "solver": s.solver,
            "ECDF area [95 % CI]": (_ci(s.area), s.area[0]),
            "fitness area": s.fitness_area, "parameter area": s.parameter_area}
        for k in ERT_COLUMNS:
            row[f"ERT {k} [95 % CI]"] = (_ci(s.ert.get(k, (math.nan,) * 3)),
                                         s.ert.get(k, (math.nan,))[0])
        row["reached p0.01"] = s.hit_rate.get("p0.01", math.nan)
        row[f"median precision at {b10}"] = s.precision[b10][1]
        row[f"median precision at {b}"] = s.precision[b][1]
        row["runs"] = s.runs
        row["failed"] = s.errors
        rows.append(row)
    return rows


def _cell(v: object) -> str:
    """A table cell: our formatted numbers as they are, any text (names) escaped."""
    if isinstance(v, tuple):
        return v[0]
    if isinstance(v, float):
        return _fmt(v)
    return markdown(v)


def markdown_table(rows: list[dict[str, object]]) -> list[str]:
    """Rows as a Markdown table; headers and text cells escaped (:func:`~ema_bench.escape.
    markdown`): names come from plugins and records."""
    if not rows:
        return ["(no runs)"]
    cols = list(rows[0])
    return (["| " + " | ".join(markdown(c) for c in cols) + " |", "|" + "---|" * len(cols)]
            + ["| " + " | ".join(_cell(r[c]) for c in cols) + " |" for r in rows])


def sanity_rows(sanity: list[SanityScore], track: str) -> list[dict[str, object]]:
    return [{"solver": s.solver, "stayed within 1 % of nominal": f"{s.stayed}/{s.runs}",
             "median largest range error": s.median_max_range_error}
            for s in sanity if s.track == track]


def instance_rows(scores: list[AnytimeScore], track: str) -> list[dict[str, object]]:
    """Solvers x instances: the ECDF area of each solver on each instance."""
    per = [s for s in scores if s.track == track and s.cases != ALL]
    order = case_order()   # the suites' order, then others
    cases = sorted(dict.fromkeys(s.cases for s in per), key=lambda c: (order.get(c, 1e9), c))
    solvers = [s.solver for s in scores if s.track == track and s.cases == ALL]
    area = {(s.solver, s.cases): s.area[0] for s in per}
    return [{"solver": sv, **{c: area.get((sv, c), math.nan) for c in cases}}
            for sv in solvers]


def write_leaderboards(records: list[dict], out: Path, header: str) -> list[Path]:
    """Per track: ``leaderboard_<track>.md`` (ranking by ECDF area, the sanity row, per
    instance areas) and ``leaderboard_<track>.csv`` (every anytime score, aggregate and per
    instance); returns the paths written."""
    scores = anytime_scores(records, per_case=True)
    sanity = sanity_scores(records)
    v2 = board_suite(records).grouped
    # a grouped suite (emafdi-v2): every (tier, condition) scored apart too (CSV rows
    # cases=t7@no-prior)
    grouped = scaling.group_scores(records) if v2 else []
    written = []
    for track in dict.fromkeys(r["track"] for r in records):
        rows = [s for s in scores if s.track == track] + \
            [s for s in grouped if s.track == track]
        csv_path = out / f"leaderboard_{track}.csv"
        flat = [s.row() for s in rows]
        fields = list(dict.fromkeys(k for r in flat for k in r))
        with open(csv_path, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=fields)
            w.writeheader()
            for r in flat:
                w.writerow({k: csv_value(v) for k, v in r.items()})
        md_path = out / f"leaderboard_{track}.md"
        md = [f"# Leaderboard, {track} track", "", header, "", _track_note(track), ""]
        md += v2_markdown(records, grouped, track) if v2 else [
            "## Ranking: ECDF area over every (instance, target) pair", "",
            "Instances: every one but the sanity case. Targets: fitness within "
            "1e-1 .. 1e-4 of the instance's f*-to-nominal gap (f0.1 .. f0.0001) and the "
            "best-so-far point within 10, 3, 1 % of every fault's range (p0.1 .. p0.01). "
            f"{AREA_NOTE} Precision: (best fitness - f*) / (f_nominal - f*), median over runs.",
            "", *markdown_table(ranking_rows(scores, track)), "",
            "## Sanity: the healthy actuator (nominal case, not ranked)", "",
            *markdown_table(sanity_rows(sanity, track)), "",
            "## ECDF area per instance", "",
            *markdown_table(instance_rows(scores, track)), ""]
        md_path.write_text("\n".join(md))
        written += [md_path, csv_path]
    return written


# --- emafdi-v2: tiers x conditions, scaling, global vs local, saturation --------------------
AREA_NOTE = ("Area: a target reached at evaluation h of budget B counts (ln B - ln h) / ln B, "
             "a miss 0; mean over runs and targets, 95 % bootstrap interval over runs.")


def group_heading(tier: int, cond: str, records: list[dict]) -> str:
    """``Tier 7, no-prior (dimension 7, budget 8750, 20 instances)``."""
    budgets = sorted({r["budget"] for r in records})
    n = len({r["case"] for r in records})
    return (f"Tier {tier}, {cond} (dimension {tier}, budget "
            f"{', '.join(map(str, budgets))}, {n} instance{'s' if n != 1 else ''})")


def _power(p: float) -> str:
    """``1e-1``, ``1e-6``: a precision of the fitness ladder."""
    return f"{p:.0e}".replace("e-0", "e-")


def group_targets(tier: int, records: list[dict]) -> str:
    """What the targets of a (tier, condition) group are (its suite's ladders)."""
    suite = board_suite(records)
    with_f = any(hits(r).keys() & set(FITNESS_TARGETS) for r in records)
    ladder = suite.fitness_precisions
    fit = (f"fitness within {len(ladder)} precisions {_power(ladder[0])} .. "
           f"{_power(ladder[-1])} of the instance's f*-to-nominal gap and "
           if with_f else "no fitness targets (no shipped f* for these instances yet); ")
    scale = ("range" if suite.target_scales is None else
             "its noise-allowed scale (max(1 % of range, z sigma) / 1 %)")
    return (f"Targets: {fit}the best-so-far point within 10, 3, 1 % of {scale} of every "
            f"judged parameter (tier {tier}: {tier} parameters).")


def global_local_rows(rows: list[GlobalLocal], prior: list[GlobalLocal],
                      track: str) -> list[dict[str, object]]:
    """The global-vs-local table of a track: one row per tier (``prior``: the same
    comparison with the prior, for the last column)."""
    with_prior = {r.tier: r for r in prior if r.track == track}
    out = []
    for r in (r for r in rows if r.track == track):
        p = with_prior.get(r.tier)
        out.append({
            "tier": r.tier, "global solvers": ", ".join(r.global_solvers),
            "local solvers": ", ".join(r.local_solvers), "pairs": r.pairs,
            "global reached p0.01": (f"{r.global_hits}/{r.global_runs}",
                                     r.global_hits / r.global_runs),
            "local reached p0.01": (f"{r.local_hits}/{r.local_runs}",
                                    r.local_hits / r.local_runs),
            "global area": r.global_area, "local area": r.local_area,
            "area global - local [95 % CI]": (_ci(r.area_diff), r.area_diff[0]),
            "reached global - local [95 % CI]": (_ci(r.rate_diff), r.rate_diff[0]),
            "with the prior: area global - local": ((_ci(p.area_diff), p.area_diff[0]) if p
                                                    else ("-", None)),
            "best global": f"{r.best_global[0]} {_fmt(r.best_global[1])}",
            "best local": f"{r.best_local[0]} {_fmt(r.best_local[1])}"})
    return out


def scaling_rows(points: list[ScalingPoint], track: str) -> list[dict[str, object]]:
    """ERT to the 1 % parameter target per solver and condition (rows) and tier (columns),
    with the runs that reached it."""
    tiers = sorted({p.dim for p in points if p.track == track})
    by: dict[tuple[str, str], dict[int, ScalingPoint]] = defaultdict(dict)
    for p in points:
        if p.track == track:
            by[(p.solver, p.condition)][p.dim] = p
    out = []
    for (solver, cond), pts in sorted(by.items()):
        row: dict[str, object] = {"solver": solver, "condition": cond}
        for t in tiers:
            p = pts.get(t)
            row[f"tier {t}: ERT [95 % CI]"] = (_ci(p.ert), p.ert[0]) if p else ("-", None)
            row[f"tier {t}: reached"] = (f"{p.hits}/{p.runs}", p.hits / p.runs) if p \
                else ("-", None)
        out.append(row)
    return out


def v2_markdown(records: list[dict], grouped: list[AnytimeScore], track: str) -> list[str]:
    """The emafdi-v2 part of a track's leaderboard: the saturation check, global vs local
    without a prior (table and the answer), the ERT scaling table, and one ranking per tier
    and condition."""
    gl = scaling.global_vs_local(records)
    prior = scaling.global_vs_local(records, "prior")
    cs = by_instance.claims(records)
    md = ["## Saturation check", "",
          *(f"- {line}" for line in scaling.saturation_lines(records, grouped, track,
                                                               name=markdown)), "",
          "## Claims by instance", "", by_instance.fragile_line(cs, track, markdown), "",
          *(f"- {line}" for line in by_instance.separation_lines(cs, records, track,
                                                                 name=markdown)), "",
          by_instance.CLAIMS_NOTE, "",
          *markdown_table(by_instance.claim_rows(cs, track)), "",
          "## Global vs local search without a prior", "", scaling.answer(gl, track), "",
          "Groups: the scope each solver declares where it is registered (`ema-bench "
          "solvers`); in neither group: "
          + (", ".join(markdown(s) for s in sorted({s for r in gl if r.track == track
                                                    for s in r.others}))
             or "none") + ". Each (instance, seed) "
          "pair that every compared solver ran is one pair: the mean of each group's runs' "
          "ECDF areas (and of reaching the 1 % parameter target) on it, the difference "
          "global - local, 95 % bootstrap interval over the pairs.", "",
          *markdown_table(global_local_rows(gl, prior, track)), "",
          "## Scaling: ERT to the 1 % parameter target against dimension", "",
          "ERT (COCO): evaluations summed over runs (a run that reached the target counted "
          "until it did, the others at their budget) over the runs that reached it; "
          "interval: the bootstrap interval of the hit rate per evaluation, inverted. Plot: "
          "`ert_scaling.png`.", "",
          *markdown_table(scaling_rows(scaling.scaling_points(grouped), track)), ""]
    for (tr, tier, cond), recs in scaling.groups(records).items():
        if tr != track:
            continue
        md += [f"## {group_heading(tier, cond, recs)}", "", group_targets(tier, recs) + " "
               + AREA_NOTE, "",
               *markdown_table(ranking_rows(grouped, track, scaling.group_label(tier, cond))),
               ""]
    md += ["Per-instance scores: `leaderboard_" + track + ".csv` (rows by case; rows "
           "`t<tier>@<condition>` are the tables above).", ""]
    return md


def _track_note(track: str) -> str:
    if track == "twin":
        return ("Twin track: the measured traces come from the monitor model itself plus sensor "
                "noise, so the truth is the optimum (pure optimisation).")
    return ("Reference track: the measured traces come from the detailed reference model "
            "(three-phase BLDC with hysteresis control at 1 us): model-form mismatch, as in the "
            "paper.")


def write_paper_tables(records: list[dict], scores: list[SolverScore], out: Path, header: str,
                       paper: dict | None) -> Path:
    """The paper's Tables 2-5 beside ours (reference track, medians over seeds) for the
    paper GA and for the best solver of each case."""
    seeds = len({r["seed"] for r in records if r["track"] == "reference"})
    over = "the estimate of its one seed" if seeds == 1 else f"median estimate over {seeds} seeds"
    lines = ["# The paper's Tables 2-5 beside ours", "", header, "",
             "Ours: reference track (detailed model makes the data, monitor model is fitted), "
             f"{over}; accuracy is the paper's `1 - |est - true| / |true|`, "
             "range error is `|est - true| / (upper - lower)` (defined when the truth is 0).", ""]
    by = defaultdict(list)
    for r in records:
        if r["track"] == "reference":
            by[(paper_case(r["case"]), r["solver"])].append(r)
    for case, spec in CASES.items():
        ref_scores = [s for s in scores if s.track == "reference"
                      and paper_case(s.case) == case]
        if not ref_scores:
            continue
        best = ref_scores[0].solver
        table = paper["cases"].get(case) if paper else None
        lines += [f"## {case}" + (f" (paper Table {table['table']})" if table else ""), ""]
        solvers = ["paper-ga"] + ([best] if best != "paper-ga" else [])
        head = "| parameter | unit | true | paper estimate | paper acc % |"
        sep = "|---|---|---:|---:|---:|"
        for s in solvers:
            head += f" {markdown(s)} estimate | {markdown(s)} acc % | {markdown(s)} range err % |"
            sep += "---:|---:|---:|"
        lines += [head, sep]
        for j, n in enumerate(FAULT_NAMES):
            row = (f"| {n} | {FAULT_UNITS[n]} | {spec.faults[j]:g} | "
                   f"{_fmt(table['estimate'][n], 6) if table else '-'} | "
                   f"{_fmt(table['accuracy_pct'][n], 4) if table else '-'} |")
            for s in solvers:
                recs = by.get((case, s), [])
                if not recs:
                    row += " - | - | - |"
                    continue
                est = float(np.median([r["x"][n] for r in recs]))
                # re-derived from the final vector and the truth, never the claims
                acc = [a for a in (derived(r).accuracy[n] for r in recs) if a is not None]
                rerr = float(np.median([derived(r).range_error[n] for r in recs]))
                row += (f" {est:.6g} | {_fmt(float(np.median(acc)), 4) if acc else '-'} | "
                        f"{100 * rerr:.3g} |")
            lines.append(row)
        fit_truth = [r["fitness_at_truth"] for r in by.get((case, "paper-ga"), [])]
        if fit_truth:
            lines += ["", f"Fitness of the true vector on this track (model-form bias): "
                          f"median {np.median(fit_truth):.3g}."]
        lines.append("")
    path = out / "paper_tables.md"
    path.write_text("\n".join(lines))
    return path


def paper_case(case: str) -> str:
    """The paper case a run's case is: a v1 case as it is; an emafdi-v2 tier-4 case with the
    prior (v1's problem, bit for bit) by its instance (``small@prior`` -> ``small``;
    :attr:`~ema_bench.suites.base.Instance.paper_case`)."""
    inst = find(case)
    return case if inst is None else inst.paper_case


def load_paper_results() -> dict:
    """The paper's reported numbers (shipped with the package, copied from the design's
    ``paper_results.json``)."""
    return json.loads(resources.files("ema_bench").joinpath("paper_results.json").read_text())
