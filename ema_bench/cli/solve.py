"""``ema-bench solve``: identify the faults of one episode with a registered solver;
``ema-bench solvers``: list the registered solvers.

Examples::

    ema-bench solve --case small --track reference --solver cmaes --budget 2000 --seed 0
    ema-bench solve --case seeded --heterogeneity 0.5 --seed 3 --solver de --json
    ema-bench solve --case full --effect eccentricity=0.05 --solver least-squares
    ema-bench solve --case t12-s03@no-prior --solver cmaes --budget 2000   # any suite's case
    ema-bench solve --measured traces.csv --solver cmaes --plot fit.png
    ema-bench solve --measured step.csv sine.csv --test step,sine --solver cmaes
    ema-bench solve --case seeded --seed 4 --track twin --solver de --budget 5000 \
        --intervals profile --interval-plot fit_intervals.png
    ema-bench solvers

Twin track: the data come from the monitor model itself plus sensor noise (the optimum is the
truth); reference track: from the detailed reference model (model-form mismatch, as in the
paper).  With ``--measured`` the traces come from one or more files and there is no truth to
score; ``--test`` names the single test of each file without a 'test' column, in file order.

``--intervals`` adds an interval per fault (ema_bench.uncertainty): ``laplace`` (local
sandwich covariance, the default method, a few tens of evaluations), ``profile`` (profile
likelihood, up to 3000) or ``bootstrap`` (parametric refits).  The intervals are centred on
the fit polished by a local refit; off the twin track they include the monitor's calibrated
model-form allowance.  Their evaluations are counted apart from the solver's budget.
``ema-bench coverage`` measures how often such intervals contain the truth.
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ..faults import FAULTS
from ..interval_calibration_files import describe
from ..monitor import monitor_traces
from ..objective import KNOWN_TESTS, N_FAULTS
from ..progress import progress
from ..reference import SimulationError
from ..registry import available_solvers, get_solver, run_solver
from ..seeding import stream
from ..suites.problem import check_settings, make_problem
from ..uncertainty import intervals
from ..uncertainty.local import UncertaintyError
from . import CLIError, print_json, print_result
from .args import (
    MAX_BUDGET,
    PLOT_SUFFIXES,
    add_effects,
    add_faults,
    add_json,
    add_seeds,
    add_targets,
    add_test_names,
    check_output,
    count,
    effects_of,
    faults_of,
    finite,
    load_measured_files,
    run_node,
)

_SOLVE_EPILOG = "Run 'ema-bench solvers' for the registered solvers."


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``solve`` and ``solvers`` commands."""
    _register_solve(sub)
    p = sub.add_parser("solvers", help="list the registered solvers",
                       description="List every registered solver (the built-in zoo and "
                                   "plugins of the 'ema_bench.solvers' entry-point group).")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run_solvers)


def _register_solve(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("solve", help="identify the faults of one episode with a solver",
                       epilog=_SOLVE_EPILOG)
    src = p.add_mutually_exclusive_group()
    src.add_argument("--case", default=None,
                     help="a case of any suite: paper case (nominal, small, full, random), "
                          "seeded instance s00..s19, an emafdi-v2 case instance@condition "
                          "(t12-s03@no-prior), or 'seeded' for a random instance drawn from "
                          "--seed (default small)")
    src.add_argument("--measured", nargs="+", action="extend", default=None, metavar="FILE",
                     help="fit measured traces from one or more .csv, .npz or .mat files (no "
                          "truth)")
    add_faults(src)
    add_test_names(p, "--measured")
    p.add_argument("--heterogeneity", type=finite, default=1.0,
                   help="with --case seeded: how far faults may move from nominal, 0..1 "
                        "(default 1)")
    p.add_argument("--track", choices=("reference", "twin"), default="reference",
                   help="where the data come from: reference model or monitor twin "
                        "(default reference)")
    p.add_argument("--solver", default="cmaes", help="registered solver name (default cmaes)")
    p.add_argument("--budget", type=count(1, MAX_BUDGET), default=2000,
                   help="evaluation budget, counted by the problem (default 2000)")
    add_seeds(p, "the instance, the sensor noise and the solver (a leaderboard row, bit for "
                 "bit)")
    add_effects(p, "the model that makes the data")
    p.add_argument("--raw", action="store_true",
                   help="raw sum of squared errors instead of the normalised fitness")
    p.add_argument("--plot", default=None, metavar="PNG",
                   help="draw measured vs fitted monitor traces to a PNG")
    p.add_argument("--intervals", default=None, choices=("laplace", "profile", "bootstrap"),
                   help="an interval per fault by this method (default: none)")
    p.add_argument("--level", type=finite, default=0.95,
                   help="level of --intervals, in (0, 1) (default 0.95)")
    p.add_argument("--interval-plot", default=None, metavar="PNG",
                   help="with --intervals: draw the Na/Fst plane with the confidence region "
                        "to PNG (and, for profile, the profiles to PNG's name + _profiles)")
    add_targets(p)
    add_json(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")


def _check_args(args: argparse.Namespace) -> None:
    run_node(args)   # the seeds are valid
    # make_problem's own checks, before any work (the measured path has no case)
    check_settings(_case(args) if args.measured is None else "small", args.track,
                   args.budget, args.heterogeneity)
    get_solver(args.solver)   # imports this solver's plugin only (SolverError: one line)
    if args.measured is not None and args.effect:
        raise CLIError("--effect changes the simulated data; it cannot apply to --measured "
                       "traces")
    if args.measured is None and args.test is not None:
        raise CLIError("--test names the tests of --measured files; it needs --measured")
    check_output(args.plot, "--plot", folder=False, suffixes=PLOT_SUFFIXES)
    if args.interval_plot is not None and args.intervals is None:
        raise CLIError("--interval-plot needs --intervals METHOD")
    if not 0.0 < args.level < 1.0:
        raise CLIError(f"--level must lie in (0, 1), got {args.level}")
    check_output(args.interval_plot, "--interval-plot", folder=False, suffixes=PLOT_SUFFIXES)


def _case(args: argparse.Namespace):
    """--case (default small), or the vector of --faults."""
    return faults_of(args) if args.faults is not None else (args.case or "small")


def _make_problem(args: argparse.Namespace):
    if args.measured is not None:
        return make_problem(measured=load_measured_files(args.measured, args.test),
                            budget=args.budget, normalise=not args.raw)
    effects = effects_of(args)
    # the instance and the noise come from the run node's streams, the solver from its own
    # (run_solver derives it), as in a leaderboard row
    return make_problem(_case(args), track=args.track, seed=run_node(args),
                        budget=args.budget, normalise=not args.raw,
                        heterogeneity=args.heterogeneity, effects=effects or None)


@contextmanager
def _progress(problem, enabled: bool) -> Iterator[None]:
    """A progress bar on stderr (:func:`~ema_bench.progress.progress`, cleared when done) that
    follows the problem's own evaluation count (a polling thread: solvers know nothing of
    it)."""
    if not enabled:
        yield
        return
    done = threading.Event()

    def poll() -> None:
        while not done.wait(0.2):
            n = problem.evaluations
            if n != bar.done:
                bar.update(n=n - bar.done)

    with progress(problem.budget, "", unit="eval", tty=True, leave=False) as bar:
        t = threading.Thread(target=poll, daemon=True)
        t.start()
        try:
            yield
        finally:
            done.set()
            t.join()


def run(args: argparse.Namespace) -> int:
    from ..records import run_record

    t0 = time.perf_counter()
    _check_args(args)
    problem = _make_problem(args)
    show_bar = not (args.json or args.no_progress) and sys.stderr.isatty()
    with _progress(problem, show_bar):
        res = run_solver(args.solver, problem, budget=args.budget, seed=run_node(args))

    # the leaderboard's run record (ema_bench.records), plus what only a command line has;
    # case: the leaderboard's case name
    case = problem.label if args.measured is not None else \
        ("custom" if args.faults is not None else args.case or "small")
    out = run_record(problem, res, case=case,
                     track=problem.track, seed=args.seed, budget=args.budget,
                     root_seed=args.root_seed, wall_s=time.perf_counter() - t0,
                     info=get_solver(args.solver).library)
    out.update(normalised=problem.normalise, extra=res.extra)
    if args.measured is not None:  # one file: its path, as before several were accepted
        out["measured"] = args.measured[0] if len(args.measured) == 1 else args.measured
    if problem.has_truth:
        out["clock_at_success"] = problem.first_success_clock()
        if args.effect:
            out["effects"] = effects_of(args)
    if args.plot:
        _plot(problem, res, args)
        out["plot"] = args.plot
    iv = None
    if args.intervals is not None:
        iv = _intervals(problem, res, args)
        out.update(iv.as_dict())
        if args.interval_plot:
            out["interval_plots"] = _interval_plots(problem, iv, args)
    if args.json:
        print_json(out)
        return 0
    units = {f.name: f.unit for f in FAULTS}
    print(f"{res.solver} on {out['case']} ({out['track']} track, seed {args.seed}): "
          f"fitness {res.fitness:.6g} after {res.evaluations} of {args.budget} evaluations, "
          f"{res.wall_s:.2f} s, stopped: {res.stop_reason}")
    if problem.has_truth:
        print(f"{'fault':<6} {'unit':<4} {'estimate':>12} {'truth':>12} {'accuracy %':>11} "
              f"{'range err %':>11}")
        for name, v in out["x"].items():
            acc = out["accuracy"][name]
            acc_s = "-" if acc is None else f"{acc:.2f}"
            print(f"{name:<6} {units[name]:<4} {v:12.6g} {out['truth'][name]:12.6g} "
                  f"{acc_s:>11} {100 * out['range_error'][name]:11.3f}")
        first = out["evals_to_success"]
        print(f"fitness at the truth {out['fitness_at_truth']:.6g}; success (every range "
              f"error <= 1 %): {'yes' if out['success'] else 'no'}"
              + ("" if first is None else f"; first successful vector at evaluation {first}"))
    else:
        print(f"{'fault':<6} {'unit':<4} {'estimate':>12}")
        for name, v in out["x"].items():
            print(f"{name:<6} {units[name]:<4} {v:12.6g}")
    if iv is not None:
        _print_intervals(iv, out)
    if args.plot:
        print(f"plot written to {args.plot}")
    for path in out.get("interval_plots", []):
        print(f"interval plot written to {path}")
    return 0


def _intervals(problem, res, args: argparse.Namespace):
    try:
        return intervals(problem.objective, res.x, method=args.intervals, level=args.level,
                         track=problem.track, seed=stream(run_node(args), "intervals"))
    except UncertaintyError as exc:
        raise CLIError(f"no intervals: {exc}") from None


def _interval_plots(problem, iv, args: argparse.Namespace) -> list[str]:
    import numpy as np

    from ..uncertainty.plots import plot_profiles, plot_region

    truth = None
    if problem.has_truth:
        sc = problem.score(iv.estimate[:N_FAULTS]).truth
        truth = np.r_[[sc[n] for n in iv.names[:N_FAULTS]], np.zeros(len(iv.names) - N_FAULTS)]
    path = Path(args.interval_plot)
    plot_region(problem.objective, iv, path, truth=truth)
    paths = [str(path)]
    if iv.profiles:
        prof = path.with_name(f"{path.stem}_profiles{path.suffix}")
        plot_profiles(iv, prof, truth=truth)
        paths.append(str(prof))
    return paths


def _print_intervals(iv, out: dict) -> None:
    """Estimate and interval per parameter, and what the noise and tests say."""
    from ..uncertainty import conformal as cal

    # the table the factors came from, shipped or the user's (EMA_BENCH_CALIBRATION), named
    size = cal.calibration_size(iv.calibration, iv.method, iv.model_form)
    table = "" if iv.calibration == "none" else f" ({describe(cal.TABLE, size)})"
    print(f"{100 * iv.level:g} % {iv.method} intervals around the polished fit (fitness "
          f"{iv.fitness:.6g}; model form: {iv.model_form}; calibration: {iv.calibration}"
          f"{table}; {iv.evaluations} extra evaluations)")
    truth = out.get("truth") or {}
    print(f"{'param':<12} {'unit':<5} {'estimate':>12} {'interval':>28} {'width %':>8}"
          + (f" {'truth in':>8}" if truth else ""))
    for k, name in enumerate(iv.names):
        lo, hi, w = iv.low[k], iv.high[k], iv.width_percent()[k]
        line = (f"{name:<12} {iv.units.get(name, ''):<5} {iv.estimate[k]:12.6g} "
                f"{f'[{lo:.6g}, {hi:.6g}]':>28} {w:8.3f}")
        if name in truth:
            line += f" {'yes' if lo <= truth[name] <= hi else 'NO':>8}"
        print(line)
    ratio = ", ".join(f"{s} {v:.2f}" for s, v in iv.noise_ratio.items())
    print(f"residual noise / sensor noise: {ratio}")
    ident = iv.identifiability
    if ident["non_identifiable"]:
        print(f"practically non-identifiable from these tests: "
              f"{', '.join(ident['non_identifiable'])}")
    for c in ident["confounded"]:
        print(f"confounded: {c['pair'][0]} and {c['pair'][1]} (correlation "
              f"{c['correlation']:+.2f})")
    for w in iv.warnings:
        print(f"warning: {w}")


def _plot(problem, res, args: argparse.Namespace) -> None:
    from ..plots import plot_traces

    tests = tuple(KNOWN_TESTS[t] for t in problem.measured.tests)
    try:
        fitted = monitor_traces(res.x[:N_FAULTS], tests=tests)
    except SimulationError as exc:
        raise CLIError(f"cannot plot: {exc}") from None
    plot_traces([problem.measured, fitted], ["measured", f"fitted ({res.solver})"], args.plot,
                title=f"{res.solver} on {problem.label}: fitness {res.fitness:.4g}")


def run_solvers(args: argparse.Namespace) -> int:
    solvers = available_solvers()
    width = max((len(n) for n in solvers), default=4)
    lib_w = max((len(s.library) for s in solvers.values()), default=7)
    scope_w = max((len(s.scope) for s in solvers.values()), default=5)
    return print_result(args, [{"name": s.name, "description": s.description,
                                "library": s.library, "scope": s.scope,
                                "module": s.func.__module__} for s in solvers.values()],
                        [f"{s.name:<{width}}  {s.library:<{lib_w}}  {s.scope:<{scope_w}}  "
                         f"{s.description}" for s in solvers.values()])
