"""``ema-bench coverage``: measure how often the fault intervals contain the truth.

Fits with intervals on seeded instances (random faults over the whole box, instance i drawn
from run node i of --root-seed), then, per fault, the fraction of intervals that contain the
true value (with its 95 % Wilson interval), the median width in % of the fault's range, and
the evaluations the intervals cost.  Records go to OUT/TRACK_METHOD.jsonl as they finish (an
interrupted run resumes), the summary to OUT/TRACK_METHOD.json, the caterpillar plot to
OUT/TRACK_METHOD.png.

--calibrate runs the calibration instances (root seed 1, disjoint from the reported ones) and
writes their nonconformity scores to OUT/calibration.json (--out is required; the shipped
table is never written).  Intervals take their calibration factors from the shipped table
(ema_bench/uncertainty/conformal.py) unless --calibration FILE (or the environment variable
EMA_BENCH_CALIBRATION) names a user table; the output names the table used and its size.
Replacing the shipped table is
'python -m ema_bench.interval_calibration_files OUT/calibration.json',
in a checkout (docs/uncertainty.md).

Examples::

    ema-bench coverage --track twin --instances 100 --level 0.95 --out leaderboards/coverage
    ema-bench coverage --track reference --instances 50 --method profile --json
    ema-bench coverage --track twin --instances 200 --method laplace,profile --calibrate \
        --out my-calibration
    ema-bench coverage --track twin --instances 50 --calibration my-calibration/calibration.json
"""

from __future__ import annotations

import argparse

from ..faults import FAULT_NAMES
from ..interval_calibration_files import describe, inside_package, using
from ..uncertainty import conformal as cal
from ..uncertainty.methods import METHODS, MODEL_FORM_MODES
from . import CLIError, print_result
from .args import (
    MAX_BUDGET,
    add_json,
    add_quiet,
    check_output,
    count,
    finite,
    option_list,
    seed_number,
    worker_count,
)


def register(sub: argparse._SubParsersAction) -> None:
    from ..uncertainty.coverage import BUDGET, SOLVER

    p = sub.add_parser("coverage", help="measure the coverage of the fault intervals")
    p.add_argument("--track", choices=("twin", "reference"), default="twin",
                   help="where the data come from (default twin)")
    p.add_argument("--instances", type=count(1, 100_000), default=100,
                   help="seeded instances 0..N-1 (default 100)")
    p.add_argument("--level", type=finite, default=0.95,
                   help="interval level in (0, 1) (default 0.95)")
    p.add_argument("--method", type=option_list, default=["laplace"],
                   metavar="METHOD[,METHOD...]",
                   help=f"interval method(s), of {', '.join(METHODS)} (default laplace); "
                        "several share each instance's fit")
    p.add_argument("--solver", default=SOLVER, help=f"solver of the fits (default {SOLVER})")
    p.add_argument("--budget", type=count(1, MAX_BUDGET), default=BUDGET,
                   help=f"evaluation budget of each fit (default {BUDGET})")
    p.add_argument("--root-seed", type=seed_number, default=0,
                   help="root of the instances' seeds (default 0; the calibration uses 1)")
    p.add_argument("--noise-scale", type=finite, default=1.0,
                   help="multiply the estimated noise level (sensitivity studies; default 1)")
    p.add_argument("--model-form", choices=list(MODEL_FORM_MODES), default="auto",
                   help="model-form allowance (default auto: none on twin, discrepancy "
                        "otherwise)")
    p.add_argument("--calibrate", action="store_true",
                   help="run the calibration instances (root seed 1) and write their scores "
                        "to OUT/calibration.json (requires --out)")
    p.add_argument("--calibration", default=None, metavar="FILE",
                   help="calibrate the intervals with this user table (as --calibrate wrote "
                        "it) instead of the shipped one (default: $EMA_BENCH_CALIBRATION, "
                        "else shipped)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="folder for records (resumable), summary and plot")
    p.add_argument("--workers", type=worker_count, default=1, help="processes (default 1)")
    add_json(p, "the summary")
    add_quiet(p)


def run(args: argparse.Namespace) -> int:
    from ..registry import get_solver

    if not 0.0 < args.level < 1.0:
        raise CLIError(f"--level must lie in (0, 1), got {args.level}")
    if not args.noise_scale > 0:
        raise CLIError(f"--noise-scale must be positive, got {args.noise_scale}")
    get_solver(args.solver)   # SolverError: a LookupError, printed in one line by main()
    bad = [m for m in args.method if m not in METHODS]
    if bad or not args.method or len(set(args.method)) != len(args.method):
        raise CLIError(f"--method takes distinct methods of {list(METHODS)}, got "
                       f"{','.join(args.method)}")
    root = cal.CALIBRATION_ROOT_SEED if args.calibrate else args.root_seed
    if args.calibrate and args.root_seed not in (0, root):
        raise CLIError("--calibrate runs at the calibration root seed; drop --root-seed")
    if args.calibrate and args.out is None:
        raise CLIError("--calibrate writes OUT/calibration.json: give --out DIR (the shipped "
                       "table is read-only)")
    if args.calibrate and args.calibration:
        raise CLIError("--calibrate makes a calibration table; drop --calibration")
    if args.calibrate and inside_package(args.out):
        raise CLIError(f"--out {args.out}: inside the package, whose data is read-only")
    out = check_output(args.out, "--out", folder=True)
    with using(cal.TABLE, args.calibration):
        cal.active_table()   # a table that is no table fails here, in one line, before work
        return _run(args, root, out)


def _run(args: argparse.Namespace, root: int, out) -> int:
    from ..uncertainty.coverage import Settings, run_methods

    all_settings = [Settings(track=args.track, method=m, level=args.level, solver=args.solver,
                             budget=args.budget, root_seed=root, noise_scale=args.noise_scale,
                             model_form=args.model_form) for m in args.method]
    stems = [f"{args.track}_{m}" for m in args.method]
    paths = [None if out is None else out / f"{stem}.jsonl" for stem in stems]
    runs = run_methods(all_settings, args.instances, paths, workers=args.workers,
                       quiet=args.quiet or args.json)
    summaries = [_summary(records, method, stem, out, args)
                 for method, stem, records in zip(args.method, stems, runs)]
    return print_result(args, summaries[0] if len(summaries) == 1 else summaries,
                        [line for s in summaries for line in _lines(s, root, args)])


def _summary(records: list[dict], method: str, stem: str, out, args: argparse.Namespace
             ) -> dict:
    """Write calibration scores (with --calibrate), the summary and the plot of one method."""
    import numpy as np

    from ..jsonio import write_checked
    from ..uncertainty.coverage import recalibrated, summarise, write_calibration

    kind = cal.calibration_kind(args.track)
    mode = records[0]["model_form"]
    made = None
    if args.calibrate:
        made = out / cal.TABLE.name
        write_calibration({cal.calibration_key(kind, method, mode): records}, made)
    # the intervals as the active table (or the one just made) calibrates them now
    # (uncalibrated where it has no scores for this method)
    with using(cal.TABLE, made):
        data = cal.active_table()
        fac = cal.calibration_factor(kind, method, mode, args.level, data)
        source = describe(cal.TABLE, cal.calibration_size(kind, method, mode, data))
    factors = np.ones(len(FAULT_NAMES)) if fac is None else fac
    records = recalibrated(records, dict(zip(FAULT_NAMES, factors)))
    summary = summarise(records)
    summary["calibration"] = "none" if fac is None else kind
    summary["calibration_table"] = source
    summary["calibration_factor"] = dict(zip(FAULT_NAMES, map(float, factors)))
    if out is not None:
        from ..uncertainty.coverage import SUMMARY_SCHEMA
        from ..uncertainty.plots import plot_coverage

        write_checked(out / f"{stem}.json", summary, SUMMARY_SCHEMA, "\n", indent=1)
        plot_coverage(records, out / f"{stem}.png")
        summary["files"] = [str(out / f"{stem}{s}") for s in (".jsonl", ".json", ".png")]
    return summary


def _lines(summary: dict, root: int, args: argparse.Namespace) -> list[str]:
    """The text table of one method's summary."""
    table = "" if summary["calibration"] == "none" else f" ({summary['calibration_table']})"
    ev, band = summary["interval_evaluations"], summary["coverage_interval"]
    return [
        f"coverage of {100 * args.level:g} % {summary['method']} intervals, {args.track} "
        f"track, {summary['instances']} seeded instances (root seed {root}; fits: "
        f"{args.solver}, budget {args.budget}; model form: {summary['model_form']}; "
        f"calibration: {summary['calibration']}{table})",
        f"{'fault':<6} {'coverage':>9} {'95 % interval':>16} {'median width':>13} "
        f"{'factor':>7} {'noise only':>10}",
        *(f"{n:<6} {summary['coverage'][n]:9.3f} "
          f"{f'[{band[n][0]:.3f}, {band[n][1]:.3f}]':>16} "
          f"{summary['median_width'][n]:11.3f} % {summary['calibration_factor'][n]:7.3f} "
          f"{summary['coverage_noise_only'][n]:10.3f}" for n in FAULT_NAMES),
        f"interval cost: median {ev['median']:.0f}, max {ev['max']} evaluations per fit; "
        f"fits with a noise ratio above 1.2 (not at the optimum): {summary['misfits']}; "
        f"no interval: {summary['errors']}",
        *([f"records, summary and plot: {', '.join(summary['files'])}"]
          if "files" in summary else [])]
