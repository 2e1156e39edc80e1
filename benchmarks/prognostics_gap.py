"""Where a tracker loses against a level of the data-only bound, unit by unit.

Reads a tracker's lines of ``benchmarks/prognostics_offline.py`` (``tracker``: its expected hit
at each failing unit's cut) and the lines of ``benchmarks/prognostics_ceiling.py`` on the same
campaign (one expected hit per level), both judged on the board's futures of each unit (the
same ``oracle`` figure: checked), and prints, for the units of one failing fault, each unit's
cut position, whether its short had begun by the cut, the two expected hits and their
difference (sorted, the largest loss first), then the ratios to the oracle and the paired
difference (bootstrap over units, 4,000 resamples, seed 0: ``prognostics_offline``'s) overall
and by cut position (``tables.GROUPS``) and by ``begun``::

    python benchmarks/prognostics_gap.py leaderboards/campaign/fleet-bayes-whole-offline.jsonl \\
        leaderboards/campaign/coil-short-ceiling.jsonl --level fits --fault Na
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from prognostics_offline import _ratio  # benchmarks/ (the script's folder) is on the path

from ema_bench.prognostics.tables import GROUPS

POSITIONS = ("early", "mid", "late")


def _lines(path: Path) -> dict[str, dict]:
    return {d["unit"]: d for d in map(json.loads, path.read_text().splitlines())}


def joined(tracker: Path, ceiling: Path, level: str, fault: str) -> list[dict]:
    """One row per unit of ``fault`` in both files: ``tracker``, ``committed`` (the level's
    expected hit, under the name ``_ratio`` pairs against) and ``oracle``."""
    t, c = _lines(tracker), _lines(ceiling)
    rows = []
    for u in sorted(set(t) & set(c)):
        if c[u]["failing_fault"] != fault:
            continue
        if abs(t[u]["oracle"] - c[u]["oracle"]) > 1e-9:
            raise SystemExit(f"{u}: the two files judge on other futures (oracle "
                             f"{t[u]['oracle']} against {c[u]['oracle']})")
        pos = next(g for g in POSITIONS if GROUPS[g](c[u]))
        rows.append({"unit": u, "position": pos, "begun": c[u]["begun"],
                     "tracker": t[u]["tracker"], "committed": c[u][level],
                     "oracle": c[u]["oracle"], "point": t[u]["rul"],
                     "level_point": c[u]["points"][level],
                     "oracle_point": c[u]["points"]["oracle"]})
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("tracker", type=Path, help="prognostics_offline.py lines")
    p.add_argument("ceiling", type=Path, help="prognostics_ceiling.py lines, same campaign")
    p.add_argument("--level", default="fits", help="the bound's level (default fits)")
    p.add_argument("--fault", default="Na", help="failing fault (default Na)")
    a = p.parse_args()
    rows = joined(a.tracker, a.ceiling, a.level, a.fault)
    for r in sorted(rows, key=lambda r: r["tracker"] - r["committed"]):
        print(f"{r['unit']} {r['position']:5s} begun {int(r['begun'])}: tracker "
              f"{r['tracker']:.3f} (point {r['point']:.1f}), {a.level} {r['committed']:.3f} "
              f"({r['level_point']:.1f}), oracle {r['oracle']:.3f} ({r['oracle_point']:.1f}),"
              f" difference {r['tracker'] - r['committed']:+.3f}")
    groups = {"all": rows, **{g: [r for r in rows if r["position"] == g] for g in POSITIONS},
              "begun": [r for r in rows if r["begun"]],
              "not begun": [r for r in rows if not r["begun"]]}
    q = np.quantile
    for name, sel in groups.items():
        if not sel:
            continue
        idx = np.random.default_rng(0).integers(0, len(sel), (4000, len(sel)))
        (t, tb), (c, cb) = _ratio(sel, "tracker", idx), _ratio(sel, "committed", idx)
        lost = sum(r["committed"] - r["tracker"] for r in sel)
        print(f"{a.fault} {name} ({len(sel)} units): tracker {t:.3f} [{q(tb, .025):.3f}, "
              f"{q(tb, .975):.3f}], {a.level} {c:.3f} [{q(cb, .025):.3f}, {q(cb, .975):.3f}];"
              f" difference {t - c:+.3f} [{q(tb - cb, .025):+.3f}, {q(tb - cb, .975):+.3f}]"
              f", {lost:+.2f} expected hits lost")


if __name__ == "__main__":
    main()
