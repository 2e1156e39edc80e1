"""The committed campaign leaderboard (leaderboards/campaign): regenerable and re-scorable."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ema_bench.prognostics.campaign import make_campaign
from ema_bench.prognostics.scoring import score_tracking

ROOT = Path(__file__).resolve().parents[1] / "leaderboards" / "campaign"
SCORES = json.loads((ROOT / "scores.json").read_text())
# the committed command of the twin campaign (leaderboards/campaign/README.md)
TWIN = {"units": 24, "track": "twin", "seed": 8228}


def assert_same_json(got, want, where: str = "") -> None:
    """Same structure, keys, strings and integers; floats to 1e-12 relative.  The committed
    campaign was made on an Intel CPU with AVX-512: there numpy's vectorised ``sin`` and
    ``expm1`` can round the last bit differently than on a CPU without it (seen on an AMD
    EPYC: one grease friction 1.1337352514174574e-05 against ...576e-05).  On one machine the
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


def test_the_twin_campaign_regenerates(tmp_path):
    make_campaign("fleet-v1", **TWIN, out=tmp_path / "c")
    for name in ("manifest.json", "truth.json"):
        assert_same_json(json.loads((tmp_path / "c" / name).read_text()),
                         json.loads((ROOT / "twin" / "campaign" / name).read_text()), name)


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


@pytest.mark.parametrize("committed", SCORES, ids=lambda r: f"{r['track']}-{r['tracker']}")
def test_committed_runs_rescore_to_the_committed_figures(committed):
    got = score_tracking(ROOT / committed["track"] / committed["tracker"])
    for key in ("units", "failing_units", "rul_rmse", "phm08_score", "alpha_lambda",
                "rul_coverage", "false_replacements", "early_replacements"):
        assert got[key] == pytest.approx(committed[key]), key


def test_every_tracker_is_on_both_tracks_and_the_twin_fleet_is_large_enough():
    import importlib.metadata

    shipped = {ep.name for ep in importlib.metadata.entry_points(group="ema_bench.trackers")}
    assert {"refit-trend", "kalman", "particle"} <= shipped
    rows = {(r["track"], r["tracker"]) for r in SCORES}
    assert rows == {(t, n) for t in ("twin", "reference") for n in shipped}
    twin = [r for r in SCORES if r["track"] == "twin"]
    assert all(r["units"] >= 20 and not r["untracked"] and not r["failed_units"] for r in twin)
