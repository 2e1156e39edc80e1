"""Two source trees' kernel speed, interleaved: tier 4, 7 and 12 evaluations per CPU second of
suite emafdi-v2 (``ema_bench.bench.tier_rates``, what ``ema-bench bench`` reports as
``tier_evals_per_cpu_s``) of an old build against a new one, measured in alternating rounds
(old, new, new, old, ...) so a burst of load from elsewhere hits both alike.

Each tree runs in a process of its own that imports ``ema_bench`` from it (``PYTHONPATH``;
its numba cache is its own, so the first run compiles), sets the tiers up once and times one
round per request.  Every figure is the median over rounds, CPU time on one thread; the ratio
is new over old (1.0: no change).  Make the old tree with ``git worktree add --detach
/tmp/old COMMIT`` (and remove it after with ``git worktree remove /tmp/old``).

    python benchmarks/build_ab.py --old /tmp/old [--new .] [--batch 32] [--rounds 9] [--json]
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
import json, sys
import ema_bench
from ema_bench.bench import tier_rates, tier_setups
setups = tier_setups(int(sys.argv[1]))
print(json.dumps({"tree": ema_bench.__file__}), flush=True)
for _ in sys.stdin:
    print(json.dumps({str(t): r for t, r in tier_rates(setups).items()}), flush=True)
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
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    loads = [os.getloadavg()[0]]
    procs = {name: _start(tree, a.batch)[0] for name, tree in (("old", a.old), ("new", a.new))}
    rounds: dict[str, list[dict[str, float]]] = {"old": [], "new": []}
    try:
        for k in range(a.rounds):   # old first, then new first: ABBA
            for name in (("old", "new") if k % 2 == 0 else ("new", "old")):
                rounds[name].append(_round(procs[name]))
    finally:
        for proc in procs.values():
            proc.stdin.close()
            proc.wait()
    loads.append(os.getloadavg()[0])
    rates = {name: {t: statistics.median(r[t] for r in rs) for t in rs[0]}
             for name, rs in rounds.items()}
    out = {"batch": a.batch, "rounds": a.rounds, "evals_per_cpu_s": rates,
           "new_over_old": {t: rates["new"][t] / rates["old"][t] for t in rates["old"]},
           "load_avg": loads}
    if a.json:
        print(json.dumps(out, indent=1))
        return
    for t, v in out["new_over_old"].items():
        print(f"tier {t:>2}: old {rates['old'][t]:8.1f}, new {rates['new'][t]:8.1f} "
              f"evals/CPU-s  (new/old {v:.3f})")
    print(f"load average before/after: {loads[0]:.2f} / {loads[1]:.2f}")


if __name__ == "__main__":
    main()
