"""``ema-bench blind``: score the missing-physics workflow on hidden cases.

Draws N cases (library effects above their detection thresholds, null cases, decoys outside
the library) with random faults, runs ``diagnose`` on each without showing it the answer, and
reports naming accuracy, false alarms, held-out gap closed and parameter error.  A decoy
counts as handled when it is reported unexplained, or named with the nearest effect flagged
partial (the model with that effect still leaves the bootstrap envelopes).  Results are
appended to OUT/blind.jsonl as cases finish; rerunning the same command resumes (OUT defaults
to ema-bench-blind-seed<S>-n<N> in the current folder).  Progress: a bar in a terminal, one
line per finished case otherwise (--quiet: none).
"""

from __future__ import annotations

import argparse
import sys


def register(sub: argparse._SubParsersAction) -> None:
    from .args import add_json, add_quiet

    p = sub.add_parser("blind", help="blind test of the missing-physics workflow",
                       description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cases", type=int, default=30, help="hidden cases (default 30)")
    p.add_argument("--seed", type=int, default=0,
                   help="root seed R of the suite (default 0); case i is run i of it: the "
                        "traces of 'ema-bench simulate --root-seed R --seed i', the diagnosis "
                        "of 'ema-bench diagnose --root-seed R --seed i'")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="write blind.jsonl and summary.json here, resumable (default "
                        "ema-bench-blind-seed<S>-n<N>)")
    add_json(p, "the summary and the cases")
    add_quiet(p)
    p.set_defaults(func=run)


def default_out(seed: int, cases: int) -> str:
    """The folder a blind suite writes to without ``--out``: named by what it holds, so the
    same command resumes and another seed or size never mixes in."""
    return f"ema-bench-blind-seed{seed}-n{cases}"


def run(args: argparse.Namespace) -> int:
    import json
    from pathlib import Path

    from ..diagnosis.blind import run_blind
    from . import CLIError, print_json
    from .args import check_output

    if args.cases < 1:
        raise CLIError("--cases must be >= 1")
    # before any work: the suite takes minutes per case
    out = check_output(args.out or default_out(args.seed, args.cases), "--out", folder=True)
    if args.out is None and not args.quiet:
        print(f"writing to {out}/ (rerun the same command to resume)", file=sys.stderr)
    res = run_blind(args.cases, args.seed, out, quiet=args.quiet)
    (Path(out) / "summary.json").write_text(json.dumps(
        {"command": "ema-bench " + " ".join(sys.argv[1:]), **res["summary"]}, indent=1))
    if args.json:
        print_json(res)
        return 0
    s = res["summary"]
    print(f"blind suite: {s['cases']} cases, seed {args.seed}")
    print(f"  naming accuracy (top-1): {s['naming_accuracy']:.0%} of {s['effect_cases']} "
          f"effect cases  {s['per_effect']}")
    print(f"  of which flagged partial (a discrepancy remains): {s['named_partial']}")
    print(f"  false alarms: {s['false_alarms']} of {s['null_cases']} null cases")
    o = s["decoys_by_outcome"]
    print(f"  decoys not misnamed: {s['decoys_unexplained_or_partial']} of "
          f"{s['decoy_cases']} (unexplained {o['unexplained']}, named but partial "
          f"{o['named_partial']}, not detected {o['not_detected']}, named {o['named']})")
    print(f"  median held-out gap closed: {s['median_heldout_gap_closed']:.0%}; median "
          f"parameter error: {s['median_param_error']:.1%}")
    if s.get("interval_coverage"):
        print(f"  named effects whose 95 % profile interval contains the truth: "
              f"{s['interval_coverage']}")
    for r in res["records"]:
        truth = f"{r['effect']}={r['value']:.3g}" if r["effect"] else "nothing"
        print(f"    case {r['index']:>3} {r['kind']:<6} {truth:<28} -> {r['verdict']:<11} "
              f"{','.join(r['named']) or r.get('partial') or ''}"
              f"{' (partial)' if r['named'] and r.get('partial') else ''}")
    return 0
