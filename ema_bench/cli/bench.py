"""``ema-bench bench``: model speed on this machine, measured side by side in one run.

Interleaved rounds, medians, CPU time beside wall time and the load average seen:
monitor evaluations per second batched on all threads and per CPU second on one thread; the
cost of a one-candidate call (idle, and with every core kept busy by other processes; and of
a tier-12 one); the objective's evaluations per CPU second on suite emafdi-v2's tiers 4, 7
and 12 and their ratios to tier 4; the numba/C time ratios, scalar and lanes, the lanes also
against the 8-lane C twin on tiers 4 and 12 (needs a C compiler and a source checkout:
benchmarks/c/monitor.c); the plain-Python baseline (the same equations, JIT off); import,
cache-load and cold-compile times; the median time to a successful identification for cmaes
and powell on the four paper cases, in this process and from a cold command line.  See
``ema_bench.bench`` for every key.

It takes a few minutes; --quick skips the start-up and time-to-success figures.
"""

from __future__ import annotations

import argparse
import sys

from . import print_result
from .args import add_json, count, seed_number


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="measure model speed and time to a solution")
    p.add_argument("--batch", type=count(1, 65_536), default=256,
                   help="candidates per batch (default 256)")
    p.add_argument("--repeat", type=count(1, 1000), default=7,
                   help="interleaved rounds, medians reported (default 7)")
    p.add_argument("--naive", type=count(1, 1000), default=2, metavar="N",
                   help="evaluations of the plain-Python baseline (default 2, ~0.5 s each)")
    p.add_argument("--tts-seeds", type=count(1, 1000), default=3, metavar="N",
                   help="seeds per case for the time to success (default 3)")
    p.add_argument("--quick", action="store_true",
                   help="skip the start-up and time-to-success figures")
    p.add_argument("--seed", type=seed_number, default=0, help="root seed (default 0)")
    add_json(p)


def _fmt(v: object, spec: str) -> str:
    return "n/a" if v is None else format(v, spec)


def run(args: argparse.Namespace) -> int:
    from ..bench import run_bench

    show = None if args.json else (lambda msg: print(f"... {msg}", file=sys.stderr))
    r = run_bench(batch=args.batch, repeat=args.repeat, naive_evals=args.naive,
                  tts_seeds=args.tts_seeds, seed=args.seed, startup=not args.quick,
                  tts=not args.quick, progress=show)
    la = r["load_avg"]
    return print_result(args, r, [
        f"monitor, batched ({r['numba_threads']} threads): {r['monitor_evals_per_s']:9.0f} "
        "evals/s",
        f"monitor, one thread:        {r['monitor_evals_per_cpu_s']:9.0f} evals/CPU-s "
        f"(lanes; scalar kernel {r['monitor_evals_per_cpu_s_scalar']:.0f}, "
        f"{r['lanes_speedup']:.2f}x)",
        f"one-candidate call:         {r['single_call_ms']:9.2f} ms "
        f"({r['single_call_ms_loaded']:.2f} ms with every core busy)",
        f"numba / C time (scalar):    {_fmt(r['c_time_ratio'], '9.2f')}"
        f"  (numba lanes / scalar C: {_fmt(r['lanes_c_time_ratio'], '.2f')})"
        + (f"  ({r['c_unavailable']})" if r["c_unavailable"] else ""),
        *(f"numba lanes / 8-lane C, tier {t:>2}: {v:5.2f}  (C lanes / scalar C "
          f"{r['c_lanes_vs_c_scalar'][t]:.2f})"
          for t, v in (r["c_lanes_time_ratio"] or {}).items()),
        "objective, one thread:      "
        + "  ".join(f"tier {t} {v:.0f} evals/CPU-s ({r['tier_ratio'][t]:.2f}x tier 4)"
                    for t, v in r["tier_evals_per_cpu_s"].items()),
        f"one tier-12 candidate:      {r['single_call_ms_tier12']:9.2f} ms",
        f"plain Python, one thread:   {r['naive_python_evals_per_s']:9.2f} evals/CPU-s "
        f"(numba {r['speedup_vs_naive_python']:.0f}x faster)",
        f"reference episode:          {r['reference_episode_s']:9.3f} s",
        *([f"import / cache load / cold compile: {r['import_s']:.2f} / "
           f"{r['cache_load_s']:.2f} / {r['cold_compile_s']:.1f} s"] if "import_s" in r else []),
        *(f"time to success, {label}, {solver:<7} (s): "
          + "  ".join(f"{c} {_fmt(v, '.2f')}" for c, v in cases.items())
          for key, label in (("time_to_success_warm_s", "warm"),
                             ("time_to_success_cold_s", "cold"))
          for solver, cases in r.get(key, {}).items()),
        f"load average: {la['before']:.2f} before, {la['max']:.2f} max, {la['after']:.2f} "
        "after"])
