"""``ema-bench diagnose``: does the fitted model miss physics in these traces, and what?

The traces must hold the step and sine tests (fitted) and the held-out sine ``sine2``
(never fitted, used to judge candidates), e.g. from
``ema-bench simulate --tests step,sine,sine2 --out traces.csv``.  Any format load_traces reads
(CSV, NPZ, MAT), in one file or several: a file holding one unnamed test (no 'test' column)
gets its name from ``--test``, one name per file in order.  Verdicts: none, effect (named,
with its value and interval; two or three effects at once when no single one explains the
discrepancy; faults of the acquisition chain beside them, each with its value and interval),
acquisition (only faults of the recording named: a low-pass, a time shift, a drift, mains hum
or outliers on one channel), unexplained (the discrepancy left open, and the nearest library
effect or set if it explains part of it).  A discrepancy is a held-out fitness above what
the fitted model plus sensor noise reaches, or training residual statistics outside their
bootstrap envelopes.

Examples::

    ema-bench simulate --case small --effect delay=6e-4 --tests step,sine,sine2 --out d.csv
    ema-bench diagnose d.csv --report report/ --json
    ema-bench diagnose step.csv sine.csv sine2.csv --test step,sine,sine2
"""

from __future__ import annotations

import argparse

from ..diagnosis.results import Settings
from . import print_result
from .args import (
    MAX_BUDGET,
    add_json,
    add_quiet,
    add_seeds,
    add_test_names,
    check_output,
    count,
    load_measured_files,
    run_node,
)


def register(sub: argparse._SubParsersAction) -> None:
    d = Settings()
    p = sub.add_parser("diagnose", help="find and name physics the monitor model misses")
    p.add_argument("traces", nargs="+", metavar="TRACES",
                   help="measured traces (.csv, .npz, .mat): one or more files that together "
                        "hold step, sine and sine2")
    add_test_names(p, "TRACES")
    p.add_argument("--report", default=None, metavar="DIR",
                   help="write report.md, diagnosis.json and plots to DIR")
    p.add_argument("--solver", default=d.solver, help=f"fitting solver (default {d.solver})")
    p.add_argument("--budget", type=count(100, MAX_BUDGET), default=d.budget,
                   help=f"evaluations per fit (default {d.budget})")
    p.add_argument("--bootstrap", type=count(10, 10_000), default=d.n_boot,
                   help=f"bootstrap replicates (default {d.n_boot})")
    add_seeds(p, "the fits and the bootstrap")
    add_json(p, "the diagnosis")
    add_quiet(p)


def run(args: argparse.Namespace) -> int:
    from ..diagnosis.report import write_report
    from ..diagnosis.workflow import diagnose
    from ..progress import progress
    from ..registry import get_solver
    from ..seeding import stream

    # --budget >= 100 and --bootstrap >= 10: their argparse types refuse less
    get_solver(args.solver)
    check_output(args.report, "--report", folder=True)
    measured = load_measured_files(args.traces, args.test)
    with progress(None, "diagnose", unit="stage", quiet=args.quiet) as bar:
        d = diagnose(measured, Settings(solver=args.solver, budget=args.budget,
                                        n_boot=args.bootstrap),
                     seed=stream(run_node(args), "diagnosis"),
                     on_stage=bar.note)
    if args.report:
        write_report(d, measured, args.report, source=", ".join(args.traces))
    from ..diagnosis.interval_table import source

    out = d.as_dict()
    out["effects"] = [{k: e[k] for k in ("name", "params", "interval", "gap_before",
                                          "gap_after", "gap_closed", "partial")}
                      for e in out["effects"]]
    return print_result(args, out, [
        f"verdict: {d.verdict}. {d.message}",
        *(f"  {name} = {v:.4g} (95 % interval {e.interval[0]:.4g} .. {e.interval[1]:.4g})"
          f"{', partial' if e.partial else ''}"
          for e in d.effects for name, v in e.params.items()),
        *(f"  {a.name} = {a.value:.4g} (95 % interval {a.interval[0]:.4g} .. "
          f"{a.interval[1]:.4g}): {a.description}{', partial' if a.partial else ''}"
          for a in d.acquisition),
        *([f"  effect intervals calibrated by: {source()}"] if d.effects else []),
        "faults before -> after: " + ", ".join(
            f"{n} {v['before']:.4g} -> {v['after']:.4g}" for n, v in d.faults.items()),
        *([f"report written to {args.report}/report.md"] if args.report else [])])
