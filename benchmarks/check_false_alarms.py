"""How often does ``ema-bench leaderboard --check`` cry wolf, and does it catch a real loss?

A check compares a rerun with the committed baseline run by run (same solver, instance, track
and seed).  Same code, same seeds: the same runs, so no test is made.  What the check must
tolerate is a change that moves every run like a fresh draw (another compiler, a harmless
refactor that reorders floating-point sums): then "now" and "committed" are two independent
samples of the same solver.  This script plays that by resampling a pool of runs made at the
check's budget over many seeds (``--pool``, e.g. a ``--quick`` sweep with ``--seeds 10``):

- **false alarms**: for each trial, two disjoint sets of ``--seeds-per-check`` seeds; one plays
  "committed", the other "now" (relabelled to the committed seeds so that runs pair up);
  ``compare`` over every solver and track; the trial alarms if anything is flagged.
- **power**: the same, with one solver's "now" runs doctored worse (every target reached
  ``--slowdown`` times later, or missed when that is beyond the budget); the trial detects
  when that solver is flagged.

Prints (and with ``--json`` writes) the rates with Clopper-Pearson 95 % intervals.

    python benchmarks/check_false_alarms.py --pool leaderboards/quick leaderboards/check-pool \
        --trials 400 --json benchmarks/results/check_false_alarms.json

(``leaderboards/quick`` holds seeds 0-1 and ``leaderboards/check-pool`` seeds 2-5 of
``ema-bench leaderboard --quick --seeds 6``.)
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy import stats

from ema_bench.leaderboard.check import ALPHA, compare
from ema_bench.leaderboard.run_store import RUNS_FILE, read_records, unique


def relabel(records: list[dict], seeds: list[int]) -> list[dict]:
    """The runs of ``seeds``, their seeds renamed 0, 1, ... in that order."""
    index = {s: i for i, s in enumerate(seeds)}
    return [{**r, "seed": index[r["seed"]]} for r in records if r["seed"] in index]


def slow_down(record: dict, factor: float) -> dict:
    """A doctored worse run: every improvement found ``factor`` times later (its evidence,
    the trace and trajectory, moved: the scores re-derive the targets from it and never read
    the claims; what falls beyond the budget is cut, so those targets are missed)."""
    def later(points: list) -> list:
        return [[1 if p[0] == 1 else int(p[0] * factor), *p[1:]] for p in points]

    out = {**record, "evaluations": record["budget"], "trace": later(record["trace"])}
    if record.get("trajectory"):
        out["trajectory"] = later(record["trajectory"])
    return out


def interval(k: int, n: int) -> tuple[float, float]:
    """Clopper-Pearson 95 % interval of a rate k / n."""
    ci = stats.binomtest(k, n).proportion_ci(0.95, method="exact")
    return float(ci.low), float(ci.high)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pool", required=True, nargs="+", metavar="DIR",
                    help="folders whose runs.jsonl hold the check's runs over many seeds")
    ap.add_argument("--trials", type=int, default=400)
    ap.add_argument("--seeds-per-check", type=int, default=2)
    ap.add_argument("--slowdown", type=float, default=4.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=None, metavar="FILE")
    args = ap.parse_args(argv)

    pool = unique(r for d in args.pool for r in read_records(Path(d) / RUNS_FILE))
    seeds = sorted({r["seed"] for r in pool})
    solvers = sorted({r["solver"] for r in pool})
    need = 2 * args.seeds_per_check
    if len(seeds) < need:
        print(f"the pool has {len(seeds)} seeds; {need} are needed", file=sys.stderr)
        return 2
    rng = np.random.default_rng(args.seed)
    alarms = detections = 0
    flagged_by: dict[str, int] = {}
    for i in range(args.trials):
        pick = rng.permutation(seeds)[:need].tolist()
        committed = relabel(pool, pick[:args.seeds_per_check])
        now = relabel(pool, pick[args.seeds_per_check:])
        bad = compare(now, committed)
        alarms += bool(bad)
        for r in bad:
            flagged_by[r.solver] = flagged_by.get(r.solver, 0) + 1
        victim = solvers[i % len(solvers)]
        doctored = [slow_down(r, args.slowdown) if r["solver"] == victim else r for r in now]
        detections += any(r.solver == victim for r in compare(doctored, committed))
    out = {"pool": args.pool, "runs": len(pool), "seeds": len(seeds),
           "solvers": solvers, "trials": args.trials, "alpha": ALPHA,
           "seeds_per_check": args.seeds_per_check,
           "false_alarm_rate": alarms / args.trials,
           "false_alarm_ci95": interval(alarms, args.trials),
           "false_alarms_by_solver": flagged_by,
           "slowdown": args.slowdown, "detection_rate": detections / args.trials,
           "detection_ci95": interval(detections, args.trials)}
    print(json.dumps(out, indent=1))
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
