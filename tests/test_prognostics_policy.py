"""Replacement policies (ema_bench/prognostics/policy.py): the cost model against hand
arithmetic, the oracle policy against every threshold policy and against brute force."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest

from ema_bench.prognostics.policy import (
    DMAX,
    SIGNALS,
    PolicyError,
    expected_costs,
    oracle_delays,
    policy_table,
    rate,
    read_thresholds,
    score_policy,
    tracker_rate,
)

ROOT = Path(__file__).resolve().parents[1] / "leaderboards" / "campaign"


def _rows(flights, rul_low, rul=None):
    rul = rul_low if rul is None else rul
    return [{"flight": f, "rul_low": lo, "rul": r} for f, lo, r in zip(flights, rul_low, rul)]


#: Two units, every 10 flights.  A: cut at 100, futures R = 30 or 50 (equal weights); its
#: tracker's lower bound 35 at the cut.  B: cut at 200, futures 100, 20, 60 (weights 1, 2, 1);
#: its tracker's lower bound 5 at flight 150, before the cut.
TOY_TRUTH = {"A": {"last_flight": 100}, "B": {"last_flight": 200}}
TOY_FUTURES = {"A": (np.array([30.0, 50.0]), np.array([1.0, 1.0])),
               "B": (np.array([100.0, 20.0, 60.0]), np.array([1.0, 2.0, 1.0]))}
TOY_STEPS = {"A": _rows(range(0, 101, 10), [200.0] * 10 + [35.0]),
             "B": _rows(range(0, 201, 10), [200.0] * 15 + [5.0] + [200.0] * 5)}


def test_the_toy_costs_by_hand_are_the_tables():
    # threshold 10 on the lower bound.  A: 35 - 3 x 10 <= 10, replaced 30 flights after the
    # cut, at 130: the R = 30 future fails at 130 (12 inspections before: 6 + 400), the R = 50
    # one is replaced (13 inspections: 6.5 + 40); E cost 226.25 over 130 flights.
    # B: replaced at 150 (15 inspections: 7.5 + 40 = 47.5 over 150 flights), every future.
    cost = 0.5 * (406.0 + 46.5) + 47.5
    flights = 130.0 + 150.0
    got = score_policy(TOY_STEPS, TOY_FUTURES, TOY_TRUTH, 10, "rul_low", 10.0, n_boot=50)
    assert got["cost_per_100_flights"]["value"] == pytest.approx(100 * cost / flights)
    assert got["cost_per_unit"] == pytest.approx(cost / 2)
    assert got["failures"] == pytest.approx(0.5)
    table = "\n".join(policy_table([{"tracker": "toy", "track": "twin", **got}]))
    assert f"| {100 * cost / flights:.2f} [" in table          # 97.77
    assert f"| {cost / 2:.1f} | 0.5 |" in table


def _brute_rate(futures, truth, every):
    """The best cost per 100 flights over every pair of delays on the grid, from the cost
    model written out again (independently of policy.unit_cost)."""
    grid = np.arange(0.0, DMAX + every, every)
    per = []
    for u in sorted(futures):
        r, w = futures[u]
        w = w / w.sum()
        c = truth[u]["last_flight"]
        fail = grid[:, None] >= r[None, :]
        end = np.where(fail, c + r[None, :], c + grid[:, None])
        insp = np.where(fail, np.ceil(end / every) - 1, np.floor(end / every))
        cost = 0.5 * insp + np.where(fail, 400.0, 40.0)
        per.append(((cost * w).sum(axis=1), (end * w).sum(axis=1)))
    (ca, fa), (cb, fb) = per
    return float(100 * ((ca[:, None] + cb[None, :]) / (fa[:, None] + fb[None, :])).min())


def test_the_oracle_policy_is_the_best_pair_of_delays():
    o = expected_costs(oracle_delays(TOY_FUTURES, TOY_TRUTH, 10), TOY_FUTURES, TOY_TRUTH, 10)
    assert rate(o) == pytest.approx(_brute_rate(TOY_FUTURES, TOY_TRUTH, 10), rel=1e-12)


def test_the_oracle_policy_is_never_worse_than_a_threshold_policy():
    """A reviewer's check: on 30 random units, for both signals and thresholds 0-300, the
    tracker policy never costs less per flight than the oracle policy on the same futures;
    replacing every unit at its cut costs less per unit and more per flight."""
    rng = np.random.default_rng(7)
    every, truth, futures, steps = 10, {}, {}, {}
    for k in range(30):
        u = f"u{k:02d}"
        cut = 10 * int(rng.integers(10, 40))
        truth[u] = {"last_flight": cut}
        futures[u] = (rng.gamma(3.0, 30.0, 300), rng.uniform(0.1, 1.0, 300))
        n = cut // every + 1
        low = np.sort(rng.uniform(0, 400, n))[::-1]
        steps[u] = _rows(range(0, cut + 1, every), low, low + rng.uniform(0, 80, n))
    o = expected_costs(oracle_delays(futures, truth, every), futures, truth, every)
    for signal, theta in itertools.product(SIGNALS, range(0, 301, 20)):
        e = tracker_rate(steps, futures, truth, every, signal, float(theta))
        assert rate(e) >= rate(o) - 1e-9, (signal, theta)
    at_cut = expected_costs(dict.fromkeys(futures, 0.0), futures, truth, every)
    assert at_cut["cost"].mean() < o["cost"].mean()
    assert rate(at_cut) > rate(o)
    # degenerate predictors cannot meet the 1.2x target: one that never calls a
    # replacement (every unit flies to failure) and one that calls it at once
    never = {u: _rows(range(0, truth[u]["last_flight"] + 1, every),
                      [math.inf] * (truth[u]["last_flight"] // every + 1)) for u in truth}
    for degenerate in (never, {u: _rows([r["flight"] for r in steps[u]], [0.0] * len(steps[u]))
                               for u in steps}):
        assert rate(tracker_rate(degenerate, futures, truth, every, "rul_low", 50.0)) \
            > 1.2 * rate(o)


def test_a_unit_without_a_step_at_its_cut_never_replaces():
    steps = {"A": TOY_STEPS["A"][:-1], "B": TOY_STEPS["B"]}
    e = tracker_rate(steps, TOY_FUTURES, TOY_TRUTH, 10, "rul_low", 10.0)
    assert e["fail"][0] == 1.0   # every future of A fails before DMAX


def test_a_bad_thresholds_file_is_one_line(tmp_path):
    bad = tmp_path / "t.json"
    bad.write_text(json.dumps({"format": "ema-bench-policy-thresholds", "version": 1,
                               "trackers": {"x": {"signal": "rul_high", "threshold": 3}}}))
    with pytest.raises(PolicyError, match="needs a signal"):
        read_thresholds(bad)
    bad.write_text("{")
    with pytest.raises(PolicyError, match="cannot read"):
        read_thresholds(bad)


def test_the_committed_thresholds_were_tuned_on_the_training_split():
    from ema_bench.prognostics.campaign import manifest_digest

    doc = read_thresholds(ROOT / "policy_thresholds.json")
    split = json.loads((ROOT / "training_split.json").read_text())
    # the split is the committed published campaign, every unit of it
    manifest = json.loads((ROOT.parent.parent / split["campaign"] / "manifest.json").read_text())
    assert split["manifest_digest"] == manifest_digest(manifest)
    assert split["units"] == [u["unit"] for u in manifest["units"]]
    assert doc["tuned_on"]["manifest_digest"] == split["manifest_digest"]
    assert doc["tuned_on"]["seed"] == split["seed"] is not None
    assert set(doc["trackers"]) >= {"fleet-bayes-cut", "kalman"}
    assert all(math.isfinite(t["threshold"]) for t in doc["trackers"].values())


# slow: the reference campaign's futures (about 10 CPU-s; the twin campaign's would be 60)
@pytest.mark.slow
def test_the_committed_policy_table_rescores_and_meets_its_target():
    from ema_bench.jsonio import plain
    from ema_bench.prognostics.policy import score_policies

    committed = {(r["track"], r["tracker"]): r
                 for r in json.loads((ROOT / "policy.json").read_text())}
    runs = [ROOT / "reference" / "fleet-bayes", ROOT / "reference" / "fleet-bayes-cut"]
    for got in plain(score_policies(runs, ROOT / "policy_thresholds.json")):
        want = committed[(got["track"], got["tracker"])]
        assert got["ratio"]["value"] == pytest.approx(want["ratio"]["value"], rel=1e-9)
        for part in ("value", "ci"):
            assert got["cost_per_100_flights"][part] == pytest.approx(
                want["cost_per_100_flights"][part], rel=1e-9)
    best = min(r["ratio"]["value"] for r in committed.values() if r["ratio"]["value"])
    assert 1.0 <= best <= 1.2
