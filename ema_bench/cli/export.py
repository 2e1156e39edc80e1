"""``ema-bench export``: convert run records (runs.jsonl) for other analysis tools.

--format ioh writes IOHprofiler data, which IOHanalyzer and iohinspector load: one folder per
solver, one function per case@track, one run per record (instance = seed, plus 1000 x root
seed when that is not 0).  Runs that failed with an error are skipped and counted.  Records
of several files are merged; a run found in two files is exported once.

Examples::

    ema-bench export --format ioh leaderboards/runs.jsonl --out ioh-data
    ema-bench export --format ioh lb1/runs.jsonl lb2/runs.jsonl --out ioh-data --json
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterable
from pathlib import Path

from ..leaderboard.ioh import export_ioh

#: format name -> exporter ``(records, out folder) -> files written``
FORMATS: dict[str, Callable[[Iterable[dict], Path], list[Path]]] = {"ioh": export_ioh}


def register(sub: argparse._SubParsersAction) -> None:
    from .args import add_json

    p = sub.add_parser("export", help="convert run records for other tools (IOHprofiler)",
                       description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("runs", nargs="+", metavar="RUNS.jsonl",
                   help="run records, as written by 'ema-bench leaderboard'")
    p.add_argument("--format", choices=FORMATS, required=True,
                   help="output format: ioh (IOHprofiler JSON + .dat)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    add_json(p, "a summary")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..leaderboard.ioh import split_runs
    from ..leaderboard.store import is_error, unique
    from . import print_json
    from .args import check_output, read_run_files

    out = check_output(args.out, "--out", folder=True)
    records = unique(read_run_files(args.runs))
    runs, skipped = split_runs(records)
    if not runs:
        from . import CLIError

        why = (f"all {len(records)} records are of runs that failed or made no evaluation"
               if records else "they hold no run records")
        raise CLIError(f"nothing to export from {', '.join(args.runs)}: {why}")
    files = FORMATS[args.format](runs, out)
    errors = sum(map(is_error, skipped))
    summary = {
        "format": args.format, "out": str(out), "runs": len(runs),
        "skipped": len(skipped), "skipped_errors": errors,
        "solvers": sorted({str(r["solver"]) for r in runs}),
        "functions": sorted({f"{r['case']}@{r['track']}" for r in runs}),
        "files": [str(f) for f in files],
    }
    if args.json:
        print_json(summary)
    else:
        print(f"{len(runs)} runs of {len(summary['solvers'])} solvers on "
              f"{len(summary['functions'])} functions -> {out} ({len(files)} files)")
        if skipped:
            print(f"skipped {len(skipped)} runs: {errors} failed with an error, "
                  f"{len(skipped) - errors} made no evaluation")
    return 0
