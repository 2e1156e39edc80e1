"""Replay of tracking runs (``campaign score --replay``): a run's lines are what its
registered tracker gives from the campaign's traces, or the run is not scored.

The campaign is the fault-injection suite's (4 units x 4 twin inspections, no truth: the
forged run is refused before any scoring); the tracker draws from its unit's seed, so a
replay that gave a unit another unit's seed, or the root seed, would not agree.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import sweep_jobs

from ema_bench.cli import main
from ema_bench.prognostics.replay import replay_track
from ema_bench.prognostics.track_run import track_campaign
from ema_bench.prognostics.tracking import Inspection, TrackerError, TrackStep, register_tracker


@register_tracker("seeded-age", description="test tracker: the age plus a draw of its seed")
def seeded_age(campaign_info, seed):
    from ema_bench.faults import FAULT_NAMES, LOWER, NOMINAL, UPPER

    rng = np.random.default_rng(seed)

    def step(insp: Inspection) -> TrackStep:
        return TrackStep(flight=insp.flight,
                         estimate={n: float(v) for n, v in zip(FAULT_NAMES, NOMINAL)},
                         low={n: float(v) for n, v in zip(FAULT_NAMES, LOWER)},
                         high={n: float(v) for n, v in zip(FAULT_NAMES, UPPER)},
                         rul=insp.flight + 100.0 * rng.random(), rul_low=0.0,
                         rul_high=math.inf, failing_fault=None, replace=False,
                         evaluations=0)
    return step


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    root = tmp_path_factory.mktemp("replay")
    camp = sweep_jobs.campaign(root / "campaign")
    return track_campaign(camp, "seeded-age", root / "run", seed=5)


def lines(run):
    return [json.loads(x) for x in (run / "track.jsonl").read_text().splitlines()]


def copy(run, name: str):
    """A copy of ``run`` beside it (its manifest names the campaign relative to it)."""
    import shutil

    return shutil.copytree(run, run.parent / name)


def forge(run, name: str, unit: str, rul: float):
    """A copy of ``run`` whose last step of ``unit`` claims ``rul``."""
    out = copy(run, name)
    rows = lines(run)
    last = [r for r in rows if r["unit"] == unit][-1]
    last["rul"] = rul
    (out / "track.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return out


def test_an_honest_run_replays_line_for_line(run):
    r = replay_track(run, k=4)
    assert r.ok, r.findings
    assert r.units == ["u000", "u001", "u002", "u003"] and r.tracked == 4
    assert r.escape_chance == 0.0


def test_a_forged_rul_is_found_and_the_run_not_scored(run, capsys):
    true_last = [x for x in lines(run) if x["unit"] == "u002"][-1]["rul"]
    bad = forge(run, "bad", "u002", true_last * 0.9)
    r = replay_track(bad, units=["u002"])
    assert not r.ok and r.findings == [
        f"u002 inspection 3.rul: recorded {true_last * 0.9!r}, replayed {true_last!r}"]
    # the command refuses it before scoring (this campaign has no truth to score against)
    assert main(["campaign", "score", str(bad), "--replay", "4", "--no-oracle"]) == 1
    err = capsys.readouterr().err
    assert "u002 inspection 3.rul" in err and "not scored" in err
    # a sample that misses the forged unit passes it, and says how likely that was
    r = replay_track(bad, k=1, seed=0)
    assert r.units != ["u002"] and r.ok and r.escape_chance == 0.75


def test_a_change_of_one_rounding_passes_and_of_a_millionth_does_not(run):
    true_last = [x for x in lines(run) if x["unit"] == "u001"][-1]["rul"]
    near = forge(run, "near", "u001", true_last * (1 + 1e-9))
    assert replay_track(near, units=["u001"]).ok
    off = forge(run, "off", "u001", true_last * (1 + 1e-5))
    assert not replay_track(off, units=["u001"]).ok


def test_another_tracker_config_or_an_unknown_unit_is_refused(run):
    other = copy(run, "other")
    m = json.loads((other / "manifest.json").read_text())
    m["config"] = {"horizon": 3}
    (other / "manifest.json").write_text(json.dumps(m))
    r = replay_track(other, k=1)
    assert not r.ok and "config" in r.findings[0]
    with pytest.raises(TrackerError, match="no tracked unit 'u009'"):
        replay_track(run, units=["u009"])


# --- ``campaign policy`` costs verified track files only (issue 47) ---------------------------

@pytest.fixture(scope="module")
def published(tmp_path_factory):
    """A 2-unit published campaign (truth in place) tracked by ``life-table``, as the
    committed board's runs are, with thresholds tuned on it by the command."""
    root = tmp_path_factory.mktemp("policy")
    assert main(["campaign", "make", "fleet-v1", "--units", "2", "--every", "50", "--seed",
                 "5", "--out", str(root / "campaign"), "--quiet"]) == 0
    assert main(["campaign", "track", str(root / "campaign"), "--tracker", "life-table",
                 "--out", str(root / "run"), "--quiet"]) == 0
    assert main(["campaign", "policy", str(root / "run"), "--tune", str(root / "t.json"),
                 "--replay", "1", "--json"]) == 0
    return root


def test_the_policy_table_says_what_it_replayed(published, capsys):
    capsys.readouterr()
    md = published / "policy.md"
    assert main(["campaign", "policy", str(published / "run"), "--thresholds",
                 str(published / "t.json"), "--markdown", str(md), "--json"]) == 0
    said = [x for x in md.read_text().splitlines() if x.startswith("Replayed before costing: ")]
    assert len(said) == 1 and "life-table, 2 of 2 units re-tracked (u000, u001; sample seed" \
        in said[0] and "every line agrees" in said[0]
    doc = json.loads(capsys.readouterr().out)[0]
    assert doc["replay"]["units"] == ["u000", "u001"] and doc["replay"]["tracked"] == 2
    assert f"sample seed {doc['replay']['sample_seed']}" in said[0]


def test_an_edited_track_file_is_refused_by_policy(published, capsys):
    from ema_bench.prognostics.policy import score_policies

    rows = lines(published / "run")
    failing = json.loads((published / "campaign" / "truth.json").read_text())["units"]
    unit = next(u for u, t in sorted(failing.items()) if t["eol"] is not None)
    # the unit's last step claims an early end: replaced at once, a dearer policy
    for r in (r for r in rows if r["unit"] == unit):
        r["rul_low"] = r["rul"] = 0.0
    bad = copy(published / "run", "edited")
    (bad / "track.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    t = published / "t.json"
    honest, edited = (score_policies([run], t, n_boot=10)[0]["cost_per_100_flights"]["value"]
                      for run in (published / "run", bad))
    assert edited != honest   # unverified, the edit moves the table
    capsys.readouterr()
    assert main(["campaign", "policy", str(bad), "--thresholds", str(t), "--replay-unit",
                 unit]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "not costed" in err[0] and f"{unit} inspection 0.rul" in err[0]
    # the tune refuses it too, and writes nothing
    assert main(["campaign", "policy", str(bad), "--tune", str(published / "t2.json"),
                 "--replay-unit", unit]) == 2
    assert not (published / "t2.json").exists()
