"""``ema-bench validate``: check run records before they join a leaderboard.

Each record must be of this suite and model version (``ema-bench suite`` shows them), carry a
complete manifest (versions, platform, CPU, threads), stay within its budget, agree with
itself (trace, targets, truth) and, re-evaluated here, its best vector must have the fitness
it reports.  Each solver must cover every instance of the suite but the sanity case, for the
same seeds, on each track it enters (--partial skips that).  Exit 0: accepted; 1: refused,
with one line per reason; 2: the files cannot be read.  docs/submitting-results.md is the
whole submission path.

Examples::

    ema-bench validate my-solver/runs.jsonl
    ema-bench validate shard0/runs.jsonl shard1/runs.jsonl --json
    ema-bench validate leaderboards/quick/runs.jsonl --partial
"""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    from .args import add_json

    p = sub.add_parser("validate", help="check third-party run records (suite, manifest, "
                                        "budget, re-evaluated fitness)",
                       description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("runs", nargs="+", metavar="RUNS.jsonl", help="run records to check")
    p.add_argument("--partial", action="store_true",
                   help="do not require every instance of the suite (a shard, a quick run)")
    p.add_argument("--no-reevaluate", action="store_true",
                   help="skip re-evaluating each reported vector (fast, weaker)")
    add_json(p, "the findings")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..leaderboard.store import unique
    from ..leaderboard.validate import validate
    from ..suite import SUITE_ID
    from . import CLIError, print_json
    from .args import read_run_files

    records = unique(read_run_files(args.runs))
    if not records:
        raise CLIError(f"no run records in {', '.join(args.runs)}")
    found = validate(records, reevaluate=not args.no_reevaluate, complete=not args.partial)
    if args.json:
        print_json({"suite": SUITE_ID, "records": len(records), "accepted": not found,
                    "findings": [{"key": f.key, "problem": f.problem} for f in found]})
    elif found:
        print(f"REFUSED: {len(found)} finding(s) in {len(records)} records (suite {SUITE_ID}):")
        for f in found:
            print(f"  {f}")
    else:
        print(f"accepted: {len(records)} records of suite {SUITE_ID}")
    return 1 if found else 0
