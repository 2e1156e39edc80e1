"""Paired difference of two trackers' expected-hit ratios to the oracle on one campaign.

Reads the ``--json`` output of ``ema-bench campaign score`` (with its per-unit rows) and
prints, per track and failing fault, each tracker's expected hits over the oracle's (summed
over the failing units both scored) and the difference's 95 % interval from a paired
bootstrap over units (4,000 resamples, seed 0: the bootstrap of
``benchmarks/prognostics_offline.py``)::

    ema-bench campaign score RUN... --json > scores_full.json
    python benchmarks/prognostics_paired.py scores_full.json fleet-bayes-whole fleet-bayes-cut
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from prognostics_offline import _ratio  # benchmarks/ (the script's folder) is on the path


def _hits(rows: list[dict]) -> dict[str, float]:
    return {u["unit"]: u["expected_hit"] for u in rows if u.get("expected_hit") is not None}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scores", help="campaign score --json output (with per-unit rows)")
    p.add_argument("a", help="tracker a (the difference is a - b)")
    p.add_argument("b", help="tracker b")
    args = p.parse_args()
    by = {(r["tracker"], r["track"]): r for r in json.load(open(args.scores))}
    for track in dict.fromkeys(t for _, t in by):
        if (args.a, track) not in by or (args.b, track) not in by:
            continue
        ra, rb = by[(args.a, track)], by[(args.b, track)]
        ea, eb, oracle = _hits(ra["per_unit"]), _hits(rb["per_unit"]), _hits(
            ra["oracle_per_unit"])
        fault = {u["unit"]: u["failing_fault"] for u in ra["per_unit"]}
        units = sorted(set(ea) & set(eb) & set(oracle))
        for g in (None, "Fst", "BLK", "Na"):
            sel = [u for u in units if g is None or fault[u] == g]
            if not sel:
                continue
            lines = [{"a": ea[u], "b": eb[u], "oracle": oracle[u]} for u in sel]
            idx = np.random.default_rng(0).integers(0, len(sel), (4000, len(sel)))
            (ra, ba), (rb, bb) = _ratio(lines, "a", idx), _ratio(lines, "b", idx)
            lo, hi = np.quantile(ba - bb, [0.025, 0.975])
            print(f"{track} {g or 'all'} ({len(sel)} failing): {args.a} {ra:.3f}, {args.b} "
                  f"{rb:.3f}, difference {ra - rb:+.3f} [{lo:+.3f}, {hi:+.3f}]")


if __name__ == "__main__":
    main()
