"""``ema-bench simulate``: run the reference or monitor model on the standard tests.

Examples::

    ema-bench simulate --case small --model reference --seed 0 --out traces.csv
    ema-bench simulate --faults Na=0.95,Fst=0.3378,BLK=0.01,Gprop=1e5 --plot out.png
    ema-bench simulate --case full --effect eccentricity=0.02 --out full_ecc.npz
    ema-bench simulate --case all          # the four paper cases, summary table
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ..faults import CASES, faults_to_dict, get_case
from . import CLIError, print_result
from .args import (
    PLOT_SUFFIXES,
    add_effects,
    add_faults,
    add_json,
    add_seeds,
    check_output,
    comma_list,
    effects_of,
    faults_of,
    run_node,
)

MODELS = ("reference", "monitor")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("simulate", help="simulate the actuator and write its traces")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--case", default=None,
                     help="paper case: nominal, small, full, random, or 'all' for the four "
                          "(default nominal)")
    add_faults(src)
    add_effects(p, "the model")
    p.add_argument("--model", choices=MODELS, default="reference",
                   help="reference (detailed, 1 us step) or monitor (cheap) (default reference)")
    p.add_argument("--tests", default="step,sine",
                   help="comma-separated protocol tests: step, sine, and the held-out sine2 "
                        "that 'ema-bench diagnose' needs (default step,sine)")
    add_seeds(p, "the sensor noise (the same noise 'ema-bench solve --seed k' fits)")
    p.add_argument("--no-noise", action="store_true",
                   help="clean outputs: no sensor noise, no ADC quantisation")
    p.add_argument("--out", default=None, metavar="PATH",
                   help="write traces (.csv or .npz; with --case all, a folder)")
    p.add_argument("--plot", default=None, metavar="PNG", help="draw the 8 signals to a PNG")
    add_json(p, "the summary")


def _simulate(x, effects, model, node, clean, tests):
    from ..instances import twin_traces
    from ..monitor import monitor_traces
    from ..reference import simulate_reference
    from ..seeding import seed_repr, stream

    seed = stream(node, "noise")
    if model == "reference":
        return simulate_reference(x, effects, seed=None if clean else seed, noise=not clean,
                                  adc=not clean, tests=tests)
    if clean:
        return monitor_traces(x, effects, tests=tests)
    # the twin track's data maker: the same noise `solve --track twin --seed k` fits
    return twin_traces(x, effects, seed, tests).with_meta(faults=faults_to_dict(x),
                                                           seed=seed_repr(seed))


def summarise(tr) -> dict[str, float]:
    """A few figures a person checks first (per test)."""
    from ..params import DEFAULT_PARAMS
    from ..protocol import STANDARD_TESTS

    out = {}
    for spec in STANDARD_TESTS:
        if spec.name not in tr.tests:
            continue
        cmd = spec.command_at_samples(1e-4)
        y = tr.data[spec.name]
        n = y.shape[0]
        target = np.interp(tr.time(spec.name), np.arange(cmd.size) * 1e-4, cmd)
        out[spec.name] = {
            "rms_tracking_error_rad": float(np.sqrt(np.mean((y[:, 0] - target[:n]) ** 2))),
            "final_position_rad": float(y[-1, 0]),
            "peak_speed_rad_s": float(np.abs(y[:, 2]).max()),
            "peak_current_A": float(y[:, 3].max()),
            "motor_minus_surface_max_rad":
                float(np.abs(y[:, 1] * DEFAULT_PARAMS.tau - y[:, 0]).max()),
        }
    return out


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ..effects import effects_vector
    from ..objective import KNOWN_TESTS
    from ..plots import plot_traces
    from ..traces import Traces

    node = run_node(args)
    effects = effects_vector(effects_of(args))
    names = comma_list(args.tests)
    bad = [t for t in names if t not in KNOWN_TESTS]
    if bad or not names:
        raise CLIError(f"unknown test(s) {bad}; known: {list(KNOWN_TESTS)}")
    tests = tuple(KNOWN_TESTS[t] for t in names)
    if args.faults is not None:
        runs = {"custom": faults_of(args)}
    elif args.case == "all":
        runs = {n: c.x for n, c in CASES.items()}
    else:
        case = get_case(args.case or "nominal")
        runs = {case.name: case.x}
    # every output is checked before the (reference: seconds-long) simulation
    check_output(args.out, "--out", folder=len(runs) > 1,
                 suffixes=() if len(runs) > 1 else Traces.SAVE_SUFFIXES)
    check_output(args.plot, "--plot", folder=False, suffixes=PLOT_SUFFIXES)
    results, traces = {}, {}
    for name, x in runs.items():
        t0 = time.perf_counter()
        tr = _simulate(x, effects, args.model, node, args.no_noise, tests)
        tr = tr.with_meta(case=name)
        traces[name] = tr
        results[name] = {"faults": faults_to_dict(x), "wall_s": time.perf_counter() - t0,
                         **summarise(tr)}
        if args.out:
            if len(runs) > 1:
                Path(args.out).mkdir(parents=True, exist_ok=True)
                tr.save(Path(args.out) / f"{name}.csv")
            else:
                tr.save(args.out)
    if args.plot:
        plot_traces(list(traces.values()), list(traces), args.plot,
                    title=f"{args.model} model, seed {args.seed}")
    return print_result(args, {"model": args.model, "seed": args.seed, "runs": results}, [
        f"{args.model} model, seed {args.seed}" + (", clean" if args.no_noise else ""),
        f"{'case':<8} {'test':<5} {'rms err rad':>11} {'final rad':>9} {'peak w rad/s':>12} "
        f"{'peak I A':>8} {'max |th_m tau - th_u| rad':>25} {'wall s':>7}",
        *(f"{name:<8} {test:<5} {r[test]['rms_tracking_error_rad']:11.4f} "
          f"{r[test]['final_position_rad']:9.4f} {r[test]['peak_speed_rad_s']:12.1f} "
          f"{r[test]['peak_current_A']:8.2f} {r[test]['motor_minus_surface_max_rad']:25.4f} "
          f"{r['wall_s']:7.2f}"
          for name, r in results.items() for test in ("step", "sine") if test in r),
        *([f"traces written to {args.out}"] if args.out else []),
        *([f"plot written to {args.plot}"] if args.plot else [])])
