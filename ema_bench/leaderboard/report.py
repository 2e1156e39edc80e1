"""Tables: ``leaderboard_<track>.md`` / ``.csv`` and ``paper_tables.md``."""

from __future__ import annotations

import csv
import json
import math
from collections import defaultdict
from importlib import resources
from pathlib import Path

import numpy as np

from ..faults import CASES, FAULT_NAMES, FAULT_UNITS
from .scores import ALL, SolverScore


def _fmt(v: float, digits: int = 3) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    if isinstance(v, float) and math.isinf(v):
        return "inf"
    return f"{v:.{digits}g}"


def write_leaderboards(scores: list[SolverScore], out: Path, header: str) -> list[Path]:
    """One Markdown and one CSV leaderboard per track; returns the paths written."""
    written = []
    by_track: dict[str, list[SolverScore]] = defaultdict(list)
    for s in scores:
        by_track[s.track].append(s)
    for track, rows in by_track.items():
        csv_path = out / f"leaderboard_{track}.csv"
        with open(csv_path, "w", newline="") as fh:
            fields = list(rows[0].row())
            w = csv.DictWriter(fh, fieldnames=fields)
            w.writeheader()
            for s in rows:
                w.writerow({k: (v if not isinstance(v, float) else repr(v))
                            for k, v in s.row().items()})
        md = [f"# Leaderboard, {track} track", "", header, "",
              _track_note(track), ""]
        cases = [ALL] + [c for c in dict.fromkeys(s.case for s in rows) if c != ALL]
        for case in cases:
            md += [f"## {'all cases' if case == ALL else case}", "",
                   "| rank | solver | success | ERT (evals) | median evals to success | "
                   "median fitness | " + " | ".join(f"acc {n} %" for n in FAULT_NAMES) +
                   " | median wall s |",
                   "|---:|---|---:|---:|---:|---:|" + "---:|" * len(FAULT_NAMES) + "---:|"]
            for rank, s in enumerate((s for s in rows if s.case == case), 1):
                md.append(
                    f"| {rank} | {s.solver} | {s.successes}/{s.runs}"
                    f"{f' ({s.errors} failed)' if s.errors else ''} | {_fmt(s.ert)} | "
                    f"{_fmt(s.median_evals_to_success)} | {_fmt(s.median_fitness)} | "
                    + " | ".join(_fmt(s.accuracy[n], 4) for n in FAULT_NAMES)
                    + f" | {_fmt(s.median_wall_s)} |")
            md.append("")
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
            head += f" {s} estimate | {s} acc % | {s} range err % |"
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
                acc = [r["accuracy"][n] for r in recs if r["accuracy"][n] is not None]
                rerr = float(np.median([r["range_error"][n] for r in recs]))
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
