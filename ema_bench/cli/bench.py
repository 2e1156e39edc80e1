"""``ema-bench bench``: model speed on this machine, measured side by side in one run.

Figures: monitor evaluations per second (both tests, 8 outputs) for a batch and one at a time,
reference-model wall time per episode, the naive ``solve_ivp`` baseline and the ratios.
"""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="measure model speed (monitor, reference, naive baseline)",
                       description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--batch", type=int, default=256, help="candidates per batch (default 256)")
    p.add_argument("--repeat", type=int, default=3, help="timed repetitions, best kept")
    p.add_argument("--naive", type=int, default=1, metavar="N",
                   help="candidates through the slow solve_ivp baseline (default 1)")
    p.add_argument("--seed", type=int, default=0, help="root seed (default 0)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..bench import run_bench
    from . import CLIError, print_json

    if args.batch < 1 or args.repeat < 1 or args.naive < 1:
        raise CLIError("--batch, --repeat and --naive must be >= 1")
    result = run_bench(batch=args.batch, repeat=args.repeat, naive_candidates=args.naive,
                       seed=args.seed)
    if args.json:
        print_json(result)
        return 0
    print(f"monitor, batch of {result['batch']:>4}: {result['monitor_evals_per_s']:10.0f} evals/s")
    print(f"monitor, one at a time:  {result['monitor_single_evals_per_s']:10.0f} evals/s")
    print(f"naive solve_ivp:         {result['naive_evals_per_s']:10.3f} evals/s")
    print(f"speed-up vs naive:       {result['speedup_vs_naive']:10.0f} x (batched)")
    print(f"reference episode:       {result['reference_episode_s']:10.3f} s")
    print(f"reference / monitor cost per simulated second, one thread: "
          f"{result['monitor_vs_reference_cost_ratio']:.0f} x")
    return 0
