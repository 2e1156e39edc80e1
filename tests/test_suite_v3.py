"""Suite emafdi-v3 (ema_bench.suites.v3): v2's problems under v3 keys on model version 4,
with their own best-known table; parameter targets the noise allows (a perfect optimiser
reaches them, one that stops 1 % of range off on a well-conditioned instance does not); the
dense fitness ladder; the Monte Carlo of the joint probability against closed forms."""

from __future__ import annotations

import time

import numpy as np
import pytest
from scipy import stats

from ema_bench import suites
from ema_bench.leaderboard.derive import derive
from ema_bench.leaderboard.validate import check_record
from ema_bench.params import DEFAULT_PARAMS, model_params
from ema_bench.records import run_record
from ema_bench.registry import finish
from ema_bench.seeding import run_seed
from ema_bench.suites import v1, v2, v3
from ema_bench.suites.problem import make_problem
from ema_bench.suites.targets import FITNESS_PRECISIONS, SuiteError
from ema_bench.trace_cache import MODEL_VERSION


def test_every_v3_key_round_trips_through_the_registry():
    order = v3.SUITE.case_order()
    # every tier, every instance (20 a tier, + the paper cases on tier 4), every condition
    assert len(order) == len(v2.SUITE.case_order()) and len(set(order)) == len(order)
    for case in order:
        inst = suites.instance(case)
        assert inst.case == case and inst.suite is v3.SUITE
        assert suites.suite_of(case).id == "emafdi-v3"
        base = suites.instance(case.removeprefix(v3.PREFIX))
        assert base.suite is v2.SUITE and np.array_equal(inst.truth, base.truth)
        assert inst.names == base.names and inst.budget == base.budget
        assert inst.group == base.group and inst.prior == base.prior
    assert suites.instance("v3-t12-s19@surface-current").dim == 12
    assert suites.find("v3-t12-s20@prior") is None            # tiers hold s00 .. s19
    with pytest.raises(SuiteError, match="offered on tiers"):
        suites.find("v3-t12-s00@step-only")
    assert suites.find("v3-small") is None                     # a v3 key names a condition
    with pytest.raises(SuiteError, match="v3-t7-s03@no-prior"):
        suites.instance("v3-nope@prior")


def test_v3_runs_on_model_version_4_and_v1_v2_stay_on_version_3():
    """v3's problems, tables and records are model version 4's (the located commutation
    transfer); v1's and v2's stay version 3's, the installation's default."""
    assert v3.SUITE.model_version == "4"
    assert v1.SUITE.model_version == v2.SUITE.model_version == MODEL_VERSION == "3"
    assert suites.instance("v3-t7-s03@no-prior").params == model_params("4")
    assert suites.instance("t7-s03@no-prior").params is DEFAULT_PARAMS
    assert suites.instance("small").params is DEFAULT_PARAMS
    assert v3.shipped_targets()["model_version"] == "4"
    assert v3.shipped_tolerances()["model_version"] == "4"
    assert v2.shipped_targets()["model_version"] == v1.shipped_targets()["model_version"] == "3"


def test_make_problem_of_a_v3_case_is_the_v2_problem_on_model_version_4():
    """The same data maker and fitness as v2's case with model version 4's monitor: the
    twin data and every fitness to the bit; the reference data (no monitor in them) are
    v2's.  At the pair of points of ``full`` where version 3 drops a commutation transfer on
    one side (tests/test_commutation_located.py) v3's fitness is version 4's, not v2's."""
    from test_commutation_located import JUMP_PAIR

    node = run_seed(0, 1)
    p = make_problem("v3-t7-s03@no-prior", track="twin", seed=node, budget=None)
    q = make_problem("t7-s03@no-prior", track="twin", seed=node, budget=None,
                     params=model_params("4"))
    assert p.dim == 7 and p.start is None and p.budget == v2.BUDGET_PER_DIM * 7
    assert p.label == "v3-t7-s03@no-prior"
    assert np.array_equal(p.objective.data, q.objective.data)
    x = suites.instance("v3-t7-s03@prior").truth
    assert p.objective.evaluate(x[None, :])[0][0] == q.objective.evaluate(x[None, :])[0][0]
    f = {}
    for case, params in (("v3-full@prior", None), ("full@prior", model_params("4")),
                         ("full@prior", None)):
        r = make_problem(case, track="reference", seed=run_seed(0, 0), budget=1,
                         params=params)
        f[case, params is None] = r.objective.evaluate(JUMP_PAIR)[0]
    assert np.array_equal(f["v3-full@prior", True], f["full@prior", False])
    v2_jump, v3_jump = (abs(np.diff(f[k])[0]) for k in (("full@prior", True),
                                                        ("v3-full@prior", True)))
    assert v3_jump < 0.01 * v2_jump


def test_a_v3_record_is_model_version_4_and_a_relabel_is_refused():
    """A v3 run's record says model version 4 and validates; labelled 3 (what v3 was
    before) it is refused and, on resume, stale; a v2 record stays version 3 (2 compatible),
    and version 2 is no compatible version of v3's."""
    from ema_bench.sweep.store import is_current

    truth = suites.instance("v3-small@prior").truth
    rec = _run("v3-small@prior", "twin", 0, truth)
    assert rec["model_version"] == "4" and check_record(rec, reevaluate=False) == []
    assert is_current(rec)
    for label in ("3", "2"):
        assert not is_current({**rec, "model_version": label})
        assert any(m.startswith(f"model version '{label}', expected '4'")
                   for m in check_record({**rec, "model_version": label}, reevaluate=False))
    old = _run("small@prior", "twin", 0, truth)
    assert old["model_version"] == "3" and check_record(old, reevaluate=False) == []
    assert is_current(old) and is_current({**old, "model_version": "2"})
    assert check_record({**old, "model_version": "4"}, reevaluate=False) != []


#: Shipped v3 entries recomputed here: each tier, both tracks, a tier-4 full-information
#: seed beyond 0, the objectives with less information, and seed 1 of objectives other than
#: tier 4's with full information (an entry polished on another seed's noise, or on another
#: model version, does not give its f* at its x* here).
RECOMPUTED = ("v3-small@prior|twin|3", "v3-full@prior|reference|0",
              "v3-s07@step-only|twin|0", "v3-t7-s02@prior|reference|0",
              "v3-t12-s06@surface-current|twin|0", "v3-s07@step-only|twin|1",
              "v3-t12-s06@surface-current|reference|1")


@pytest.mark.parametrize("key", RECOMPUTED)
def test_v3s_table_is_model_version_4s_fitness_at_its_x_star_to_the_bit(key):
    case, track, seed = key.split("|")
    entry = v3.shipped_targets()["entries"][key]
    p = make_problem(case, track=track, seed=run_seed(0, int(seed)), budget=1)
    x = np.array([[entry["x_star"][n] for n in p.names]])
    assert p.objective.evaluate(x)[0][0] == entry["f_star"]
    assert p.objective.params == model_params("4")


def test_v3s_tables_cover_the_suite_and_agree_with_each_other():
    """Every key of :func:`v3.target_keys` and no other; each entry polished from the truth
    (``f*`` at most the fitness there) below the nominal; the seed-0 reference entries hold
    the clean-data fit, and the tolerance table's reference bias is its offset from the
    truth (twin: none), one entry per objective and track."""
    entries = v3.shipped_targets()["entries"]
    assert sorted(entries) == sorted(v3.target_keys())
    assert len(entries) == 734 and v3.shipped_targets()["method"]["root_seed"] == 0
    for key, e in entries.items():
        # the polish starts at the truth through the unit box (a round trip of rounding
        # size): where the optimum is the truth to 1e-10 of range (full@step-only, reference)
        # its best point's f is 1.3e-9 of f above the truth's
        assert e["f_star"] <= e["fitness_at_truth"] * (1 + 1e-8) and \
            e["f_star"] < e["f_nominal"], key
        case, track, seed = key.split("|")
        assert ("clean_x" in e) == (track == "reference" and seed == "0"), key
    tol = v3.shipped_tolerances()["entries"]
    assert len(tol) == 2 * len({k.split("|")[0] for k in entries}) == 298
    for key, e in tol.items():
        case, track = key.split("|")
        inst = suites.instance(case)
        known = inst.best_known("reference", 0)
        bias = np.array([known["clean_x"][n] for n in inst.names]) - inst.truth \
            if track == "reference" else np.zeros(inst.dim)
        assert np.allclose(e["bias"], bias, rtol=0, atol=1e-12 * inst.ranges.max()), key


def _entry(case: str, track: str) -> dict:
    return v3.shipped_tolerances()["entries"][v3.tolerance_key(case, track)]


def _run(case: str, track: str, seed: int, x: np.ndarray) -> dict:
    """The record of a run that evaluates ``x`` once (an optimiser that stops there)."""
    p = make_problem(case, track=track, seed=run_seed(0, seed), budget=3)
    p.evaluate(x[None, :])
    res = finish(p, "stops-at-x", "budget", time.perf_counter())
    return run_record(p, res, case=case, track=track, seed=seed, budget=3, root_seed=0,
                      wall_s=0.0)


def _x_star(case: str, track: str, seed: int) -> np.ndarray:
    inst = suites.instance(case)
    return np.array([inst.best_known(track, seed)["x_star"][n] for n in inst.names])


def test_a_perfect_optimiser_reaches_every_parameter_target_where_v2_denies_it():
    """t12-s16 (twin, seed 0): the shipped best fit of the noisy data lies more than 1 % of
    range from the truth on gear stiffness (sigma 1.36 % of range), so v2's 1 % target and
    success are out of reach of any optimiser; v3's tolerance ``max(1 % of range, z sigma)``
    (checked here by hand from the table) holds it."""
    case, track = "v3-t12-s16@prior", "twin"
    inst, e = suites.instance(case), _entry(case, track)
    x = _x_star(case, track, 0)
    err = np.abs(x - inst.truth)
    assert np.any(err > 0.01 * inst.ranges)
    assert np.all(err <= np.maximum(0.01 * inst.ranges, e["z"] * np.array(e["sigma"])))
    rec = _run(case, track, 0, x)
    assert check_record(rec, reevaluate=False) == []
    d = derive(rec)
    assert d.success and d.parameter_hits == {"0.1": 1, "0.03": 1, "0.01": 1}
    old = derive({**_run(case.removeprefix(v3.PREFIX), track, 0, x)})
    assert not old.success and old.parameter_hits["0.01"] is None


def test_an_optimiser_1_percent_off_on_a_well_conditioned_instance_misses_the_target():
    """small@prior (tier 4, z = 0: the tolerance is 1 % of range): stopping 1.02 % of range
    off the truth on the weakest parameter misses the 1 % target and success, reaches 3 %."""
    case, track = "v3-small@prior", "twin"
    inst, e = suites.instance(case), _entry(case, track)
    assert e["z"] == 0.0 and e["p_old"] >= 0.95
    weakest = int(np.argmax(np.array(e["sigma"]) / inst.ranges))
    x = inst.truth.copy()
    x[weakest] += 0.0102 * inst.ranges[weakest]
    d = derive(_run(case, track, 0, x))
    assert not d.success and d.parameter_hits == {"0.1": 1, "0.03": 1, "0.01": None}


def test_the_shipped_best_fits_lie_inside_the_tolerances_as_often_as_promised():
    """Every shipped noisy best fit x* (v1's and v2's tables, every seed, both tracks):
    inside every judged tolerance at least as often as inside 1 % of range, and on at least
    90 % of them (the table promises >= 95 % per case; the polish is not the exact best fit
    everywhere); on tier 12 strictly more often than under the 1 % rule."""
    inside = {"old": [], "new": []}
    tier12 = {"old": 0, "new": 0}
    for key, e in v3.shipped_tolerances()["entries"].items():
        case, track = key.split("|")
        inst = suites.instance(case)
        assert e["p_new"] >= v3.COVERAGE and e["p_new"] >= e["p_old"]
        judged = np.array(e["judged"])
        tol = np.maximum(0.01 * inst.ranges, e["z"] * np.array(e["sigma"]))
        for seed in range(v2.TARGET_SEEDS):
            if inst.best_known(track, seed) is None:
                continue
            err = np.abs(_x_star(case, track, seed) - inst.truth)[judged]
            old = bool(np.all(err <= 0.01 * inst.ranges[judged]))
            new = bool(np.all(err <= tol[judged]))
            assert new or not old
            inside["old"].append(old)
            inside["new"].append(new)
            if inst.dim == 12:
                tier12["old"] += old
                tier12["new"] += new
    assert len(inside["new"]) > 400 and np.mean(inside["new"]) >= 0.9
    assert tier12["new"] > tier12["old"]


def test_the_frame_scales_are_the_tolerances_over_the_floor():
    inst = suites.instance("v3-t12-s06@no-prior")    # no-prior: prior's entry
    e = _entry("v3-t12-s06@prior", "reference")
    truth, scale, judged = inst.frame("reference")
    assert np.allclose(scale * 0.01, np.maximum(0.01 * inst.ranges,
                                                e["z"] * np.array(e["sigma"])))
    assert np.array_equal(judged, e["judged"])
    assert np.array_equal(suites.instance("t12-s06@prior").frame("twin")[1], inst.ranges)


def test_joint_probability_matches_closed_forms():
    # independent coordinates: the product of the marginal probabilities
    sd, tol = np.array([1.0, 0.5, 2.0]), np.array([1.5, 1.0, 3.0])
    exact = np.prod(2 * stats.norm.cdf(tol / sd) - 1)
    assert v3.joint_probability(np.diag(sd ** 2), np.zeros(3), tol) == \
        pytest.approx(exact, abs=3e-3)
    # correlated pair with a bias: the rectangle probability of scipy's bivariate normal
    cov = np.array([[1.0, 0.8], [0.8, 1.0]])
    bias, t = np.array([0.3, -0.2]), np.array([1.2, 1.0])
    mvn = stats.multivariate_normal(bias, cov)
    rect = (mvn.cdf(t) - mvn.cdf([-t[0], t[1]]) - mvn.cdf([t[0], -t[1]]) + mvn.cdf(-t))
    assert v3.joint_probability(cov, bias, t) == pytest.approx(rect, abs=3e-3)


def test_noise_z_is_the_smallest_z_that_reaches_the_coverage():
    """Two independent parameters, sigma 1 % and 0.3 % of a unit range: z solves
    ``(2 Phi(z) - 1) (2 Phi(max(1, 0.3 z) / 0.3) - 1) = 0.95`` (to 0.01)."""
    cov, ranges = np.diag([0.01 ** 2, 0.003 ** 2]), np.ones(2)
    z, p_old, p_new = v3.noise_z(cov, np.zeros(2), ranges)

    def p(zz):
        return np.prod([2 * stats.norm.cdf(max(0.01, zz * s) / s) - 1 for s in (0.01, 0.003)])
    assert p_old == pytest.approx(p(0.0), abs=3e-3) and p_new >= 0.95
    assert p(z + 0.02) >= 0.95 - 3e-3 and p(z - 0.03) < 0.95
    assert v3.noise_z(np.diag([0.001 ** 2] * 2), np.zeros(2), ranges)[0] == 0.0


def test_the_dense_fitness_ladder_holds_the_old_one_and_reaches_one_in_a_million():
    ladder = v3.FITNESS_PRECISIONS
    assert len(ladder) == 21 and ladder[0] == 0.1 and ladder[-1] == 1e-6
    assert set(FITNESS_PRECISIONS) <= set(ladder)
    assert np.allclose(np.diff(np.log10(ladder)), -0.25, atol=2e-3)
    assert suites.instance("v3-t7-s00@prior").fitness_precisions == ladder
    assert suites.instance("t7-s00@prior").fitness_precisions == FITNESS_PRECISIONS


def test_the_ecdfs_of_fitness_and_parameter_targets_count_apart():
    """A v3 run 1.02 % of range off on small's weakest parameter: its parameter ECDF is 2 of
    3 targets, its fitness ECDF the share of the 21-target ladder its fitness reaches
    (counted here from f*, f_nominal and the ladder), and the pooled ECDF weighs both."""
    from ema_bench.leaderboard.anytime import ecdf_curve

    case, track = "v3-small@prior", "twin"
    inst = suites.instance(case)
    x = inst.truth.copy()
    x[0] += 0.0102 * inst.ranges[0]
    rec = _run(case, track, 0, x)
    known = inst.best_known(track, 0)
    levels = known["f_star"] + np.array(v3.FITNESS_PRECISIONS) * (known["f_nominal"] -
                                                                   known["f_star"])
    reached_f = int(np.sum(rec["fitness"] <= levels))
    assert 0 < reached_f < 21
    grid = np.array([1, 3])
    assert np.allclose(ecdf_curve([rec], grid, "p"), 2 / 3)
    assert np.allclose(ecdf_curve([rec], grid, "f"), reached_f / 21)
    assert np.allclose(ecdf_curve([rec], grid), (reached_f + 2) / 24)


#: The point the fixed-point test solver evaluates (set by the test that registers it).
_POINT: list[np.ndarray] = []


def test_a_v3_hit_is_re_derived_on_v3_tolerances_and_not_carried_to_a_v2_label():
    """The cheapest way to a v3 score not earned: take a run that reaches a v3 tolerance
    wider than 1 % of range and file it under v2's key, whose 1 % target it does not reach.
    The judge re-derives the hits on each suite's own tolerances and refuses the relabel."""
    from ema_bench import register_solver
    from ema_bench.leaderboard.tasks import Task, run_task
    from ema_bench.leaderboard.validate import check_record
    from ema_bench.registry import SolveResult

    inst = suites.instance("v3-t12-s03@prior")
    i = inst.names.index("eccentricity")
    tol = v3.scales(inst, "twin")[i] * 0.01
    assert tol > 0.02 * inst.ranges[i]     # this instance's tolerance: over 2 % of range
    x = inst.truth.copy()
    step = 0.016 * inst.ranges[i]          # 1.6 % of range: inside v3's, outside v2's 1 %
    x[i] += step if x[i] + step <= inst.upper[i] else -step
    _POINT[:] = [x]

    @register_solver("test-v3-fixed-point", description="evaluates one given point",
                     library="numpy")
    def _fixed(problem, budget, seed):
        problem.evaluate(_POINT[0])
        return SolveResult("test-v3-fixed-point", _POINT[0], 0.0, 1, "done", 0.0, {})

    r = run_task(Task("test-v3-fixed-point", "v3-t12-s03@prior", "twin", 0, 2))
    assert r["targets"]["parameters"]["0.01"] == 1     # its one evaluation reaches it
    assert check_record(r) == []
    forged = {**r, "case": "t12-s03@prior", "suite": "emafdi-v2"}
    found = check_record(forged)
    assert any(m.startswith("targets.parameters") and "'0.01': None" in m for m in found)


# slow: three sweeps and their reports (about 8 CPU-s)
@pytest.mark.slow
def test_a_v3_board_slice_is_resumed_by_a_larger_command_without_rerunning_it(tmp_path):
    """The v3 board is grown slice by slice into one folder (docs/suite-v3.md): a larger
    command over the same folder runs only the runs missing, leaves the finished ones as
    they were (same line, byte for byte), and every record is model version 4's; a record
    labelled version 3 (a v3 run before the move) is stale and run again."""
    import json

    from ema_bench.cli import main
    from ema_bench.leaderboard.validate import validate

    out = tmp_path / "v3"
    runs = out / "runs.jsonl"

    def board(per_tier: int) -> list[str]:
        argv = ["leaderboard", "--suite", "emafdi-v3", "--tiers", "4", "--conditions",
                "prior", "--per-tier", str(per_tier), "--solvers", "random", "--tracks",
                "twin", "--seeds", "1", "--budget-per-dim", "3", "--executor", "serial",
                "--no-plots", "--quiet", "--out", str(out)]
        assert main(argv) == 0
        return runs.read_text().splitlines()

    first = board(1)
    assert len(first) == 1 and json.loads(first[0])["case"] == "v3-small@prior"
    grown = board(2)
    assert grown[0] == first[0] and len(grown) == 2
    recs = [json.loads(line) for line in grown]
    assert [r["model_version"] for r in recs] == ["4", "4"]
    assert validate(recs, per_tier=2) == []
    # the first run relabelled version 3: stale, so the same command runs it again
    runs.write_text(json.dumps({**recs[0], "model_version": "3"}) + "\n" + grown[1] + "\n")
    again = board(2)
    assert len(again) == 3 and again[1] == grown[1]
    assert json.loads(again[2])["key"] == recs[0]["key"]
    assert json.loads(again[2])["model_version"] == "4"


def test_v3s_table_keys_are_v2s_objectives_and_v1s_problems_and_select_as_v2s():
    """v3 polishes its own entries of every v2 objective (seeds 0 and 1, the board's two)
    and of tier 4 with full information (seeds 0-4, where v2 reads v1's table); ``ema-bench
    targets --suite emafdi-v3`` selects with v2's options and refuses v1's ``--cases``."""
    import argparse

    from ema_bench.cli.targets import _keys

    keys = v3.target_keys()
    by_seed = {k: sum(key.endswith(f"|{k}") for key in keys) for k in range(5)}
    assert by_seed == {0: 252 + 46, 1: 252 + 46, 2: 46, 3: 46, 4: 46}
    assert {key.removeprefix(v3.PREFIX) for key in keys if key[-2:] in ("|0", "|1")} >= \
        set(v2.target_keys(2))

    def sel(**kw):
        base = dict(suite="emafdi-v3", cases=None, tiers=None, conditions=None,
                    per_tier=None, seeds=None, tracks=None)
        return _keys(argparse.Namespace(**{**base, **kw}))

    assert sel(tiers=["4"], conditions=["no-prior"], per_tier=1, seeds=2,
               tracks=["twin"]) == ["v3-small@prior|twin|0", "v3-small@prior|twin|1"]
    # without --seeds: the shipped seeds (0 and 1)
    assert sel(tiers=["12"], conditions=["surface-current"], per_tier=1, tracks=["twin"]) == \
        ["v3-t12-s00@surface-current|twin|0", "v3-t12-s00@surface-current|twin|1"]
    with pytest.raises(SuiteError, match="not --cases"):
        sel(cases=["small"])
    # the sweep's selection names the suite the user asked for, not the one v3 builds on
    from ema_bench.suites import SUITES
    from ema_bench.suites.base import Selection
    with pytest.raises(SuiteError, match="^--suite emafdi-v3 picks its instances"):
        SUITES["emafdi-v3"].sweep_cases(Selection(cases=["small"]))
