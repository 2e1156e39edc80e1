"""``ema-bench leaderboard``: run solvers x instances x tracks x seeds and score them.

The instances are those of the suite (emafdi-v1: the paper's four cases and the seeded
s00..s19; 'ema-bench targets --show' lists them).  Scores are anytime, COCO-style: per solver
and track, the area under the ECDF of (instance, target) pairs reached against evaluations
(fitness targets from each instance's best-known optimum f*, parameter targets at 10/3/1 %
of range), ERT per target with bootstrap intervals, fixed-budget quantiles; the nominal case
is a sanity row outside the ranking.

Each run is appended to OUT/runs.jsonl as it finishes; rerunning the same command resumes
(finished runs are skipped, runs that failed with an error are tried again).  Several sweeps
may share one OUT at once (e.g. on two machines sharing a disk): each run is claimed by one
of them, runs once and is counted once.  A run that raises (a broken solver) or whose worker
dies is recorded as failed, scored as an unsuccessful run at its budget, and listed at the
end; the sweep goes on.  Writes leaderboard_<track>.md/.csv, paper_tables.md,
leaderboard.html (sortable tables and plots in one file), convergence, ECDF, fit-overlay and
Figure 5 plots under OUT (--suite emafdi-v2: rankings per tier x condition, an ECDF per tier and
condition, ERT to the 1 % parameter target against dimension, global vs local search without
a prior, the saturation check; docs/suite-v2.md).  Progress: a bar in a terminal, one line
per finished run otherwise (--quiet: none).

Examples::

    ema-bench leaderboard --quick --out /tmp/lb              # small, for CI
    ema-bench leaderboard --seeds 10 --budget 5000 --out leaderboards   # the full suite
    ema-bench leaderboard --executor dask --scheduler tcp://10.0.0.5:8786 --shard 0/4 --out lb
    ema-bench leaderboard --quick --check leaderboards/      # exit 1 on a regression
    ema-bench leaderboard --quick --check     # no checkout: the baseline installed with the wheel
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from ..leaderboard.run_store import RUNS_FILE, read_records
from ..registry import available_solvers
from ..suites import SUITES
from ..suites.base import Selection
from ..sweep.executors import EXECUTORS
from . import CLIError, print_result
from .args import (
    MAX_BUDGET,
    add_json,
    add_legacy,
    add_quiet,
    add_targets,
    check_output,
    count,
    option_list,
    seed_number,
    worker_count,
)

QUICK = {"seeds": 2}    # and the suite's quick cases and budget (emafdi-v1: 400)
DEFAULT = {"seeds": 10}


def _shard(text: str) -> tuple[int, int]:
    try:
        i, n = (int(v) for v in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected i/n, got {text!r}") from None
    return i, n


def register(sub: argparse._SubParsersAction) -> None:
    from ..suites import DEFAULT as DEFAULT_SUITE

    p = sub.add_parser("leaderboard",
                       help="compare solvers on the suite's instances x tracks x seeds")
    p.add_argument("--solvers", type=option_list, default=None,
                   help="comma-separated solver names (default: every registered solver)")
    p.add_argument("--cases", type=option_list, default=None,
                   help="comma-separated instances or groups: all (the suite, default), "
                        "paper (nominal,small,full,random), lhs (s00..s19), quick (paper "
                        "and s00..s03, the --quick default)")
    p.add_argument("--suite", choices=tuple(SUITES), default=DEFAULT_SUITE.id,
                   help="emafdi-v1 (default: the four faults, --cases), emafdi-v2 (tiers "
                        "x conditions, docs/suite-v2.md) or emafdi-v3 (v2's problems on "
                        "the targets the noise allows, docs/suite-v3.md)")
    p.add_argument("--tiers", type=option_list, default=None,
                   help="emafdi-v2: comma-separated tiers (default 4,7,12)")
    p.add_argument("--conditions", type=option_list, default=None,
                   help="emafdi-v2: comma-separated conditions (default prior,no-prior,"
                        "step-only)")
    p.add_argument("--per-tier", type=count(1, 1000), default=None,
                   help="emafdi-v2: the first N instances of each tier (default all)")
    p.add_argument("--budget-per-dim", type=count(1, 10**6), default=None,
                   help="emafdi-v2: evaluations per searched dimension (default 1250)")
    p.add_argument("--tracks", type=option_list, default=["reference", "twin"],
                   help="comma-separated tracks (default reference,twin)")
    p.add_argument("--seeds", type=count(1, 1000), default=None,
                   help=f"seeds per (solver, case, track) (default {DEFAULT['seeds']}, "
                        f"quick {QUICK['seeds']})")
    p.add_argument("--budget", type=count(1, MAX_BUDGET), default=None,
                   help="evaluations per run (default: the suite's; emafdi-v1 5000, quick "
                        "400; emafdi-v2 --budget-per-dim x the tier)")
    p.add_argument("--root-seed", type=seed_number, default=0, help="root seed of the sweep")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="output folder, required (with --check: a temp folder by default); "
                        "rerun with the same DIR to resume")
    p.add_argument("--executor", choices=EXECUTORS, default="processes",
                   help="serial, processes (local cores, default) or dask")
    p.add_argument("--workers", type=worker_count, default=None,
                   help="worker processes (default: cores)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of an existing Dask scheduler (default: a LocalCluster)")
    p.add_argument("--shard", type=_shard, default=(0, 1), metavar="i/n",
                   help="run only the i-th of n interleaved slices of the tasks (0-based)")
    p.add_argument("--quick", action="store_true",
                   help=f"small budget and seeds for CI ({QUICK['seeds']} seeds; emafdi-v1: "
                        "budget 400, the quick cases)")
    p.add_argument("--check", default=None, metavar="DIR", nargs="?", const="",
                   help="compare with the committed runs in DIR (and DIR/*/; no DIR: the "
                        "checkout's leaderboards/, else the quick baseline installed with "
                        "the package) of the same "
                        "budget and seeds, else larger-budget runs re-scored at this budget: "
                        "exit 1 when a solver's ECDF area is significantly lower (one-sided "
                        "Mann-Whitney per solver and track, family-wise level 5 %%)")
    p.add_argument("--no-plots", action="store_true", help="tables only")
    p.add_argument("--report-only", action="store_true",
                   help="run nothing: rebuild tables and plots from the records already in "
                        "OUT (e.g. after merging shards or to publish a partial sweep)")
    add_targets(p)
    add_legacy(p, "score")
    add_json(p, "a summary")
    add_quiet(p)


def run(args: argparse.Namespace) -> int:
    from ..leaderboard.check import compare, load_baseline
    from ..leaderboard.run import leaderboard, select
    from ..leaderboard.tasks import make_tasks

    if args.check is not None:
        from ..leaderboard.check import packaged_baseline, require_baseline

        # before any work: a check without a baseline used to run every task first
        folder = args.check or packaged_baseline()
        if folder is None:
            raise CLIError("--check: no folder given and no baseline installed with this "
                           "package (a checkout has leaderboards/)")
        args.check = str(require_baseline(folder))
    preset = QUICK if args.quick else DEFAULT
    seeds = args.seeds if args.seeds is not None else preset["seeds"]
    # the suite reads its own options (SuiteError, one line, for one it does not take)
    suite = SUITES[args.suite]
    cases = suite.sweep_cases(Selection(args.cases, args.tiers, args.conditions,
                                        args.per_tier, args.quick))
    budget = suite.sweep_budget(cases, args.budget, args.budget_per_dim, args.quick)
    # --seeds, --budget and --budget-per-dim are >= 1 by their argparse types
    if args.out is None and args.check is None:
        # no default: a sweep written into the committed leaderboards/ by accident would
        # mix with (and be resumed from) the published runs
        raise CLIError("--out DIR is required: the folder for runs.jsonl, tables and plots "
                       "(rerun with the same DIR to resume)")
    # --report-only scores what is on disk: its solvers come from the records, so no
    # plugin is imported (a plugin's import code must not run where scores are computed)
    solvers = args.solvers or (_recorded_solvers(args.out) if args.report_only
                               else list(available_solvers()))
    # before any work: a sweep must not fail at its first write, hours in
    out = check_output(args.out or tempfile.mkdtemp(prefix="ema-lb-"), "--out", folder=True)
    summary = leaderboard(solvers, cases, args.tracks, seeds, budget, out,
                          executor=args.executor, workers=args.workers,
                          scheduler=args.scheduler, shard=args.shard,
                          root_seed=args.root_seed, plots=not args.no_plots,
                          quiet=args.quiet,   # the header's command: from sys.argv
                          run=not args.report_only, legacy=args.legacy)
    lines: list[str] = []   # the text output (--json: the summary)
    if args.check:
        tasks = make_tasks(solvers, cases, args.tracks, seeds, budget, args.root_seed,
                           args.shard)
        committed, used = load_baseline(args.check, budget, seeds,
                                        {(t.solver, t.case, t.track, t.seed, t.root_seed)
                                         for t in tasks})
        if not committed:
            folder = Path(args.check)
            if used["other_model_version"]:
                from ..suites import suite_of
                version = suite_of(tasks[0].case).model_version if tasks else "?"
                raise CLIError(f"the committed runs in {folder} were made on another model "
                               f"version than this suite's ({version}): they are stale and "
                               "not comparable; regenerate them (leaderboards/README.md "
                               "lists the commands)")
            raise CLIError(f"no committed runs of these tasks (same seeds and root seed) at "
                           f"budget >= {budget} in {folder / RUNS_FILE} or "
                           f"{folder / '*' / RUNS_FILE}")
        now = select(read_records(out / RUNS_FILE), tasks)
        regressions = compare(now, committed)
        summary["regressions"] = [str(r) for r in regressions]
        summary["baseline"] = used
        against = (f"{args.check} (budget {budget}, {seeds} seeds; "
                   f"committed runs at this budget: {used['same_budget']}, re-scored "
                   f"from a larger budget: {used['re_scored']})")
        lines = ([f"REGRESSIONS against {against}:", *(f"  {r}" for r in regressions)]
                 if regressions else [f"no regression against {against}"])
    errors = summary["errors"]   # the runs that failed, one line each (scored as unsuccessful)
    print_result(args, {"out": str(out), **summary}, [
        *lines, f"{summary['runs']} runs ({summary['ran']} new) -> {out}",
        str(summary["targets"]),
        *(f"  {f}" for f in summary.get("files", [])),
        *([f"{len(errors)} runs FAILED with an error (scored as unsuccessful at their "
           "budget; rerun the command to retry them):"] if errors else []),
        *(f"  {e['key']} (budget {e['budget']}): {e['error_type']}: {e['error']}"
          for e in errors)])
    return 1 if summary.get("regressions") else 0


def _recorded_solvers(out: str | None) -> list[str]:
    """The solvers of the records in ``out/runs.jsonl`` (``--report-only`` without
    ``--solvers``), read without importing any plugin."""
    from ..leaderboard.judge import read_runs

    path = Path(out or ".") / RUNS_FILE
    return list(dict.fromkeys(str(r["solver"]) for r in read_runs([path]))) \
        if path.is_file() else []
