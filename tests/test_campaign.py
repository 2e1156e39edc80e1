"""Campaigns: files written and read back, seeds, splits, hidden truth, the command line."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from ema_bench.cli import main
from ema_bench.faults import FAULT_INDEX
from ema_bench.prognostics import campaign as cmod
from ema_bench.prognostics.campaign import (
    CAMPAIGNS,
    Campaign,
    CampaignError,
    CampaignSpec,
    load_campaign,
    load_truth,
    make_campaign,
)
from ema_bench.prognostics.laws import THRESHOLDS, crossed
from ema_bench.traces import Traces

# a small design for fast tests: 3 units, one of them gain drift only, sparse inspections
MINI = CampaignSpec("mini-test", "test campaign", inspection_every=40, drift_share=0.34)


@pytest.fixture(scope="module", autouse=True)
def mini_spec():
    CAMPAIGNS[MINI.name] = MINI
    yield
    del CAMPAIGNS[MINI.name]


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """The same test campaign twice (same seed), another seed, and a train split."""
    base = tmp_path_factory.mktemp("campaigns")
    out = {}
    for key, kw in {"a": dict(seed=3), "b": dict(seed=3), "c": dict(seed=4),
                    "train": dict(seed=3, split="train")}.items():
        out[key] = make_campaign(MINI.name, units=3, out=base / key, **kw)
    return out


def files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes()
            for p in sorted(root.rglob("*")) if p.is_file()}


def test_campaign_round_trip(made):
    c = made["a"]
    assert isinstance(c, Campaign) and c.name == MINI.name and c.split == "test"
    assert c.track == "twin" and c.seed == 3 and c.inspection_every == 40
    assert c.thresholds == THRESHOLDS and c.tests == ("step", "sine")
    assert list(c.units) == ["u000", "u001", "u002"]
    for recs in c.units.values():
        assert [r.index for r in recs] == list(range(len(recs)))
        assert [r.flight for r in recs] == [40 * i for i in range(len(recs))]
        assert set(recs[1].conditions) == {"ambient_temp_C", "winding_temp_C",
                                           "flights_since_last", "duty_since_last"}
    t = c.traces(c.units["u000"][1])
    assert isinstance(t, Traces) and t.tests == ("step", "sine")
    assert load_campaign(c.root / "manifest.json").units == c.units
    assert c.info()["thresholds"] == THRESHOLDS


def test_same_seed_same_bytes_other_seed_differs(made):
    a, b, c = (files(made[k].root) for k in "abc")
    assert a == b
    assert a["truth.json"] != c["truth.json"]
    assert a["u000/i000.npz"] != c["u000/i000.npz"]


def test_truth_is_hidden_from_what_trackers_see(made):
    c = made["a"]
    doc = json.loads((c.root / "manifest.json").read_text())
    # the published cut rule is no truth (its words aside: "rule" holds "rul")
    assert doc.pop("cut_rule")["stop"] == [0.5, 0.95]
    manifest = json.dumps(doc)
    for word in ("faults", "eol", "rul", "failing", "effects", "params", "truth", "digest"):
        assert word not in manifest
    t = c.traces(c.units["u001"][0])
    assert set(t.meta) == {"model", "noise", "adc", "unit", "inspection", "flight"}
    truth = load_truth(c.root)
    assert set(truth) == set(c.units)
    for label, recs in c.units.items():
        assert list(truth[label]["faults"]) == [str(r.flight) for r in recs]


def test_test_units_stop_within_50_to_95_percent_of_life(made):
    truth = load_truth(made["a"].root)
    failing = [t for t in truth.values() if t["eol"] is not None]
    assert len(failing) == 2
    for t in failing:
        assert 0.5 <= t["last_flight"] / t["eol"] <= 0.95
        assert t["true_rul"] == t["eol"] - t["last_flight"] > 0
        assert t["life_fraction"] == pytest.approx(t["last_flight"] / t["eol"])
        j = FAULT_INDEX[t["failing_fault"]]
        assert crossed(t["failing_fault"], t["faults_at_eol"][j])
        # the hidden future runs up to, not past, the end of life
        assert all(t["last_flight"] < int(f) < t["eol"] for f in t["faults_after"])


def test_train_units_run_to_failure_and_never_cross_before(made):
    c = made["train"]
    truth = load_truth(c.root)
    for label, t in truth.items():
        last = c.units[label][-1].flight
        assert t["last_flight"] == last and t["faults_after"] == {}
        if t["eol"] is None:
            continue
        assert last < t["eol"] <= last + c.inspection_every  # the last inspection before EOL
        for values in t["faults"].values():
            assert not any(crossed(n, values[FAULT_INDEX[n]]) for n in THRESHOLDS)


def test_gain_drift_units_never_fail(made):
    for key in ("a", "train"):
        drift = [t for t in load_truth(made[key].root).values() if t["kind"] == ["Gprop"]]
        assert len(drift) == 1
        t = drift[0]
        assert t["eol"] is None and t["true_rul"] is None and t["failing_fault"] is None
        values = np.array(list(t["faults"].values()))
        assert np.ptp(values[:, :3], axis=0).max() == 0.0  # Na, Fst, BLK constant
        assert np.ptp(values[:, 3]) > 0.0


def test_remake_replaces_an_old_campaign_and_refuses_other_folders(tmp_path):
    out = tmp_path / "c"
    make_campaign(MINI.name, units=3, inspection_every=200, out=out)
    c = make_campaign(MINI.name, units=2, inspection_every=200, out=out)
    assert not (out / "u002").exists() and list(c.units) == ["u000", "u001"]
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with pytest.raises(CampaignError, match="not a campaign folder"):
        make_campaign(MINI.name, units=1, out=other)
    assert (other / "notes.txt").read_text() == "mine"
    with pytest.raises(CampaignError, match="unknown campaign 'nope'"):
        make_campaign("nope", out=tmp_path / "x")
    with pytest.raises(CampaignError, match="units must be"):
        make_campaign(MINI.name, units=0, out=tmp_path / "x")


def _broken(tmp_path: Path, src: Campaign, edit) -> Path:
    dst = tmp_path / "broken"
    shutil.rmtree(dst, ignore_errors=True)
    shutil.copytree(src.root, dst)
    doc = json.loads((dst / "manifest.json").read_text())
    text = edit(doc, dst)
    (dst / "manifest.json").write_text(text if isinstance(text, str) else json.dumps(doc))
    return dst


@pytest.mark.parametrize("edit, message", [
    (lambda d, p: '{"format": "ema-bench-campaign", "version": 1,', "not valid JSON"),
    (lambda d, p: d.update(format="ema-bench-track", tracker="kalman"),
     "not a campaign manifest.*tracking run"),
    (lambda d, p: d.update(version=9), "version 9 is not supported"),
    (lambda d, p: d.pop("thresholds"), "missing 'thresholds'"),
    (lambda d, p: d.update(seed="3"), "'seed' has the wrong type"),
    (lambda d, p: (p / "u001" / "i001.npz").unlink(), "unit u001 inspection 1: file "
                                                     "u001/i001.npz is missing"),
    (lambda d, p: d["units"][0]["inspections"][1].update(index=5), "index 5 out of order"),
    (lambda d, p: d["units"][0]["inspections"][1].update(file="../x.npz"), "inside the"),
])
def test_load_campaign_rejects_broken_manifests(tmp_path, made, edit, message):
    with pytest.raises(CampaignError, match=message):
        load_campaign(_broken(tmp_path, made["a"], edit))


def test_load_campaign_names_missing_and_unfinished_folders(tmp_path, made):
    with pytest.raises(CampaignError, match="no such campaign folder"):
        load_campaign(tmp_path / "absent")
    with pytest.raises(CampaignError, match="no manifest.json"):
        load_campaign(tmp_path)
    half = tmp_path / "half"
    shutil.copytree(made["a"].root, half)
    (half / cmod.PARTIAL).write_text("{}")
    with pytest.raises(CampaignError, match="not finished"):
        load_campaign(half)
    (half / cmod.PARTIAL).unlink()
    (half / "truth.json").write_text("[]")
    with pytest.raises(CampaignError, match="not a campaign truth file"):
        load_truth(half)


def test_cli_make_writes_a_campaign_and_reports_errors(tmp_path, capsys):
    out = tmp_path / "cli"
    assert main(["campaign", "make", MINI.name, "--units", "2", "--seed", "1", "--every", "100",
                 "--split", "train", "--out", str(out), "--json", "--quiet"]) == 0
    summary = json.loads(capsys.readouterr().out)
    c = load_campaign(out)
    assert summary["units"] == 2 and summary["split"] == "train" and c.inspection_every == 100
    assert summary["inspections"] == sum(len(v) for v in c.units.values())
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "a.txt").write_text("x")
    for argv, message in [(["nope"], "unknown campaign"),
                          ([MINI.name, "--units", "0"], "argument --units: must be from 1"),
                          ([MINI.name, "--every", "0"], "argument --every: must be from 1"),
                          ([MINI.name, "--out", str(tmp_path / "junk")], "not a campaign")]:
        assert main(["campaign", "make", *argv, "--quiet"]) == 2
        assert message in capsys.readouterr().err


def test_reference_track_inspection(tmp_path):
    c = make_campaign(MINI.name, units=1, track="reference", inspection_every=150,
                      out=tmp_path / "ref")
    recs = c.units["u000"]
    assert len(recs) >= 2 and c.track == "reference"
    assert c.traces(recs[0]).meta["model"] == "reference"


def test_trackers_get_the_settings_without_a_folder_as_a_fresh_copy(made):
    c = made["a"]
    info = c.info()
    # no seed: with it (and the public, deterministic generation) the lives could be simulated
    # again
    assert set(info) == {"name", "track", "split", "inspection_every", "thresholds",
                         "laws", "tests", "model_version", "definition_version", "cut_rule"}
    assert str(c.root) not in json.dumps(info) and "truth" not in json.dumps(info)
    assert info["cut_rule"] == {"rule": cmod.CUT_RULE, "stop": [0.5, 0.95]}
    assert info["definition_version"] == MINI.version == 2
    info["laws"]["fst_shape"] = 99.0            # a tracker's edit stays its own
    info["thresholds"]["Fst"] = 0.0
    assert c.info()["laws"]["fst_shape"] != 99.0 and c.thresholds["Fst"] == THRESHOLDS["Fst"]


def test_the_truth_is_bound_to_its_manifest(made):
    a, c = made["a"], made["c"]
    doc = cmod.read_truth(a.root, a)
    manifest = json.loads((a.root / "manifest.json").read_text())
    assert doc["manifest_digest"] == cmod.manifest_digest(manifest) == a.digest
    with pytest.raises(CampaignError, match="truth of another campaign.*seed"):
        load_truth(c.root, a)
    with pytest.raises(CampaignError, match="no such truth file"):
        load_truth(a.root / "nowhere.json", a)


def test_cut_likelihood_is_the_cut_rule(made):
    """cut_likelihood against the rule itself (_inspection_flights drawn 4000 times per
    life), lives from shorter than two spacings to long."""
    rng = np.random.default_rng(1)
    draws = 4000
    for life in (23, 37, 151, 300, 455):
        h = type("H", (), {"horizon": life})()
        cuts = [cmod._inspection_flights(h, 10, "test", (0.5, 0.95), rng)[-1]
                for _ in range(draws)]
        flights = range(0, life + 20, 10)
        p = np.array([float(cmod.cut_likelihood(f, life, 10, (0.5, 0.95))) for f in flights])
        freq = np.array([cuts.count(f) / draws for f in flights])
        assert p.sum() == pytest.approx(1.0)
        assert np.abs(p - freq).max() < 0.025, (life, p, freq)
    # vectorised over lives; a life not after the cut, or infinite, has probability 0
    # (151: 150 lies past 95 % of it; 200: 150 nearest to u x 200 for u x 200 in [145, 155])
    got = cmod.cut_likelihood(150, np.array([150.0, 151.0, 200.0, 300.0, np.inf]), 10,
                              (0.5, 0.95))
    assert got[0] == got[1] == got[4] == 0.0
    assert got[2] == pytest.approx(10 / (0.45 * 200))
    # life 300: the grid inside [150, 285]; 150 is its first point, nearest to u x 300 for
    # u x 300 in [150, 155]: 5 / (0.45 x 300)
    assert got[3] == pytest.approx(5 / (0.45 * 300))
