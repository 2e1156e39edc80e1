"""Two source trees' kernel speed, interleaved: tier 4, 7 and 12 evaluations per CPU second of
suite emafdi-v2 (``ema_bench.bench.tier_rates``, what ``ema-bench bench`` reports as
``tier_evals_per_cpu_s``; and ``12 single``: tier-12 candidates one a call, the scalar
kernel) of an old build against a new one, measured in alternating rounds
(old, new, new, old, ...) so a burst of load from elsewhere hits both alike.

Each tree runs in ``--procs`` processes of its own that import ``ema_bench`` from it
(``PYTHONPATH``; its numba cache is its own, so the first run compiles), set the tiers up once
and time one round per request.  Why several: one process of a tree runs steadily 10-20 %
faster or slower than another of the same tree (an A/A run, ``--old . --new .``, gave 0.87 with
one process each), which would pass for a change.  Every figure is the median over all
rounds of a tree's processes, CPU time on one thread; the ratio is new over old (1.0: no
change); ``spread`` is the range of the processes' own medians.  Make the old tree with
``git worktree add --detach /tmp/old COMMIT`` (remove it after: ``git worktree remove
/tmp/old``).

    python benchmarks/build_ab.py --old /tmp/old [--new .] [--procs 3] [--batch 32]
        [--rounds 9] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

# the worker: set the tiers up, then one round of tier_rates per line read
_WORKER = """
import json, sys, time
import ema_bench
from ema_bench.bench import one_thread, tier_rates, tier_setups
setups = tier_setups(int(sys.argv[1]))
obj, X = setups[12]
print(json.dumps({"tree": ema_bench.__file__}), flush=True)
for _ in sys.stdin:
    out = {str(t): r for t, r in tier_rates(setups).items()}
    with one_thread():   # one candidate a call: the scalar kernel
        t0 = time.process_time()
        for x in X[:16]:
            obj.evaluate(x[None, :])
        out["12 single"] = 16 / (time.process_time() - t0)
    print(json.dumps(out), flush=True)
"""


def _start(tree: Path, batch: int) -> tuple[subprocess.Popen, str]:
    tree = tree.resolve()
    env = {**os.environ, "PYTHONPATH": str(tree)}
    # in the tree: ``python -c`` puts the working directory first on the path
    proc = subprocess.Popen([sys.executable, "-c", _WORKER, str(batch)], env=env, text=True,
                            cwd=tree, stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    hello = json.loads(proc.stdout.readline())["tree"]
    if not Path(hello).resolve().is_relative_to(tree):
        proc.kill()
        raise SystemExit(f"{tree}: ema_bench was imported from {hello}, not from the tree")
    return proc, hello


def _round(proc: subprocess.Popen) -> dict[str, float]:
    proc.stdin.write("go\n")
    proc.stdin.flush()
    return json.loads(proc.stdout.readline())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", type=Path, required=True, help="the old source tree")
    ap.add_argument("--new", type=Path, default=Path("."), help="the new one (default: .)")
    ap.add_argument("--procs", type=int, default=3, help="processes per tree")
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    loads = [os.getloadavg()[0]]
    procs = {(name, i): _start(tree, a.batch)[0] for i in range(a.procs)
             for name, tree in (("old", a.old), ("new", a.new))}
    rounds: dict[tuple[str, int], list[dict[str, float]]] = {k: [] for k in procs}
    order = list(procs)
    try:
        for k in range(a.rounds):   # old first, then new first, and so on
            for key in (order if k % 2 == 0 else order[::-1]):
                rounds[key].append(_round(procs[key]))
    finally:
        for proc in procs.values():
            proc.stdin.close()
            proc.wait()
    loads.append(os.getloadavg()[0])
    tiers = list(rounds[order[0]][0])
    rates = {name: {t: statistics.median(r[t] for (n, _), rs in rounds.items() if n == name
                                         for r in rs) for t in tiers} for name in ("old", "new")}
    spread = {name: {t: [min(m := [statistics.median(r[t] for r in rs)
                                   for (n, _), rs in rounds.items() if n == name]), max(m)]
                     for t in tiers} for name in ("old", "new")}
    out = {"batch": a.batch, "rounds": a.rounds, "procs": a.procs, "evals_per_cpu_s": rates,
           "new_over_old": {t: rates["new"][t] / rates["old"][t] for t in tiers},
           "spread": spread, "load_avg": loads}
    if a.json:
        print(json.dumps(out, indent=1))
        return
    for t, v in out["new_over_old"].items():
        lo, hi = spread["old"][t], spread["new"][t]
        print(f"tier {t:>2}: old {rates['old'][t]:8.1f} ({lo[0]:.0f}..{lo[1]:.0f}), new "
              f"{rates['new'][t]:8.1f} ({hi[0]:.0f}..{hi[1]:.0f}) evals/CPU-s  "
              f"(new/old {v:.3f})")
    print(f"load average before/after: {loads[0]:.2f} / {loads[1]:.2f}")


if __name__ == "__main__":
    main()
