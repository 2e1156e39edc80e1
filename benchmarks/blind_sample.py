"""A stratified sample of a committed blind suite, rerun with the current workflow, old vs new.

The whole committed suite of root seed 9672 (60 cases) costs about 35 CPU-min; this reruns
``--per`` cases of each category (drawn with ``--sample-seed``, so no case is picked by hand)
and writes ``OUT/blind.jsonl`` (resumable, as ``ema-bench blind`` writes it),
``OUT/summary.json`` (:func:`~ema_bench.diagnosis.blind.summarise` of the sample) and
``OUT/compare.json``: per case the committed and the new verdict, names and CPU seconds, and
per category the median CPU time of both.

    python benchmarks/blind_sample.py --committed leaderboards/blind_r3/rerun_seed9672 \\
        --cases 60 --seed 9672 --per 2 --sample-seed 46 --workers 2 \\
        --out leaderboards/blind_r4/sample_seed9672
"""

from __future__ import annotations

import argparse
import functools
import json
import statistics
import sys
from pathlib import Path

import numpy as np

from ema_bench.diagnosis import blind
from ema_bench.diagnosis.results import Settings
from ema_bench.jsonio import dumps
from ema_bench.leaderboard.run_store import read_records
from ema_bench.sweep.loop import run_sweep
from ema_bench.sweep.store import Store, is_current


def sample(cases: list[blind.BlindCase], per: int, seed: int) -> list[blind.BlindCase]:
    """``per`` cases of each category (all when it has fewer), drawn by ``seed``, in index
    order."""
    rng = np.random.default_rng(seed)
    out = []
    for c in dict.fromkeys(x.category for x in cases):
        of = [x for x in cases if x.category == c]
        out += [of[i] for i in sorted(rng.choice(len(of), min(per, len(of)), replace=False))]
    return sorted(out, key=lambda x: x.index)


def _outcome(r: dict) -> dict:
    return {"verdict": r["verdict"], "named": r["named"],
            "named_acquisition": r.get("named_acquisition", []), "partial": r.get("partial"),
            "cpu_s": round(float(r.get("cpu_s", float("nan"))), 1)}


def compare(old: dict[str, dict], new: list[dict]) -> dict:
    """Per case old and new outcomes, and per category the median CPU seconds of both."""
    rows = [{"key": r["key"], "category": r["category"], "old": _outcome(old[r["key"]]),
             "new": _outcome(r)} for r in new]
    cats = {}
    for c in dict.fromkeys(r["category"] for r in rows):
        rs = [r for r in rows if r["category"] == c]
        cats[c] = {"cases": len(rs),
                   "same_outcome": sum(r["old"]["verdict"] == r["new"]["verdict"]
                                       and r["old"]["named"] == r["new"]["named"]
                                       and r["old"]["named_acquisition"]
                                       == r["new"]["named_acquisition"] for r in rs),
                   "median_cpu_s_old": statistics.median(r["old"]["cpu_s"] for r in rs),
                   "median_cpu_s_new": statistics.median(r["new"]["cpu_s"] for r in rs)}
    every = {"median_cpu_s_old": statistics.median(r["old"]["cpu_s"] for r in rows),
             "median_cpu_s_new": statistics.median(r["new"]["cpu_s"] for r in rows)}
    return {"categories": cats, "all": every, "cases": rows}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--committed", required=True, help="folder of the committed suite")
    p.add_argument("--cases", type=int, required=True)
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--per", type=int, default=2)
    p.add_argument("--sample-seed", type=int, required=True)
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--out", required=True)
    a = p.parse_args(argv)
    chosen = sample(blind.draw_cases(a.cases, a.seed), a.per, a.sample_seed)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    run = functools.partial(blind._run_task, blind.run_case, a.seed, Settings())
    with Store(out / blind.CASES_FILE, schema=blind.CASE_SCHEMA) as store:
        run_sweep([blind._job(c) for c in chosen], run, [store],
                  executor="serial" if a.workers <= 1 else "processes", workers=a.workers,
                  label="blind", unit="case", quiet=False)
        got = {r["key"]: r for r in store.records if is_current(r)}
    records = [got[f"case{c.index}"] for c in chosen]
    (out / "summary.json").write_text(dumps(blind.summarise(records), indent=1))
    old = {r["key"]: r for r in read_records(Path(a.committed) / blind.CASES_FILE)}
    res = compare(old, records)
    (out / "compare.json").write_text(json.dumps(res, indent=1))
    print(json.dumps({"categories": res["categories"], "all": res["all"]}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
