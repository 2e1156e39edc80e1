"""One leaderboard run: tasks -> records on disk -> scores, tables and plots."""

from __future__ import annotations

import shlex
import sys
import time
from collections.abc import Iterator
from pathlib import Path

from .. import jsonio
from ..faults import CASES
from ..progress import Progress, progress
from ..suite import SANITY_CASES, SUITE_ID
from ..trace_cache import MODEL_VERSION
from .anytime import anytime_scores
from .claims import Claim, holder, try_claim
from .executors import Runner, execute
from .figures import (
    convergence_plot,
    ecdf_plot,
    landscape,
    landscape_plot,
    overlay_plot,
    valley_rise,
)
from .page import write_page
from .report import load_paper_results, write_leaderboards, write_paper_tables
from .scores import score_records
from .store import RUNS_FILE, RunStore, is_error, read_records, run_identity, unique
from .tasks import Task, make_tasks, run_task


def run_tasks(tasks: list[Task], out: Path, executor: str = "processes",
              workers: int | None = None, scheduler: str | None = None, quiet: bool = False,
              runner: Runner = run_task) -> int:
    """Run what is not yet in ``out/runs.jsonl``, appending each record as it finishes.

    Runs recorded as errors are run again (the error may have been transient; a success
    supersedes the error record).  Each task is claimed (:mod:`.claims`) just before it
    starts: a task another process claimed is left to it, and waited for at the end (run
    here after all if its claimer dies first), so sweeps sharing ``out`` split the work and
    run nothing twice.  Returns how many runs this process executed."""
    with RunStore(out / RUNS_FILE) as store:
        pending = [t for t in tasks if t.identity not in store.done]
        with progress(len(pending), f"leaderboard ({executor})", "run", quiet=quiet) as bar:
            ran = 0
            while pending:
                elsewhere: list[Task] = []
                ran += _run_claimed(pending, out, store, elsewhere, bar, executor, workers,
                                    scheduler, runner)
                pending = _wait_for_others(elsewhere, out, store, bar)
    return ran


def _run_claimed(tasks: list[Task], out: Path, store: RunStore, elsewhere: list[Task],
                 bar: Progress, executor: str, workers: int | None, scheduler: str | None,
                 runner: Runner) -> int:
    """Run the ``tasks`` this process can claim, appending their records; returns how
    many ran."""
    claims: dict[tuple, Claim] = {}
    ran = 0
    try:
        feed = _claimed(tasks, out, store, claims, elsewhere, bar)
        for rec in execute(feed, executor, workers, scheduler, runner):
            store.append(rec)
            claim = claims.pop(run_identity(rec), None)
            if claim is not None:
                claim.release()
            ran += 1
            bar.update(rec["key"] + (f" FAILED ({rec['error_type']})" if is_error(rec)
                                     else ""))
    finally:
        for claim in claims.values():
            claim.release()
    return ran


def _claimed(tasks: list[Task], out: Path, store: RunStore, claims: dict[tuple, Claim],
             elsewhere: list[Task], bar: Progress) -> Iterator[Task]:
    """The tasks this process claims, as the executor asks for them; those another process
    holds go to ``elsewhere``, those recorded meanwhile are dropped."""
    for t in tasks:
        claim = try_claim(out, t.identity, t.key)
        if claim is None:
            elsewhere.append(t)
            continue
        claims[t.identity] = claim   # from now on the caller releases it, come what may
        store.refresh()   # another sweep may have recorded it since we listed the work
        if store.settled(t.identity):
            claims.pop(t.identity).release()
            bar.update(f"{t.key} (run by another process)")
            continue
        yield t


def _wait_for_others(tasks: list[Task], out: Path, store: RunStore, bar: Progress,
                     poll_s: float = 0.5) -> list[Task]:
    """Wait until some of ``tasks`` (claimed by other processes) are released; return those
    still unrecorded (their claimer died: run them here).  Holds no claim while waiting, so
    two sweeps never wait for each other."""
    noted = False
    while tasks:
        store.refresh()
        for t in tasks:
            if store.settled(t.identity):
                bar.update(f"{t.key} (run by another process)")
        tasks = [t for t in tasks if not store.settled(t.identity)]
        if any(_is_free(out, t) for t in tasks):
            return tasks
        if tasks and not noted:
            who = sorted({holder(out, t.identity) for t in tasks} - {""})
            bar.note(f"waiting for {len(tasks)} runs claimed by another process "
                     f"({', '.join(who) or 'unknown'})")
            noted = True
        if tasks:
            time.sleep(poll_s)
    return tasks


def _is_free(out: Path, task: Task) -> bool:
    claim = try_claim(out, task.identity, task.key)
    if claim is None:
        return False
    claim.release()
    return True


def select(records: list[dict], tasks: list[Task]) -> list[dict]:
    """The current-model records of these tasks (same key, budget and root seed), one per
    run (:func:`~.store.unique`), in task order."""
    order = {t.identity: i for i, t in enumerate(tasks)}
    recs = [r for r in unique(records) if run_identity(r) in order]
    return sorted(recs, key=lambda r: order[run_identity(r)])


def failures(records: list[dict]) -> list[dict[str, object]]:
    """What went wrong in the runs recorded as errors, one short entry each."""
    return [{k: r[k] for k in ("key", "budget", "root_seed", "error_type", "error")}
            for r in records if is_error(r)]


def write_outputs(records: list[dict], out: Path, command: str, plots: bool = True,
                  landscape_n: int = 40, expected: int | None = None) -> dict[str, object]:
    """Tables and plots of ``records`` under ``out``; returns a summary."""
    partial = (f" **PARTIAL: {len(records)} of the sweep's {expected} runs are done; rerun "
               f"the sweep's command (without --report-only) to resume.**"
               if expected and len(records) < expected else "")
    failed = failures(records)
    errors = (f" {len(failed)} runs failed with an error (counted as unsuccessful at their "
              "budget; summary.json lists them)." if failed else "")
    suites = ", ".join(sorted({str(r.get("suite", SUITE_ID)) for r in records}))
    header = (f"Produced by `{command}`: {len(records)} runs, suite {suites}, model "
              f"version {MODEL_VERSION}.{partial}{errors}")
    # scores and the ECDF count failed runs as unsuccessful; what needs a fit, finished runs
    finished = [r for r in records if not is_error(r)]
    scores = score_records(records)
    written = write_leaderboards(records, out, header)
    written.append(write_paper_tables(finished, scores, out, header, load_paper_results()))
    summary: dict[str, object] = {"errors": failed}
    images: list[Path] = []
    if plots:
        p = out / "ecdf.png"
        ecdf_plot(records, p)
        images.append(p)
    if plots and finished:
        for track in dict.fromkeys(r["track"] for r in finished):
            if any(r["track"] == track and r["case"] in CASES
                   and r["case"] not in SANITY_CASES for r in finished):
                p = out / f"convergence_{track}.png"
                convergence_plot(finished, track, p)
                images.append(p)
        # one fit shown before/after: the best solver's run on the hardest paper case
        ref = [r for r in finished if r["track"] == "reference"] or finished
        full = [r for r in ref if r["case"] == "full"] or ref
        p = out / "fit_overlay.png"
        overlay_plot(min(full, key=lambda r: r["fitness"]), p)
        images.append(p)
        if landscape_n:
            land = landscape(landscape_n)
            p = out / "figure5_landscape.png"
            landscape_plot(land, p)
            images.append(p)
            summary["figure5_valley_rise"] = {"raw": valley_rise(land["raw"]),
                                              "normalised": valley_rise(land["normalised"])}
    written += images
    written.append(write_page(records, out / "leaderboard.html", header, images))
    summary["files"] = [str(p) for p in written]
    (out / "summary.json").write_text(jsonio.dumps(
        {"command": command, "runs": len(records), "suite": suites,
         "model_version": MODEL_VERSION, **summary,
         "anytime": [s.row() for s in anytime_scores(records)],
         "scores": [s.row() for s in scores]}, indent=1, default=str))
    return summary


def leaderboard(solvers, cases, tracks, seeds: int, budget: int, out: Path,
                executor: str = "processes", workers: int | None = None,
                scheduler: str | None = None, shard: tuple[int, int] = (0, 1),
                root_seed: int = 0, plots: bool = True, quiet: bool = False,
                command: str | None = None, landscape_n: int = 40,
                run: bool = True, runner: Runner = run_task) -> dict[str, object]:
    """Run (or resume) a leaderboard and write its outputs.  See ``ema-bench leaderboard``.

    With ``run=False`` nothing runs: the outputs are rebuilt from the records on disk, and
    the header says how many of the sweep's runs they cover."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tasks = make_tasks(solvers, cases, tracks, seeds, budget, root_seed, shard)
    ran = run_tasks(tasks, out, executor, workers, scheduler, quiet, runner) if run else 0
    records = select(read_records(out / RUNS_FILE), tasks)
    if not records:
        raise ValueError(f"no records of this sweep in {out / RUNS_FILE}")
    command = command or "ema-bench " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    summary = write_outputs(records, out, command, plots=plots, landscape_n=landscape_n,
                            expected=len(tasks))
    return {"ran": ran, "runs": len(records), **summary}
