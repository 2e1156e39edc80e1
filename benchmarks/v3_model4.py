"""Suite emafdi-v3's move to model version 4: its best-known table against version 3's.

v3 read v2's tables (v1's for tier 4 with full information) on model version 3 until it
moved to version 4 (``suite_targets_v3.json``, ``ema-bench targets --suite emafdi-v3``).

For every entry of v3's table, the version-3 entry of the same problem, track and seed:
whether ``f*`` and ``x*`` are identical to the bit, the relative change of ``f*`` and the
largest move of ``x*`` in % of range, per tier, condition and track, then the largest moves
(a few CPU-seconds, no simulation).

    python benchmarks/v3_model4.py > benchmarks/results/v3_model4_shift.md
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from ema_bench.suites import instance, v2, v3
from ema_bench.suites.targets import target_key


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


def main() -> None:
    rows = [shift(k, e) for k, e in sorted(v3.shipped_targets()["entries"].items())]
    groups: dict = defaultdict(list)
    for r in rows:
        groups[r["group"]].append(r)
    print("# Suite emafdi-v3's best-known entries: model version 4 against version 3\n")
    print(f"{len(rows)} entries polished on model version 4; f* identical to the bit on "
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
