"""Suite emafdi-v3's move to model version 4: its best-known table against version 3's.

v3 read v2's tables (v1's for tier 4 with full information) on model version 3 until it
moved to version 4 (``suite_targets_v3.json``, ``ema-bench targets --suite emafdi-v3``).

- default: for every entry of v3's table recomputed on version 4, the version-3 entry of the
  same problem, track and seed: whether ``f*`` and ``x*`` are identical to the bit, the
  relative change of ``f*`` and the largest move of ``x*`` in % of range, per tier,
  condition and track, then the largest moves (a few CPU-seconds, no simulation);
- ``--carry``: while the recomputation is unfinished (it resumes from
  ``suite_targets_v3.json.partial.jsonl``), write the table of the entries recomputed so
  far and fill each key still missing from its version-3 entry: its polished point ``x*``
  (and clean-data fit) kept, ``f*``, ``f_nominal`` and the fitness at the truth evaluated
  on version 4 (three evaluations a key; where the truth is lower, it is ``x*``),
  ``"carried": "3"`` (not polished on version 4: a
  version-4 polish may find a lower ``f*``; the default report says by how much the
  recomputed ones did).

    python benchmarks/v3_model4.py --carry          # after an interrupted 'ema-bench targets'
    python benchmarks/v3_model4.py > benchmarks/results/v3_model4_shift.md
"""

from __future__ import annotations

import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from ema_bench.faults import NOMINAL
from ema_bench.jsonio import write_atomic
from ema_bench.seeding import run_seed
from ema_bench.suites import instance, v2, v3
from ema_bench.suites.best_known import ENTRY_SCHEMA, compute_targets
from ema_bench.suites.problem import make_problem
from ema_bench.suites.targets import target_key
from ema_bench.sweep.store import Store

TABLE = Path("ema_bench") / v3.TARGETS_FILE


def version_3_entry(key: str) -> dict:
    """The entry v3 read before it moved to model version 4: v2's case's (v1's table on
    tier 4 with full information)."""
    case, track, seed = key.split("|")
    base = instance(case.removeprefix(v3.PREFIX))
    entry = base.best_known(track, int(seed), 0, v2.SUITE.model_version)
    if entry is None:
        raise SystemExit(f"{key}: no version-3 entry of {target_key(base.case, track, seed)}")
    return entry


def shift(key: str, new: dict) -> dict:
    inst = instance(key.split("|")[0])
    old = version_3_entry(key)
    x4 = np.array([new["x_star"][n] for n in inst.names])
    x3 = np.array([old["x_star"][n] for n in inst.names])
    move = np.abs(x4 - x3) / inst.ranges
    return {"key": key, "group": (inst.group[0], inst.group[1], key.split("|")[1]),
            "f_same": new["f_star"] == old["f_star"], "x_same": bool(np.all(x4 == x3)),
            "f_rel": (new["f_star"] - old["f_star"]) / old["f_star"],
            "x_move": float(move.max()), "x_worst": inst.names[int(np.argmax(move))]}


def carried(key: str, entry: dict) -> dict:
    """The version-3 ``entry`` of ``key`` on version 4: ``f*`` at its ``x*``, ``f_nominal``
    and the fitness at the truth evaluated on version 4's problem (one point a call, as
    the tests recompute them)."""
    case, track, seed = key.split("|")
    p = make_problem(case, track=track, seed=run_seed(0, int(seed)), budget=1)
    inst = instance(case)
    nominal = np.r_[NOMINAL, np.zeros(inst.dim - NOMINAL.size)]
    x = np.array([entry["x_star"][n] for n in p.names])
    f = {name: float(p.objective.evaluate(v[None, :])[0][0])
         for name, v in (("f_star", x), ("f_nominal", nominal), ("fitness_at_truth",
                                                                 inst.truth))}
    new = {**entry, **f, "carried": "3"}
    if f["fitness_at_truth"] < f["f_star"]:   # the truth is the best point known now
        new.update(f_star=f["fitness_at_truth"], x_star=dict(zip(p.names, inst.truth)),
                   bias_range_error=0.0, bias_range_errors=dict.fromkeys(p.names, 0.0))
    return new


def carry() -> None:
    """The table of the recomputed entries, the missing keys carried where they reproduce."""
    partial = TABLE.with_name(TABLE.name + ".partial.jsonl")
    with Store(partial, identity=lambda r: r["key"], schema=ENTRY_SCHEMA) as store:
        done = {r["key"] for r in store.records}
    keys = v3.target_keys()
    data = compute_targets(TABLE, workers=1, quiet=True, keys=[k for k in keys if k in done])
    moved = []
    for key in keys:
        if key in done:
            continue
        old = version_3_entry(key)
        data["entries"][key] = new = carried(key, old)
        moved.append((new["f_star"] - old["f_star"]) / old["f_star"])
    data["method"]["carried"] = {"entries": len(moved),
                                 "command": "python benchmarks/v3_model4.py --carry"}
    write_atomic(TABLE, json.dumps(data, indent=0, sort_keys=True) + "\n")
    m = np.abs(moved) if moved else np.zeros(1)
    print(f"{len(done)} entries recomputed on model version 4, {len(moved)} carried from "
          f"version 3 (x* kept, f* evaluated on version 4: changed on {int(np.sum(m > 0))}, "
          f"by at most {m.max():.2e} of f*)")


def main() -> None:
    if sys.argv[1:] == ["--carry"]:
        return carry()
    entries = v3.shipped_targets()["entries"]
    carried = sum("carried" in e for e in entries.values())
    rows = [shift(k, e) for k, e in sorted(entries.items()) if "carried" not in e]
    groups: dict = defaultdict(list)
    for r in rows:
        groups[r["group"]].append(r)
    print("# Suite emafdi-v3's best-known entries: model version 4 against version 3\n")
    print(f"{len(rows)} entries recomputed on model version 4 ({carried} more carried from "
          f"version 3 until recomputed); f* identical to the bit on "
          f"{sum(r['f_same'] for r in rows)}, x* on {sum(r['x_same'] for r in rows)}; "
          f"f* lower on version 4 on {sum(r['f_rel'] < 0 for r in rows)}, higher on "
          f"{sum(r['f_rel'] > 0 for r in rows)}.\n")
    print("| tier | condition | track | entries | f* changed | x* changed | largest f* "
          "change (abs, of f*) | median | largest x* move (% of range) | median |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for (d, cond, track), g in sorted(groups.items()):
        fr = np.abs([r["f_rel"] for r in g])
        xm = np.array([r["x_move"] for r in g]) * 100
        print(f"| {d} | {cond} | {track} | {len(g)} | {sum(not r['f_same'] for r in g)} | "
              f"{sum(not r['x_same'] for r in g)} | {fr.max():.2e} | {np.median(fr):.1e} | "
              f"{xm.max():.3f} | {np.median(xm):.4f} |")
    for title, order in (("The largest moves", lambda r: -r["x_move"]),
                         ("The largest changes of f*", lambda r: -abs(r["f_rel"]))):
        print(f"\n## {title}\n")
        print("| entry | f* change (of f*) | x* move (% of range) | on |")
        print("|---|---|---|---|")
        for r in sorted(rows, key=order)[:10]:
            print(f"| {r['key'].replace('|', ' ')} | {r['f_rel']:+.2e} | "
                  f"{100 * r['x_move']:.3f} | {r['x_worst']} |")


if __name__ == "__main__":
    main()
