"""``ema-bench blind``: score the missing-physics workflow on hidden cases.

Draws N cases with random faults in fixed shares of seven categories: single library effects
(1.5-4x their detection thresholds), near-threshold effects (1-1.5x), pairs of effects
(1.5-3x each), null cases from the reference model and from the monitor model itself,
physical decoys outside the library (quadratic damping, hinge friction) and acquisition-chain
decoys applied to the recorded traces (a slow filter, 400 Hz mains hum, clipping, a time
shift, drift or outliers on one channel).  It runs ``diagnose`` on each without showing it the
answer, and reports per category: naming accuracy (top-1), both effects of a pair named,
false alarms, decoys handled, held-out gap closed, parameter error and interval coverage.  A
decoy counts as handled when it is reported unexplained or not detected, or named with the
effect flagged partial (the model with it still leaves the bootstrap envelopes).  Results are
appended to OUT/blind.jsonl as cases finish (--workers N: N processes); rerunning the same
command resumes (OUT defaults to ema-bench-blind-seed<S>-n<N> in the current folder).
Progress: a bar in a terminal, one line per finished case otherwise (--quiet: none).
--extra K and --fourth K add K cases of each third-round category (an effect beside an
acquisition-chain fault, three effects) and of each fourth-round one (an effect beside an
acquisition fault sized at 1-4x and at 1-1.5x its measured detection threshold) after the
N, which they leave as drawn; --chain K adds K cases of each whole-chain category (an effect
beside one fault kind on several channels at once, and beside heavy-tailed noise on every
channel) after those.  --outside K adds K cases of each outside-library category after
those: physics of a known form no library effect holds (the two decoys, a Stribeck
friction peak, a position-dependent transmission stiffness, a saturating torque constant),
judged on the dictionary term the diagnosis names (its equation and form), and nulls made by
the reference and by the monitor, on which no term may be discovered; then K of each of the
current loop's and a sensor's (an inverter's dead-time voltage, a resolver's second harmonic),
judged alike.

--calibrate fits the true effect sets of the effect cases of the suite of root seed 1 (never
a reported seed) and writes the nonconformity scores of their intervals to
OUT/interval_calibration.json (--out is required; the shipped table is never written); about
15 CPU-seconds per effect case.  The factor widening every named effect's interval comes from
the shipped table (ema_bench/diagnosis/effect_interval_calibration.py) unless --calibration FILE (or
EMA_BENCH_INTERVAL_CALIBRATION) names a user table; the summary names the table and its size.
Replacing the shipped table is 'python -m ema_bench.interval_calibration_files
OUT/interval_calibration.json', in a checkout (docs/diagnosis.md).
"""

from __future__ import annotations

import argparse
import sys

from . import CLIError, print_result
from .args import add_json, add_quiet, check_output, comma_list, count, seed_number, worker_count


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("blind", help="blind test of the missing-physics workflow")
    p.add_argument("--cases", type=count(0, 10_000), default=30, help="hidden cases (default 30)")
    p.add_argument("--seed", type=seed_number, default=0,
                   help="root seed R of the suite (default 0); case i is run i of it: the "
                        "traces of 'ema-bench simulate --root-seed R --seed i' (reference-model "
                        "cases, before any acquisition decoy), the diagnosis of 'ema-bench "
                        "diagnose --root-seed R --seed i'")
    # the later rounds' categories, each drawn after the cases before it
    for flag, what in (
            ("--extra", "third-round category (an effect beside an acquisition-chain fault, "
                        "three effects at once), after the --cases cases"),
            ("--fourth", "fourth-round category (an effect beside an acquisition fault sized "
                         "at 1-4x, and at 1-1.5x, its detection threshold), after the others"),
            ("--chain", "whole-chain category (an effect beside a fault of the whole "
                        "recording chain sized at 1-4x its threshold, and beside heavy-tailed "
                        "noise on every channel), after the others"),
            ("--outside", "outside-library category (physics of a known form no library "
                          "effect holds, judged on the term the diagnosis names; nulls made "
                          "by the reference and by the monitor, judged on discovering "
                          "nothing), after the others")):
        p.add_argument(flag, type=count(0, 1000), default=0, metavar="K",
                       help=f"K more cases of each {what}, which they leave as they were "
                            "(default 0)")
    p.add_argument("--only", default=None, metavar="CATEGORIES",
                   help="comma-separated categories: run and summarise only their cases of "
                        "the suite drawn (e.g. a rerun of part of a committed suite)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="write blind.jsonl and summary.json here, resumable (default "
                        "ema-bench-blind-seed<S>-n<N>)")
    p.add_argument("--workers", type=worker_count, default=1,
                   help="processes running cases at once (default 1; each takes one core)")
    p.add_argument("--calibrate", action="store_true",
                   help="recompute the effect intervals' calibration on the effect cases of "
                        "--cases cases of root seed 1, into OUT/interval_calibration.json "
                        "(requires --out)")
    p.add_argument("--calibration", default=None, metavar="FILE",
                   help="widen the effect intervals with this user table (as --calibrate "
                        "wrote it) instead of the shipped one (default: "
                        "$EMA_BENCH_INTERVAL_CALIBRATION, else shipped)")
    add_json(p, "the summary and the cases")
    add_quiet(p)


def default_out(seed: int, cases: int, extra: int = 0, fourth: int = 0, chain: int = 0,
                outside: int = 0) -> str:
    """The folder a blind suite writes to without ``--out``: named by what it holds, so the
    same command resumes and another seed or size never mixes in."""
    return (f"ema-bench-blind-seed{seed}-n{cases}" + (f"-x{extra}" if extra else "")
            + (f"-f{fourth}" if fourth else "") + (f"-c{chain}" if chain else "")
            + (f"-o{outside}" if outside else ""))


def run(args: argparse.Namespace) -> int:
    if args.cases + args.extra + args.fourth + args.chain + args.outside < 1:   # each >= 0
        raise CLIError("--cases, --extra, --fourth, --chain and --outside must be >= 0 (not "
                       "all 0), --workers >= 1")
    only = None
    if args.only is not None:
        from ..diagnosis.blind import KINDS

        only = comma_list(args.only)
        unknown = [c for c in only if c not in KINDS]
        if unknown or not only:
            raise CLIError(f"--only: unknown categories {unknown}; known: {', '.join(KINDS)}")
    if args.calibrate:
        return _calibrate(args)
    from ..diagnosis.interval_table import TABLE, active_table
    from ..interval_calibration_files import using

    with using(TABLE, args.calibration):
        active_table()   # a table that is no table fails here, in one line, before any work
        return _run(args, only)


def _run(args: argparse.Namespace, only: list[str] | None) -> int:
    from pathlib import Path

    from ..diagnosis.blind import run_blind
    from ..diagnosis.blind_summary import SUMMARY_SCHEMA
    from ..diagnosis.interval_table import source
    from ..jsonio import write_checked

    # before any work: the suite takes minutes per case
    out = check_output(args.out or default_out(args.seed, args.cases, args.extra, args.fourth,
                                               args.chain, args.outside), "--out", folder=True)
    if args.out is None and not args.quiet:
        print(f"writing to {out}/ (rerun the same command to resume)", file=sys.stderr)
    res = run_blind(args.cases, args.seed, out, quiet=args.quiet, workers=args.workers,
                    extra=args.extra, only=only, fourth=args.fourth, chain=args.chain,
                    outside=args.outside)
    res["summary"]["interval_calibration"] = source()
    write_checked(Path(out) / "summary.json",
                  {"command": "ema-bench " + " ".join(sys.argv[1:]), **res["summary"]},
                  SUMMARY_SCHEMA, indent=1)
    return print_result(args, res, summary_lines(res["summary"], args.seed)
                        + [case_line(r) for r in res["records"]])


def _calibrate(args: argparse.Namespace) -> int:
    from ..diagnosis import effect_interval_calibration as ic
    from ..interval_calibration_files import inside_package

    if args.seed not in (0, ic.CALIBRATION_SEED) or args.calibration or args.extra or \
            args.only or args.fourth or args.chain or args.outside:
        raise CLIError(f"--calibrate runs the cases of root seed {ic.CALIBRATION_SEED}; drop "
                       "--seed, --calibration, --extra, --fourth, --chain, --outside and "
                       "--only")
    if args.out is None:
        raise CLIError("--calibrate writes OUT/interval_calibration.json: give --out DIR (the "
                       "shipped table is read-only)")
    if inside_package(args.out):
        raise CLIError(f"--out {args.out}: inside the package, whose data is read-only")
    path = check_output(args.out, "--out", folder=True) / ic.TABLE.name
    data = ic.calibrate(path, args.cases, workers=args.workers, quiet=args.quiet)
    return print_result(args, data, [
        f"{len(data['scores'])} effect intervals of {data['effect_cases']} cases scored; "
        f"95 % factor {data['factor_95']:.3g}; written to {path} (use it with "
        f"--calibration {path})"])


def _pct(x: float, digits: int = 0) -> str:
    return "-" if x != x else f"{x:.{digits}%}"


def _category_line(name: str, b: dict) -> str:
    """One line of figures of a category block of the summary."""
    n = b["cases"]
    if name in ("single", "near_threshold"):
        return (f"named top-1 {b['correct']}/{n} ({_pct(b['naming_accuracy'])}), partial "
                f"{b['named_partial']}, gap closed {_pct(b['median_heldout_gap_closed'])}, "
                f"param error {_pct(b['median_param_error'], 2)}, intervals cover "
                f"{b['interval_coverage'] or '-'}  {b['per_effect']}")
    if name == "two_effect":
        return (f"both named {b['both_named']}/{n}, at least one {b['one_named']}/{n}, gap "
                f"closed {_pct(b['median_heldout_gap_closed'])}, intervals cover "
                f"{b['interval_coverage'] or '-'}")
    if name == "three_effect":
        return (f"all three named {b['all_named']}/{n} ({_pct(b['all_named_rate'])}), "
                f"effects named {b['effects_named']}, confident misnames "
                f"{b['confident_misnames']}, gap closed "
                f"{_pct(b['median_heldout_gap_closed'])}, intervals cover "
                f"{b['interval_coverage'] or '-'}")
    from ..diagnosis.blind import EFFECT_ACQUISITION

    if name in EFFECT_ACQUISITION:
        return (f"effect named {b['effect_named']}/{n} ({_pct(b['effect_named_rate'])}), "
                f"acquisition fault named {b['acquisition_named']}/{n}, named or flagged "
                f"{b['acquisition_named_or_flagged']}/{n} "
                f"({_pct(b['acquisition_named_or_flagged_rate'])}), confident misnames "
                f"{b['confident_misnames']}, intervals cover {b['interval_coverage'] or '-'}"
                f"  {b['per_acquisition']}")
    if name in ("null", "monitor_null"):
        return f"false alarms {b['false_alarms']}/{n}  {b['by_verdict']}"
    from ..diagnosis.blind_categories import OUTSIDE_KINDS

    if name in OUTSIDE_KINDS:
        return (f"right term (equation and form) {b['right_term']}/{n} "
                f"({_pct(b['right_term_rate'])}), a term named {b['term_named']}/{n}, gap "
                f"closed when right {_pct(b['median_gap_closed_when_named'])}, median "
                f"{b['median_cpu_s']:.0f} CPU-s  {b['right_by_physics']}")
    if name in ("outside_null", "outside_monitor_null"):
        return (f"terms discovered {b['discoveries']}, false alarms {b['false_alarms']}/{n}  "
                f"{b['by_verdict']}")
    o = b["by_outcome"]
    return (f"handled {b['ok']}/{n} (unexplained {o['unexplained']}, named but partial "
            f"{o['named_partial']}, acquisition fault named "
            f"{o.get('acquisition_named', 0)}, not detected {o['not_detected']}, named "
            f"{o['named']})  {b['ok_by_decoy']}")


def summary_lines(s: dict, seed: int) -> list[str]:
    """The text summary: overall figures, then one line per category that has cases."""
    lines = [f"blind suite: {s['cases']} cases, seed {seed}",
             f"  naming accuracy (top-1): {_pct(s['naming_accuracy'])} of {s['effect_cases']} "
             "single and near-threshold cases",
             f"  false alarms: {s['false_alarms']} of {s['null_cases']} null cases (reference "
             "and monitor data)",
             f"  decoys not misnamed: {s['decoys_unexplained_or_partial']} of "
             f"{s['decoy_cases']}",
             f"  cases with a confidently named suspect that is not there: "
             f"{s.get('confident_misnames', '-')}",
             f"  median held-out gap closed: {_pct(s['median_heldout_gap_closed'])}; median "
             f"parameter error: {_pct(s['median_param_error'], 2)}"]
    if s.get("interval_calibration"):
        lines.append(f"  effect intervals calibrated by: {s['interval_calibration']}")
    if s.get("interval_coverage"):
        lines.append("  named true effects whose 95 % profile interval contains the truth: "
                     f"{s['interval_coverage']}")
    for name, b in s["per_category"].items():
        if b["cases"]:
            lines.append(f"  {name:<17} {b['cases']:>3}: {_category_line(name, b)}")
    return lines


def _truth(r: dict) -> str:
    """What a case hides, shortly: its effects, decoy and channel, or nothing."""
    effects = ",".join(f"{k}={v:.3g}" for k, v in r["effects"].items())
    if r["category"] == "acquisition_decoy":
        return f"{r['decoy']}({r['decoy_params'].get('signal', '')})"
    from ..diagnosis.blind import EFFECT_ACQUISITION

    if r["category"] in EFFECT_ACQUISITION:
        return f"{effects}+{r['decoy']}({r['decoy_params'].get('signal', '')})"
    if r["category"] == "monitor_null":
        return "nothing (monitor)"
    return effects or "nothing"


def case_line(r: dict) -> str:
    """One finished case: index, category, truth, verdict and what was named."""
    suspects = r["named"] + r.get("named_acquisition", [])
    named = ",".join(suspects) or r.get("partial") or ""
    partial = " (partial)" if suspects and r.get("partial") else ""
    return (f"    case {r['index']:>3} {r['category']:<17} {_truth(r):<44} -> "
            f"{r['verdict']:<11} {named}{partial}")
