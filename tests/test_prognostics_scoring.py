"""Scoring a tracked campaign: hand-written campaign, truth and track files in the spec's format
with every figure computed by hand (arithmetic in the comments), the error paths, the CLI, and
one small real campaign end to end."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping

import numpy as np
import pytest

from ema_bench.cli import main
from ema_bench.faults import FAULT_NAMES
from ema_bench.prognostics.campaign import (
    CampaignError,
    load_truth,
    make_campaign,
    manifest_digest,
)
from ema_bench.prognostics.scoring import ScoringError, score_tracking
from ema_bench.prognostics.track_run import track_campaign
from ema_bench.prognostics.tracking import TrackerError, TrackStep, register_tracker

INF = math.inf
THRESHOLDS = {"Na": 0.85, "Fst": 0.6756, "BLK": 0.03}
# detection levels, 25 % of the way from nominal (Na 1, Fst 0.1689, BLK 0) to the threshold:
# Na 0.9625, Fst 0.295575, BLK 0.0075


def _faults(flights, na=1.0, fst=0.18, blk=0.001, gprop=1e5):
    """Truth per flight: a fault given as a list follows the flights, a number is constant."""
    cols = [v if isinstance(v, list) else [v] * len(flights) for v in (na, fst, blk, gprop)]
    return {str(f): [c[k] for c in cols] for k, f in enumerate(flights)}


def _steps(unit, flights, truth, *, est=None, half=None, rul, rul_low, rul_high,
           failing="Fst", replace_at=None):
    """Track lines: estimates = truth unless ``est`` overrides a fault (list per flight),
    intervals estimate -+ ``half`` (per fault, default a small share covering the truth)."""
    est, half = est or {}, {"Na": 0.005, "Fst": 0.01, "BLK": 0.0005, "Gprop": 1e3,
                            **(half or {})}
    lines = []
    for k, f in enumerate(flights):
        x = {n: (est[n][k] if n in est else truth[str(f)][j])
             for j, n in enumerate(FAULT_NAMES)}
        h = {n: (half[n][k] if isinstance(half[n], list) else half[n]) for n in FAULT_NAMES}
        lines.append({"key": f"{unit}/{k:03d}", "unit": unit, "index": k, "flight": f,
                      "estimate": x, "low": {n: x[n] - h[n] for n in x},
                      "high": {n: x[n] + h[n] for n in x},
                      "rul": None if rul[k] == INF else rul[k],
                      "rul_low": rul_low[k], "rul_high": None if rul_high[k] == INF
                      else rul_high[k], "failing_fault": failing,
                      "replace": f == replace_at, "evaluations": 10})
    return lines


def write_fixture(root, name="fix-v1", seed=7):
    """Four units (every 10 flights):

    u000 fails by Fst at 100; inspected 0..60 (cut 60, true RUL 40); Fst truth 0.17 + 0.004 f,
         estimated exactly with intervals +- 0.04; Gprop estimated 1e4 high (10 % of its 1e5
         range) +- 5e3.
    u001 fails by Na at 60; inspected 0..30 (cut 30, true RUL 30); replacement called at 20,
         tracked on to its cut.
    u002 never fails (gain drift); replacement called at 20; Fst estimated 0.13512 high at 20.
    u003 fails by BLK at 80; inspected 0..40 (cut 40, true RUL 40); never tracked.
    """
    camp, run = root / "camp", root / "run"
    camp.mkdir(parents=True)
    run.mkdir()
    fl0, fl1, fl2, fl3 = range(0, 70, 10), range(0, 40, 10), range(0, 30, 10), range(0, 50, 10)
    fst0 = [0.17 + 0.004 * f for f in fl0]     # 0.17 0.21 0.25 0.29 0.33 0.37 0.41
    truth = {
        "u000": {"eol": 100, "failing_fault": "Fst", "last_flight": 60,
                 "faults": _faults(fl0, fst=fst0)},
        "u001": {"eol": 60, "failing_fault": "Na", "last_flight": 30,
                 "faults": _faults(fl1, na=[1.0, 1.0, 0.95, 0.9])},
        "u002": {"eol": None, "failing_fault": None, "last_flight": 20,
                 "faults": _faults(fl2, gprop=[1e5, 1.1e5, 1.2e5])},
        "u003": {"eol": 80, "failing_fault": "BLK", "last_flight": 40,
                 "faults": _faults(fl3, blk=[0.001, 0.005, 0.01, 0.015, 0.02])},
    }
    for u, t in truth.items():
        t.update(unit=u, true_rul=None if t["eol"] is None else t["eol"] - t["last_flight"],
                 kind=[], effects={f: {} for f in t["faults"]})
    flights = {"u000": fl0, "u001": fl1, "u002": fl2, "u003": fl3}
    manifest = {"format": "ema-bench-campaign", "version": 2, "name": name,
                "definition_version": 2, "track": "twin", "seed": seed, "split": "test",
                "inspection_every": 10, "tests": ["step", "sine"], "thresholds": THRESHOLDS,
                "laws": {}, "cut_rule": {"rule": "nearest-inspection-to-uniform-share",
                                         "stop": [0.5, 0.95]}, "model_version": "2",
                "units": [{"unit": u, "inspections": [
                    {"index": k, "flight": f, "file": f"{u}/i{k:03d}.npz", "conditions": {}}
                    for k, f in enumerate(fl)]} for u, fl in flights.items()]}
    (camp / "manifest.json").write_text(json.dumps(manifest))
    (camp / "truth.json").write_text(json.dumps(
        {"format": "ema-bench-campaign-truth", "version": 2, "name": name, "seed": seed,
         "track": "twin", "split": "test", "manifest_digest": manifest_digest(manifest),
         "units": truth}))
    (run / "manifest.json").write_text(json.dumps(
        {"format": "ema-bench-track", "version": 2, "tracker": "hand", "seed": 0,
         "campaign": "../camp", "campaign_name": name, "track": "twin", "split": "test",
         "campaign_seed": seed}))
    lines = [
        # true RUL 100 90 80 70 60 50 40
        *_steps("u000", fl0, truth["u000"]["faults"],
                est={"Gprop": [1.1e5] * 7}, half={"Fst": 0.04, "Gprop": 5e3},
                rul=[INF, 150, 100, 60, 62, 45, 44], rul_low=[INF, 90, 70, 50, 50, 38, 35],
                rul_high=[INF, INF, 200, 90, 80, 60, 50]),
        # true RUL 60 50 40 30; Na high at 20: 0.96 < 0.9625
        *_steps("u001", fl1, truth["u001"]["faults"],
                est={"Na": [1.0, 0.99, 0.95, 0.9]}, half={"Na": [0.005, 0.02, 0.01, 0.01]},
                rul=[INF, 70, 36, 20], rul_low=[INF, 50, 20, 10], rul_high=[INF, INF, 40, 30],
                replace_at=20),
        # Fst at 20: 0.18 + 0.13512 = 0.31512, interval [0.30512, 0.32512], past the level
        *_steps("u002", fl2, truth["u002"]["faults"],
                est={"Fst": [0.18, 0.18, 0.31512]}, rul=[INF] * 3, rul_low=[INF] * 3,
                rul_high=[INF] * 3, replace_at=20),
    ]
    (run / "track.jsonl").write_text("".join(json.dumps(x) + "\n" for x in lines))
    return camp, run


@pytest.fixture()
def fixture_run(tmp_path):
    return write_fixture(tmp_path)


def test_the_headline_at_the_cut_matches_the_hand_computation(fixture_run):
    _, run = fixture_run
    res = score_tracking(run, oracle=False)
    assert (res["units"], res["tracked"], res["failing_units"]) == (4, 3, 3)
    assert res["untracked"] == ["u003"] and res["failed_units"] == []
    assert res["missing_at_cut"] == 1
    # the horizon: 50 inspection intervals of 10 flights
    assert res["rul_horizon"] == 500.0
    h = res["headline"]
    # at the cuts (u000, u001, u003): predictions 44, 20 (after u001's replacement call at 20:
    # judged at its cut all the same), inf (u003 untracked); truths 40, 30, 40
    # within +-20 %: 44 in [32, 48]; 20 out of [24, 36]; inf out: 1 / 3
    assert h["within"]["value"] == pytest.approx(1 / 3)
    # clipped to 500: errors 4, 10, 460
    assert h["mae"]["value"] == pytest.approx(474 / 3)
    assert h["rmse"]["value"] == pytest.approx(math.sqrt((16 + 100 + 460 ** 2) / 3))
    assert h["phm08"]["value"] == pytest.approx(
        (math.expm1(0.4) + math.expm1(10 / 13) + math.expm1(46)) / 3)
    # intervals [35, 50] holds 40, [10, 30] holds 30 (bound), u003 none: 2 / 3; widths 15,
    # 20, inf
    assert h["coverage"]["value"] == pytest.approx(2 / 3)
    assert math.isinf(h["width"]["value"])
    # robust PHM08: the median of the three terms, u001's expm1(10/13)
    assert h["phm08_median"]["value"] == pytest.approx(math.expm1(10 / 13))
    # 95 % interval scores: 15 and 20 (no miss), u003 none: inf
    assert math.isinf(h["is95"]["value"])
    # no oracle: no expected hits; no quantiles given: no CRPS, no 50 / 80 % figures
    not_scored = {"expected", "crps", "is50", "is80", "cov50", "cov80"}
    assert {k for k, v in h.items() if math.isnan(v["value"])} == not_scored
    assert res["reliability"] == {"0.95": pytest.approx(2 / 3)}
    # bootstrap intervals bracket the value; no oracle asked: no ratio
    for k, v in h.items():
        lo, hi = v["ci"]
        assert k in not_scored or lo <= v["value"] <= hi, k
        assert "ratio" not in v
    assert h["within"]["ci"][0] == 0.0 and h["within"]["ci"][1] >= 2 / 3


def test_decisions_and_diagnostics_match_the_hand_computation(fixture_run):
    _, run = fixture_run
    res = score_tracking(run, oracle=False)
    d = res["decisions"]
    # u001 (fails at 60) replaced at 20: early (40 > 3 x 10 flights), 40 flights wasted;
    # u002 never fails: a false replacement; no inspection saw < 10 flights of life left
    assert (d["replacements"], d["false_replacements"], d["early_replacements"],
            d["failures_in_service"]) == (2, 1, 1, 0)
    assert d["wasted_flights"] == 40.0 and d["maintenance_cost"] == 2 / 4
    g = res["diagnostics"]
    # alpha-lambda: u000 judged at 50 (lambda 0.5: 45 in [40, 60]) and 60 (0.6: 44 in
    # [32, 48]), none at 70+; u001 at 30 (0.5: 20 out of [24, 36]), none at 36+; u003 none
    assert g["alpha_lambda"]["0.5"] == {"share": 0.5, "units": 2}
    assert g["alpha_lambda"]["0.6"] == {"share": 1.0, "units": 1}
    assert g["alpha_lambda"]["0.9"]["units"] == 0 and math.isnan(g["alpha_lambda"]["0.9"]["share"])
    # horizons, bounds +- 0.1 EOL: u000 (+- 10) errors inf 60 20 10 2 5 4: first in at 30,
    # stays: 70 and 70; u001 (+- 6) errors inf 20 4 10: in at 20 (first entry 60 - 20 = 40),
    # out at 30 (strict 0); u003 0: medians 40 (first entry) and 0 (strict) - a mean would give
    # 36.7 and 23.3
    assert (g["prognostic_horizon"], g["prognostic_horizon_strict"]) == (40.0, 0.0)
    # monotonicity: u000 inf 150 100 60 62 45 44: 5 down, 1 up: 4 / 6; u001 inf 70 36 20: 1
    assert g["monotonicity"] == pytest.approx(5 / 6)
    assert g["fault_monotonicity"] == 1.0
    # failing fault at the cut: Fst right for u000, wrong for u001, none for u003
    assert g["failing_fault_named"] == pytest.approx(1 / 3)


def test_the_profile_diagnostics_read_the_unconditioned_forecasts(fixture_run):
    """A cut-conditioned tracker gives ``profile_rul`` beside its ``rul``: the headline is
    judged on ``rul`` at the cut, the prognostic horizon and alpha-lambda on the profile."""
    _, run = fixture_run
    before = score_tracking(run, oracle=False)
    lines = [json.loads(x) for x in (run / "track.jsonl").read_text().splitlines()]
    eol = {"u000": 100, "u001": 60, "u002": None}
    for r in lines:   # the profile: the true RUL at every inspection (null: no failure)
        r["profile_rul"] = None if eol[r["unit"]] is None else eol[r["unit"]] - r["flight"]
    (run / "track.jsonl").write_text("".join(json.dumps(r) + "\n" for r in lines))
    after = score_tracking(run, oracle=False)
    assert json.dumps(after["headline"]) == json.dumps(before["headline"])
    # inside the bounds from the first inspection: PH = EOL - 0 (u000 100, u001 60, u003
    # untracked 0): median 60, strict too; every tracked unit within the cone at lambda 0.5
    g = after["diagnostics"]
    assert (g["prognostic_horizon"], g["prognostic_horizon_strict"]) == (60.0, 60.0)
    assert g["alpha_lambda"]["0.5"] == {"share": 1.0, "units": 2}
    assert g["monotonicity"] == pytest.approx(1.0)


def test_fault_tracking_and_detection_match_the_hand_computation(fixture_run):
    _, run = fixture_run
    res = score_tracking(run, oracle=False)
    # 14 tracked inspections (7 + 4 + 3: u001 is tracked past its replacement call); errors
    # as a share of the range (Na 0.2, Fst 0.6756, Gprop 1e5): Na -0.05 at u001's 10; Fst 0.2
    # at u002's 20; Gprop 0.1 at u000's 7
    assert res["fault_error"]["Na"] == pytest.approx(math.sqrt(0.05 ** 2 / 14))
    assert res["fault_error"]["Fst"] == pytest.approx(math.sqrt(0.2 ** 2 / 14))
    assert res["fault_error"]["BLK"] == 0.0
    assert res["fault_error"]["Gprop"] == pytest.approx(math.sqrt(7 * 0.1 ** 2 / 14))
    assert res["fault_coverage"] == pytest.approx(
        {"Na": 1.0, "Fst": 13 / 14, "BLK": 1.0, "Gprop": 7 / 14})
    # onsets: u000 Fst at 40, first flagged at 50: 10; u001 Na at 20, flagged there: 0
    assert (res["onsets"], res["detections"], res["detection_delay"]) == (2, 2, 5.0)
    # healthy unit-fault inspections: u000 7 + 4 + 7, u001 2 + 4 + 4, u002 3 + 3 + 3 = 37;
    # one false flag (u002 Fst at 20)
    assert res["false_alarm_rate"] == pytest.approx(1 / 37)


def test_per_unit_rows(fixture_run):
    _, run = fixture_run
    rows = {u["unit"]: u for u in score_tracking(run, oracle=False)["per_unit"]}
    assert sorted(rows) == ["u000", "u001", "u002", "u003"]
    u0, u1, u2, u3 = rows["u000"], rows["u001"], rows["u002"], rows["u003"]
    assert (u0["rul"], u0["true_rul"], u0["covered"], u0["within"], u0["width"],
            u0["cut"]) == (44.0, 40.0, True, True, 15.0, 60)
    assert u0["detection"]["Fst"] == {"onset": 40.0, "delay": 10.0, "false_flags": 0,
                                      "healthy": 4}
    assert (u1["inspections"], u1["cut"], u1["replaced_at"], u1["early_replacement"],
            u1["rul"]) == (4, 30, 20, True, 20.0)
    assert u2["replaced_at"] == 20 and "rul" not in u2
    assert u2["detection"]["Fst"]["false_flags"] == 1
    assert (u3["inspections"], u3["at_cut"], u3["rul"], u3["covered"]) == (0, False, INF, False)


def test_alpha_is_a_keyword_argument(fixture_run):
    _, run = fixture_run
    # alpha 0.1: 44 in [36, 44] (bound) still; alpha 0.05: out of [38, 42]
    assert score_tracking(run, alpha=0.1, oracle=False)["headline"]["within"]["value"] == \
        pytest.approx(1 / 3)
    res = score_tracking(run, alpha=0.05, oracle=False)
    assert res["headline"]["within"]["value"] == 0.0 and res["alpha"] == 0.05
    with pytest.raises(ScoringError, match="alpha"):
        score_tracking(run, alpha=1.2)


def test_an_infinite_prediction_is_clipped_in_the_errors_not_in_the_hit_rate(tmp_path):
    camp, run = write_fixture(tmp_path)
    lines = [json.loads(x) for x in (run / "track.jsonl").read_text().splitlines()]
    for x in lines:
        if x["unit"] == "u000" and x["flight"] == 60:
            x["rul"] = x["rul_high"] = None          # inf: the tracker sees no failure
    (run / "track.jsonl").write_text("".join(json.dumps(x) + "\n" for x in lines))
    h = score_tracking(run, oracle=False)["headline"]
    # u000's prediction counts as the horizon 500 in the errors: 460, 10, 460
    assert h["mae"]["value"] == pytest.approx(930 / 3)
    assert math.isfinite(h["phm08"]["value"])
    assert h["within"]["value"] == 0.0
    # [35, inf] holds the truth but is infinitely wide
    assert h["coverage"]["value"] == pytest.approx(2 / 3) and math.isinf(h["width"]["value"])


def _rewrite(path, edit):
    lines = [json.loads(x) for x in path.read_text().splitlines()]
    path.write_text("".join(json.dumps(y) + "\n" for x in lines if (y := edit(x)) is not None))


def test_missing_and_broken_files_are_named(tmp_path):
    camp, run = write_fixture(tmp_path)
    (run / "track.jsonl").rename(run / "track.bak")
    with pytest.raises(ScoringError, match="track.jsonl: no such file"):
        score_tracking(run, oracle=False)
    (run / "track.bak").rename(run / "track.jsonl")
    (camp / "truth.json").rename(tmp_path / "truth.json")
    with pytest.raises(CampaignError, match="truth.json: no such truth file.*--truth"):
        score_tracking(run, oracle=False)
    # given explicitly, it scores
    assert score_tracking(run, truth=tmp_path / "truth.json", oracle=False)["tracked"] == 3
    (run / "manifest.json").unlink()
    with pytest.raises(TrackerError, match="manifest.json"):
        score_tracking(run)
    with pytest.raises(TrackerError, match="not a tracking run"):
        score_tracking(tmp_path / "nowhere")


def test_a_version_1_run_is_refused(tmp_path):
    camp, run = write_fixture(tmp_path)
    m = json.loads((run / "manifest.json").read_text())
    (run / "manifest.json").write_text(json.dumps({**m, "version": 1}))
    with pytest.raises(ScoringError, match="version 1.*track the campaign again"):
        score_tracking(run, oracle=False)


def test_nan_and_foreign_steps_are_errors(tmp_path):
    camp, run = write_fixture(tmp_path)
    track = run / "track.jsonl"
    good = track.read_text()
    _rewrite(track, lambda x: {**x, "rul": math.nan} if x["key"] == "u000/002" else x)
    with pytest.raises(ScoringError, match="u000 flight 20: RUL is NaN"):
        score_tracking(run, oracle=False)
    track.write_text(good)
    _rewrite(track, lambda x: {**x, "unit": "u999", "key": "u999/000"}
             if x["key"] == "u000/000" else x)
    with pytest.raises(ScoringError, match=r"\['u999'\] are not in"):
        score_tracking(run, oracle=False)
    track.write_text(good)
    _rewrite(track, lambda x: {**x, "flight": 15} if x["key"] == "u000/001" else x)
    with pytest.raises(ScoringError, match="flight 15: not an inspection flight"):
        score_tracking(run, oracle=False)


def test_another_campaign_is_refused(tmp_path):
    camp, run = write_fixture(tmp_path)
    m = json.loads((run / "manifest.json").read_text())
    (run / "manifest.json").write_text(json.dumps({**m, "campaign_name": "fleet-v1"}))
    with pytest.raises(ScoringError, match="another campaign.*campaign_name"):
        score_tracking(run, oracle=False)
    (run / "manifest.json").write_text(json.dumps({**m, "campaign_seed": 8}))
    with pytest.raises(ScoringError, match="remade"):
        score_tracking(run, oracle=False)


def test_a_truth_file_of_another_campaign_is_refused(tmp_path):
    camp, run = write_fixture(tmp_path / "a")
    other, _ = write_fixture(tmp_path / "b", seed=8)
    with pytest.raises(CampaignError, match="truth of another campaign.*seed"):
        score_tracking(run, truth=other / "truth.json", oracle=False)
    # same name and seed, but its manifest is not this one (one inspection's log differs):
    # the digest tells them apart
    same, _ = write_fixture(tmp_path / "c")
    m = json.loads((camp / "manifest.json").read_text())
    m["units"][0]["inspections"][1]["conditions"] = {"ambient_temp_C": 1.0}
    (camp / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(CampaignError, match="manifest_digest"):
        score_tracking(run, oracle=False)
    with pytest.raises(CampaignError, match="manifest_digest"):
        score_tracking(run, truth=same / "truth.json", oracle=False)
    # the CLI says it in one line
    assert main(["campaign", "score", str(run), "--truth", str(other / "truth.json")]) == 2


def test_an_empty_run_scores_every_failing_unit_as_a_miss(tmp_path):
    camp, run = write_fixture(tmp_path)
    (run / "track.jsonl").write_text("")
    res = score_tracking(run, oracle=False)
    assert res["tracked"] == 0 and res["untracked"] == ["u000", "u001", "u002", "u003"]
    assert res["headline"]["within"]["value"] == 0.0
    assert res["headline"]["mae"]["value"] == pytest.approx((460 + 470 + 460) / 3)
    assert math.isnan(res["fault_error"]["Na"])


# --- the CLI ---------------------------------------------------------------------------------

def test_score_cli_json_has_the_contract_keys(fixture_run, capsys):
    _, run = fixture_run
    assert main(["campaign", "score", str(run), "--json", "--alpha", "0.05",
                 "--no-oracle"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("headline", "decisions", "diagnostics", "units", "failing_units",
                "untracked", "fault_error", "fault_coverage", "detection_delay",
                "false_alarm_rate", "per_unit", "rul_horizon", "missing_at_cut"):
        assert key in out
    assert set(out["headline"]) == {"expected", "within", "mae", "rmse", "phm08",
                                    "phm08_median", "coverage", "width", "is95", "crps",
                                    "is50", "is80", "cov50", "cov80"}
    assert (out["alpha"], out["headline"]["within"]["value"]) == (0.05, 0.0)


def test_score_cli_json_is_strict_json_with_null_for_undefined_figures(tmp_path, capsys):
    """No unit tracked: per-fault errors are undefined (NaN) and the width infinite; --json
    writes them as null, which every JSON parser reads, not as NaN or Infinity."""
    _, run = write_fixture(tmp_path)
    (run / "track.jsonl").write_text("")
    assert main(["campaign", "score", str(run), "--json", "--no-oracle"]) == 0

    def refuse(name):
        raise ValueError(f"not JSON: {name}")
    out = json.loads(capsys.readouterr().out, parse_constant=refuse)
    assert out["fault_error"]["Na"] is None and out["headline"]["width"]["value"] is None
    assert out["untracked"] == ["u000", "u001", "u002", "u003"]


def test_score_cli_table_and_errors(fixture_run, tmp_path, capsys):
    _, run = fixture_run
    assert main(["campaign", "score", str(run), "--no-oracle"]) == 0
    out, err = capsys.readouterr()
    # no oracle: no expected hits ("-"); the realised hit rate beside
    assert "| hand | twin | 4 | 3 | - | 33% [" in out and "within +-20 %" in out
    assert "1 failing unit(s) without a prediction at their cut" in err
    assert main(["campaign", "score", str(tmp_path / "nowhere")]) == 2
    assert "not a tracking run" in capsys.readouterr().err
    assert main(["campaign", "score", str(run), "--alpha", "2"]) == 2
    assert "--alpha" in capsys.readouterr().err
    # the oracle needs the units' law parameters, which this hand-made truth lacks
    assert main(["campaign", "score", str(run)]) == 2
    assert "no law parameters" in capsys.readouterr().err


# --- a real campaign, tracked without its truth file ---------------------------------------

RUL = 100.0


@register_tracker("constant-scoring-test", description="test: nominal estimates, RUL 100")
def _constant(campaign_info, seed):
    def step(insp):
        nominal = {"Na": 1.0, "Fst": 0.1689, "BLK": 0.0, "Gprop": 1e5}
        return TrackStep(insp.flight, nominal, {n: v - 1e-3 for n, v in nominal.items()},
                         {n: v + 1e-3 for n, v in nominal.items()}, RUL, 50.0, 150.0,
                         "Fst", False, 0)
    return step


def _walk(obj, seen=None):
    """Every string, path and number reachable from ``obj`` through mappings, sequences,
    dataclass fields and attributes (what a tracker could read of what it is given)."""
    seen = set() if seen is None else seen
    if id(obj) in seen:
        return
    seen.add(id(obj))
    if isinstance(obj, (str, bytes, os.PathLike)):
        yield obj
    elif isinstance(obj, np.ndarray) or isinstance(obj, (int, float, bool)) or obj is None:
        return
    elif isinstance(obj, Mapping):
        for k, v in obj.items():
            yield from _walk(k, seen)
            yield from _walk(v, seen)
    elif isinstance(obj, (list, tuple, set, frozenset)):
        for v in obj:
            yield from _walk(v, seen)
    elif hasattr(obj, "__dict__") or hasattr(obj, "__dataclass_fields__"):
        names = set(getattr(obj, "__dict__", {})) | set(getattr(obj, "__dataclass_fields__", {}))
        for n in names:
            yield from _walk(getattr(obj, n), seen)


@register_tracker("cheater-scoring-test", description="test: hunts for the truth in what it "
                  "is given")
def _cheater(campaign_info, seed):
    """Reports what it found in its steps' ``extra`` (it runs in a worker process)."""
    found = [("info", sorted(campaign_info))] + [("leak", str(x)) for x in _walk(campaign_info)]

    def step(insp):
        for x in _walk(insp):
            if isinstance(x, os.PathLike) or (isinstance(x, str) and (
                    "truth" in x.lower() or ("/" in x and os.path.exists(x)))):
                found.append(("leak", str(x)))
        s = _constant(campaign_info, seed)(insp)
        s.extra = {"found": found}
        return s
    return step


@pytest.fixture(scope="module")
def real(tmp_path_factory):
    """A 4-unit twin campaign (seed 2) whose truth file is moved away before tracking."""
    root = tmp_path_factory.mktemp("score")
    camp = make_campaign("fleet-v1", units=4, track="twin", seed=2, out=root / "camp",
                         quiet=True)
    (root / "secret").mkdir()
    truth_file = root / "secret" / "truth.json"
    (camp.root / "truth.json").rename(truth_file)
    track_campaign(camp.root, "constant-scoring-test", root / "run", quiet=True)
    return load_truth(truth_file), score_tracking(root / "run", truth=truth_file), root


def test_a_campaign_without_its_truth_tracks_and_scores_as_computed_from_its_truth(real):
    truth, res, root = real
    assert not (root / "camp" / "truth.json").exists()
    failing = sorted((u, t) for u, t in truth.items() if t["eol"] is not None)
    assert res["units"] == res["tracked"] == 4 and res["failing_units"] == len(failing) >= 2
    true = np.array([t["eol"] - t["last_flight"] for _, t in failing], dtype=float)
    h = res["headline"]
    assert h["within"]["value"] == pytest.approx(np.mean(np.abs(RUL - true) <= 0.2 * true))
    assert h["mae"]["value"] == pytest.approx(np.mean(np.abs(RUL - true)))
    assert h["rmse"]["value"] == pytest.approx(np.sqrt(np.mean((RUL - true) ** 2)))
    d = RUL - true
    assert h["phm08"]["value"] == pytest.approx(np.mean(np.where(d < 0, np.expm1(-d / 13),
                                                                 np.expm1(d / 10))))
    assert h["coverage"]["value"] == pytest.approx(np.mean((50 <= true) & (true <= 150)))
    assert h["width"]["value"] == 100.0
    assert res["decisions"]["false_replacements"] == 0 and res["untracked"] == []
    # nominal estimates: Fst's error is the truth's distance from nominal, pooled
    fst = [v[1] for t in truth.values() for v in t["faults"].values()]
    assert res["fault_error"]["Fst"] == pytest.approx(
        np.sqrt(np.mean(np.square((0.1689 - np.array(fst)) / (0.8445 - 0.1689)))))
    # without --truth the campaign folder has none: one line saying how to give it
    with pytest.raises(CampaignError, match="no such truth file"):
        score_tracking(root / "run")


def test_a_tracker_cannot_reach_the_truth_through_what_it_is_given(real, tmp_path):
    *_, root = real
    (tmp_path / "camp").symlink_to(root / "camp")
    # the truth file back in the folder: still nothing given to the tracker leads there
    import shutil
    shutil.copy(root / "secret" / "truth.json", root / "camp" / "truth.json")
    try:
        track_campaign(root / "camp", "cheater-scoring-test", tmp_path / "run", quiet=True)
    finally:
        (root / "camp" / "truth.json").unlink()
    rows = [json.loads(x) for x in (tmp_path / "run" / "track.jsonl").read_text().splitlines()]
    last = {r["unit"]: r for r in sorted(rows, key=lambda r: r["index"])}   # holds it all
    found = [tuple(f) for r in last.values() for f in r["extra"]["found"]]
    info = [x for k, x in found if k == "info"]
    assert len(info) == 4 and "root" not in info[0]
    leaks = [x for k, x in found if k == "leak" and ("/" in str(x) or "truth" in str(x).lower())]
    assert leaks == []
    # the walk does find a path where there is one (catches a walker that sees nothing)
    assert [x for x in _walk({"a": [{"b": root / "camp"}]})] == ["a", "b", root / "camp"]


def test_the_oracle_and_the_board_figures_are_pinned_on_a_small_fixed_campaign(real):
    """Pinned by value: a one-line change to the oracle (its cut weighting, its point, its
    seed) or to the board's statistics (a median for a mean, the bootstrap) moves these."""
    truth, res, root = real
    o = {u["unit"]: (u["rul"], u["rul_low"], u["rul_high"]) for u in res["oracle_per_unit"]}
    assert sorted(o) == sorted(PINNED_ORACLE)
    for unit, want in PINNED_ORACLE.items():
        assert o[unit] == pytest.approx(want), unit
    assert {u: t["true_rul"] for u, t in truth.items()
                                                  if t["eol"]} == {"u000": 73, "u001": 197,
                                                                   "u003": 64}
    h = res["headline"]
    assert {k: (round(v["value"], 6), [round(x, 6) for x in v["ci"]],
                round(v["oracle"], 6), round(v["ratio"], 6), [round(x, 6) for x in v["ratio_ci"]])
            for k, v in h.items() if k in ("within", "mae", "width")} == PINNED_BOARD
    g = res["diagnostics"]
    assert (g["prognostic_horizon"], g["prognostic_horizon_strict"]) == PINNED_PH
    # a second scoring gives the same (seeded bootstrap, seeded oracle)
    again = score_tracking(root / "run", truth=root / "secret" / "truth.json")
    assert json.dumps(again["headline"]) == json.dumps(res["headline"])   # NaN: not scored


def test_a_run_written_from_the_truth_earns_its_realised_hits_not_its_expected_ones(real,
                                                                                   tmp_path):
    """The attempt to earn the headline without forecasting: a track.jsonl whose RULs at the
    cut are the true RULs (and a zero-width interval on them) hits every unit as realised, but
    its expected hits, judged on the units' futures, are no better than the oracle's Bayes
    point (the true RUL is one draw of a spread-out future)."""
    import shutil

    truth, _, root = real
    run = tmp_path / "forged"
    shutil.copytree(root / "run", run)
    (run / "manifest.json").write_text((root / "run" / "manifest.json").read_text().replace(
        '"campaign": "../camp"', f'"campaign": "{root / "camp"}"'))
    lines = [json.loads(x) for x in (run / "track.jsonl").read_text().splitlines()]
    for r in lines:
        t = truth[r["unit"]]
        if t["eol"] is not None and r["flight"] == t["last_flight"]:
            r["rul"] = r["rul_low"] = r["rul_high"] = float(t["eol"] - t["last_flight"])
    (run / "track.jsonl").write_text("".join(json.dumps(r) + "\n" for r in lines))
    h = score_tracking(run, truth=root / "secret" / "truth.json")["headline"]
    assert h["within"]["value"] == 1.0 and h["coverage"]["value"] == 1.0
    assert h["expected"]["value"] < 0.6 < h["expected"]["oracle"]
    assert h["expected"]["ratio"] < 1.0


def test_the_no_sensing_references_score_low(real):
    """Through the real commands on the small campaign, and on 400 lives drawn from fleet-v1's
    laws with the real cut rule (the references read no trace, so no traces are needed)."""
    from ema_bench.prognostics.campaign import _inspection_flights
    from ema_bench.prognostics.laws import FleetLaws, unit_history
    from ema_bench.prognostics.tracking import Inspection, get_tracker
    from ema_bench.seeding import child

    truth, _, root = real
    for name in ("rul-age", "life-table"):
        track_campaign(root / "camp", name, root / name, quiet=True)
        r = score_tracking(root / name, truth=root / "secret" / "truth.json", oracle=False)
        assert r["tracked"] == 4 and r["decisions"]["replacements"] == 0
    info = {"laws": FleetLaws().to_dict(), "inspection_every": 10, "thresholds": THRESHOLDS,
            "cut_rule": {"stop": [0.5, 0.95]}}
    steps = {n: get_tracker(n).start(info, np.random.SeedSequence(0))
             for n in ("rul-age", "life-table")}
    hits = {n: 0 for n in steps}
    rng = np.random.default_rng(5)
    n_units = 0
    for k in range(400):
        h = unit_history(child(np.random.SeedSequence(99), k), FleetLaws())
        if h.eol is None:
            continue
        cut = _inspection_flights(h, 10, "test", (0.5, 0.95), rng)[-1]
        insp = Inspection("u", 0, cut, None, {}, THRESHOLDS, 10)
        n_units += 1
        for n, step in steps.items():
            hits[n] += abs(step(insp).rul - (h.eol - cut)) <= 0.2 * (h.eol - cut)
    share = {n: v / n_units for n, v in hits.items()}
    # RUL = age is within +-20 % only when the cut falls at 44-55 % of life: about 10 %
    assert share["rul-age"] < 0.2 and share["life-table"] < 0.3
    assert share["life-table"] > share["rul-age"]


def test_score_cli_writes_plots_and_a_markdown_table(real, tmp_path, capsys):
    *_, root = real
    table = tmp_path / "scores.md"
    assert main(["campaign", "score", str(root / "run"), "--truth",
                 str(root / "secret" / "truth.json"), "--plots", str(tmp_path / "plots"),
                 "--markdown", str(table)]) == 0
    lines = table.read_text().splitlines()
    # the file names its campaign first: this one's seed is published
    assert lines[0] == ("Campaign: **published**, fleet-v1 (definition 2), twin track, 4 test "
                        "units, seed 2 (public: it ranks honest trackers only).") and lines[1] == ""
    lines = lines[2:]
    assert lines[0].startswith("| tracker | track |") and lines[2].startswith(
        "| constant-scoring-test | twin |")
    assert lines[3].startswith("| **oracle** | twin |")
    pngs = sorted(p.name for p in (tmp_path / "plots").glob("*.png"))
    assert "rul_errors_twin.png" in pngs and "alpha_lambda_twin.png" in pngs
    assert "reliability_twin.png" in pngs
    # the tables by failing fault and cut position, the tracker's row and the oracle's
    at = lines.index(next(x for x in lines if x.startswith("**expected within +-20 % by")))
    assert lines[at + 2].startswith("| tracker | Fst (") and "| late (" in lines[at + 2]
    assert lines[at + 4].startswith("| constant-scoring-test | ")
    assert lines[at + 5].startswith("| **oracle** | ")
    assert "rul_constant-scoring-test-twin.png" in pngs
    assert any(n.startswith("unit_constant-scoring-test-twin_u") for n in pngs)
    assert capsys.readouterr().out.splitlines() == lines


#: The oracle's (point, 2.5 %, 97.5 %) at each failing unit's cut of the campaign above
#: (true RULs: u000 73, u001 197, u003 64: each within +-20 % of the oracle's point).
PINNED_ORACLE = {"u000": (68.0, 16.0, 84.0), "u001": (236.0, 71.0, 290.0),
                 "u003": (65.6, 34.0, 92.0)}
#: figure: (value, bootstrap interval, oracle's value, ratio, paired ratio interval)
PINNED_BOARD = {"within": (0.0, [0.0, 0.0], 1.0, 0.0, [0.0, 0.0]),
                "mae": (53.333333, [27.0, 97.0], 15.2, 3.508772, [2.487179, 22.5]),
                "width": (100.0, [100.0, 100.0], 115.0, 0.869565, [0.456621, 1.724138])}
#: median prognostic horizons, first entry and strict (flights)
PINNED_PH = (123.0, 0.0)
