"""A ``fleet-bayes`` variant judged on a committed run's own fits, without re-fitting
(issue 47: the coil-short change point measured on every failing unit in CPU-minutes).

The ``fleet-bayes`` family's trackers fit each inspection the same way (the same fitter and
seeds) and differ in what they do with the fits.  This script serves each unit the fits its
committed ``fleet-bayes-cut`` run recorded (estimate and 95 % interval: the fit's standard
deviation is the larger half-width over 1.96, as ``_common.Fitter`` makes it), feeds them to
the variant's own factory with the run's unit seeds (seed scheme 1, as the committed twin runs
were tracked), and runs the forward paths at the cut only: each step draws its paths from a
generator of its own (``rng_of(mc_seed, index)``), so the cut's RUL does not depend on the
earlier steps' paths.  Served to ``fleet-bayes-cut`` itself, the fits give the
committed RUL at every cut exactly (``... fleet-bayes-cut``: difference +0.000).  Each point,
the committed run's and the oracle's are judged on the board's futures of the unit
(``expected.FUTURES_SEED``), as on the board, and the paired ratios to the oracle are printed
overall, by failing fault and by cut position, with bootstrap intervals::

    python benchmarks/prognostics_offline.py leaderboards/campaign/twin/fleet-bayes-cut \\
        fleet-bayes-onset --out offline.jsonl [--units u002,u013]

``--truth-fits`` serves the true faults instead (the variant's ceiling with perfect sensing:
what is left to the oracle is what it knows of the unit's law parameters).  Lines already in
``--out`` are not computed again (resumable).  About 0.6 CPU-s a unit
(futures and oracle included): the 170 failing units of the twin campaign in about 2 CPU-min.
``--set KEY=VALUE`` sets a factory keyword over the registered configuration (a variant
without registering it: ``n_paths=8000``, ``step_flights=1``), and ``--against LINES`` pairs
the difference with another variant's lines of this script instead of the committed run::

    python benchmarks/prognostics_offline.py leaderboards/campaign/twin/fleet-bayes-cut \
        fleet-bayes-whole --set step_flights=1 --out step1.jsonl \
        --against leaderboards/campaign/fleet-bayes-whole-offline.jsonl
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from prognostics_subset import judge, pending  # benchmarks/ (the script's folder) is on the path

import ema_bench_trackers._common as common
import ema_bench_trackers.fleet_bayes as fb
from ema_bench.faults import FAULT_NAMES
from ema_bench.prognostics import track_io, track_run, tracking
from ema_bench.prognostics.campaign import load_campaign, load_truth
from ema_bench.prognostics.tables import GROUPS

_AT_CUT = {"now": False}
_SERVED: dict[int, dict] = {}
#: With --truth-fits: unit -> flight -> the true faults, served as exact fits.
_TRUE: dict[str, dict[str, list]] = {}


def _cut_only(d0, advance, d_thr, step, horizon=fb.HORIZON_FLIGHTS):
    if _AT_CUT["now"]:
        return common.first_passage(d0, advance, d_thr, step, horizon)
    return np.full(d0.shape, np.inf)   # an earlier step's paths: not needed


def _served_setup(info, seed, *args, **kwargs):
    """``unit_setup`` with a fitter that returns the committed run's fit of each inspection."""
    u = common.unit_setup(info, seed, *args, **kwargs)

    def fitter(insp):
        r = _SERVED[insp.index]
        x, lo, hi = (np.array([r[k][n] for n in FAULT_NAMES]) for k in ("estimate", "low",
                                                                          "high"))
        sd = np.maximum(np.maximum(hi - x, x - lo) / common.Z95, 1e-6 * common.RANGE)
        if _TRUE:   # perfect sensing: the tracker's ceiling
            x, sd = np.array(_TRUE[insp.unit][str(insp.flight)], float), 1e-5 * common.RANGE
            lo, hi = x - common.Z95 * sd, x + common.Z95 * sd
        return common.Fit(x, lo, hi, sd, 0.0, 1.0, int(r["evaluations"]), "served")
    return dataclasses.replace(u, fitter=fitter)


#: Factory keywords set on the command line (``--set n_paths=8000``), over the registered ones.
_SET: dict[str, float] = {}


def cut_rul(tracker: str, info: dict, manifest_units: list[dict], steps: list[dict],
            order: list[str]) -> float:
    """The variant's RUL at the unit's cut, from the committed steps' fits."""
    spec = tracking.get_tracker(tracker)
    if spec.factory is not fb.factory:
        raise SystemExit(f"{tracker}: not a fleet-bayes variant (trackers/fleet_bayes.py)")
    unit = steps[0]["unit"]
    _SERVED.clear()
    _SERVED.update({r["index"]: r for r in steps})
    conditions = {i["index"]: i["conditions"] for i in manifest_units}
    step = fb.factory(info, track_run.unit_seed(0, order.index(unit), 1),
                      **{**spec.config, **_SET})
    for k, r in enumerate(steps):
        _AT_CUT["now"] = k == len(steps) - 1
        out = step(SimpleNamespace(unit=unit, index=r["index"], flight=r["flight"],
                                   conditions=conditions[r["index"]]))
    return float(out.rul)


def measure(run: str, tracker: str, out: Path, units: list[str] | None,
            truth_fits: bool = False) -> list[dict]:
    fb.first_passage, fb.unit_setup = _cut_only, _served_setup
    log = track_io.read_track(run)
    camp = load_campaign(track_io.campaign_path(run, log.manifest), traces=False)
    truth = load_truth(camp.root, camp)
    if truth_fits:
        _TRUE.update({u: t["faults"] for u, t in truth.items()})
    manifest = json.loads((camp.root / "manifest.json").read_text())
    listed = {u["unit"]: u["inspections"] for u in manifest["units"]}
    order = list(camp.units)
    failing = [u for u in order if truth[u]["eol"] is not None]
    for u in pending(out, units or failing):
        t0 = time.process_time()
        point = cut_rul(tracker, camp.info(), listed[u], log.steps[u], order)
        line = {"unit": u, "failing_fault": truth[u]["failing_fault"],
                "life_fraction": truth[u]["life_fraction"], "rul": point,
                **judge(camp, truth, u, point, log.steps[u][-1]["rul"]),
                "cpu_s": time.process_time() - t0}
        with out.open("a") as fh:
            fh.write(json.dumps(line) + "\n")
    return [json.loads(x) for x in out.read_text().splitlines()]


def _ratio(sel: list[dict], key: str, idx: np.ndarray) -> tuple[float, np.ndarray]:
    e, o = (np.array([x[k] for x in sel]) for k in (key, "oracle"))
    return e.sum() / o.sum(), e[idx].sum(1) / o[idx].sum(1)


def summary(lines: list[dict], against: Path | None = None) -> None:
    """Ratios to the oracle and the paired difference to the committed run, overall, by
    failing fault and by cut position; with ``against`` (another ``--out`` of this script, the
    same units) the difference is to that variant's lines instead."""
    if against is not None:
        other = {d["unit"]: d["tracker"] for d in map(json.loads,
                                                        against.read_text().splitlines())}
        lines = [{**x, "committed": other[x["unit"]]} for x in lines]
    groups = {"all": lines, **{g: [x for x in lines if rule(x)] for g, rule in GROUPS.items()}}
    for name, sel in groups.items():
        if not sel:
            continue
        idx = np.random.default_rng(0).integers(0, len(sel), (4000, len(sel)))
        (t, tb), (c, cb) = _ratio(sel, "tracker", idx), _ratio(sel, "committed", idx)
        q = np.quantile
        print(f"{name} ({len(sel)} units): ratio to the oracle {t:.3f} [{q(tb, .025):.3f}, "
              f"{q(tb, .975):.3f}], committed {c:.3f} [{q(cb, .025):.3f}, {q(cb, .975):.3f}];"
              f" difference {t - c:+.3f} [{q(tb - cb, .025):+.3f}, {q(tb - cb, .975):+.3f}]")
    print(f"{sum(x['cpu_s'] for x in lines):.0f} CPU-s")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run", help="a committed fleet-bayes-cut run (its campaign's truth beside "
                               "its manifest)")
    p.add_argument("tracker", help="a fleet-bayes variant (fleet-bayes-onset, ...)")
    p.add_argument("--out", type=Path, required=True, help="JSON lines, appended")
    p.add_argument("--units", help="comma-separated units (default: every failing unit)")
    p.add_argument("--truth-fits", action="store_true",
                   help="serve each inspection's true faults as its fit (standard deviation "
                        "1e-5 of the range): the variant's ceiling with perfect sensing")
    p.add_argument("--against", type=Path, help="pair with this --out of another variant "
                   "(e.g. leaderboards/campaign/fleet-bayes-whole-offline.jsonl) instead of "
                   "the committed run")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="a factory keyword over the registered configuration (a number), e.g. "
                        "n_paths=8000 or step_flights=1 (repeatable)")
    a = p.parse_args()
    for kv in a.set:
        k, v = kv.split("=", 1)
        _SET[k] = int(v) if v.isdigit() else float(v)
    summary(measure(a.run, a.tracker, a.out, a.units.split(",") if a.units else None,
                    a.truth_fits), a.against)


if __name__ == "__main__":
    main()
