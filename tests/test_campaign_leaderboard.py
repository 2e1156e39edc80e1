"""The committed campaign leaderboard (leaderboards/campaign): regenerable and re-scorable.

Rescoring runs the oracle once per campaign (about 1 min for the 200-unit twin campaign on one
idle core; memoised across the runs of a campaign)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ema_bench.jsonio import plain
from ema_bench.prognostics.campaign import (
    _drift_units,
    _make_unit,
    get_spec,
    load_campaign,
    manifest_digest,
    read_truth,
)
from ema_bench.prognostics.scoring import HEADLINE, score_tracking
from ema_bench.seeding import as_seed_sequence, run_seed

ROOT = Path(__file__).resolve().parents[1] / "leaderboards" / "campaign"
SCORES = json.loads((ROOT / "scores.json").read_text())
PARTIAL = (json.loads((ROOT / "scores-partial.json").read_text())
           if (ROOT / "scores-partial.json").exists() else [])
# the committed commands (leaderboards/campaign/README.md)
MADE = {"twin": {"units": 200, "seed": 4273}, "reference": {"units": 24, "seed": 1919}}


def assert_same_json(got, want, where: str = "") -> None:
    """Same structure, keys, strings and integers; floats to 1e-12 relative.  The committed
    campaign was made on one CPU; on a CPU with another SIMD instruction set numpy's
    vectorised ``sin`` and ``expm1`` can round the last bit differently (seen on an AMD EPYC:
    one grease friction 1.1337352514174574e-05 against ...576e-05).  On one machine the
    files are byte-identical per seed (tests/test_campaign.py)."""
    assert type(got) is type(want), where
    if isinstance(want, dict):
        assert list(got) == list(want), where
        for k in want:
            assert_same_json(got[k], want[k], f"{where}/{k}")
    elif isinstance(want, list):
        assert len(got) == len(want), where
        for i, (g, w) in enumerate(zip(got, want)):
            assert_same_json(g, w, f"{where}/{i}")
    elif isinstance(want, float):
        assert got == pytest.approx(want, rel=1e-12, abs=0.0), where
    else:
        assert got == want, where


def test_assert_same_json_catches_what_it_must():
    base = {"a": [1, 2.0, "x"], "b": {"c": 1.0e-5}}
    assert_same_json(json.loads(json.dumps(base)), base)
    assert_same_json({"a": [1, 2.0, "x"], "b": {"c": 1.0e-5 * (1 + 2e-16)}}, base)  # last bit
    for bad in ({"a": [1, 2.0, "y"], "b": {"c": 1.0e-5}},          # a string
                {"a": [1, 2.0], "b": {"c": 1.0e-5}},               # a list's length
                {"a": [1, 2.0, "x"], "b": {"c": 1.0001e-5}},       # a float beyond 1e-12
                {"a": [1, 2.0, "x"], "b": {"d": 1.0e-5}},          # a key
                {"a": [1, 2, "x"], "b": {"c": 1.0e-5}},            # a float written as an int
                {"b": {"c": 1.0e-5}, "a": [1, 2.0, "x"]}):         # key order (the file's)
        with pytest.raises(AssertionError):
            assert_same_json(bad, base)


@pytest.mark.parametrize("track", ["twin"])
def test_the_committed_campaign_regenerates(track, tmp_path):
    """Five units of the 200 made again through make_campaign's own per-unit path (all of
    them would write 160 MB of traces): their manifest entries and truth records are the
    committed ones, and the truth is bound to the committed manifest."""
    manifest = json.loads((ROOT / track / "campaign" / "manifest.json").read_text())
    truth = json.loads((ROOT / track / "campaign" / "truth.json").read_text())
    assert truth["manifest_digest"] == manifest_digest(manifest)
    assert (manifest["seed"], len(manifest["units"])) == (MADE[track]["seed"],
                                                          MADE[track]["units"])
    spec = get_spec(manifest["name"])
    seed, n = manifest["seed"], len(manifest["units"])
    drift = _drift_units(as_seed_sequence(seed), n, spec.drift_share)
    for u in (0, 1, 57, 123, n - 1):
        label = f"u{u:03d}"
        entries, record = _make_unit(tmp_path, label, run_seed(seed, u), spec,
                                     manifest["inspection_every"], manifest["split"], track,
                                     wear=u not in drift)
        assert_same_json(json.loads(json.dumps(entries)), manifest["units"][u]["inspections"],
                         label)
        assert_same_json(json.loads(json.dumps(record)), truth["units"][label], label)


def _run(row: dict) -> Path:
    return ROOT / row["track"] / row["tracker"]


# slow: the oracle of each campaign (about 30 CPU-s for the 200-unit twin one); the fast loop
# pins score_tracking and its oracle on a small real campaign (test_prognostics_scoring.py)
@pytest.mark.slow
@pytest.mark.parametrize("committed", SCORES + PARTIAL,
                         ids=lambda r: f"{r['track']}-{r['tracker']}"
                         + ("-partial" if r.get("tracked_only") else ""))
def test_committed_runs_rescore_to_the_committed_figures(committed):
    # as the committed JSON holds them: a non-finite figure (an infinite width) as null
    got = plain(score_tracking(_run(committed),
                               tracked_only=committed.get("tracked_only", False)))
    for key in ("units", "failing_units", "scored_units", "missing_at_cut"):
        assert got[key] == committed[key], key
    for k in HEADLINE:
        for part in ("value", "ci", "oracle", "ratio", "ratio_ci"):
            g, w = got["headline"][k][part], committed["headline"][k][part]
            for a, b in zip(g, w) if isinstance(w, list) else [(g, w)]:
                assert (a is None and b is None) or a == pytest.approx(b), (k, part)
    assert got["decisions"] == committed["decisions"]


#: Shipped trackers not yet tracked on the committed campaigns, and why (the lead decides).
NOT_ON_THE_BOARD = {
    "fleet-bayes-onset": "issue 47: not significantly above fleet-bayes-cut: 0.923 [0.904, "
                         "0.942] of the oracle's expected hits against 0.905 on the twin "
                         "campaign's 170 failing units, difference +0.018 [-0.001, +0.041]; "
                         "coil shorts 0.871 against 0.818 (leaderboards/campaign/"
                         "fleet-bayes-onset-offline.jsonl); a full track costs ~40 CPU-min",
}


def test_the_board_ranks_on_a_large_twin_campaign_and_the_references_score_low():
    import importlib.metadata

    shipped = {ep.name for ep in importlib.metadata.entry_points(group="ema_bench.trackers")}
    # every shipped tracker complete on both committed campaigns (no partial run left), but
    # those named here, with the reason they are not on the board yet
    assert set(NOT_ON_THE_BOARD) <= shipped
    for track in MADE:
        assert shipped - set(NOT_ON_THE_BOARD) == {r["tracker"] for r in SCORES
                                                   if r["track"] == track}, track
    assert PARTIAL == []
    twin = {r["tracker"]: r for r in SCORES if r["track"] == "twin"}
    ref = twin["kalman"]
    assert ref["units"] >= 200 and ref["failing_units"] >= 170
    assert all(r["missing_at_cut"] == 0 and not r["tracked_only"] for r in twin.values())
    for name in ("rul-age", "life-table"):
        assert twin[name]["headline"]["within"]["value"] < 0.30
    # the oracle, on the same units for every complete run, beats every tracker on the hit rate
    oracle = {r["headline"]["within"]["oracle"] for r in twin.values()}
    assert len(oracle) == 1
    best = max(r["headline"]["within"]["value"] for r in twin.values())
    assert best < oracle.pop() <= 1.0
    # the published cut rule is worth something to a tracker that uses it, as to the oracle
    cut, plain_ = twin["fleet-bayes-cut"]["headline"], twin["fleet-bayes"]["headline"]
    assert cut["within"]["value"] > plain_["within"]["value"]
    assert cut["mae"]["value"] < plain_["mae"]["value"]
    # each committed campaign's truth is its manifest's
    for track in MADE:
        camp = load_campaign(ROOT / track / "campaign", traces=False)
        assert read_truth(ROOT / track / "campaign", camp)["seed"] == MADE[track]["seed"]
    assert np.isfinite(ref["rul_horizon"])


def _first_step(tmp_path: Path, scheme: int | None) -> tuple[dict, dict]:
    """``fleet-bayes``'s first step on twin unit u001 (its inspection made again through
    make_campaign's per-unit path), with the settings of a replay of the given seed scheme,
    beside the committed run's first line."""
    from ema_bench.prognostics.campaign import load_campaign
    from ema_bench.prognostics.track_io import read_track
    from ema_bench.prognostics.track_run import run_unit, unit_seed
    from ema_bench.prognostics.tracking import Inspection, get_tracker
    from ema_bench.traces import load_traces

    manifest = json.loads((ROOT / "twin" / "campaign" / "manifest.json").read_text())
    spec = get_spec(manifest["name"])
    entries, _ = _make_unit(tmp_path, "u001", run_seed(manifest["seed"], 1), spec,
                            manifest["inspection_every"], manifest["split"], "twin", wear=True)
    e = entries[0]
    insp = Inspection(unit="u001", index=0, flight=e["flight"],
                      traces=load_traces(tmp_path / e["file"]), conditions=e["conditions"],
                      thresholds=manifest["thresholds"],
                      inspection_every=manifest["inspection_every"])
    settings = load_campaign(ROOT / "twin" / "campaign", traces=False).info()
    if scheme is not None:
        settings["seed_scheme"] = scheme
    rows, _ = run_unit(get_tracker("fleet-bayes"), settings, "u001", [insp],
                       unit_seed(0, 1, 1))
    return rows[0], read_track(ROOT / "twin" / "fleet-bayes").steps["u001"][0]


@pytest.mark.slow
def test_a_committed_scheme_1_run_gives_its_first_fit_again(tmp_path, monkeypatch, made_under):
    """The committed twin ``fleet-bayes`` run (seed scheme 1) replays: its first inspection's
    CMA-ES fit, seeded by the run's scheme (``campaign_info["seed_scheme"]``, which replay
    gives a scheme-1 run), is the committed one to the bit; seeded by this version's scheme
    it is another fit (every committed model-based run failed its replay so).  Two CMA-ES
    fits of 1,500 evaluations, about 10 CPU-s; the fast test below pins the settings."""
    from ema_bench.prognostics.replay import _differences

    if not made_under("openblas SkylakeX"):   # the committed run's kernel
        return
    monkeypatch.delenv("EMA_BENCH_FIT_CACHE", raising=False)
    got, want = _first_step(tmp_path, 1)
    got = {k: v for k, v in got.items() if k in want}   # fields added after the run
    assert _differences(got, want, "u001") == []
    assert got["estimate"] == want["estimate"]
    other, _ = _first_step(tmp_path, None)
    assert other["estimate"]["BLK"] != want["estimate"]["BLK"]


def test_a_replay_of_a_scheme_1_run_tells_the_tracker_its_scheme(tmp_path):
    """``unit_inputs`` adds ``seed_scheme`` to the published settings for a run of another
    scheme only, and the baselines' fitter seeds its solver by it (and keys its cache by it)."""
    import sweep_jobs

    from ema_bench.prognostics.campaign import load_campaign
    from ema_bench.prognostics.track_run import unit_inputs
    from ema_bench.seeding import SEED_SCHEME
    from ema_bench_trackers._common import fit_key, unit_setup

    camp = load_campaign(sweep_jobs.campaign(tmp_path / "campaign"))
    unit = next(iter(camp.units))
    now, _ = unit_inputs(camp, unit)
    old, inspections = unit_inputs(camp, unit, 1)
    assert "seed_scheme" not in now and old == {**now, "seed_scheme": 1} and SEED_SCHEME != 1
    seed = np.random.SeedSequence(5)
    a, b = (unit_setup(s, seed, 100, 100).fitter for s in (now, old))
    assert (a.seed_scheme, b.seed_scheme) == (SEED_SCHEME, 1)
    assert fit_key(a, inspections[0]) != fit_key(b, inspections[0])
