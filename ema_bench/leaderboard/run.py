"""One leaderboard run: tasks -> records on disk -> scores, tables and plots."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path

from .executors import execute
from .figures import (
    convergence_plot,
    ecdf_plot,
    landscape,
    landscape_plot,
    overlay_plot,
    valley_rise,
)
from .report import load_paper_results, write_leaderboards, write_paper_tables
from .scores import score_records
from .store import RUNS_FILE, RunStore, read_records, run_identity
from .tasks import Task, make_tasks


def run_tasks(tasks: list[Task], out: Path, executor: str = "processes",
              workers: int | None = None, scheduler: str | None = None,
              progress: bool = True) -> int:
    """Run what is not yet in ``out/runs.jsonl``, appending each record as it finishes.

    Returns how many runs were executed now (0 when everything was already done)."""
    with RunStore(out / RUNS_FILE) as store:
        todo = [t for t in tasks if t.identity not in store.done]
        for rec in execute(todo, executor, workers, scheduler, progress):
            store.append(rec)
    return len(todo)


def select(records: list[dict], tasks: list[Task]) -> list[dict]:
    """The current-model records of these tasks (same key, budget and root seed), in task
    order."""
    order = {t.identity: i for i, t in enumerate(tasks)}
    recs = [r for r in records if run_identity(r) in order]
    return sorted(recs, key=lambda r: order[run_identity(r)])


def write_outputs(records: list[dict], out: Path, command: str, plots: bool = True,
                  landscape_n: int = 40, expected: int | None = None) -> dict[str, object]:
    """Tables and plots of ``records`` under ``out``; returns a summary."""
    partial = (f" **PARTIAL: {len(records)} of the sweep's {expected} runs are done; rerun "
               f"the sweep's command (without --report-only) to resume.**"
               if expected and len(records) < expected else "")
    header = (f"Produced by `{command}`: {len(records)} runs.{partial} "
              "Success = every parameter within 1 % of its range of the truth; "
              "ERT = evaluations summed over runs (failures at their budget) / successes.")
    scores = score_records(records)
    written = write_leaderboards(scores, out, header)
    written.append(write_paper_tables(records, scores, out, header, load_paper_results()))
    summary: dict[str, object] = {}
    if plots:
        for track in dict.fromkeys(r["track"] for r in records):
            p = out / f"convergence_{track}.png"
            convergence_plot(records, track, p)
            written.append(p)
        p = out / "ecdf.png"
        ecdf_plot(records, p)
        written.append(p)
        # one fit shown before/after: the best solver's run on the hardest paper case
        ref = [r for r in records if r["track"] == "reference"] or records
        full = [r for r in ref if r["case"] == "full"] or ref
        p = out / "fit_overlay.png"
        overlay_plot(min(full, key=lambda r: r["fitness"]), p)
        written.append(p)
        if landscape_n:
            land = landscape(landscape_n)
            p = out / "figure5_landscape.png"
            landscape_plot(land, p)
            written.append(p)
            summary["figure5_valley_rise"] = {"raw": valley_rise(land["raw"]),
                                              "normalised": valley_rise(land["normalised"])}
    summary["files"] = [str(p) for p in written]
    (out / "summary.json").write_text(json.dumps(
        {"command": command, "runs": len(records), **summary,
         "scores": [s.row() for s in scores]}, indent=1, default=str))
    return summary


def leaderboard(solvers, cases, tracks, seeds: int, budget: int, out: Path,
                executor: str = "processes", workers: int | None = None,
                scheduler: str | None = None, shard: tuple[int, int] = (0, 1),
                root_seed: int = 0, plots: bool = True, progress: bool = True,
                command: str | None = None, landscape_n: int = 40,
                run: bool = True) -> dict[str, object]:
    """Run (or resume) a leaderboard and write its outputs.  See ``ema-bench leaderboard``.

    With ``run=False`` nothing runs: the outputs are rebuilt from the records on disk, and
    the header says how many of the sweep's runs they cover."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tasks = make_tasks(solvers, cases, tracks, seeds, budget, root_seed, shard)
    ran = run_tasks(tasks, out, executor, workers, scheduler, progress) if run else 0
    records = select(read_records(out / RUNS_FILE), tasks)
    if not records:
        raise ValueError(f"no records of this sweep in {out / RUNS_FILE}")
    command = command or "ema-bench " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    summary = write_outputs(records, out, command, plots=plots, landscape_n=landscape_n,
                            expected=len(tasks))
    return {"ran": ran, "runs": len(records), **summary}
