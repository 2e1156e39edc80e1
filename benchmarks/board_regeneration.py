"""The campaign board's regeneration, timed: the documented commands on a sample campaign.

Runs the commands of ``leaderboards/campaign/README.md`` as a user runs them (the
``ema-bench`` CLI, each in a subprocess) on a sample of the twin campaign (the board's
definition and seed, fewer units), in one pass from a **cold** fit cache shared between the
trackers (``EMA_BENCH_FIT_CACHE=OUT/fits``, fresh), and times each command: wall, and the user
and system CPU of the command and every worker process it waited for (the accounting of GNU
``time``: ``getrusage(RUSAGE_CHILDREN)``)::

    ema-bench campaign make fleet-v1 --units 12 --track twin --seed 4273 --out OUT/campaign
    ema-bench campaign make fleet-v1 --units 2 --track reference --seed 1919 ...  (its cost)
    ema-bench campaign track OUT/campaign --tracker T --out OUT/runs/T --workers 2   (x 8)
    ema-bench campaign score OUT/runs/... --truth ... --json --markdown ... --plots ...
    ema-bench campaign policy OUT/runs/... --thresholds POLICY_THRESHOLDS --replay 2 ...

Each tracker's CPU per inspection, scaled to the board's campaigns (4,796 twin and 685
reference inspections), and the reference track's cost of making a campaign per inspection
give the board's cost (:func:`scaled`); the wall time on two idle cores counts the tracking
runs' CPU halved (both workers busy) and the rest whole (one process).  Scoring and the
policy table are scaled by inspections as well (an upper bound: the policy's replay of two
units per run does not grow with the campaign).  The machine's load average is recorded
before and after every command.  Results are written after every command to ``--json``
(``--rescale`` recomputes the board's figures of a written one)::

    nice -n 10 python benchmarks/board_regeneration.py --out /tmp/regen \\
        --json leaderboards/campaign/regeneration.json
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

from ema_bench.prognostics.sealed import BOARD_TRACKERS

ROOT = Path(__file__).resolve().parents[1]



def _load() -> list[float]:
    return [float(v) for v in Path("/proc/loadavg").read_text().split()[:3]]


def timed(cmd: list[str], env: dict, log: Path) -> dict:
    """Run ``cmd`` and return its wall and CPU seconds (itself and every waited-for worker)."""
    before, load0, t0 = resource.getrusage(resource.RUSAGE_CHILDREN), _load(), time.time()
    with log.open("w") as f:
        rc = subprocess.run(cmd, env=env, stdout=f, stderr=subprocess.STDOUT).returncode
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if rc != 0:
        sys.exit(f"{' '.join(cmd[:4])}: exit {rc}, see {log}")
    return {"command": " ".join(cmd), "wall_s": round(time.time() - t0, 2),
            "user_s": round(after.ru_utime - before.ru_utime, 2),
            "sys_s": round(after.ru_stime - before.ru_stime, 2),
            "load_before": load0, "load_after": _load()}


def inspections(folder: Path) -> int:
    doc = json.loads((folder / "manifest.json").read_text())
    return sum(len(u["inspections"]) for u in doc["units"])


#: Inspections of the board's campaigns (their committed manifests: 4,796 and 685).
BOARD = {t: inspections(ROOT / "leaderboards" / "campaign" / t / "campaign")
         for t in ("twin", "reference")}


def scaled(doc: dict) -> dict:
    """Add the board's figures to a measurement: each step's CPU per inspection of its sample
    times the board's inspections (tracking, scoring and the policy table: both campaigns;
    making: each track's own), and the wall on two idle cores: the tracking runs keep both
    workers busy (CPU / 2), making, scoring and the policy table run on one core (CPU)."""
    n, board = doc["sample_inspections"], sum(BOARD.values())
    cpu = {k: r["user_s"] + r["sys_s"] for k, r in doc["steps"].items()}
    per = {k.removeprefix("track "): v / n for k, v in cpu.items() if k.startswith("track ")}
    out = {f"track {t}": v * board for t, v in per.items()}
    out["make twin"] = cpu["make twin"] / n * BOARD["twin"]
    if "make reference" in cpu:
        out["make reference"] = (cpu["make reference"] / doc["reference_sample_inspections"]
                                 * BOARD["reference"])
    for k in ("score", "policy"):
        out[k] = cpu[k] / n * board
    parallel = sum(v for k, v in out.items() if k.startswith("track "))
    doc["board_inspections"] = BOARD
    doc["cpu_s_per_inspection"] = {t: round(v, 4) for t, v in per.items()}
    doc["board_cpu_min"] = {k: round(v / 60, 2) for k, v in out.items()}
    doc["board_twin_tracking_cpu_min"] = round(sum(per.values()) * BOARD["twin"] / 60, 1)
    doc["board_total_cpu_min"] = round(sum(out.values()) / 60, 1)
    doc["board_wall_min_on_2_cores"] = round(
        (parallel / 2 + sum(out.values()) - parallel) / 60, 1)
    return doc


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True, help="work folder (must not exist)")
    p.add_argument("--json", type=Path, required=True, help="results, written as they come")
    p.add_argument("--units", type=int, default=12, help="twin sample units (default 12)")
    p.add_argument("--reference-units", type=int, default=2,
                   help="reference-track units made, for that track's cost (default 2)")
    p.add_argument("--seed", type=int, default=4273, help="the twin board's seed")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--trackers", default=",".join(BOARD_TRACKERS))
    p.add_argument("--rescale", action="store_true",
                   help="only recompute the board's figures of an existing --json")
    a = p.parse_args()
    if a.rescale:   # the samples stay in --out
        doc = json.loads(a.json.read_text())
        if "make reference" in doc["steps"]:
            doc["reference_sample_inspections"] = inspections(a.out / "reference")
        a.json.write_text(json.dumps(scaled(doc), indent=1) + "\n")
        return
    if a.out.exists():
        sys.exit(f"{a.out}: exists; the measurement needs a fresh folder (a cold fit cache)")
    eb = str(Path(sys.executable).with_name("ema-bench"))
    out = a.out.resolve()
    env = {**os.environ, "EMA_BENCH_FIT_CACHE": str(out / "fits")}
    (out / "logs").mkdir(parents=True)
    (out / "fits").mkdir()
    doc = {"what": "board regeneration on a sample, cold shared fit cache (benchmarks/"
                   "board_regeneration.py)", "cpus": os.cpu_count(), "steps": {}}

    def step(name: str, cmd: list[str]) -> dict:
        doc["steps"][name] = r = timed(cmd, env, out / "logs" / f"{name}.txt")
        a.json.write_text(json.dumps(doc, indent=1) + "\n")
        print(f"{name}: {r['wall_s']:.0f} s wall, {r['user_s'] + r['sys_s']:.0f} CPU-s",
              flush=True)
        return r

    camp, hidden = out / "campaign", out / "hidden"
    step("make twin", [eb, "campaign", "make", "fleet-v1", "--units", str(a.units), "--track",
                       "twin", "--seed", str(a.seed), "--out", str(camp), "--quiet"])
    hidden.mkdir()
    shutil.move(str(camp / "truth.json"), str(hidden / "truth.json"))   # tracking never reads it
    if a.reference_units:
        step("make reference", [eb, "campaign", "make", "fleet-v1", "--units",
                                str(a.reference_units), "--track", "reference", "--seed",
                                "1919", "--out", str(out / "reference"), "--quiet"])
    trackers = a.trackers.split(",")
    runs = [str(out / "runs" / t) for t in trackers]
    for t, run in zip(trackers, runs):
        step(f"track {t}", [eb, "campaign", "track", str(camp), "--tracker", t, "--out", run,
                            "--workers", str(a.workers), "--quiet"])
    truth = str(hidden / "truth.json")
    step("score", [eb, "campaign", "score", *runs, "--truth", truth, "--json", "--markdown",
                   str(out / "scores.md"), "--plots", str(out / "plots")])
    step("policy", [eb, "campaign", "policy", *runs, "--truth", truth, "--thresholds",
                    str(ROOT / "leaderboards" / "campaign" / "policy_thresholds.json"),
                    "--replay", "2", "--markdown", str(out / "policy.md"), "--json"])

    doc["sample_inspections"] = inspections(camp)
    doc["reference_sample_inspections"] = (inspections(out / "reference")
                                           if a.reference_units else None)
    a.json.write_text(json.dumps(scaled(doc), indent=1) + "\n")
    print(f"board: {doc['board_total_cpu_min']:.1f} CPU-min, "
          f"{doc['board_wall_min_on_2_cores']:.1f} min on 2 idle cores")


if __name__ == "__main__":
    main()
