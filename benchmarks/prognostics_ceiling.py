"""How far can a tracker get on coil shorts?  Bounds that know everything the oracle knows
but the unit's coil growth rate (issue 47: is >= 0.9 of the oracle on coil shorts reachable?).

The oracle (``ema_bench/prognostics/oracle.py``) knows four things no tracker sees: the unit's
law parameters (friction rate, wear rate, mean duty and the coil's growth rate ``g``), its
true faults at the cut without noise, whether (and when) its coil short began, and the cut
rule's weighting, which is published.  Each **level** below is given all of that except
``g``, which it must infer from a view of the unit's past; its futures are the oracle's
(:func:`~ema_bench.prognostics.oracle.unit_futures`, the same generator) with each path's
``g`` drawn from the posterior of that view, and its point is the Bayes point for +-20 %
(:func:`~ema_bench.prognostics.bayes.best_point`):

- ``oracle``: the true ``g`` (reproduces the oracle's point exactly: a check of the plumbing);
- ``flights``: the exact shorted share after **every flight** since the onset and every
  flight's duty (the unit's history, regenerated from the campaign's public seed and checked
  against ``truth.json``): each flight's log-share rise is ``g duty eps``, ``eps ~ Gamma(4,
  1/4)``, so the likelihood is exact (``loglik_flights``);
- ``inspections``: the exact share at the **inspections** only (and at the onset, whose
  flight it is told) with every flight's duty: each interval's rise is ``g sum(duty eps)``,
  a weighted sum of gammas, matched to a gamma in mean and variance (``loglik_intervals``);
- ``prior``: nothing on ``g`` but the fleet's prior (a tracker before the onset).

A tracker sees noisy fits of the share at the inspections only, the logged duty per interval
(not per flight), and neither the onset flight nor the other parameters, so every view it
has is a garbling of ``flights`` (and, but for the within-interval duties and the onset
flight, of ``inspections``): given that level's information, its Bayes point maximises each
unit's posterior expected hit, and no tracker's point does better in expectation over units
drawn from the laws, on every group defined by what the level knows (the units whose short
has begun by the cut, ``begun``).  The issue's coil-short group is defined by the unit's
future (the fault that fails first), so a tracker could trade other units for it; the bound
there is the level's figure, not a theorem.

Every unit's points (each level's, the committed run's at the cut, the oracle's) are judged on
the board's futures (``expected.FUTURES_SEED``) as on the board; the paired ratios to the
oracle are printed with bootstrap intervals over units, overall, by failing fault, by cut
position and for ``begun``::

    python benchmarks/prognostics_ceiling.py leaderboards/campaign/twin/fleet-bayes-cut \\
        --out ceiling.jsonl [--units u002,u013]

On the training split only (the published twin campaign); lines already in ``--out`` are
kept (resumable).  About 2 CPU-s a unit (five sets of 4,000 futures).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np
from prognostics_offline import _ratio  # benchmarks/ (the script's folder) is on the path
from prognostics_subset import judge_points, pending

from ema_bench.faults import FAULT_INDEX
from ema_bench.prognostics import track_io
from ema_bench.prognostics.bayes import best_point
from ema_bench.prognostics.campaign import get_spec, load_campaign, load_truth
from ema_bench.prognostics.laws import unit_history
from ema_bench.prognostics.oracle import N_PATHS, unit_futures
from ema_bench.prognostics.tables import GROUPS
from ema_bench.seeding import child, run_seed, stream

LEVELS = ("oracle", "flights", "inspections", "prior")
F_NA = FAULT_INDEX["Na"]
#: The log-growth grid of the posterior: the prior's median +- 6 log-sds, this many points.
GRID = 4001


def log_grid(laws: dict) -> np.ndarray:
    """Grid of ``log g`` covering the fleet's prior (log-normal) by +- 6 log-sds."""
    mu, s = math.log(laws["na_growth_median"]), laws["na_growth_sigma"]
    return np.linspace(mu - 6.0 * s, mu + 6.0 * s, GRID)


def log_prior(lg: np.ndarray, laws: dict) -> np.ndarray:
    """The fleet's log-normal prior of ``g`` as a density of ``log g`` (unnormalised)."""
    mu, s = math.log(laws["na_growth_median"]), laws["na_growth_sigma"]
    return -0.5 * ((lg - mu) / s) ** 2


def loglik_flights(lg: np.ndarray, rise: np.ndarray, duty: np.ndarray, k: float
                   ) -> np.ndarray:
    """Log-likelihood of ``log g`` from each flight's rise of the log share (``rise = g duty
    eps``, ``eps ~ Gamma(k, 1/k)``: ``rise / duty ~ Gamma(k, g / k)``), exact."""
    z = np.asarray(rise, float) / np.asarray(duty, float)
    g = np.exp(lg)[:, None]
    return np.sum(-k * np.log(g) - k * z[None, :] / g, axis=1)


def loglik_intervals(lg: np.ndarray, rise: np.ndarray, d1: np.ndarray, d2: np.ndarray,
                     k: float) -> np.ndarray:
    """Log-likelihood of ``log g`` from each interval's rise of the log share, ``g sum(duty_f
    eps_f)`` (mean ``g d1``, variance ``g^2 d2 / k``, ``d1``, ``d2`` the sums of the flights'
    duties and squared duties): a gamma of that mean and variance (shape ``k d1^2 / d2``)."""
    rise, d1, d2 = (np.asarray(a, float) for a in (rise, d1, d2))
    shape = k * d1 ** 2 / d2
    scale = np.exp(lg)[:, None] * (d2 / (k * d1))[None, :]
    return np.sum(-shape[None, :] * np.log(scale) - rise[None, :] / scale, axis=1)


def posterior_draws(lg: np.ndarray, logpost: np.ndarray, rng: np.random.Generator,
                    n: int) -> np.ndarray:
    """``n`` draws of ``g`` from a posterior of ``log g`` on the grid ``lg`` (each draw
    spread uniformly over its grid cell)."""
    p = np.exp(logpost - logpost.max())
    i = rng.choice(lg.size, size=n, p=p / p.sum())
    h = lg[1] - lg[0]
    return np.exp(lg[i] + h * (rng.random(n) - 0.5))


def growth_evidence(level: str, history, onset: int, cut: int, flights: list[int],
                    laws: dict, lg: np.ndarray) -> np.ndarray:
    """The log-likelihood of ``log g`` on the grid that ``level`` knows at the cut (zero for
    ``prior``, and for every level while no short has begun)."""
    if level == "prior" or onset >= cut:
        return np.zeros_like(lg)
    k = laws["na_growth_shape"]
    log_s = np.full(history.faults.shape[0], -np.inf)
    log_s[onset:cut + 1] = np.log(1.0 - history.faults[onset:cut + 1, F_NA])
    if level == "flights":
        f = np.arange(onset + 1, cut + 1)
        return loglik_flights(lg, log_s[f] - log_s[f - 1], history.duty[f - 1], k)
    points = sorted({onset, *(f for f in flights if onset < f <= cut)})
    a, b = np.array(points[:-1]), np.array(points[1:])
    d = history.duty
    d1 = np.array([d[x:y].sum() for x, y in zip(a, b)])
    d2 = np.array([(d[x:y] ** 2).sum() for x, y in zip(a, b)])
    return loglik_intervals(lg, log_s[b] - log_s[a], d1, d2, k)


def unit_points(camp, truth: dict, unit: str, k: int, history, flights: list[int]) -> dict:
    """Each level's Bayes point at the unit's cut (flights)."""
    t, laws = truth[unit], camp.laws
    cut, onset = int(t["last_flight"]), int(t["params"]["na_onset"])
    lg = log_grid(laws)
    stop = tuple(camp.cut_rule["stop"])
    out = {}
    for j, level in enumerate(LEVELS):
        if level == "oracle":
            g = None
        else:
            post = log_prior(lg, laws) + growth_evidence(level, history, onset, cut, flights,
                                                         laws, lg)
            g = posterior_draws(lg, post, np.random.default_rng(child(child(2, k), j)), N_PATHS)
        rul, w, _ = unit_futures(t, laws, camp.thresholds, camp.inspection_every, stop,
                                 np.random.default_rng(child(0, k)), N_PATHS, na_growth=g)
        out[level] = best_point(rul, w, 0.2)
    return out


def history_of(camp, truth: dict, unit: str):
    """The unit's life regenerated from the campaign's public seed (as ``campaign make``
    draws it), checked against the truth's faults at every inspection flight."""
    node = run_seed(camp.seed, list(camp.units).index(unit))
    h = unit_history(stream(node, "instance"), get_spec(camp.name).laws, wear=True)
    for f, x in truth[unit]["faults"].items():
        if not np.allclose(h.faults[int(f), F_NA], x[F_NA], rtol=0, atol=1e-12):
            raise SystemExit(f"{unit}: the regenerated history is not the truth's at {f}")
    return h


def measure(run: str, out: Path, units: list[str] | None) -> list[dict]:
    log = track_io.read_track(run)
    camp = load_campaign(track_io.campaign_path(run, log.manifest), traces=False)
    if camp.seed is None:
        raise SystemExit(f"{run}: a sealed campaign; the bounds are measured on the "
                         "published training split only")
    truth = load_truth(camp.root, camp)
    order = sorted(truth)
    failing = [u for u in camp.units if truth[u]["eol"] is not None]
    for u in pending(out, units or failing):
        t0 = time.process_time()
        t = truth[u]
        flights = [int(f) for f in t["faults"]]
        points = unit_points(camp, truth, u, order.index(u), history_of(camp, truth, u),
                             flights)
        points["committed"] = float(log.steps[u][-1]["rul"])
        hits = judge_points(camp, truth, u, points)
        line = {"unit": u, "failing_fault": t["failing_fault"],
                "life_fraction": t["life_fraction"],
                "begun": int(t["params"]["na_onset"]) <= int(t["last_flight"]),
                "points": points, **hits, "cpu_s": time.process_time() - t0}
        with out.open("a") as fh:
            fh.write(json.dumps(line) + "\n")
    return [json.loads(x) for x in out.read_text().splitlines()]


def summary(lines: list[dict]) -> list[str]:
    """Per group, each level's and the committed run's expected ratio to the oracle."""
    groups = {"all": lines, **{g: [x for x in lines if rule(x)] for g, rule in GROUPS.items()},
              "begun": [x for x in lines if x["begun"]],
              "Na, begun": [x for x in lines if x["begun"] and x["failing_fault"] == "Na"],
              "Na, not begun": [x for x in lines if not x["begun"]
                                and x["failing_fault"] == "Na"]}
    q = np.quantile
    text = []
    for name, sel in groups.items():
        if not sel:
            continue
        idx = np.random.default_rng(0).integers(0, len(sel), (4000, len(sel)))
        cells = []
        for key in (*LEVELS[1:], "committed"):
            r, rb = _ratio(sel, key, idx)
            cells.append(f"{key} {r:.3f} [{q(rb, .025):.3f}, {q(rb, .975):.3f}]")
        text.append(f"{name} ({len(sel)} units): " + "; ".join(cells))
    text.append(f"{sum(x['cpu_s'] for x in lines):.0f} CPU-s")
    return text


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run", help="a committed run of the training split (its campaign's truth "
                               "beside its manifest): its point at the cut is judged beside")
    p.add_argument("--out", type=Path, required=True, help="JSON lines, appended")
    p.add_argument("--units", help="comma-separated units (default: every failing unit)")
    a = p.parse_args()
    print("\n".join(summary(measure(a.run, a.out, a.units.split(",") if a.units else None))))


if __name__ == "__main__":
    main()
