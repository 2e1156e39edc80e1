"""Missing-physics workflow: its pieces, a small blind suite, and the CLI."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ema_bench.diagnosis.blind import draw_cases, run_case, summarise
from ema_bench.diagnosis.envelopes import Envelope
from ema_bench.diagnosis.features import NOISE_STD, residual_features
from ema_bench.diagnosis.screening import score_effects
from ema_bench.diagnosis.workflow import DiagnosisError, Settings, diagnose
from ema_bench.effects import EFFECTS, LIBRARY
from ema_bench.faults import CASES
from ema_bench.reference import simulate_reference

SETTINGS = Settings(budget=2500, n_boot=30)


def test_library_has_ten_effects_with_bounds_bands_and_signatures():
    lib = [e for e in EFFECTS if e.library]
    assert len(lib) == 10 and len(LIBRARY) == 10
    for e in lib:
        assert e.lower <= 0.0 <= e.upper and e.trivial > 0 and e.signature and e.description


def test_a_bias_shows_as_bias_in_noise_units():
    n = 300
    y = np.zeros((n, 4))
    y[:, 2] = np.linspace(-100, 100, n)
    res = np.zeros((n, 4))
    res[:, 0] = 2 * NOISE_STD[0]
    f = residual_features({"step": res}, {"step": y}, {"step": np.zeros(n)})
    assert f["step.theta_u.bias"] == pytest.approx(2.0)
    assert f["step.theta_m.bias"] == 0.0


def test_envelope_flags_only_excess_beyond_the_bootstrap():
    rng = np.random.default_rng(0)
    env = Envelope(("a.rms", "a.bias"), rng.normal(size=(40, 2)))
    assert env.outside({"a.rms": 0.5, "a.bias": -0.3}, 6.0) == []
    assert env.outside({"a.rms": -50.0, "a.bias": 0.0}, 6.0) == []   # rms: one-sided
    assert {n for n, _, _ in env.outside({"a.rms": 50.0, "a.bias": -50.0}, 6.0)} == \
        {"a.rms", "a.bias"}


def test_score_test_ranks_the_effect_that_explains_the_residual():
    rng = np.random.default_rng(1)
    m = 500
    base = np.zeros(m)
    jac = rng.normal(size=(m, 3))                # what the faults can absorb
    sig_a, sig_b = rng.normal(size=m), rng.normal(size=m)
    residual = 0.4 * sig_a + 0.05 * rng.normal(size=m)
    ranked = score_effects(residual, base, jac, {"eccentricity": (0.1 * sig_a, 0.1),
                                                 "cogging": (0.1 * sig_b, 0.1)})
    assert ranked[0].name == "eccentricity" and ranked[0].score > 100 * ranked[1].score
    assert ranked[0].step == pytest.approx(0.4, rel=0.1)


def test_workflow_needs_a_held_out_test():
    tr = simulate_reference(CASES["small"].x, noise=False, adc=False)
    with pytest.raises(DiagnosisError, match="sine2"):
        diagnose(tr, SETTINGS)


# four cases of the committed 30-case suite (leaderboards/blind): viscous friction, sensor
# offset, a quadratic-damping decoy and a null case, run blind with the default settings
BLIND = [draw_cases(30, 0)[i] for i in (2, 3, 7, 6)]


@pytest.fixture(scope="module")
def blind_records():
    return [run_case(c, 0, Settings()) for c in BLIND]


def test_small_blind_suite(blind_records):
    s = summarise(blind_records)
    assert [c.kind for c in BLIND] == ["effect", "effect", "decoy", "null"]
    assert s["false_alarms"] == 0                       # null: verdict none
    assert s["naming_accuracy"] == 1.0                  # both effects named top-1
    assert s["decoys_unexplained_or_partial"] == 1      # the decoy is not named
    assert s["decoys_by_outcome"] == {"unexplained": 1, "named_partial": 0, "not_detected": 0,
                                      "named": 0}
    assert s["median_heldout_gap_closed"] >= 0.7
    assert s["median_param_error"] < 0.1


def test_blind_results_reproduce_the_committed_suite(blind_records):
    path = Path(__file__).resolve().parents[1] / "leaderboards" / "blind" / "blind.jsonl"
    committed = {r["key"]: r for r in map(json.loads, path.read_text().splitlines())}
    for r in blind_records:
        c = committed[r["key"]]
        assert (r["verdict"], r["named"], r["partial"]) == (c["verdict"], c["named"],
                                                            c["partial"])
    assert not blind_records[0]["named_partial"]    # viscous friction: nothing left over


def test_decoy_stand_in_is_flagged_partial():
    """A hinge-friction decoy (outside the library) whose held-out gap a library effect
    mostly closes: the effect is named, but flagged partial because the augmented model
    still leaves the envelopes (case 26 of the committed seed-0 suite)."""
    case = draw_cases(30, 0)[26]
    assert (case.kind, case.effect) == ("decoy", "hinge_friction")
    r = run_case(case, 0, Settings())
    assert r["verdict"] == "effect" and r["partial"] == r["named"][0]
    assert r["decoy_ok"] and "residual discrepancy remains" in r["message"]
    path = Path(__file__).resolve().parents[1] / "leaderboards" / "blind" / "blind.jsonl"
    committed = {c["key"]: c for c in map(json.loads, path.read_text().splitlines())}
    assert (r["named"], r["partial"]) == (committed["case26"]["named"],
                                          committed["case26"]["partial"])


def test_blind_draw_is_seeded_and_covers_the_kinds():
    a, b = draw_cases(30, 0), draw_cases(30, 0)
    assert a == b and a != draw_cases(30, 1)
    kinds = {c.kind for c in a}
    assert kinds == {"effect", "null", "decoy"}
    for c in a:
        if c.kind == "effect":
            spec = next(e for e in EFFECTS if e.name == c.effect)
            assert spec.detect <= abs(c.value) <= max(abs(spec.lower), spec.upper)


def test_diagnose_cli_on_a_file(tmp_path):
    path = tmp_path / "d.csv"
    cli = [sys.executable, "-m", "ema_bench.cli"]
    subprocess.run(cli + ["simulate", "--case", "small", "--effect", "cogging=0.05", "--tests",
                          "step,sine,sine2", "--seed", "4", "--out", str(path)], check=True,
                   capture_output=True)
    res = subprocess.run(cli + ["diagnose", str(path), "--json", "--budget", "2500",
                                "--report", str(tmp_path / "rep")],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    assert out["verdict"] == "effect" and out["effects"][0]["name"] == "cogging"
    e = out["effects"][0]
    assert set(e) == {"name", "params", "interval", "gap_before", "gap_after", "gap_closed",
                      "partial"}
    assert e["interval"][0] > 0 and e["gap_closed"] >= 0.7 and e["partial"] is False
    assert set(out["faults"]["Na"]) == {"before", "after"}
    report = (tmp_path / "rep" / "report.md").read_text()
    assert "cogging" in report and (tmp_path / "rep" / "residuals.png").is_file()
    bad = subprocess.run(cli + ["diagnose", str(tmp_path / "missing.csv")],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "missing.csv" in bad.stderr


# --- the verdict's rules at their edges (constructed cases, no fitting) -----------------------
def _reasons(**changes):
    from ema_bench.diagnosis.workflow import Settings, acceptance_reasons

    # a clear acceptance: closes 90 % of the gap, beats the noise band, improves the
    # training fit, a value well outside the trivial band with an interval excluding zero
    kw = dict(closed=0.9, improvement=5.0, noise_band=1.0, fit_before=2.0, fit_after=1.0,
              value=0.02, trivial=0.001, ci=(0.015, 0.025),
              accept_closed=Settings().accept_closed)
    return acceptance_reasons(**{**kw, **changes})


def test_acceptance_rules_at_their_edges():
    from ema_bench.diagnosis.workflow import Settings

    assert Settings().accept_closed == 0.7
    assert _reasons() == []
    # an interval containing zero is never accepted, however much it closes
    assert _reasons(ci=(-0.001, 0.03)) == ["interval includes zero"]
    assert _reasons(ci=(0.0, 0.03)) == ["interval includes zero"]
    # 60 % of the held-out gap is not enough (the rule asks 70 %); 70 % is
    assert any("closes 60 %" in r for r in _reasons(closed=0.6))
    assert _reasons(closed=0.7) == []
    # an improvement inside the noise band is not evidence
    assert _reasons(improvement=1.0) == ["held-out improvement within the bootstrap spread"]
    assert _reasons(fit_after=2.0) == ["does not improve the training fit"]
    assert any("trivial band" in r for r in _reasons(value=-0.0005, ci=(-0.0006, -0.0004)))


def test_an_effect_seen_only_on_the_held_out_test_is_detected():
    from ema_bench.diagnosis.workflow import detected, holdout_test

    rng = np.random.default_rng(0)
    boot = 1.0 + 0.01 * rng.standard_normal(200)       # held-out fitness of model + noise
    med, z, threshold = holdout_test(1.5, boot, z_max=4.0)
    assert med == pytest.approx(np.median(boot))
    assert threshold >= boot.max() and threshold < 1.5 and z > 4.0
    # no training feature leaves its envelope, yet the held-out test shows the effect
    assert detected([], 1.5, threshold)
    assert not detected([], float(np.median(boot)), threshold)
    assert detected([("feature", 1.0, 9.0)], float(np.median(boot)), threshold)
