"""Scoring a tracked campaign: hand-written campaign, truth and track files in the spec's format
with every figure computed by hand (arithmetic in the comments), the error paths, the CLI, and
one small real campaign end to end."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from ema_bench.cli import main
from ema_bench.faults import FAULT_NAMES
from ema_bench.prognostics.campaign import CampaignError, load_truth, make_campaign
from ema_bench.prognostics.scoring import CAP_FACTOR, ScoringError, score_tracking
from ema_bench.prognostics.tracking import (
    TrackerError,
    TrackStep,
    register_tracker,
    track_campaign,
)

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


def write_fixture(root, name="fix-v1"):
    """Four units (every 10 flights):

    u000 fails by Fst at 100; inspected 0..60; Fst truth 0.17 + 0.004 f, estimated exactly
         with intervals +- 0.04; Gprop estimated 1e4 high (10 % of its 1e5 range) +- 5e3.
    u001 fails by Na at 60; inspected 0..30 but replaced at 20 (the step at 30 is ignored).
    u002 never fails (gain drift); replaced at 20; Fst estimated 0.13512 high at 20.
    u003 fails by BLK at 80; never tracked.
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
    manifest = {"format": "ema-bench-campaign", "version": 1, "name": name, "track": "twin",
                "seed": 7, "split": "test", "inspection_every": 10, "tests": ["step", "sine"],
                "thresholds": THRESHOLDS, "laws": {}, "model_version": "2",
                "units": [{"unit": u, "inspections": [
                    {"index": k, "flight": f, "file": f"{u}/i{k:03d}.npz", "conditions": {}}
                    for k, f in enumerate(fl)]} for u, fl in flights.items()]}
    (camp / "manifest.json").write_text(json.dumps(manifest))
    (camp / "truth.json").write_text(json.dumps(
        {"format": "ema-bench-campaign-truth", "version": 1, "name": name, "seed": 7,
         "units": truth}))
    (run / "manifest.json").write_text(json.dumps(
        {"format": "ema-bench-track", "version": 1, "tracker": "hand", "seed": 0,
         "campaign": "../camp", "campaign_name": name, "track": "twin", "split": "test",
         "campaign_seed": 7}))
    lines = [
        # true RUL 100 90 80 70 60 50 40
        *_steps("u000", fl0, truth["u000"]["faults"],
                est={"Gprop": [1.1e5] * 7}, half={"Fst": 0.04, "Gprop": 5e3},
                rul=[INF, 150, 100, 60, 62, 45, 44], rul_low=[INF, 90, 70, 50, 50, 38, 35],
                rul_high=[INF, INF, 200, 90, 80, 60, 50]),
        # true RUL 60 50 40 (30: after the replacement); Na high at 20: 0.96 < 0.9625
        *_steps("u001", fl1, truth["u001"]["faults"],
                est={"Na": [1.0, 0.99, 0.95, 0.9]}, half={"Na": [0.005, 0.02, 0.01, 0.01]},
                rul=[INF, 70, 30, 20], rul_low=[INF, 50, 20, 10], rul_high=[INF, INF, 35, 30],
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


def test_fleet_figures_match_the_hand_computation(fixture_run):
    _, run = fixture_run
    res = score_tracking(run)
    assert (res["units"], res["tracked"], res["failing_units"]) == (4, 3, 3)
    assert res["untracked"] == ["u003"] and res["failed_units"] == []
    # cap: 2 x the longest life, 100
    assert res["rul_cap"] == 200.0
    # final predictions: u000 44 at 60 (true 40, d = +4); u001 30 at its replacement, flight
    # 20 (true 40, d = -10; its step at 30 is ignored)
    assert res["rul_rmse"] == pytest.approx(math.sqrt((16 + 100) / 2))
    assert res["rul_mae"] == pytest.approx(7.0)
    assert res["phm08_score"] == pytest.approx(math.exp(0.4) - 1 + math.exp(10 / 13) - 1)
    # alpha-lambda over the 3 failing units: u000 judged at 50 (t_lambda = 0.5 x 100): 45 in
    # [40, 60]; u001 tracked only to 20 < 30: miss; u003 untracked: miss
    assert res["alpha_lambda"] == pytest.approx(1 / 3)
    # coverage: u000 [35, 50] holds 40; u001 [20, 35] misses 40; u003 untracked: 1 / 3
    assert res["rul_coverage"] == pytest.approx(1 / 3)
    # predicted failing fault Fst: right for u000, wrong for u001
    assert res["failing_fault_named"] == 0.5
    # horizon (+- 10 around u000's true RUL: errors 100 (capped) 60 20 10 2 5 4, inside from 30 on:
    # 100 - 30 = 70; u001: last error 10 > 6: 0): median 35
    assert res["prognostic_horizon"] == 35.0
    # monotonicity of u000's capped RUL 200 150 100 60 62 45 44: 5 down, 1 up: 4 / 6; u001's
    # 200 70 30: 1; mean 5 / 6
    assert res["monotonicity"] == pytest.approx(5 / 6)
    assert res["fault_monotonicity"] == 1.0
    assert res["false_replacements"] == 1 and res["early_replacements"] == 1


def test_fault_tracking_and_detection_match_the_hand_computation(fixture_run):
    _, run = fixture_run
    res = score_tracking(run)
    # 13 tracked inspections (7 + 3 + 3); errors as a share of the range (Na 0.2, Fst 0.6756,
    # Gprop 1e5): Na -0.05 and 0 at u001's 10, 20 (0.99 vs 1.0; 0.95 vs 0.95); Fst 0.2 at
    # u002's 20; Gprop 0.1 at u000's 7
    assert res["fault_error"]["Na"] == pytest.approx(math.sqrt(0.05 ** 2 / 13))
    assert res["fault_error"]["Fst"] == pytest.approx(math.sqrt(0.2 ** 2 / 13))
    assert res["fault_error"]["BLK"] == 0.0
    assert res["fault_error"]["Gprop"] == pytest.approx(math.sqrt(7 * 0.1 ** 2 / 13))
    # coverage: Fst misses u002's 20 (0.18 outside [0.30512, 0.32512]); Gprop misses u000's 7
    # (1e5 outside 1.1e5 +- 5e3)
    assert res["fault_coverage"] == pytest.approx(
        {"Na": 1.0, "Fst": 12 / 13, "BLK": 1.0, "Gprop": 6 / 13})
    # onsets: u000 Fst at 40 (0.33 > 0.295575), first flagged at 50 (low 0.37 - 0.04 = 0.33;
    # at 40 low 0.29 is not past): 10; u001 Na at 20 (0.95 < 0.9625), flagged there (high
    # 0.96): 0; median 5
    assert (res["onsets"], res["detections"], res["detection_delay"]) == (2, 2, 5.0)
    # healthy unit-fault inspections: u000 Na 7 + Fst 4 + BLK 7, u001 Na 2 + Fst 3 + BLK 3,
    # u002 3 + 3 + 3 = 35; one false flag (u002 Fst at 20, low 0.30512 past the level)
    assert res["false_alarm_rate"] == pytest.approx(1 / 35)


def test_per_unit_rows(fixture_run):
    _, run = fixture_run
    rows = {u["unit"]: u for u in score_tracking(run)["per_unit"]}
    assert sorted(rows) == ["u000", "u001", "u002"]
    u0, u1, u2 = rows["u000"], rows["u001"], rows["u002"]
    assert (u0["rul"], u0["true_rul"], u0["rul_covered"], u0["alpha_lambda"],
            u0["alpha_lambda_flight"], u0["prognostic_horizon"]) == (44.0, 40.0, True, True,
                                                                      50, 70.0)
    assert u0["detection"]["Fst"] == {"onset": 40.0, "delay": 10.0, "false_flags": 0,
                                      "healthy": 4}
    # replaced at 20: its last step counts, 3 inspections
    assert (u1["inspections"], u1["last_flight"], u1["replaced"], u1["early_replacement"],
            u1["alpha_lambda"]) == (3, 20, True, True, None)
    assert u2["replaced"] and "rul" not in u2
    assert u2["detection"]["Fst"]["false_flags"] == 1


def test_alpha_and_lambda_are_keyword_arguments(fixture_run):
    _, run = fixture_run
    # lambda 0.3: u000 judged at 30 (true RUL 70, prediction 60): in the 20 % cone [56, 84],
    # out of the 10 % one [63, 77]; u001 at 20 (t = 18): 30 out of [32, 48] either way
    assert score_tracking(run, lam=0.3)["alpha_lambda"] == pytest.approx(1 / 3)
    assert score_tracking(run, alpha=0.1, lam=0.3)["alpha_lambda"] == 0.0
    res = score_tracking(run, alpha=0.1, lam=0.3)
    assert (res["alpha"], res["lambda"]) == (0.1, 0.3)
    with pytest.raises(ScoringError, match="alpha"):
        score_tracking(run, alpha=1.2)


def test_infinite_predictions_are_capped(tmp_path):
    camp, run = write_fixture(tmp_path)
    lines = [json.loads(x) for x in (run / "track.jsonl").read_text().splitlines()]
    for x in lines:
        if x["unit"] == "u000" and x["flight"] == 60:
            x["rul"] = x["rul_high"] = None          # inf: the tracker sees no failure
    (run / "track.jsonl").write_text("".join(json.dumps(x) + "\n" for x in lines))
    res = score_tracking(run)
    # u000's final prediction counts as the cap 200: errors +160 and -10
    assert res["rul_rmse"] == pytest.approx(math.sqrt((160 ** 2 + 100) / 2))
    assert res["phm08_score"] == pytest.approx(math.expm1(16) + math.expm1(10 / 13))
    assert math.isfinite(res["phm08_score"])
    # the interval [35, inf] still holds the truth
    assert res["rul_coverage"] == pytest.approx(1 / 3)


def _rewrite(path, edit):
    lines = [json.loads(x) for x in path.read_text().splitlines()]
    path.write_text("".join(json.dumps(y) + "\n" for x in lines if (y := edit(x)) is not None))


def test_missing_and_broken_files_are_named(tmp_path):
    camp, run = write_fixture(tmp_path)
    (run / "track.jsonl").rename(run / "track.bak")
    with pytest.raises(ScoringError, match="track.jsonl: no such file"):
        score_tracking(run)
    (run / "track.bak").rename(run / "track.jsonl")
    (camp / "truth.json").rename(camp / "truth.bak")
    with pytest.raises(CampaignError, match="truth.json: no such file"):
        score_tracking(run)
    (camp / "truth.bak").rename(camp / "truth.json")
    (run / "manifest.json").unlink()
    with pytest.raises(TrackerError, match="manifest.json"):
        score_tracking(run)
    with pytest.raises(TrackerError, match="not a tracking run"):
        score_tracking(tmp_path / "nowhere")


def test_nan_and_foreign_steps_are_errors(tmp_path):
    camp, run = write_fixture(tmp_path)
    track = run / "track.jsonl"
    good = track.read_text()
    _rewrite(track, lambda x: {**x, "rul": math.nan} if x["key"] == "u000/002" else x)
    with pytest.raises(ScoringError, match="u000 flight 20: RUL is NaN"):
        score_tracking(run)
    track.write_text(good)
    _rewrite(track, lambda x: {**x, "unit": "u999", "key": "u999/000"}
             if x["key"] == "u000/000" else x)
    with pytest.raises(ScoringError, match=r"\['u999'\] are not in"):
        score_tracking(run)
    track.write_text(good)
    _rewrite(track, lambda x: {**x, "flight": 15} if x["key"] == "u000/001" else x)
    with pytest.raises(ScoringError, match="flight 15: not an inspection flight"):
        score_tracking(run)


def test_another_campaign_is_refused(tmp_path):
    camp, run = write_fixture(tmp_path)
    m = json.loads((run / "manifest.json").read_text())
    (run / "manifest.json").write_text(json.dumps({**m, "campaign_name": "fleet-v1"}))
    with pytest.raises(ScoringError, match="another campaign.*campaign_name"):
        score_tracking(run)
    (run / "manifest.json").write_text(json.dumps({**m, "campaign_seed": 8}))
    with pytest.raises(ScoringError, match="remade"):
        score_tracking(run)


def test_an_empty_run_scores_every_unit_untracked(tmp_path):
    camp, run = write_fixture(tmp_path)
    (run / "track.jsonl").write_text("")
    res = score_tracking(run)
    assert res["tracked"] == 0 and res["untracked"] == ["u000", "u001", "u002", "u003"]
    assert math.isnan(res["rul_rmse"]) and res["alpha_lambda"] == 0.0
    assert math.isnan(res["fault_error"]["Na"]) and res["per_unit"] == []


# --- the CLI ---------------------------------------------------------------------------------

def test_score_cli_json_has_the_contract_keys(fixture_run, capsys):
    _, run = fixture_run
    assert main(["campaign", "score", str(run), "--json", "--alpha", "0.1", "--lam",
                 "0.3"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("rul_rmse", "rul_mae", "phm08_score", "alpha_lambda", "rul_coverage",
                "false_replacements", "units", "failing_units", "untracked", "fault_error",
                "fault_coverage", "detection_delay", "false_alarm_rate",
                "prognostic_horizon", "monotonicity", "per_unit"):
        assert key in out
    assert (out["alpha"], out["lambda"], out["alpha_lambda"]) == (0.1, 0.3, 0.0)



def test_score_cli_json_is_strict_json_with_null_for_undefined_figures(tmp_path, capsys):
    """No unit tracked: RMSE and errors are undefined (NaN); --json writes them as null, which
    every JSON parser reads, not as NaN, which jq and JSON.parse refuse."""
    _, run = write_fixture(tmp_path)
    (run / "track.jsonl").write_text("")
    assert main(["campaign", "score", str(run), "--json"]) == 0

    def refuse(name):
        raise ValueError(f"not JSON: {name}")
    out = json.loads(capsys.readouterr().out, parse_constant=refuse)
    assert out["rul_rmse"] is None and out["fault_error"]["Na"] is None
    assert out["alpha_lambda"] == 0.0 and out["untracked"] == ["u000", "u001", "u002", "u003"]

def test_score_cli_table_and_errors(fixture_run, tmp_path, capsys):
    _, run = fixture_run
    assert main(["campaign", "score", str(run)]) == 0
    out, err = capsys.readouterr()
    assert "| hand | twin |" in out and "RUL RMSE" in out
    assert "1 unit(s) not tracked (u003)" in err
    assert main(["campaign", "score", str(tmp_path / "nowhere")]) == 2
    assert "not a tracking run" in capsys.readouterr().err
    assert main(["campaign", "score", str(run), "--alpha", "2"]) == 2
    assert "--alpha" in capsys.readouterr().err


# --- a real campaign, tracked by a tracker whose answers are known ---------------------------

RUL = 100.0


@register_tracker("constant-scoring-test", description="test: nominal estimates, RUL 100")
def _constant(campaign_info, seed):
    def step(insp):
        nominal = {"Na": 1.0, "Fst": 0.1689, "BLK": 0.0, "Gprop": 1e5}
        return TrackStep(insp.flight, nominal, {n: v - 1e-3 for n, v in nominal.items()},
                         {n: v + 1e-3 for n, v in nominal.items()}, RUL, 50.0, 150.0,
                         "Fst", False, 0)
    return step


@pytest.fixture(scope="module")
def real(tmp_path_factory):
    root = tmp_path_factory.mktemp("score")
    camp = make_campaign("fleet-v1", units=4, track="twin", seed=2, out=root / "camp",
                         quiet=True)
    track_campaign(camp, "constant-scoring-test", root / "run", quiet=True)
    return load_truth(camp.root), score_tracking(root / "run"), root / "run"


def test_a_real_campaign_scores_as_computed_from_its_truth(real):
    truth, res, _ = real
    failing = [t for t in truth.values() if t["eol"] is not None]
    assert res["units"] == res["tracked"] == 4 and res["failing_units"] == len(failing) >= 1
    true = np.array([t["eol"] - t["last_flight"] for t in failing], dtype=float)
    assert res["rul_rmse"] == pytest.approx(np.sqrt(np.mean((RUL - true) ** 2)))
    d = RUL - true
    assert res["phm08_score"] == pytest.approx(np.sum(np.where(d < 0, np.exp(-d / 13) - 1,
                                                               np.exp(d / 10) - 1)))
    assert res["rul_coverage"] == pytest.approx(np.mean((50 <= true) & (true <= 150)))
    assert res["false_replacements"] == 0 and res["untracked"] == []
    # nominal estimates: Fst's error is the truth's distance from nominal, pooled
    fst = [v[1] for t in truth.values() for v in t["faults"].values()]
    assert res["fault_error"]["Fst"] == pytest.approx(
        np.sqrt(np.mean(np.square((0.1689 - np.array(fst)) / (0.8445 - 0.1689)))))
    assert res["rul_cap"] == CAP_FACTOR * max(t["eol"] for t in failing)


def test_oracle_bound_on_a_real_campaign(real, fixture_run):
    truth, _, run = real
    res = score_tracking(run, oracle=True)
    # every failing test unit stops at 50-95 % of life: each has a judged inspection
    assert res["oracle_units"] == sum(t["eol"] is not None for t in truth.values())
    assert 0.0 <= res["oracle_alpha_lambda"] <= 1.0 and 0.0 <= res["oracle_rul_coverage"] <= 1.0
    assert score_tracking(run, oracle=True)["oracle_alpha_lambda"] == res["oracle_alpha_lambda"]
    with pytest.raises(ScoringError, match="no law parameters"):
        score_tracking(fixture_run[1], oracle=True)


def test_score_cli_writes_plots_and_a_markdown_table(real, tmp_path, capsys):
    *_, run = real
    table = tmp_path / "scores.md"
    assert main(["campaign", "score", str(run), "--plots", str(tmp_path / "plots"),
                 "--markdown", str(table)]) == 0
    lines = table.read_text().splitlines()
    assert lines[0].startswith("| tracker | track |") and lines[2].startswith(
        "| constant-scoring-test | twin |")
    pngs = sorted(p.name for p in (tmp_path / "plots").glob("*.png"))
    assert "rul_errors.png" in pngs and "rul_constant-scoring-test-twin.png" in pngs
    assert any(n.startswith("unit_constant-scoring-test-twin_u") for n in pngs)
    assert capsys.readouterr().out.splitlines() == lines
