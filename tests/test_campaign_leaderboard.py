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


def test_the_twin_campaign_regenerates_byte_for_byte(tmp_path):
    make_campaign("fleet-v1", **TWIN, out=tmp_path / "c")
    for name in ("manifest.json", "truth.json"):
        assert (tmp_path / "c" / name).read_bytes() == (ROOT / "twin" / "campaign" /
                                                        name).read_bytes()


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
