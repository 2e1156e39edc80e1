"""The sealed test campaign (issue 47, item 6): ``ema-bench campaign sealed`` draws a campaign
from a secret seed, moves its truth out before any tracker runs, tracks, scores and writes a
table that names the campaign as sealed by its truth file's digest, never its seed.

CI exercises the whole path on 2 units with the cheapest board tracker (``rul-age``, worker
processes and the oracle included): a few seconds.  The committed sealed table
(``leaderboards/campaign/sealed``) was written by the same command on a larger campaign whose
truth file stays with the maintainer."""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path

import pytest

from ema_bench.cli import main
from ema_bench.prognostics.track_io import read_track

ROOT = Path(__file__).resolve().parents[1] / "leaderboards" / "campaign"
#: A standalone integer of 12 digits or more (a 63-bit seed has up to 19), not part of a float.
LONG_INT = re.compile(rb"(?<![\d.eE+-])\d{12,}(?![\d.eE])")
#: The seed of a replay's sample of units (fresh entropy, printed to repeat the check): not the
#: campaign's.
SAMPLE_SEED = re.compile(rb'(sample seed |"sample_seed": )\d+')


@pytest.fixture(scope="module")
def sealed(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("sealed") / "s"
    assert main(["campaign", "sealed", "--units", "2", "--trackers", "rul-age", "--out",
                 str(out), "--quiet", "--json", "--replay", "1"]) == 0
    return out


def test_the_seed_is_in_the_moved_truth_alone(sealed):
    truth = json.loads((sealed / "truth.json").read_text())
    seed = truth["secret_seed"]
    assert truth["seed"] is None and isinstance(seed, int) and seed >= 0
    assert not (sealed / "campaign" / "truth.json").exists()   # moved before tracking
    seen = [p for p in sealed.rglob("*") if p.is_file() and p.name != "truth.json"]
    names = {p.relative_to(sealed).as_posix() for p in seen}
    assert {"campaign/manifest.json", "runs/rul-age/track.jsonl", "scores.md",
            "scores.json"} <= names
    assert not any(str(seed).encode() in p.read_bytes() for p in seen)
    log = read_track(sealed / "runs" / "rul-age")
    assert log.manifest["campaign_seed"] is None and len(log.steps) == 2


def test_the_table_names_the_sealed_campaign_by_its_truth_digest(sealed, capsys, tmp_path):
    digest = hashlib.sha256((sealed / "truth.json").read_bytes()).hexdigest()
    md = (sealed / "scores.md").read_text()
    assert md.splitlines()[0].startswith("Campaign: **sealed**")
    assert f"`{digest}`" in md and "| rul-age | twin | 2 |" in md and "**oracle**" in md
    doc = json.loads((sealed / "scores.json").read_text())
    assert doc["truth_sha256"] == digest and doc["results"][0]["tracker"] == "rul-age"
    # rerun: resumed, not drawn again (the same truth); with thresholds the policy table
    thresholds = tmp_path / "t.json"
    thresholds.write_text(json.dumps({"format": "ema-bench-policy-thresholds", "version": 1,
                                      "trackers": {"rul-age": {"signal": "rul",
                                                               "threshold": 0.0}}}))
    assert main(["campaign", "sealed", "--units", "2", "--trackers", "rul-age", "--out",
                 str(sealed), "--quiet", "--policy", str(thresholds)]) == 0
    assert hashlib.sha256((sealed / "truth.json").read_bytes()).hexdigest() == digest
    out = capsys.readouterr().out
    assert digest in out and "| **oracle policy** | twin | 2 |" in out
    # RUL = age is 0 at installation: replaced at flight 0, an infinite cost per flight
    policy = json.loads((sealed / "scores.json").read_text())["policy"]
    assert policy[0]["cost_per_100_flights"]["value"] is None   # inf, written as null


def test_a_published_campaign_is_refused_as_sealed(tmp_path, capsys):
    out = tmp_path / "s"
    assert main(["campaign", "make", "fleet-v1", "--units", "1", "--every", "50", "--seed",
                 "5", "--out", str(out / "campaign"), "--quiet"]) == 0
    (out / "campaign" / "truth.json").rename(out / "truth.json")
    assert main(["campaign", "sealed", "--units", "1", "--trackers", "rul-age", "--out",
                 str(out)]) == 2
    assert "not a sealed campaign" in capsys.readouterr().err


def test_the_committed_sealed_table_gives_its_digest_and_no_seed():
    md = (ROOT / "sealed" / "scores.md").read_bytes()
    doc = json.loads((ROOT / "sealed" / "scores.json").read_text())
    assert md.startswith(b"Campaign: **sealed**")
    assert re.fullmatch(r"[0-9a-f]{64}", doc["truth_sha256"])
    assert doc["truth_sha256"].encode() in md
    for blob in (md, (ROOT / "sealed" / "scores.json").read_bytes()):
        assert b"secret_seed" not in blob and not LONG_INT.search(SAMPLE_SEED.sub(b"", blob))


def test_no_threshold_is_tuned_on_a_sealed_campaign(sealed, tmp_path, capsys):
    assert main(["campaign", "policy", str(sealed / "runs" / "rul-age"), "--truth",
                 str(sealed / "truth.json"), "--tune", str(tmp_path / "t.json")]) == 2
    assert "tracks a sealed campaign" in capsys.readouterr().err
    assert not (tmp_path / "t.json").exists()


def test_a_sealed_table_judges_verified_track_files_only(sealed, tmp_path, capsys):
    """``campaign sealed`` replays every run as ``campaign policy`` does before scoring or
    costing it: a run folder edited between two invocations (the rerun resumes it) is
    refused, one line, nothing written; an honest one ends its table with what was
    replayed."""
    import shutil

    md = (sealed / "scores.md").read_text().splitlines()
    said = [x for x in md if x.startswith("Replayed before scoring and costing: ")]
    doc = json.loads((sealed / "scores.json").read_text())["replay"]["rul-age"]
    assert doc["tracked"] == 2 and set(doc["units"]) <= {"u000", "u001"}
    assert len(said) == 1 and f"rul-age, {len(doc['units'])} of 2 units re-tracked (" \
        in said[0] and f"sample seed {doc['sample_seed']}): every line agrees" in said[0]
    # an edited copy: the last step of one unit claims its end (RUL 0), which the policy
    # table would cost as a replacement at the cut
    copy = tmp_path / "edited"
    shutil.copytree(sealed, copy)
    (copy / "scores.md").unlink()
    track = copy / "runs" / "rul-age" / "track.jsonl"
    rows = [json.loads(x) for x in track.read_text().splitlines()]
    unit = rows[-1]["unit"]
    rows[-1]["rul"] = rows[-1]["rul_low"] = 0.0
    track.write_text("".join(json.dumps(r) + "\n" for r in rows))
    thresholds = tmp_path / "t.json"
    thresholds.write_text(json.dumps({"format": "ema-bench-policy-thresholds", "version": 1,
                                      "trackers": {"rul-age": {"signal": "rul",
                                                               "threshold": 0.0}}}))
    capsys.readouterr()
    assert main(["campaign", "sealed", "--units", "2", "--trackers", "rul-age", "--out",
                 str(copy), "--quiet", "--policy", str(thresholds), "--replay-unit",
                 unit]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and f"{unit} inspection {rows[-1]['index']}.rul" in err[0] \
        and "not scored or costed" in err[0]
    assert not (copy / "scores.md").exists()
