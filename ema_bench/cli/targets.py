"""``ema-bench targets``: (re)compute the suite's best-known optima f* (its fixed targets).

One long multi-solver polishing run per (instance, track, noise seed) of the suite: zoo
least-squares warm-started at the truth, zoo powell from its best, zoo cmaes from nominal
(2700 evaluations in all; ema_bench/best_known.py documents the method).  It writes the JSON
the package ships as ema_bench/suite_targets.json; entries are appended to
OUT.partial.jsonl as they finish, so an interrupted run resumes.  About 3 CPU-s per entry,
460 entries.  --show prints the shipped table's summary instead.

Examples::

    ema-bench targets --out ema_bench/suite_targets.json          # regenerate (~25 CPU-min)
    ema-bench targets --show --json
"""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    from .args import add_json, add_quiet, worker_count

    p = sub.add_parser("targets", help="compute or show the suite's best-known optima f*",
                       description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default=None, metavar="FILE.json",
                   help="where to write the table (required unless --show)")
    p.add_argument("--workers", type=worker_count, default=None, help="processes (default: cores)")
    p.add_argument("--show", action="store_true", help="summarise the shipped table")
    add_json(p, "the summary")
    add_quiet(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..suite import describe, shipped_targets
    from . import CLIError, print_json
    from .args import check_output

    if args.show:
        data = shipped_targets()
    elif args.out is None:
        raise CLIError("--out FILE.json is required (or --show)")
    else:
        from ..best_known import compute_targets

        out = check_output(args.out, "--out", folder=False, suffixes=(".json",))
        data = compute_targets(out, workers=args.workers, quiet=args.quiet)
    entries = data["entries"]
    bias = sorted(((e["bias_range_error"], k) for k, e in entries.items()), reverse=True)
    summary = {**describe(), "entries": len(entries),
               "largest_bias": [{"key": k, "bias_range_error": b} for b, k in bias[:5]]}
    if args.json:
        print_json(summary)
    else:
        print(f"suite {summary['suite']} (model version {summary['model_version']}): "
              f"{len(entries)} best-known optima")
        for b, k in bias[:5]:
            print(f"  {k}: best-known point {100 * b:.2f} % of range from the truth")
    return 0
