"""A tracker measured on chosen units of a committed campaign, beside a committed run and the
oracle, by expected hits at the cut (issue 47: a tracker too costly to put on the whole board).

Each unit is tracked exactly as ``campaign track`` would (the unit's seed of root seed 0, from
the campaign's traces: make them with the README's ``campaign make`` command); its point at
the cut, the committed run's and the oracle's are judged on the board's futures of that unit
(``expected.FUTURES_SEED``, the child of the unit's place in the sorted truth), so the three
are paired exactly as on the board::

    python benchmarks/prognostics_subset.py CAMPAIGN_DIR fleet-bayes-onset \\
        leaderboards/campaign/twin/fleet-bayes-cut u002,u013 --out subset.jsonl

prints the mean expected hits and the ratios to the oracle (with a paired bootstrap interval
of the difference); lines already in ``--out`` are not tracked again (resumable).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from ema_bench.prognostics import track_io, track_run, tracking
from ema_bench.prognostics.campaign import load_campaign
from ema_bench.prognostics.expected import FUTURES_SEED, hit_probability
from ema_bench.prognostics.oracle import N_PATHS, oracle_unit, unit_futures
from ema_bench.seeding import child


def judge(camp, truth: dict, unit: str, point: float, committed: float) -> dict:
    """Expected hits at the unit's cut of the tracker's ``point``, the committed run's RUL and
    the oracle's, on the board's futures of the unit (unit ``k`` of the sorted truth: child
    ``k`` of ``FUTURES_SEED``; the oracle's own futures: child ``k`` of 0)."""
    k = sorted(truth).index(unit)
    oracle = oracle_unit(truth[unit], camp.laws, camp.thresholds, camp.inspection_every,
                         tuple(camp.cut_rule["stop"]), np.random.default_rng(child(0, k)))
    return judge_points(camp, truth, unit, {"tracker": point, "committed": committed,
                                            "oracle": oracle["rul"]})


def pending(out: Path, units: list[str]) -> list[str]:
    """The ``units`` without a line in ``out`` yet (the scripts resume where they stopped)."""
    done = ({json.loads(x)["unit"] for x in out.read_text().splitlines()} if out.exists()
            else set())
    return [u for u in units if u not in done]


def judge_points(camp, truth: dict, unit: str, points: dict[str, float]) -> dict[str, float]:
    """Expected hit of each named point (flights) at the unit's cut, on the board's futures
    of the unit (child ``k`` of ``FUTURES_SEED``, ``k`` its place in the sorted truth)."""
    k = sorted(truth).index(unit)
    rul, w, _ = unit_futures(truth[unit], camp.laws, camp.thresholds, camp.inspection_every,
                             tuple(camp.cut_rule["stop"]),
                             np.random.default_rng(child(FUTURES_SEED, k)), N_PATHS)
    return {name: hit_probability(point, rul, w) for name, point in points.items()}


def measure(camp_dir: str, tracker: str, committed: str, units: list[str], out: Path) -> list:
    camp = load_campaign(camp_dir)
    log = track_io.read_track(committed)
    truth = json.loads((track_io.campaign_path(committed, log.manifest) / "truth.json").read_text())
    truth = truth["units"]
    order = list(camp.units)
    for u in pending(out, units):
        t0 = time.process_time()
        rows: list[dict] = []
        settings, inspections = track_run.unit_inputs(camp, u)
        rows, _ = track_run.run_unit(tracking.get_tracker(tracker), settings, u, inspections,
                                     track_run.unit_seed(0, order.index(u)))
        point = track_io.regroup(rows)[0][u][-1]["rul"]
        line = {"unit": u, "fault": truth[u]["failing_fault"],
                **judge(camp, truth, u, point, log.steps[u][-1]["rul"]),
                "cpu_s": time.process_time() - t0}
        with out.open("a") as fh:
            fh.write(json.dumps(line) + "\n")
    return [json.loads(x) for x in out.read_text().splitlines()]


def summary(lines: list[dict]) -> None:
    for name, sel in (("coil shorts", [x for x in lines if x["fault"] == "Na"]),
                      ("other modes", [x for x in lines if x["fault"] != "Na"])):
        if not sel:
            continue
        e = {k: np.array([x[k] for x in sel]) for k in ("tracker", "committed", "oracle")}
        idx = np.random.default_rng(0).integers(0, len(sel), (2000, len(sel)))
        diff = (e["tracker"][idx].sum(1) - e["committed"][idx].sum(1)) / e["oracle"][idx].sum(1)
        print(f"{name} ({len(sel)} units): expected hits tracker {e['tracker'].mean():.3f}, "
              f"committed {e['committed'].mean():.3f}, oracle {e['oracle'].mean():.3f}; "
              f"ratio to the oracle {e['tracker'].sum() / e['oracle'].sum():.3f} against "
              f"{e['committed'].sum() / e['oracle'].sum():.3f}; difference "
              f"[{np.quantile(diff, 0.025):.3f}, {np.quantile(diff, 0.975):.3f}] (paired "
              f"bootstrap); {sum(x['cpu_s'] for x in sel):.0f} CPU-s")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("campaign", help="the campaign folder with its traces")
    p.add_argument("tracker")
    p.add_argument("committed", help="a committed tracking run of that campaign")
    p.add_argument("units", help="comma-separated units")
    p.add_argument("--out", type=Path, required=True, help="JSON lines, appended")
    a = p.parse_args()
    summary(measure(a.campaign, a.tracker, a.committed, a.units.split(","), a.out))


if __name__ == "__main__":
    main()
