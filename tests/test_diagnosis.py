"""Missing-physics workflow: its pieces, a small blind suite, and the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from inprocess import run_cli

from ema_bench.diagnosis.blind import draw_cases, run_case, summarise
from ema_bench.diagnosis.envelopes import Envelope
from ema_bench.diagnosis.features import NOISE_STD, residual_features
from ema_bench.diagnosis.results import DiagnosisError, Settings
from ema_bench.diagnosis.screening import score_effects
from ema_bench.diagnosis.workflow import diagnose
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


# three cases of the committed 60-case suite (leaderboards/blind, root seed 9672): a pair of
# effects, data made by the monitor itself, and a single effect at heavy stiction, run blind
# with the default settings and the seed scheme the suite was made with (1: the fits'
# solver seeds spawned; under the one-way scheme 2 the pair case 11 is named partial)
SEED, N_CASES = 9672, 60
PAIR, MONITOR_NULL, SINGLE = 11, 4, 43
BLIND = [draw_cases(N_CASES, SEED)[i] for i in (PAIR, MONITOR_NULL, SINGLE)]
COMMITTED = Path(__file__).resolve().parents[1] / "leaderboards" / "blind" / "blind.jsonl"


@pytest.fixture(scope="module")
def blind_records():
    return [run_case(c, SEED, Settings(seed_scheme=1)) for c in BLIND]


# slow: three cases run blind with the default settings (about 80 CPU-s); the fast loop builds
# and scores cases with a stand-in diagnosis (test_blind_suite.py) and runs the workflow on the
# monitor's own data below and on a recording's drift (test_diagnosis_acquisition.py)
@pytest.mark.slow
def test_small_blind_suite(blind_records):
    assert [c.category for c in BLIND] == ["two_effect", "monitor_null", "single"]
    pair, null, single = blind_records
    # both effects of the pair named, neither alone explains it
    assert pair["both_named"] and sorted(pair["named"]) == sorted(BLIND[0].effects)
    assert not pair["named_partial"]
    # data from the monitor model itself: nothing is missing
    assert null["verdict"] == "none" and not null["false_alarm"]
    # heavy stiction (Fst 0.82 N m): the single effect still named, and sized
    assert BLIND[2].faults["Fst"] > 0.65 and single["correct"]
    assert all(e < 0.1 for e in single["param_errors"].values())
    s = summarise(blind_records)
    assert s["false_alarms"] == 0 and s["naming_accuracy"] == 1.0
    assert s["per_category"]["two_effect"]["both_named"] == 1


@pytest.mark.slow
def test_blind_results_reproduce_the_committed_suite(blind_records):
    committed = {r["key"]: r for r in map(json.loads, COMMITTED.read_text().splitlines())}
    for r in blind_records:
        c = committed[r["key"]]
        assert c["root_seed"] == SEED
        assert (r["verdict"], r["named"], r["partial"]) == (c["verdict"], c["named"],
                                                            c["partial"])


def test_blind_draw_is_seeded_and_covers_the_kinds():
    a, b = draw_cases(30, 0), draw_cases(30, 0)
    assert a == b and a != draw_cases(30, 1)
    kinds = {c.kind for c in a}
    assert kinds == {"effect", "null", "decoy"}
    for c in a:
        for name, value in c.effects.items():
            spec = next(e for e in EFFECTS if e.name == name)
            assert spec.detect <= abs(value) <= max(abs(spec.lower), spec.upper)


# slow, the README's two recipes (about 20 and 60 CPU-s): the fast loop runs the same commands
# on the monitor's own data (test_data_from_the_monitor_itself_raise_no_alarm)
@pytest.mark.slow
def test_the_readme_delay_recipe_names_the_delay(tmp_path):
    """README: `simulate --tests step,sine,sine2 --effect delay=6e-4` then `diagnose`.  The
    delay shows only in the training residual statistics (its held-out fitness stays inside
    the noise band), which the first workflow could not name ("unexplained ... nearest:
    delay (partial, closes 100 %)", with "closed 0 %" in the report's header)."""
    path = tmp_path / "d.csv"
    run_cli("simulate", "--tests", "step,sine,sine2", "--effect", "delay=6e-4", "--out", path,
            check=True)
    res = run_cli("diagnose", path, "--json", "--report", tmp_path / "rep")
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    assert out["verdict"] == "effect" and [e["name"] for e in out["effects"]] == ["delay"]
    e = out["effects"][0]
    assert set(e) == {"name", "params", "interval", "gap_before", "gap_after", "gap_closed",
                      "partial"}
    assert e["interval"][0] < 6e-4 < e["interval"][1] and e["partial"] is False
    assert out["gap"]["judged_on"] == "statistics" and out["gap"]["before"] == 0.0
    assert set(out["faults"]["Na"]) == {"before", "after"}
    # the report's header and its tables come from one computation
    report = (tmp_path / "rep" / "report.md").read_text()
    closed = round(100 * out["gap"]["closed"])
    assert f"closed {closed} %." in report
    assert f"| delay | {e['params']['delay']:.4g} |" in report
    row = next(line for line in report.splitlines() if line.startswith("| delay |"))
    assert row.endswith(f"| {closed} % |")
    assert f"| {out['gap']['flagged_before']} | {out['gap']['flagged_after']} |" in report
    assert (tmp_path / "rep" / "residuals.png").is_file()
    bad = run_cli("diagnose", tmp_path / "missing.csv")
    assert bad.returncode == 2 and "missing.csv" in bad.stderr


@pytest.mark.slow
def test_the_readme_two_effect_recipe_names_both(tmp_path):
    """README: `--effect sensor_offset=1.5e-3,gear_stiffness=0.7` on the nominal case.  Each
    effect alone makes the held-out fit worse (the offset 3x), so only their joint fit
    explains the traces."""
    path = tmp_path / "two.csv"
    run_cli("simulate", "--tests", "step,sine,sine2", "--effect",
            "sensor_offset=1.5e-3,gear_stiffness=0.7", "--out", path, check=True)
    res = run_cli("diagnose", path, "--json")
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    named = {e["name"]: e for e in out["effects"]}
    assert out["verdict"] == "effect" and set(named) == {"sensor_offset", "gear_stiffness"}
    for name, truth in (("sensor_offset", 1.5e-3), ("gear_stiffness", 0.7)):
        e = named[name]
        assert e["partial"] is False and abs(e["params"][name] - truth) < 0.03 * truth
    singles = {c["name"]: c for c in out["candidates"] if len(c["effects"]) == 1}
    assert singles["sensor_offset"]["closed"] < 0.0 and not singles["sensor_offset"]["accepted"]


@pytest.mark.parametrize("seed", [0, 1])
def test_data_from_the_monitor_itself_raise_no_alarm(tmp_path, seed):
    """`simulate --model monitor --case small` then `diagnose`: the first workflow said
    "unexplained" on 3 of 3 seeds (a residual statistic over one sample of reverse speed)."""
    path = tmp_path / "m.csv"
    run_cli("simulate", "--model", "monitor", "--case", "small", "--tests", "step,sine,sine2",
            "--seed", str(seed), "--out", path, check=True)
    res = run_cli("diagnose", path, "--json")
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    assert out["verdict"] == "none" and out["effects"] == [] and out["flagged"] == []


def test_a_statistic_needs_enough_samples():
    """The step test's overshoot gives one sample of reverse speed: its mean is one noise
    draw, not a statistic (MIN_SUPPORT)."""
    from ema_bench.diagnosis.features import MIN_SUPPORT

    n = 300
    y = np.zeros((n, 4))
    y[:, 2] = 100.0
    y[:MIN_SUPPORT - 1, 2] = -100.0           # one sample short of support
    res = np.zeros((n, 4))
    res[:MIN_SUPPORT - 1, 0] = 5 * NOISE_STD[0]
    f = residual_features({"step": res}, {"step": y}, {"step": np.zeros(n)})
    assert f["step.theta_u.speed_sign"] == 0.0
    y[:MIN_SUPPORT, 2] = -100.0
    res[:MIN_SUPPORT, 0] = 5 * NOISE_STD[0]
    f = residual_features({"step": res}, {"step": y}, {"step": np.zeros(n)})
    assert f["step.theta_u.speed_sign"] == pytest.approx(-5.0)


def test_the_stuck_rotors_current_carries_no_weight():
    from ema_bench.diagnosis.stiction import STICK_SPEED, stick_weights
    from ema_bench.traces import Traces

    y = np.ones((6, 4))
    y[:, 2] = [0.0, -4.9, 4.9, -5.0, 5.0, 300.0]        # motor speed, rad/s
    w = stick_weights(Traces({"step": y}))["step"]
    assert STICK_SPEED == 5.0
    assert w[:, 3].tolist() == [0, 0, 0, 1, 1, 1]      # current: zero while stuck
    assert np.all(w[:, :3] == 1.0)                     # position, angle, speed: all kept
