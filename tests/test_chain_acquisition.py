"""Faults of the whole recording chain and heavy-tailed noise (issue 46, item 2): a fault on
several channels is one suspect with its size, heavy-tailed noise is chosen by the data and
not on clean records, and its robust loss keeps the outliers from pulling the physics.

The records are the reference model's (standing for a perfect physical fit at the true
faults) with the decoys of :mod:`ema_bench.diagnosis.decoys` applied, an implementation
independent of the fits."""

from __future__ import annotations

import numpy as np
import pytest

from ema_bench.diagnosis import acquisition as acq
from ema_bench.diagnosis import decoys, tails
from ema_bench.diagnosis.features import NOISE_STD
from ema_bench.diagnosis.results import Settings
from ema_bench.objective import KNOWN_TESTS
from ema_bench.reference import simulate_reference
from ema_bench.suites.v1 import instance_faults
from ema_bench.traces import SIGNALS, Traces

TESTS = ("step", "sine", "sine2")
TRAIN = ("step", "sine")
MIN_SCORE = Settings().min_score


@pytest.fixture(scope="module")
def records():
    """Clean reference outputs (the perfect physical fit) and a noisy record of them."""
    x = np.array(instance_faults("small"))
    specs = tuple(KNOWN_TESTS[t] for t in TESTS)
    clean = simulate_reference(x, {}, tests=specs, noise=False, adc=False)
    noisy = simulate_reference(x, {}, tests=specs, seed=3)
    return dict(clean.data), noisy


def _ones(tr: Traces) -> dict[str, np.ndarray]:
    return {t: np.ones_like(tr.data[t]) for t in tr.tests}


def _drift_all(noisy: Traces, sd_per_s: tuple[float, ...]) -> Traces:
    tr = noisy
    for c, r in zip(SIGNALS, sd_per_s):
        tr = decoys.drift(tr, c, r * float(NOISE_STD[SIGNALS.index(c)]))
    return tr


def test_a_drift_on_every_channel_is_one_suspect_with_its_size(records):
    """Drifts of 8, -12, 6 and 10 noise sd/s on the four channels: the screen's best is
    ``drift(all)`` (one suspect, not four), each member's rate within 5 % of its drift and
    the group's size the smallest (6 sd/s), its interval excluding zero and holding it."""
    clean, noisy = records
    rates = (8.0, -12.0, 6.0, 10.0)
    tr = _drift_all(noisy, rates)
    ranked = acq.screen(clean, tr.data, _ones(tr), TRAIN)
    best = ranked[0]
    assert best.fault.name == "drift(all)"
    assert acq.is_acquisition("drift(all)")
    assert best.score == pytest.approx(sum(e.score for e in ranked[1:5]), rel=1e-9)
    for p, r in zip(best.fault.parts(), rates):
        sd = float(NOISE_STD[SIGNALS.index(p.channel)])
        assert p.value / sd == pytest.approx(r, rel=0.05)
    lo, hi = best.interval
    assert best.fault.value == pytest.approx(6.0, rel=0.05) and 0.0 < lo <= 6.0 <= hi
    # the carried group is the four drifts: the record less it is the noisy record
    got = acq.carry(clean, [best.fault])
    one = acq.carry(clean, list(best.fault.parts()))
    for t in TESTS:
        np.testing.assert_array_equal(got[t], one[t])
    assert "every channel" in acq.describe(best.fault)


def test_a_shared_time_shift_on_two_channels_is_one_suspect(records):
    """``omega_m`` and ``i_eq`` both 2 samples late (one recorder clock): the screen names
    ``time_shift(omega_m,i_eq)`` first with the shared shift 2; the channels not shifted
    take no part."""
    clean, noisy = records
    tr = decoys.time_shift(decoys.time_shift(noisy, "omega_m", 2), "i_eq", 2)
    best = acq.screen(clean, tr.data, _ones(tr), TRAIN)[0]
    assert best.fault.name == "time_shift(omega_m,i_eq)"
    assert best.fault.value == 2.0 and best.interval == [2.0, 2.0]
    assert [p.name for p in best.fault.parts()] == ["time_shift(omega_m)", "time_shift(i_eq)"]


def test_a_shared_time_shift_is_proposed_on_every_channel_too(records):
    """Three channels 2 samples late, the fourth not: the screen proposes the group of the
    three and, after it at the same score, ``time_shift(all)`` at their shift (one clock
    stamps every channel; at a base fit that lags to meet a whole record's shift, some
    channels show it and others do not, so the fit through it decides)."""
    clean, noisy = records
    tr = noisy
    for c in ("theta_u", "theta_m", "omega_m"):
        tr = decoys.time_shift(tr, c, 2)
    ranked = acq.screen(clean, tr.data, _ones(tr), TRAIN)
    names = [e.fault.name for e in ranked]
    sub = names.index("time_shift(theta_u,theta_m,omega_m)")
    every = ranked[names.index("time_shift(all)")]
    assert names.index("time_shift(all)") == sub + 1
    assert every.score == ranked[sub].score and every.fault.value == 2.0
    assert [p.name for p in every.fault.parts()] == [f"time_shift({c})" for c in SIGNALS]
    # the group of all four channels is itself, not proposed twice
    tr4 = decoys.time_shift(tr, "i_eq", 2)
    ranked4 = [e.fault.name for e in acq.screen(clean, tr4.data, _ones(tr4), TRAIN)]
    assert ranked4.count("time_shift(all)") == 1


def test_the_best_whole_record_shift_is_always_fitted(records):
    """A drift of ``theta_u`` and a hum on ``i_eq`` (40 noise sd each) outscore a 1-sample
    shift of ``theta_m`` and ``omega_m``: the workflow's acquisition singles are the two best
    suspects and, below them, ``time_shift(all)`` (the base fit understates a shift of the
    whole record); without the shift, the two best alone."""
    from ema_bench.diagnosis.results import Fit
    from ema_bench.diagnosis.stiction import stick_weights
    from ema_bench.diagnosis.workflow import _Search

    clean, noisy = records
    sd = dict(zip(SIGNALS, map(float, NOISE_STD)))
    tr = decoys.mains_hum(decoys.drift(noisy, "theta_u", 40 * sd["theta_u"]), "i_eq",
                          40 * sd["i_eq"])
    shifted = decoys.time_shift(decoys.time_shift(tr, "theta_m", 1), "omega_m", 1)
    base = Fit((), np.zeros(4), 0.0, clean, 0, (), clean)
    for record, extra in ((shifted, ["time_shift(all)"]), (tr, [])):
        ranked = [e.fault.name for e in acq.screen(clean, record.data, stick_weights(record),
                                                   TRAIN) if e.score >= MIN_SCORE]
        search = _Search(record, {}, Settings(), 0, base, None, print)
        got = [e.fault.name for e in search.screen_acquisition(base)]
        assert got == ranked[:2] + extra
        assert "time_shift(all)" not in ranked[:2]


def test_one_channel_faults_make_no_group(records):
    """A drift on one channel: no group screened; the names a group may take."""
    clean, noisy = records
    tr = decoys.drift(noisy, "omega_m", 40.0)
    ranked = acq.screen(clean, tr.data, _ones(tr), TRAIN)
    assert ranked[0].fault.name == "drift(omega_m)"
    assert not any(e.fault.channel not in SIGNALS for e in ranked)
    assert acq.is_group("theta_u,i_eq") and acq.is_group("all")
    for bad in ("i_eq,theta_u", "theta_u,theta_m,omega_m,i_eq", "i_eq", "x,y"):
        assert not acq.is_group(bad)
    for bad in ("outliers(all)", "stuck(theta_u,i_eq)", "heavy_tailed(i_eq)"):
        with pytest.raises(ValueError, match="whole-chain"):
            acq.parse(bad)


def test_heavy_tailed_noise_is_chosen_and_rejected(records):
    """3 % of every channel's samples hit by 10-40 noise sd: every channel's tail share is
    near 3 %, the test chooses ``heavy_tailed(all)`` and its weights drop those samples;
    the rejected share holds the injected one (counted independently from the hits)."""
    clean, noisy = records
    tr = decoys.heavy_tailed(noisy, share=0.03, seed=5)
    hit = {t: np.abs(tr.data[t] - noisy.data[t]) > 5 * NOISE_STD for t in TESTS}
    share = sum(hit[t].sum() for t in TRAIN) / sum(hit[t].size for t in TRAIN)
    assert 0.02 < share < 0.04
    e = tails.detect(clean, tr.data, _ones(tr), TRAIN)
    assert e is not None and e.fault.name == "heavy_tailed(all)"
    lo, hi = e.interval
    assert lo <= share <= hi and e.fault.value == pytest.approx(share, rel=0.1)
    w = acq.weights([e.fault], {t: v.shape for t, v in tr.data.items()})
    for t in TESTS:      # the held-out test's samples too; few clean samples dropped
        assert (w[t][hit[t]] == 0).mean() > 0.95
        assert (w[t][~hit[t]] == 0).mean() < 0.002


@pytest.mark.parametrize("effects", [{}, {"cogging": 0.1}, {"delay": 1.6e-3}])
def test_gaussian_noise_does_not_choose_the_robust_loss(effects):
    """False alarm: clean records, and records with a strong effect the model lacks (4x its
    threshold: misfit on the current channel), at the true faults of three instances: the
    test does not choose heavy-tailed noise."""
    specs = tuple(KNOWN_TESTS[t] for t in TESTS)
    for name in ("small", "nominal", "s03"):
        x = np.array(instance_faults(name))
        model = simulate_reference(x, {}, tests=specs, noise=False, adc=False)
        rec = simulate_reference(x, effects, tests=specs, seed=11)
        assert tails.detect(dict(model.data), rec.data, _ones(rec), TRAIN) is None
        shares = tails.tail_shares(dict(model.data), rec.data, _ones(rec), TRAIN)
        assert sum(s >= tails.TAIL_SHARE for s in shares.values()) <= 1


# --- the blind suite's whole-chain categories ------------------------------------------------

def test_chain_cases_follow_the_others_and_leave_them_as_drawn():
    """``chain`` cases of each whole-chain category after the others (their draws
    unchanged): every kind of :data:`~ema_bench.diagnosis.sized.CHAIN_CHANNELS` on its
    channels, a shared shift or low-pass the same on each, a drift or hum per channel at
    1-4x its threshold there, heavy-tailed noise on every channel; the truth named as the
    workflow names a whole-chain suspect."""
    from ema_bench.diagnosis import blind, sized
    from ema_bench.diagnosis.blind import draw_cases

    before = draw_cases(20, 0, extra=2, fourth=2)
    both = draw_cases(20, 0, extra=2, fourth=2, chain=8)
    assert both[:len(before)] == before
    new = both[len(before):]
    assert [c.index for c in new] == list(range(28, 44))
    assert {c.category for c in new} == set(blind.CHAIN_CATEGORIES)
    kinds = [c.decoy for c in new if c.category == "whole_chain_acquisition"]
    assert set(kinds) == set(sized.CHAIN_CHANNELS) and len(kinds) == 8
    for c in new:
        (name, _), = c.effects.items()
        p = c.decoy_params
        assert blind.acquisition_truth(c) == f"{c.decoy}({p['signal']})"
        assert acq.is_acquisition(blind.acquisition_truth(c))
        if c.decoy == "heavy_tailed":
            assert p["signal"] == "all" and 0.02 <= p["share"] <= 0.05
            continue
        assert [q["signal"] for q in p["parts"]] == list(sized.CHAIN_CHANNELS[c.decoy])
        assert 1.0 <= p["multiple"] <= 4.0
        spec = acq.KINDS[c.decoy]
        for q in p["parts"]:
            sd = float(NOISE_STD[SIGNALS.index(q["signal"])])
            size = {"lowpass": q.get("tau"), "time_shift": q.get("samples"),
                    "drift": abs(q.get("rate", 0.0)) / sd,
                    "mains_hum": q.get("amplitude", 0.0) / sd}[c.decoy]
            assert spec.detect * p["multiple"] - 1e-12 <= size or c.decoy == "time_shift"
            assert size <= 4.0 * spec.detect + 1e-9
        if c.decoy in ("lowpass", "time_shift"):      # one parameter, shared
            assert len({q.get("tau", q.get("samples")) for q in p["parts"]}) == 1
    with pytest.raises(ValueError, match=">= 0"):
        draw_cases(10, 0, chain=-1)


def test_a_chain_case_record_is_the_reference_through_every_part():
    """A whole-chain case's record is the reference record with each channel's decoy
    applied in turn (an independent composition of :mod:`~ema_bench.diagnosis.decoys`)."""
    from ema_bench.diagnosis import blind
    from ema_bench.diagnosis.blind import draw_cases, measured_traces
    from ema_bench.seeding import run_seed, stream

    for c in draw_cases(0, 5, chain=2):
        ref = simulate_reference(np.array(list(c.faults.values())), c.effects,
                                 tests=blind.TESTS, seed=stream(run_seed(5, c.index), "noise"))
        want = ref
        if c.decoy == "heavy_tailed":
            p = {k: v for k, v in c.decoy_params.items() if k != "signal"}
            want = decoys.heavy_tailed(ref, **p)
        else:
            for q in c.decoy_params["parts"]:
                want = decoys.ACQUISITION_DECOYS[c.decoy](want, **q)
        got = measured_traces(c, 5)
        assert got.allclose(want) and not got.allclose(ref)


def _named_truth(case, seed: int, settings) -> dict:
    """A stand-in for ``run_case``: names the hidden effect and the hidden fault."""
    from types import SimpleNamespace

    from ema_bench.diagnosis import blind

    eff = [SimpleNamespace(name=n, params={n: v}, interval=[v, v], partial=False)
           for n, v in case.effects.items()]
    fault = SimpleNamespace(name=blind.acquisition_truth(case), partial=False)
    d = SimpleNamespace(verdict="effect", effects=eff, acquisition=[fault],
                        gap={"partial": None})
    return {**blind.case_record(case, seed), "verdict": "effect",
            "named": [e.name for e in eff], "named_acquisition": [fault.name], "partial": None,
            "gap_closed": 1.0, "gap_before": 2.0, "gap_after": 0.0, "message": "",
            "evaluations": 0, **blind.score(case, d), "wall_s": 0.0}


def test_cli_chain_option_runs_and_reports_the_categories(tmp_path, monkeypatch, capsys):
    """``ema-bench blind --chain K`` runs K cases of each whole-chain category, one summary
    line each; the truth named scores as named; ``--calibrate`` refuses it (exit 2)."""
    import json

    from ema_bench.cli import main
    from ema_bench.diagnosis import blind

    monkeypatch.setattr(blind, "run_case", _named_truth)
    assert main(["blind", "--cases", "0", "--chain", "2", "--seed", "3", "--out",
                 str(tmp_path), "-q"]) == 0
    out = capsys.readouterr().out
    for c in blind.CHAIN_CATEGORIES:
        line = next(s for s in out.splitlines() if s.strip().startswith(c + " "))
        assert "effect named 2/2" in line and "acquisition fault named 2/2" in line
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["categories"] == {**{c: 0 for c in blind.CATEGORIES},
                                     "whole_chain_acquisition": 2, "heavy_tailed": 2}
    assert main(["blind", "--calibrate", "--chain", "1", "--out", str(tmp_path)]) == 2
    assert "--chain" in capsys.readouterr().err


@pytest.mark.slow
def test_the_robust_loss_keeps_outliers_from_pulling_the_physics():
    """Eccentricity 0.1 beside 5 % of every channel's samples hit by 10-40 noise sd (the
    issue's heavy-tailed noise), fitted with the effect from the true faults: the squared
    loss is off the injected truth by over 10 %, the robust loss the test chose by under
    half that, its interval holding the truth and narrower than the squared loss's (whose
    noise level the outliers inflate).  About 10 CPU-s."""
    from ema_bench.diagnosis.fitting import fit, interval
    from ema_bench.diagnosis.stiction import stick_weights

    x = np.array(instance_faults("small"))
    specs = tuple(KNOWN_TESTS[t] for t in TESTS)
    rec = simulate_reference(x, {"eccentricity": 0.1}, tests=specs, seed=7)
    tr = decoys.heavy_tailed(rec, share=0.05, seed=8)
    s, start = Settings(), np.r_[x, 0.0]
    squared = fit(tr, ("eccentricity",), s, 1, start)
    noise = tails.detect(squared.raw, tr.data, stick_weights(tr), TRAIN)
    assert noise is not None and noise.fault.name == "heavy_tailed(all)"
    robust = fit(tr, ("eccentricity",), s, 1, start, (noise.fault,))
    err_sq = abs(squared.effects["eccentricity"] / 0.1 - 1)
    err_rb = abs(robust.effects["eccentricity"] / 0.1 - 1)
    assert err_sq > 0.1 and err_rb < 0.5 * err_sq
    lo_sq, hi_sq = interval(squared, tr, ("eccentricity",))["eccentricity"]
    lo, hi = interval(robust, tr, ("eccentricity",))["eccentricity"]
    assert lo <= 0.1 <= hi and hi - lo < 0.7 * (hi_sq - lo_sq)


@pytest.mark.slow
def test_a_drift_of_the_whole_chain_is_named_as_one_fault():
    """No physical effect, drifts of 10, -12, 8 and 15 noise sd/s on the four channels: the
    workflow's verdict is ``acquisition``, naming ``drift(all)`` alone (one suspect, not
    four), every member's rate within 10 % of its drift and the group's size (the smallest,
    8 sd/s) inside its interval.  About 40 CPU-s."""
    from ema_bench.diagnosis.blind import TESTS as BLIND_TESTS
    from ema_bench.diagnosis.workflow import diagnose

    x = np.array(instance_faults("small"))
    rates = (10.0, -12.0, 8.0, 15.0)
    tr = _drift_all(simulate_reference(x, {}, tests=BLIND_TESTS, seed=8), rates)
    d = diagnose(tr, Settings(budget=2500, n_boot=30), seed=2)
    assert d.verdict == "acquisition" and d.effects == []
    (a,) = d.acquisition
    assert a.name == "drift(all)" and not a.partial
    assert a.interval[0] <= 8.0 <= a.interval[1] and a.interval[0] > 0
    f = d.final.acquisition[0]
    for p, r in zip(f.parts(), rates):
        assert p.value / float(NOISE_STD[SIGNALS.index(p.channel)]) == pytest.approx(r, rel=0.1)
    assert "a drift on every channel" in d.message


@pytest.mark.slow
@pytest.mark.parametrize("seed, rounds, index, name", [
    (4189, {"chain": 6}, 3, "time_shift(all)"),
    (2154, {"fourth": 6}, 1, "time_shift(i_eq)"),
])
def test_a_time_shift_is_fitted_at_its_size(seed, rounds, index, name, monkeypatch):
    """Eccentricity 0.17 beside every channel 3 samples late (root seed 4189, case 3 of
    ``blind --chain 6``), and cogging 0.054 beside ``i_eq`` 2 samples late (root seed 2154,
    case 1 of ``blind --fourth 6``, the fourth round's miss): at the base fit the screen
    finds the shift a sample short (the physics lags to meet the rest); the fit started
    there profiles it and ends at the true size, its training fitness under a third of the
    fit held at the screened shift: the neighbour a sample later is probed (a third of a
    fit), beats the fit and is fitted in full; the next one's probe does not, and the climb
    stops.  About 10 CPU-s each."""
    from ema_bench.diagnosis import fitting
    from ema_bench.diagnosis.blind import draw_cases, measured_traces
    from ema_bench.diagnosis.stiction import stick_weights

    case = next(c for c in draw_cases(0, seed, **rounds) if c.index == index)
    params = case.decoy_params
    assert case.decoy == "time_shift" and f"time_shift({params['signal']})" == name
    truth = params["parts"][0]["samples"] if "parts" in params else params["samples"]
    tr = measured_traces(case, seed)
    s = Settings()
    base = fitting.fit(tr, (), s, 5)
    found = next(e for e in acq.screen(base.raw, tr.data, stick_weights(tr), TRAIN)
                 if e.fault.name == name)
    assert found.fault.value == truth - 1
    # ``fit`` first fits the physics through the screened shift held (``_fit_through``),
    # then profiles the shift: that first stage is the fit held at the screened shift,
    # recorded on its way (its arguments checked) instead of computed a second time
    calls, real = [], fitting._fit_through

    def through(*args):
        calls.append((args, real(*args)))
        return calls[-1][1]

    monkeypatch.setattr(fitting, "_fit_through", through)
    f = fitting.fit(tr, (), s, 6, base.x.copy(), (found.fault,))
    args, held = calls[0]
    assert args[:4] == (tr, (), s, 6) and args[5] == (found.fault,)
    assert np.array_equal(args[4], base.x)
    assert held.acquisition[0].value == found.fault.value
    assert f.acquisition[0].name == name and f.acquisition[0].value == truth
    assert f.fitness < held.fitness / 3
    probe = round(fitting.PROBE_SHARE * s.budget)
    assert f.evaluations == 2 * s.budget + 2 * probe
