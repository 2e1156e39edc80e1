"""``ema-bench export``: convert run records (runs.jsonl) for other analysis tools.

--format ioh writes IOHprofiler data, which IOHanalyzer and iohinspector load: one folder per
solver, one function per case@track, one run per record (instance = seed, 0..65535; seed,
root seed, budget, f* and f_nominal are run attributes; one root seed per export).  With
--value precision the values are (f - f*) / (f_nominal - f*), so IOH's fixed targets are the
board's fitness targets (1e-1 .. 1e-4; needs the suite's f*: root seed 0).  The sanity case
(nominal) is left out unless --include-sanity (then marked).  Runs that failed with an error
are skipped and counted.  Records of several files are merged.  Only records that
``ema-bench validate`` accepts are exported (re-evaluated; a partial board is fine): a
refused record, two records of one run, or a legacy (schema-1) record without --legacy stop
the export with one line (exit 2).

Examples::

    ema-bench export --format ioh leaderboards/runs.jsonl --out ioh-data
    ema-bench export --format ioh leaderboards/runs.jsonl --value precision --out ioh-prec
    ema-bench export --format ioh lb1/runs.jsonl lb2/runs.jsonl --out ioh-data --json
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from ..leaderboard.ioh import export_ioh, function_name, optimum, split_runs
from ..leaderboard.run_store import is_error
from ..suites.v1 import SANITY_CASES
from . import CLIError, print_result
from .args import add_json, add_legacy, add_targets, check_output

#: format name -> exporter ``(records, out folder, **options) -> files written``
FORMATS: dict[str, Callable[..., list[Path]]] = {"ioh": export_ioh}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("export", help="convert run records for other tools (IOHprofiler)")
    p.add_argument("runs", nargs="+", metavar="RUNS.jsonl",
                   help="run records, as written by 'ema-bench leaderboard'")
    p.add_argument("--format", choices=FORMATS, required=True,
                   help="output format: ioh (IOHprofiler JSON + .dat)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--value", choices=("raw", "precision"), default="raw",
                   help="raw fitness (default) or precision (f - f*) / (f_nominal - f*)")
    p.add_argument("--include-sanity", action="store_true",
                   help="export the sanity case (nominal) too, marked; left out by default")
    add_targets(p)
    p.add_argument("--no-reevaluate", action="store_true",
                   help="admit without re-evaluating the vectors (fast, weaker: as "
                        "'validate --no-reevaluate'; every other check stays)")
    add_legacy(p, "export")
    add_json(p, "a summary")


def run(args: argparse.Namespace) -> int:
    from ..leaderboard.judge import JudgeError, admitted, read_runs

    out = check_output(args.out, "--out", folder=True)
    try:   # what validate refuses is not exported (a partial board is: no completeness)
        records = admitted(read_runs(args.runs), "export", complete=False,
                           legacy=args.legacy, reevaluate=not args.no_reevaluate)
    except JudgeError as exc:
        raise CLIError(str(exc)) from None
    runs, skipped = split_runs(records)
    if not runs:
        why = (f"all {len(records)} records are of runs that failed or made no evaluation"
               if records else "they hold no run records")
        raise CLIError(f"nothing to export from {', '.join(args.runs)}: {why}")
    files = FORMATS[args.format](runs, out, value=args.value,
                                 include_sanity=args.include_sanity)
    sanity = [] if args.include_sanity else [r for r in runs if r["case"] in SANITY_CASES]
    runs = [r for r in runs if args.include_sanity or r["case"] not in SANITY_CASES]
    errors = sum(map(is_error, skipped))
    known = sum(optimum(r) is not None for r in runs)
    roots = sorted({int(r.get("root_seed") or 0) for r in runs})
    summary = {
        "format": args.format, "out": str(out), "runs": len(runs),
        "skipped": len(skipped), "skipped_errors": errors, "sanity_left_out": len(sanity),
        "solvers": sorted({str(r["solver"]) for r in runs}),
        # the exporter's names (emafdi-v2: condition@track, one dimension per tier)
        "functions": sorted({function_name(r) for r in runs}),
        "files": [str(f) for f in files], "with_f_star": known,
    }
    return print_result(args, summary, [
        f"{len(runs)} runs of {len(summary['solvers'])} solvers on "
        f"{len(summary['functions'])} functions -> {out} ({len(files)} files)",
        f"f* (run attribute, fitness targets) on {known} of {len(runs)} runs" + (
            "" if known == len(runs) else
            f"; compute the rest with 'ema-bench targets --root-seed {roots[-1]} --out "
            "T.json' and pass --targets T.json"),
        *([f"skipped {len(skipped)} runs: {errors} failed with an error, "
           f"{len(skipped) - errors} made no evaluation"] if skipped else []),
        *([f"left out {len(sanity)} runs of the sanity case (--include-sanity to export "
           "them)"] if sanity else [])])
