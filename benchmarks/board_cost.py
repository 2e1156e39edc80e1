"""The v3 board's cost, measured: a stratified sample of its runs timed in CPU seconds.

A board record keeps its run's wall time only (``ema_bench.leaderboard.cost``), which counts
every second the run waited: for a core taken by other work, or for a sweep paused while
something else was timed.  Summed, it is an upper bound of the board's cost, and on a shared
machine a loose one.  This script measures the cost instead: the board's planned runs (the
command of docs/suite-v3.md, "Regenerating the board on v3") are split into strata (tier,
condition, track, solver: a stratum's runs differ only by instance and noise seed), ``k``
runs of each stratum are drawn with ``--seed`` and run again here, one at a time, each
timed with ``time.process_time`` around :func:`ema_bench.leaderboard.tasks.run_task` (one
process, numba on one thread, the kernels compiled before the first timed run).  The board's
CPU is then the stratified estimate: each stratum's planned runs times its sample's mean,
summed, with a bootstrap interval (resampling each stratum's sample); on 2 cores running 2
runs at a time its wall time is half that.

A drawn run already in ``--store`` is also a replay: its record is compared with the rerun
(evaluations, final vector, trace), and its recorded wall time is kept beside the CPU time
measured here (how much the recorded times are inflated).  Each timed run is appended to
``--out`` as it finishes (JSON lines); a rerun of the same command times only what is
missing, so an interrupted measurement resumes::

    nice python benchmarks/board_cost.py --k 2 --seed 44 \\
        --out benchmarks/results/v3_board_cost.jsonl

``--report`` prints the estimate of a written ``--out`` without running anything.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

#: The board's command (docs/suite-v3.md): what is planned, and so what is sampled.
PLAN = {"suite": "emafdi-v3", "tiers": ("4", "7", "12"),
        "conditions": ("prior", "no-prior", "step-only", "surface-current"),
        "tracks": ("reference", "twin"), "seeds": 2,
        "solvers": ("cmaes", "bipop-cmaes", "ms-least-squares", "ng-pso", "de", "powell",
                    "lbfgsb")}
#: The cores the board is planned for (the issue: "regeneration <= 12 h on 2 cores").
CORES = 2


def plan_tasks() -> list:
    """Every run of the board's command, in the sweep's order."""
    from ema_bench.leaderboard.tasks import make_tasks
    from ema_bench.suites import SUITES
    from ema_bench.suites.base import Selection

    suite = SUITES[PLAN["suite"]]
    cases = suite.sweep_cases(Selection(None, PLAN["tiers"], PLAN["conditions"], None, False))
    budget = suite.sweep_budget(cases, None, None, False)
    return make_tasks(list(PLAN["solvers"]), cases, list(PLAN["tracks"]), PLAN["seeds"],
                      budget)


def stratum(case: str, track: str, solver: str) -> str:
    """``tier|condition|track|solver`` of a run (the tier is the instance's dimension:
    ``v3-t12-s06@prior`` is tier 12, the paper cases and ``v3-sNN`` tier 4)."""
    from ema_bench.suites import find

    return f"{find(case).dim}|{case.partition('@')[2]}|{track}|{solver}"


def draw(keys_by_stratum: dict[str, list[str]], k: int, seed: int) -> dict[str, list[str]]:
    """``k`` run keys of each stratum, drawn without replacement, each stratum from its own
    stream spawned from ``seed`` (in the strata's sorted order)."""
    names = sorted(keys_by_stratum)
    streams = np.random.SeedSequence(seed).spawn(len(names))
    out = {}
    for name, ss in zip(names, streams):
        pool = keys_by_stratum[name]
        pick = np.random.default_rng(ss).choice(len(pool), size=min(k, len(pool)),
                                                replace=False)
        out[name] = [pool[i] for i in sorted(int(i) for i in pick)]
    return out


def estimate(planned: dict[str, int], cpu: dict[str, list[float]], boot: int = 4000,
             seed: int = 0) -> dict:
    """The board's CPU hours: sum over strata of planned runs x the sample's mean CPU
    seconds, with a 95 % percentile-bootstrap interval (each stratum's sample resampled with
    replacement, the strata independently); ``missing``: planned strata with no sample (the
    estimate then covers the others only, and says so)."""
    have = sorted(s for s in planned if cpu.get(s))
    missing = sorted(s for s in planned if not cpu.get(s))
    point = math.fsum(planned[s] * float(np.mean(cpu[s])) for s in have) / 3600
    rng = np.random.default_rng(seed)
    totals = np.zeros(boot)
    for s in have:
        v = np.asarray(cpu[s], dtype=float)
        totals += planned[s] * v[rng.integers(0, v.size, size=(boot, v.size))].mean(axis=1)
    lo, hi = (np.percentile(totals, [2.5, 97.5]) / 3600).tolist() if have else (0.0, 0.0)
    return {"cpu_h": point, "cpu_h_95": [lo, hi], "wall_h": point / CORES,
            "wall_h_95": [lo / CORES, hi / CORES], "strata": len(have),
            "runs": sum(planned[s] for s in have), "missing": missing}


def _same_run(rec: dict, again: dict) -> str | None:
    """The first difference of a rerun from its record (None: reproduced)."""
    for field in ("evaluations", "x", "trace"):
        if rec.get(field) != again.get(field):
            return field
    return None


def measure(tasks: list, store: dict[str, dict], out: Path) -> None:
    """Time each of ``tasks`` not yet in ``out`` and append its line."""
    from ema_bench.leaderboard.tasks import Task, run_task
    from ema_bench.progress import configure_logging, progress

    done = {json.loads(line)["key"] for line in out.read_text().splitlines()} \
        if out.is_file() else set()
    todo = [t for t in tasks if t.key not in done]
    if not todo:
        return
    # compile and load the kernels and the instances' data path before the first timed run
    warm = todo[0]
    run_task(Task("de", warm.case, warm.track, warm.seed, 40, warm.root_seed))
    configure_logging()
    with progress(len(todo), "board cost", unit="runs") as bar:
        for t in todo:
            _time_one(t, store, out)
            bar.update(t.key)


def _time_one(t, store: dict[str, dict], out: Path) -> None:
    """Time one run, compare it with its record if the store has one, append its line."""
    from ema_bench.leaderboard.tasks import run_task

    load0 = os.getloadavg()[0]
    c, w = time.process_time(), time.perf_counter()
    rec = json.loads(json.dumps(run_task(t)))   # as the store holds it
    line = {"key": t.key, "stratum": stratum(t.case, t.track, t.solver),
            "cpu_s": round(time.process_time() - c, 3),
            "wall_s": round(time.perf_counter() - w, 3),
            "load": [round(load0, 2), round(os.getloadavg()[0], 2)]}
    old = store.get(t.key)
    if old is not None:
        line["recorded_wall_s"] = old["wall_s"]
        line["differs"] = _same_run(old, rec)
    with out.open("a") as f:
        f.write(json.dumps(line) + "\n")


def report(tasks: list, lines: list[dict], stored: set[str] = frozenset()) -> dict:
    """The estimate per tier and in all, what is left of it (the planned runs whose keys
    are not in ``stored``), and the recorded-against-measured line."""
    planned: dict[str, int] = defaultdict(int)
    left: dict[str, int] = defaultdict(int)
    for t in tasks:
        planned[stratum(t.case, t.track, t.solver)] += 1
        if t.key not in stored:
            left[stratum(t.case, t.track, t.solver)] += 1
    cpu: dict[str, list[float]] = defaultdict(list)
    for ln in lines:
        cpu[ln["stratum"]].append(float(ln["cpu_s"]))
    tiers = sorted({s.split("|")[0] for s in planned}, key=int)
    out = {"planned_runs": len(tasks), "timed_runs": len(lines),
           "by_tier": {t: estimate({s: n for s, n in planned.items()
                                    if s.split("|")[0] == t}, cpu) for t in tiers},
           "board": estimate(dict(planned), cpu),
           "left": {"stored": len({t.key for t in tasks} & set(stored)),
                    **estimate(dict(left), cpu)}}
    rec = [ln for ln in lines if "recorded_wall_s" in ln]
    out["replayed"] = {"runs": len(rec),
                       "differ": [ln["key"] for ln in rec if ln["differs"]],
                       "recorded_wall_s": math.fsum(ln["recorded_wall_s"] for ln in rec),
                       "cpu_s_here": math.fsum(ln["cpu_s"] for ln in rec),
                       "wall_s_here": math.fsum(ln["wall_s"] for ln in rec)}
    loads = [v for ln in lines for v in ln["load"]]
    out["load"] = [min(loads), max(loads)] if loads else None
    return out


def _print(r: dict) -> None:
    def line(name: str, e: dict) -> str:
        gap = f"; no sample of {len(e['missing'])} strata" if e["missing"] else ""
        return (f"{name:8s} {e['runs']:5d} runs  {e['cpu_h']:6.2f} CPU-h "
                f"[{e['cpu_h_95'][0]:.2f}, {e['cpu_h_95'][1]:.2f}]  "
                f"{e['wall_h']:6.2f} h on {CORES} cores{gap}")
    print(f"{r['timed_runs']} runs timed of the {r['planned_runs']} planned "
          f"(load {r['load']})")
    for t, e in r["by_tier"].items():
        print(line(f"tier {t}", e))
    print(line("board", r["board"]))
    print(line("left", r["left"]) + f" (the store holds {r['left']['stored']})")
    p = r["replayed"]
    if p["runs"]:
        print(f"{p['runs']} of them were in the store: {len(p['differ'])} differ; recorded "
              f"wall {p['recorded_wall_s']:.0f} s against {p['cpu_s_here']:.0f} CPU-s "
              f"({p['wall_s_here']:.0f} s wall) here")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--store", default=str(ROOT / "leaderboards" / "v3" / "runs.jsonl"),
                    help="the board's records: a drawn run found there is compared")
    ap.add_argument("--k", type=int, default=2, help="runs drawn per stratum")
    ap.add_argument("--seed", type=int, default=44, help="the draw's seed")
    ap.add_argument("--out", required=True, help="JSON lines, one per timed run (resumed)")
    ap.add_argument("--report", action="store_true", help="run nothing: print the estimate")
    ap.add_argument("--json", action="store_true", help="print the estimate as JSON")
    a = ap.parse_args()
    if a.k < 1:
        ap.error("--k must be >= 1")
    tasks = plan_tasks()
    by: dict[str, list[str]] = defaultdict(list)
    for t in tasks:
        by[stratum(t.case, t.track, t.solver)].append(t.key)
    keys = {k for ks in draw(by, a.k, a.seed).values() for k in ks}
    out = Path(a.out)
    store = {}
    if Path(a.store).is_file():
        for ln in Path(a.store).read_text().splitlines():
            if ln.strip():
                r = json.loads(ln)
                store[r["key"]] = r
    if not a.report:
        measure([t for t in tasks if t.key in keys], store, out)
    lines = [json.loads(ln) for ln in out.read_text().splitlines() if ln.strip()] \
        if out.is_file() else []
    r = report(tasks, [ln for ln in lines if ln["key"] in keys], set(store))
    print(json.dumps(r, indent=1)) if a.json else _print(r)


if __name__ == "__main__":
    main()
