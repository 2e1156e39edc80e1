"""Does iohinspector's AOCC on the precision export rank solvers as the board does?

    ema-bench export --format ioh leaderboards/runs.jsonl --value precision --out /tmp/prec
    python benchmarks/ioh_aocc_agreement.py /tmp/prec leaderboards/runs.jsonl

Per track, every pair of solvers whose board ECDF-area intervals (95 % bootstrap) separate is
checked for the same order in the AOCC (log-precision axis from 10^-4.5 to 10^-0.5: half a
decade beyond the suite's fitness targets 1e-1 .. 1e-4; log evaluations up to the budget).
Needs the [ioh] extra.  On the committed board (5280 runs): 92 separated pairs, 92 agree.
"""

from __future__ import annotations

import sys

import iohinspector as ih
import polars as pl

from ema_bench.leaderboard.anytime import anytime_scores
from ema_bench.leaderboard.run_store import read_records

LB, UB = 10 ** -4.5, 10 ** -0.5


def main(folder: str, runs: str) -> int:
    dm = ih.DataManager()
    dm.add_folder(folder)
    df = dm.load(monotonic=True, include_meta_data=True)
    df = df.with_columns(track=pl.col("function_name").str.split("@").list.get(1))
    df = ih.metrics.transform_fval(df, lb=LB, ub=UB, scale_log=True)
    recs = read_records(runs)
    aocc = ih.metrics.get_aocc(df, eval_max=max(r["budget"] for r in recs),
                               free_vars=["algorithm_name", "track"], scale_eval_log=True,
                               return_as_pandas=False)
    area = {(r["track"], r["algorithm_name"]): r["AOCC"] for r in aocc.iter_rows(named=True)}
    board = {(s.track, s.solver): s.row() for s in anytime_scores(recs)}
    pairs = agree = 0
    for (t, a), ra in sorted(board.items(), key=lambda kv: -kv[1]["ecdf_area"]):
        print(f"{t:9} {a:14} ECDF area {ra['ecdf_area']:.3f} [{ra['ecdf_area_lo']:.3f}, "
              f"{ra['ecdf_area_hi']:.3f}]  AOCC {area[(t, a)]:.3f}")
        for (u, b), rb in board.items():
            if t == u and ra["ecdf_area_lo"] > rb["ecdf_area_hi"]:
                pairs += 1
                agree += area[(t, a)] > area[(t, b)]
    print(f"separated pairs: {pairs}, AOCC agrees on {agree}")
    return 0 if agree == pairs else 1


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:3]))
