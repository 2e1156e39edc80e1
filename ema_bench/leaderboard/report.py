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
from ..suite import instance_names
from .anytime import AnytimeScore, SanityScore, anytime_scores, sanity_scores
from .derive import derived
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


def ranking_rows(scores: list[AnytimeScore], track: str) -> list[dict[str, object]]:
    """The ranking table of a track (non-sanity instances), rank by ECDF area: one dict per
    solver, display strings and the raw values for sorting (``(text, value)`` pairs)."""
    rows = []
    for rank, s in enumerate((s for s in scores if s.track == track and s.cases == ALL), 1):
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
    order = {c: i for i, c in enumerate(instance_names())}   # the suite's order, then others
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
    written = []
    for track in dict.fromkeys(r["track"] for r in records):
        rows = [s for s in scores if s.track == track]
        csv_path = out / f"leaderboard_{track}.csv"
        flat = [s.row() for s in rows]
        fields = list(dict.fromkeys(k for r in flat for k in r))
        with open(csv_path, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=fields)
            w.writeheader()
            for r in flat:
                w.writerow({k: csv_value(v) for k, v in r.items()})
        md = [f"# Leaderboard, {track} track", "", header, "", _track_note(track), "",
              "## Ranking: ECDF area over every (instance, target) pair", "",
              "Instances: every one but the sanity case. Targets: fitness within "
              "1e-1 .. 1e-4 of the instance's f*-to-nominal gap (f0.1 .. f0.0001) and the "
              "best-so-far point within 10, 3, 1 % of every fault's range (p0.1 .. p0.01). "
              "Area: a target reached at evaluation h of budget B counts (ln B - ln h) / ln B, "
              "a miss 0; mean over runs and targets, 95 % bootstrap interval over runs. "
              "Precision: (best fitness - f*) / (f_nominal - f*), median over runs.", "",
              *markdown_table(ranking_rows(scores, track)), "",
              "## Sanity: the healthy actuator (nominal case, not ranked)", "",
              *markdown_table(sanity_rows(sanity, track)), "",
              "## ECDF area per instance", "",
              *markdown_table(instance_rows(scores, track)), ""]
        md_path = out / f"leaderboard_{track}.md"
        md_path.write_text("\n".join(md))
        written += [md_path, csv_path]
    return written


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
    lines = ["# The paper's Tables 2-5 beside ours", "", header, "",
             "Ours: reference track (detailed model makes the data, monitor model is fitted), "
             "median estimate over seeds; accuracy is the paper's `1 - |est - true| / |true|`, "
             "range error is `|est - true| / (upper - lower)` (defined when the truth is 0).", ""]
    by = defaultdict(list)
    for r in records:
        if r["track"] == "reference":
            by[(r["case"], r["solver"])].append(r)
    for case, spec in CASES.items():
        ref_scores = [s for s in scores if s.track == "reference" and s.case == case]
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


def load_paper_results() -> dict:
    """The paper's reported numbers (shipped with the package, copied from the design's
    ``paper_results.json``)."""
    return json.loads(resources.files("ema_bench").joinpath("paper_results.json").read_text())
