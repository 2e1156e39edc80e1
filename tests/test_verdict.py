"""The verdict's rules at their edges (issue 15 and 17): constructed numbers, no fitting.

Every expected value is worked out by hand from the rule's statement in
``ema_bench/diagnosis/verdict.py``'s docstrings."""

from __future__ import annotations

import numpy as np
import pytest

from ema_bench.diagnosis.results import Settings, Trial
from ema_bench.diagnosis.verdict import (
    Discrepancy,
    acceptance_reasons,
    closed_share,
    closure,
    discrepancy,
    holdout_test,
    parsimony_reasons,
    penalised,
)
from ema_bench.diagnosis.workflow import _best

# a held-out gap: fitness 1.0 against floor 0.1 and threshold 0.2 (noise band 0.1)
HELD_OUT = Discrepancy(holdout=1.0, floor=0.1, threshold=0.2, severity=50.0, n_flagged=3)
# training statistics only: held-out fitness inside its noise band
STATS_ONLY = Discrepancy(holdout=0.15, floor=0.1, threshold=0.2, severity=100.0, n_flagged=4)
CLEAN = Discrepancy(holdout=0.1, floor=0.1, threshold=0.2, severity=0.0, n_flagged=0)


def test_a_held_out_fitness_inside_the_noise_band_is_never_a_gap():
    # above the floor but below the threshold: noise, so no gap and nothing detected
    d = Discrepancy(holdout=0.19, floor=0.1, threshold=0.2, severity=0.0, n_flagged=0)
    assert d.gap == 0.0 and not d.holdout_significant and not d.detected
    assert HELD_OUT.gap == pytest.approx(0.9) and HELD_OUT.holdout_significant
    assert HELD_OUT.noise_band == pytest.approx(0.1)
    # exactly at the threshold is still noise
    assert Discrepancy(0.2, 0.1, 0.2, 0.0, 0).gap == 0.0
    # statistics outside their envelopes are a discrepancy on their own
    assert STATS_ONLY.detected and STATS_ONLY.gap == 0.0


def test_severity_is_the_sum_of_the_flagged_robust_z():
    d = discrepancy(0.5, 0.1, 0.2, [("a.rms", 3.0, 12.0), ("b.bias", -1.0, -20.5)])
    assert d.severity == pytest.approx(32.5) and d.n_flagged == 2
    assert discrepancy(0.5, 0.1, 0.2, []).severity == 0.0


def test_closure_is_judged_on_the_held_out_gap_when_there_is_one():
    after = Discrepancy(holdout=0.37, floor=0.1, threshold=0.2, severity=0.0, n_flagged=0)
    # (1.0 - 0.37) / (1.0 - 0.1) = 0.7, whatever the statistics did
    assert closure(HELD_OUT, after) == ("held-out", pytest.approx(0.7))
    assert closed_share(1.0, 0.0, 0.1) == 1.0          # capped at 1
    assert closed_share(1.0, 1.45, 0.1) == pytest.approx(-0.5)
    # no gap above the floor: 1 if the fit did not get worse, else 0
    assert closed_share(0.1, 0.1, 0.2) == 1.0 and closed_share(0.1, 0.11, 0.2) == 0.0


def test_closure_falls_back_on_the_statistics_without_a_held_out_gap():
    after = Discrepancy(holdout=0.12, floor=0.1, threshold=0.2, severity=30.0, n_flagged=1)
    assert closure(STATS_ONLY, after) == ("statistics", pytest.approx(0.7))
    worse = Discrepancy(holdout=0.12, floor=0.1, threshold=0.2, severity=150.0, n_flagged=5)
    assert closure(STATS_ONLY, worse) == ("statistics", 0.0)
    assert closure(CLEAN, after) == ("none", 1.0)


def _reasons(base=HELD_OUT, after_holdout=0.2, after_severity=0.0, **changes):
    # a clear acceptance: closes (1.0 - 0.2) / 0.9 = 89 % of the held-out gap, beats the
    # noise band (0.8 > 0.1), improves the training fit, a value well outside the trivial
    # band with an interval excluding zero
    after = Discrepancy(after_holdout, 0.1, 0.2, after_severity, int(after_severity > 0))
    kw = dict(base=base, after=after, fit_before=2.0, fit_after=1.0, values={"delay": 0.02},
              trivial={"delay": 0.001}, intervals={"delay": (0.015, 0.025)},
              accept_closed=Settings().accept_closed)
    return acceptance_reasons(**{**kw, **changes})


def test_acceptance_rules_at_their_edges():
    assert Settings().accept_closed == 0.7
    assert _reasons() == []
    # an interval containing zero is never accepted, however much it closes
    assert _reasons(intervals={"delay": (-0.001, 0.03)}) == ["delay: interval includes zero"]
    assert _reasons(intervals={"delay": (0.0, 0.03)}) == ["delay: interval includes zero"]
    # not computed yet: no reason from it
    assert _reasons(intervals=None) == []
    # 60 % of the held-out gap is not enough (the rule asks 70 %); 70 % is
    assert _reasons(after_holdout=1.0 - 0.6 * 0.9) == [
        "closes 60 % of the held-out discrepancy (< 70 %)"]
    assert _reasons(after_holdout=1.0 - 0.7 * 0.9) == []
    assert _reasons(fit_after=2.0) == ["does not improve the training fit"]
    assert _reasons(values={"delay": -0.0005}) == [
        "delay -0.0005 inside its trivial band +-0.001"]
    # every effect of a set is checked
    two = _reasons(values={"delay": 0.02, "cogging": 0.001}, trivial={"delay": 0.001,
                                                                     "cogging": 0.003},
                   intervals={"delay": (0.01, 0.03), "cogging": (-0.001, 0.003)})
    assert two == ["cogging 0.001 inside its trivial band +-0.003",
                   "cogging: interval includes zero"]


def test_a_held_out_improvement_inside_the_noise_band_is_not_evidence():
    # a gap so small that closing all of it moves the fitness less than noise does
    small = Discrepancy(holdout=0.25, floor=0.1, threshold=0.2, severity=50.0, n_flagged=2)
    after = Discrepancy(0.16, 0.1, 0.2, 0.0, 0)          # closes 60 %, below the rule
    assert acceptance_reasons(base=small, after=after, fit_before=2.0, fit_after=1.0,
                              values={}, trivial={}, intervals={}, accept_closed=0.5) == [
        "held-out improvement within the bootstrap spread"]


def test_an_effect_seen_only_in_the_training_statistics_is_judged_on_them():
    # 100 -> 30 severity closes 70 %: accepted without any held-out gap
    assert _reasons(base=STATS_ONLY, after_holdout=0.12, after_severity=30.0) == []
    assert _reasons(base=STATS_ONLY, after_holdout=0.12, after_severity=40.0) == [
        "closes 60 % of the statistics discrepancy (< 70 %)"]
    # ... but not when it pushes the held-out fitness past its threshold
    assert _reasons(base=STATS_ONLY, after_holdout=0.21, after_severity=0.0) == [
        "makes the held-out fit worse than noise allows"]


def test_every_added_effect_pays_its_price():
    assert Settings().pair_penalty == 0.15
    # a pair closing 90 % against singles closing 80 % and 50 %: +10 % over the first
    assert parsimony_reasons(0.9, {"a": 0.8, "b": 0.5}, 0.15) == [
        "adds 10 % over a (< 15 % per added effect)"]
    assert parsimony_reasons(0.9, {"a": 0.75, "b": 0.5}, 0.15) == []
    # judged on the held-out test, the gain over each single must beat the noise band
    assert parsimony_reasons(0.9, {"a": 0.7}, 0.15, holdout=0.3, sub_holdout={"a": 0.35},
                             noise_band=0.1) == [
        "held-out improvement over a within the bootstrap spread"]
    assert parsimony_reasons(0.9, {"a": 0.7}, 0.15, holdout=0.3, sub_holdout={"a": 0.45},
                             noise_band=0.1) == []
    assert penalised(0.9, 2, 0.15) == pytest.approx(0.75) and penalised(0.8, 1, 0.15) == 0.8


def _trial(effects, closed, accepted=True, still=False):
    return Trial(effects, effects, "base", {n: 1.0 for n in effects}, {}, "held-out", closed,
                 closed, (1.0, 0.1), (2.0, 1.0), (50.0, 0.0), still, 100.0, accepted)


def test_the_best_set_explains_everything_first_then_pays_for_its_size():
    single, pair = _trial(("a",), 0.8), _trial(("a", "b"), 1.0)
    # 1.0 - 0.15 = 0.85 > 0.8: the pair wins; at 0.9 it would not
    assert _best([single, pair], 0.15) is pair
    assert _best([single, _trial(("a", "b"), 0.9)], 0.15) is single
    # a set that leaves no discrepancy beats one that leaves some, whatever it closes
    still = _trial(("c",), 1.0, still=True)
    assert _best([still, single], 0.15) is single
    assert _best([_trial(("a",), 1.0, accepted=False)], 0.15) is None


def test_an_effect_seen_only_on_the_held_out_test_is_detected():
    rng = np.random.default_rng(0)
    boot = 1.0 + 0.01 * rng.standard_normal(200)       # held-out fitness of model + noise
    med, z, threshold = holdout_test(1.5, boot, z_max=4.0)
    assert med == pytest.approx(np.median(boot))
    assert threshold >= boot.max() and threshold < 1.5 and z > 4.0
    # no training statistic leaves its envelope, yet the held-out test shows the effect
    assert discrepancy(1.5, med, threshold, []).detected
    assert not discrepancy(float(np.median(boot)), med, threshold, []).detected
    assert discrepancy(med, med, threshold, [("feature", 1.0, 9.0)]).detected


# --- each rule exactly at its edge (mutation survivors; values exact in binary) -------------
def test_the_rules_hold_exactly_at_their_edges():
    base = Discrepancy(holdout=0.5, floor=0.0, threshold=0.25, severity=0.0, n_flagged=0)
    after = Discrepancy(0.25, 0.0, 0.25, 0.0, 0)
    # closes 50 % with an improvement of exactly the noise band (0.25): not evidence
    assert acceptance_reasons(base=base, after=after, fit_before=2.0, fit_after=1.0,
                              values={}, trivial={}, intervals={}, accept_closed=0.5) == [
        "held-out improvement within the bootstrap spread"]
    # judged on the statistics, a held-out fitness exactly at the threshold is allowed
    assert _reasons(base=STATS_ONLY, after_holdout=0.2, after_severity=0.0) == []
    # a value exactly on its trivial band is trivial, either sign
    for v in (0.001, -0.001):
        assert _reasons(values={"delay": v}) == [
            f"delay {v:.3g} inside its trivial band +-0.001"]
    # an interval ending exactly at zero includes it
    assert _reasons(intervals={"delay": (-0.01, 0.0)}) == ["delay: interval includes zero"]
    # no gap at all (held-out exactly at the floor): nothing to close, nothing lost
    assert closed_share(0.1, 0.05, 0.1) == 1.0
    # any severity, however small, is judged on the statistics
    small = Discrepancy(0.15, 0.1, 0.2, 0.5, 1)
    assert closure(small, Discrepancy(0.15, 0.1, 0.2, 0.1, 1)) == ("statistics",
                                                                  pytest.approx(0.8))
    d = discrepancy(0.5, 0.1, 0.2, [])
    assert (d.holdout, d.floor, d.threshold) == (0.5, 0.1, 0.2)


def test_the_held_out_spread_is_the_larger_of_mad_and_half_the_std():
    # MAD rules: [1..5] has median 3, MAD 1 -> 1.4826 (half the std: 0.707)
    med, z, thr = holdout_test(6.0, np.array([1.0, 2.0, 3.0, 4.0, 5.0]), z_max=4.0)
    assert med == 3.0 and z == pytest.approx(3.0 / 1.4826)
    assert thr == pytest.approx(3.0 + 4.0 * 1.4826)
    # half the std rules: nine zeros and a 10 have MAD 0, std 3 -> 1.5
    boot = np.r_[np.zeros(9), 10.0]
    med, z, thr = holdout_test(3.0, boot, z_max=4.0)
    assert med == 0.0 and z == pytest.approx(2.0)
    assert thr == 10.0                                   # never below the largest replicate
    assert holdout_test(3.0, boot, z_max=10.0)[2] == pytest.approx(15.0)
    # identical replicates: the spread is floored, the z-score stays finite
    med, z, thr = holdout_test(1.0, np.ones(10), z_max=4.0)
    assert (med, z) == (1.0, 0.0) and thr == pytest.approx(1.0 + 4e-12, rel=0, abs=1e-15)


def test_the_parameter_price_at_its_edges():
    # exactly the price: paid
    assert parsimony_reasons(0.75, {"a": 0.5}, 0.25) == []
    assert parsimony_reasons(0.95, {"a": 0.05}, 1.0) == [
        "adds 90 % over a (< 100 % per added effect)"]
    # a held-out gain of exactly the noise band is not a gain; without a band any gain is
    assert parsimony_reasons(1.0, {"a": 0.5}, 0.25, holdout=0.25, sub_holdout={"a": 0.5},
                             noise_band=0.25) == [
        "held-out improvement over a within the bootstrap spread"]
    assert parsimony_reasons(1.0, {"a": 0.5}, 0.25, holdout=0.25,
                             sub_holdout={"a": 0.3}) == []
