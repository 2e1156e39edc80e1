"""One leaderboard run: tasks -> records on disk -> scores, tables and plots."""

from __future__ import annotations

import functools
import shlex
import sys
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

from .. import jsonio
from ..escape import code_span
from ..faults import CASES
from ..records import schema
from ..suites import DEFAULT, board_suite
from ..suites.targets import targets_note
from ..suites.v1 import SANITY_CASES
from ..sweep.executors import Runner
from ..sweep.loop import run_sweep
from ..sweep.schema import opt, req
from ..trace_cache import MODEL_VERSION
from . import by_instance
from .anytime import anytime_scores
from .cost import board_cost, cost_line
from .derive import best_known_of
from .figures import (
    ECDF_KINDS,
    convergence_plot,
    ecdf_plot,
    ecdf_tiers_plot,
    ert_scaling_plot,
    landscape,
    landscape_plot,
    overlay_plot,
    valley_rise,
)
from .judge import admitted, is_suite_case, read_runs
from .page import write_page
from .report import load_paper_results, paper_case, write_leaderboards, write_paper_tables
from .run_store import (
    RUNS_FILE,
    RunStore,
    is_error,
    model_version,
    run_identity,
    unique,
)
from .scaling import (
    global_vs_local,
    group_scores,
    saturation_lines,
    scaling_points,
)
from .scores import score_records
from .tasks import Task, failure_record, make_tasks, run_task


def run_tasks(tasks: list[Task], out: Path, executor: str = "processes",
              workers: int | None = None, scheduler: str | None = None, quiet: bool = False,
              runner: Runner = run_task) -> int:
    """Run what is not yet in ``out/runs.jsonl`` on the sweep engine
    (:func:`~ema_bench.sweep.loop.run_sweep`), appending each record as it finishes.

    Runs recorded as errors are run again (the error may have been transient; a success
    supersedes the error record).  Returns how many runs this process executed."""
    with RunStore(out / RUNS_FILE) as store:
        return run_sweep(tasks, runner, [store], executor=executor, workers=workers,
                         scheduler=scheduler, on_error=failure_record,
                         label=f"leaderboard ({executor})", unit="run", quiet=quiet).ran


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


def overlay_run(finished: list[dict]) -> dict:
    """The run whose fit ``fit_overlay.png`` shows: the best fit of the hardest paper case
    (``full``; emafdi-v2: tier 4 with the prior, v1's problem: fitness values of other
    conditions weigh other tests and cannot be compared with it), reference track first."""
    ref = [r for r in finished if r["track"] == "reference"] or finished
    full = [r for r in ref if paper_case(r["case"]) == "full"] or ref
    return min(full, key=lambda r: r["fitness"])


#: ``OUT/summary.json`` of a board, by JSON type: checked before it is written, so the
#: published JSON Schema (``ema-bench schema leaderboard-summary``) and the file agree
#: (``targets``: boards written before issue 45 lack it; ``cost`` and ``best_vs_fifth``:
#: before issue 44's report).
SUMMARY_SCHEMA = {"command": req("str"), "runs": req("int"), "suite": req("str"),
                  "model_version": req("str"), "errors": req("list"), "targets": opt("str"),
                  "files": req("list"), "anytime": req("list"), "scores": req("list"),
                  "figure5_valley_rise": opt("dict"), "global_vs_local": opt("list"),
                  "saturation": opt("dict"), "claims_by_instance": opt("list"),
                  "best_vs_fifth": opt("dict"), "cost": opt("dict")}


def write_outputs(records: list[dict], out: Path, command: str, plots: bool = True,
                  landscape_n: int = 40, expected: int | None = None) -> dict[str, object]:
    """Tables and plots of ``records`` under ``out``; returns a summary."""
    partial = (f" **PARTIAL: {len(records)} of the sweep's {expected} runs are done; rerun "
               f"the sweep's command (without --report-only) to resume.**"
               if expected and len(records) < expected else "")
    failed = failures(records)
    errors = (f" {len(failed)} runs failed with an error (counted as unsuccessful at their "
              "budget; summary.json lists them)." if failed else "")
    suites = ", ".join(sorted({str(r.get("suite", DEFAULT.id)) for r in records}))
    ranked = [r for r in records if r["case"] not in SANITY_CASES]
    targets = targets_note(sorted({int(r.get("root_seed") or 0) for r in ranked}),
                           sum(best_known_of(r) is not None for r in ranked), len(ranked))
    # the models the records were made with (a compatible earlier version's show as such)
    versions = ", ".join(sorted({model_version(r) for r in records})) or MODEL_VERSION
    legacy = sum(1 for r in records if not is_error(r) and schema(r) < 2)
    off = [r for r in records if not is_suite_case(r["case"])]
    cost = board_cost(records)
    header = (f"Produced by {code_span(command)}: {len(records)} runs, suite {suites}, model "
              f"version {versions}. {targets}{partial}{errors} {cost_line(cost)}"
              + (f" LEGACY VIEW: {legacy} schema-1 records (hits bounded, not proven)."
                 if legacy else "")
              + (f" OFF-SUITE: {len(off)} runs of cases outside every suite "
                 f"({', '.join(sorted({str(r['case']) for r in off}))}): not judged, not a "
                 "ranking." if off else ""))
    # scores and the ECDF count failed runs as unsuccessful; what needs a fit, finished runs
    finished = [r for r in records if not is_error(r)]
    scores = score_records(records)
    written = write_leaderboards(records, out, header)
    written.append(write_paper_tables(finished, scores, out, header, load_paper_results()))
    summary: dict[str, object] = {"errors": failed, "targets": targets,
                                  "cost": {**asdict(cost), "wall_h": cost.wall_h}}
    images: list[Path] = []

    def draw(name: str, plot: Callable[..., None], *data: object) -> None:
        """``plot(*data, path)`` to ``out/name``, shown on the page."""
        images.append(out / name)
        plot(*data, images[-1])

    suite = board_suite(records)
    grouped = suite.grouped
    if plots and grouped:
        # a grouped suite (emafdi-v2): tiers have their own budgets; one ECDF per tier and
        # condition instead (emafdi-v3: fitness and parameter targets apart as well)
        for track in dict.fromkeys(r["track"] for r in records):
            for kinds in ("fp", "f", "p") if suite.split_ecdf else ("fp",):
                draw(f"ecdf_tiers_{track}{ECDF_KINDS[kinds][0]}.png",
                     functools.partial(ecdf_tiers_plot, kinds=kinds), records, track)
        draw("ert_scaling.png", ert_scaling_plot, records, scaling_points(group_scores(records)))
    elif plots:
        draw("ecdf.png", ecdf_plot, records)
    if plots and finished:
        # emafdi-v2: the paper cases are tier 4 with the prior (v1's problems, bit for bit)
        paper = [{**r, "case": paper_case(r["case"])} for r in finished]
        for track in dict.fromkeys(r["track"] for r in finished):
            if any(r["track"] == track and r["case"] in CASES
                   and r["case"] not in SANITY_CASES for r in paper):
                draw(f"convergence_{track}.png", convergence_plot, paper, track)
        draw("fit_overlay.png", overlay_plot, overlay_run(finished))
        if landscape_n:
            land = landscape(landscape_n)
            draw("figure5_landscape.png", landscape_plot, land)
            summary["figure5_valley_rise"] = {"raw": valley_rise(land["raw"]),
                                              "normalised": valley_rise(land["normalised"])}
    if grouped:   # the answers the v2 report states, for scripts
        grouped = group_scores(records)
        summary["global_vs_local"] = [asdict(r) for r in global_vs_local(records)]
        summary["saturation"] = {t: saturation_lines(records, grouped, t)
                                 for t in dict.fromkeys(r["track"] for r in records)}
        cs = by_instance.claims(records)
        summary["claims_by_instance"] = [{**asdict(c), "fragile": c.fragile,
                                          "verdict": c.verdict} for c in cs]
        summary["best_vs_fifth"] = {t: by_instance.separation_lines(cs, records, t)
                                    for t in dict.fromkeys(r["track"] for r in records)}
    written += images
    written.append(write_page(records, out / "leaderboard.html", header, images))
    summary["files"] = [str(p) for p in written]
    doc = {"command": command, "runs": len(records), "suite": suites,
           "model_version": board_suite(records).model_version, **summary,
           "anytime": [s.row() for s in anytime_scores(records)],
           "scores": [s.row() for s in scores]}
    jsonio.write_checked(out / "summary.json", doc, SUMMARY_SCHEMA, indent=1, default=str)
    return summary


def leaderboard(solvers, cases, tracks, seeds: int, budget: int, out: Path,
                executor: str = "processes", workers: int | None = None,
                scheduler: str | None = None, shard: tuple[int, int] = (0, 1),
                root_seed: int = 0, plots: bool = True, quiet: bool = False,
                command: str | None = None, landscape_n: int = 40,
                run: bool = True, runner: Runner = run_task, legacy: bool = False
                ) -> dict[str, object]:
    """Run (or resume) a leaderboard and write its outputs.  See ``ema-bench leaderboard``.

    With ``run=False`` nothing runs: the outputs are rebuilt from the records on disk, and
    the header says how many of the sweep's runs they cover.  Either way the records are
    admitted by :func:`~.judge.admitted` (what ``validate`` refuses stops the report;
    ``legacy``: schema-1 records are admitted, and the header says so)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tasks = make_tasks(solvers, cases, tracks, seeds, budget, root_seed, shard)
    ran = run_tasks(tasks, out, executor, workers, scheduler, quiet, runner) if run else 0
    # nothing is scored that validate refuses (a record edited or appended in the folder)
    wanted = {t.identity for t in tasks}
    lines = read_runs([out / RUNS_FILE]) if (out / RUNS_FILE).is_file() else []
    mine = [r for r in lines if run_identity(r) in wanted]
    # cases outside every suite (``--cases seeded``) are the user's own experiment: no suite
    # ranks them and the judge cannot re-derive them; the header says so
    records = select(admitted([r for r in mine if is_suite_case(r["case"])], "leaderboard",
                              complete=False, legacy=legacy)
                     + [r for r in mine if not is_suite_case(r["case"])], tasks)
    if not records:
        raise ValueError(f"no records of this sweep in {out / RUNS_FILE}")
    command = command or "ema-bench " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    summary = write_outputs(records, out, command, plots=plots, landscape_n=landscape_n,
                            expected=len(tasks))
    return {"ran": ran, "runs": len(records), **summary}
