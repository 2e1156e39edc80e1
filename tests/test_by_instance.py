"""The board's claims by instance (ema_bench.leaderboard.by_instance): the nested bootstrap
against an ordinary bootstrap of instance means, and synthetic boards whose answers are
known by construction (a claim carried by one instance, one carried by one solver)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from ema_bench.leaderboard import by_instance
from ema_bench.leaderboard.by_instance import claims, nested_bootstrap


def test_nested_bootstrap_is_the_instance_bootstrap_when_runs_agree():
    """Cells constant within each instance: the two-level bootstrap is an ordinary
    bootstrap of the instance means (scipy's percentile interval, to Monte Carlo error)."""
    means = np.random.default_rng(3).normal(0.05, 0.04, 12)
    est, lo, hi = nested_bootstrap([[m] * 4 for m in means], seed=1, n=20000)
    ref = stats.bootstrap((means,), np.mean, n_resamples=20000, method="percentile",
                          rng=np.random.default_rng(2)).confidence_interval
    assert est == pytest.approx(means.mean(), abs=1e-12)
    assert lo == pytest.approx(ref.low, abs=0.004) and hi == pytest.approx(ref.high, abs=0.004)


def test_one_instance_cannot_carry_a_claim_that_many_runs_would():
    """Seven instances at 0 and one at +1, 20 runs each: over the 160 runs a bootstrap puts
    the mean well above 0; over instances the interval reaches 0 (a 1-in-8 chance that
    every draw misses the instance: (7/8)^8 = 34 %)."""
    cells = [[0.0] * 20] * 7 + [[1.0] * 20]
    est, lo, hi = nested_bootstrap(cells, seed=0)
    assert est == pytest.approx(1 / 8)
    assert lo == 0.0 and hi > 0.3
    runs = stats.bootstrap((np.concatenate(cells),), np.mean, method="percentile",
                           rng=np.random.default_rng(0)).confidence_interval
    assert runs.low > 0.05


def _board(areas: dict[str, list[float]], conds=("prior", "no-prior"), tier=7) -> list[dict]:
    """Synthetic records of tier ``tier``: solver -> ECDF area per instance (the same in
    every condition and track, plus a small per-condition offset)."""
    recs = []
    for s, per in areas.items():
        for i, a in enumerate(per):
            for k, c in enumerate(conds):
                for track in ("reference", "twin"):
                    recs.append({"solver": s, "case": f"t{tier}-s{i:02d}@{c}",
                                 "track": track, "seed": 0, "area": a + 0.001 * k})
    return recs


@pytest.fixture
def areas_from_records(monkeypatch):
    # the fitness-and-parameter area is the record's "area"; parameter targets only where a
    # record says ("parea"), else none (nan, as run_area gives a run without them)
    monkeypatch.setattr(by_instance, "run_area", lambda r, kinds="fp": (
        r["area"] if kinds == "fp" else r.get("parea", float("nan"))))


def test_claims_on_a_board_whose_answers_are_known(areas_from_records):
    """Six solvers on 8 instances: top beats the rest everywhere by 0.2; second and
    third-to-fifth tie on average but second wins on one instance only; global vs local:
    the global group leads only through ``top``."""
    n = 8
    base = np.linspace(0.2, 0.4, n)
    areas = {"top": base + 0.3, "second": base + np.r_[0.8, [0.0] * (n - 1)],
             "third": base + 0.05, "fourth": base + 0.04, "fifth": base + 0.03,
             "sixth": base + 0.02}
    scopes = {"top": "global", "second": "global", "third": "local", "fourth": "local",
              "fifth": "local", "sixth": "global"}
    cs = claims(_board(areas), scope_of=lambda names: {s: scopes[s] for s in names})
    by = {(c.track, c.claim): c for c in cs}
    best5 = by[("twin", "best vs 5th")]
    assert (best5.a, best5.b, best5.instances) == (("top",), ("fifth",), n)
    assert best5.diff[0] == pytest.approx(0.27, abs=1e-3) and best5.diff[1] > 0.2
    # without top: second (mean +0.1, all of it on one instance) vs sixth: fragile
    assert (best5.without_a, best5.without_b) == (("second",), ("sixth",))
    assert best5.without_diff[1] <= 0 and best5.fragile
    assert best5.verdict == "fragile: without top the interval reaches 0"
    first = by[("twin", "first vs second")]
    assert (first.a, first.b) == (("top",), ("second",))
    assert first.diff[0] == pytest.approx(0.2, abs=1e-3) and first.diff[1] <= 0
    assert first.fragile and "interval over instances" in first.verdict
    gl = by[("twin", "global vs local, no-prior")]
    assert gl.a == ("top", "second", "sixth") and gl.without == "top"
    # by construction: global (0.3 + 0.1 + 0.02) / 3 - local (0.05 + 0.04 + 0.03) / 3
    assert gl.diff[0] == pytest.approx(0.1, abs=1e-3) and gl.diff[1] > 0
    assert gl.without_diff[1] <= 0 and gl.fragile
    line = by_instance.fragile_line(cs, "twin")
    assert line.startswith("By instance: no claim holds. FRAGILE: best vs 5th on tier 7")


def test_a_solid_claim_holds_and_the_report_says_so(areas_from_records):
    """Every solver ahead of the next by 0.05 on every instance: every claim holds, with and
    without the top solver."""
    base = np.linspace(0.1, 0.3, 6)
    areas = {f"s{k}": base + 0.05 * (6 - k) for k in range(6)}
    cs = claims(_board(areas), scope_of=lambda names: dict.fromkeys(names, "global"))
    assert [c.claim for c in cs if c.track == "twin"] == ["best vs 5th", "first vs second"]
    assert all(c.holds and not c.fragile and c.verdict == "holds" for c in cs)
    rows = by_instance.claim_rows(cs, "twin")
    assert rows[0]["a"] == "s0" and rows[0]["b"] == "s4" and rows[0]["instances"] == 6
    assert by_instance.fragile_line(cs, "twin") == (
        "By instance: holds: best vs 5th on tier 7; first vs second on tier 7.")


def test_a_clear_but_negligible_difference_is_not_a_claim_that_holds(areas_from_records):
    """Every solver ahead of the next by the same small step on every instance: the
    intervals over instances all lie above 0, but a step of 0.0005 of ECDF area (best vs
    5th: 0.002) is under ``NEGLIGIBLE`` (0.003, one target in 24 reached with half the
    evaluations at the largest budget), so no claim holds and the report says why; at a
    step of 0.001 (best vs 5th 0.004) best vs 5th holds and first vs second stays
    negligible.  The case v3's board met: cmaes and bipop-cmaes run the same descent until
    a restart and differed by 0.0002 with an interval above 0."""
    assert by_instance.NEGLIGIBLE == pytest.approx(np.log(2) / np.log(15000) / 24, abs=1e-4)
    base = np.linspace(0.1, 0.3, 6)
    for step, best5_holds in ((0.0005, False), (0.001, True)):
        areas = {f"s{k}": base + step * (6 - k) for k in range(6)}
        cs = claims(_board(areas), scope_of=lambda names: dict.fromkeys(names, "global"))
        by = {(c.track, c.claim): c for c in cs}
        first = by[("twin", "first vs second")]
        assert first.diff[1] > 0 and first.diff[0] == pytest.approx(step, abs=1e-9)
        assert not first.holds and first.fragile
        assert first.verdict == f"fragile: negligible, {step:+.4f} is under 0.003"
        best5 = by[("twin", "best vs 5th")]
        assert best5.diff[0] == pytest.approx(4 * step, abs=1e-9) and best5.diff[1] > 0
        assert best5.holds is best5_holds and (best5.verdict == "holds") is best5_holds
        line, = by_instance.separation_lines(cs, _board(areas), "twin")
        if best5_holds:
            assert line.startswith("Tier 7: best (s0) and 5th (s4) separated by instance")
        else:
            assert "by less than 0.003 of area" in line and "reaches 0" not in line
    # a clear lead that rests on its top solver alone: without it the rest are level
    areas = {"top": base + 0.1, **{f"s{k}": base + 0.0005 * (6 - k) for k in range(1, 6)}}
    cs = claims(_board(areas), scope_of=lambda names: dict.fromkeys(names, "global"))
    best5, = [c for c in cs if c.track == "twin" and c.claim == "best vs 5th"]
    assert best5.holds and best5.without_diff[1] > 0
    assert best5.verdict == "fragile: without top negligible, +0.0020 is under 0.003"


def test_a_tier_that_cannot_separate_best_and_fifth_says_why(areas_from_records):
    """Eight instances: ``top`` leads ``fifth`` by 0.27 on five and trails it by 0.33 on
    three (mean +0.045): the instances disagree, the interval over them reaches 0, and the
    sentence names the three instances the fifth is ahead on, out of eight, and the two
    sides' mean areas."""
    n = 8
    base = np.full(n, 0.3)
    sign = np.r_[[1.0] * 5, [-1.0] * 3]
    areas = {"top": base + 0.3 * sign + 0.2, "second": base + 0.26, "third": base + 0.25,
             "fourth": base + 0.24, "fifth": base + 0.23, "sixth": base}
    recs = _board(areas)
    cs = claims(recs, scope_of=lambda names: dict.fromkeys(names, "global"))
    best5 = next(c for c in cs if c.track == "twin" and c.claim == "best vs 5th")
    assert best5.b == ("fifth",) and best5.ahead == 5 and best5.diff[1] <= 0
    # per instance the mean of two conditions (+0 and +0.001)
    top, fifth = 0.3 + 0.2 + 0.3 * 2 / 8 + 0.0005, 0.53 + 0.0005
    assert best5.areas == pytest.approx((top, fifth), abs=1e-12)
    (line,) = by_instance.separation_lines(cs, recs, "twin")
    a, b = (f"{v:.3f}" for v in best5.areas)     # checked above
    assert line.startswith(f"Tier 7 cannot separate its best (top, mean area {a}) and "
                           f"5th (fifth, {b}) solvers by instance: fifth is level "
                           "with or ahead of top on 3 of the 8 instances")
    assert "reaches 0." in line and "nearly every target" not in line


def test_separation_lines_say_when_a_tier_separates_or_has_too_few_solvers(
        areas_from_records):
    """Every solver 0.05 ahead of the next everywhere: separated, best ahead on all six
    instances; with four solvers the claim is not asked; near the ceiling the sentence says
    the targets leave little room."""
    base = np.linspace(0.1, 0.3, 6)
    recs = _board({f"s{k}": base + 0.05 * (6 - k) for k in range(6)})
    cs = claims(recs, scope_of=lambda names: dict.fromkeys(names, "global"))
    (line,) = by_instance.separation_lines(cs, recs, "twin")
    assert line.startswith("Tier 7: best (s0) and 5th (s4) separated by instance, +0.200 [")
    assert line.endswith("s0 ahead on 6 of 6 instances.")
    few = _board({f"s{k}": base + 0.05 * k for k in range(4)})
    cs = claims(few, scope_of=lambda names: dict.fromkeys(names, "global"))
    assert by_instance.separation_lines(cs, few, "twin") == [
        "Tier 7: fewer than 5 solvers ran it; best vs 5th is not asked."]
    high = _board({"a": np.r_[0.99, 0.95, 0.97, 0.90], "b": np.r_[0.96, 0.95, 0.95, 0.94],
                   "c": np.full(4, 0.945), "d": np.full(4, 0.94), "e": np.full(4, 0.935)})
    cs = claims(high, scope_of=lambda names: dict.fromkeys(names, "global"))
    (line,) = by_instance.separation_lines(cs, high, "twin")
    assert "cannot separate" in line and "on 1 of the 4 instances" in line
    assert "nearly every target early (mean areas above 0.9)" in line


def test_the_parameter_targets_get_a_claim_of_their_own(areas_from_records):
    """Fitness and parameter targets rank the solvers in opposite orders: the parameter
    claim ranks by the parameter area alone (``s5`` first, ``s1`` fifth) and is asked on it,
    while best vs 5th keeps the fitness-and-parameter ranking; on runs without parameter
    targets the claim is not asked."""
    base = np.linspace(0.1, 0.3, 6)
    recs = _board({f"s{k}": base + 0.05 * (6 - k) for k in range(6)})
    for r in recs:                          # s5 best on parameters, s0 worst: reversed
        r["parea"] = 0.2 + 0.1 * int(r["solver"][1]) + 0.01 * int(r["case"][4:6])
    cs = claims(recs, scope_of=lambda names: dict.fromkeys(names, "global"))
    by = {c.claim: c for c in cs if c.track == "twin"}
    assert list(by) == ["best vs 5th", "first vs second", "best vs 5th, parameter targets"]
    assert (by["best vs 5th"].a, by["best vs 5th"].b) == (("s0",), ("s4",))
    p = by["best vs 5th, parameter targets"]
    assert (p.a, p.b, p.without, p.without_a, p.without_b) == (
        ("s5",), ("s1",), "s5", ("s4",), ("s0",))
    assert p.diff[0] == pytest.approx(0.4, abs=1e-9) and p.diff[1] > 0 and not p.fragile
    # the best-vs-fifth sentence stays the fitness-and-parameter claim's
    assert [line.startswith("Tier 7: best (s0)") for line in
            by_instance.separation_lines(cs, recs, "twin")] == [True]
    for r in recs:
        del r["parea"]
    assert "best vs 5th, parameter targets" not in {c.claim for c in claims(
        recs, scope_of=lambda names: dict.fromkeys(names, "global"))}
