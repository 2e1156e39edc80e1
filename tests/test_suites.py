"""One Suite object for every suite version (ema_bench.suites): the registry is the only
parser of case keys, no consumer branches on the version, and every front door (the
``solve`` command, the adapters, the environments) takes every case of every suite with the
same records."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

import ema_bench
from ema_bench import suites
from ema_bench.adapters.run import AdapterRun
from ema_bench.adapters.scipy import minimize, simplex
from ema_bench.cli import main
from ema_bench.effects import EFFECT_INDEX, EFFECTS
from ema_bench.faults import CASES, LOWER, UPPER
from ema_bench.leaderboard.validate import validate
from ema_bench.suites.v2 import tier_instances

PACKAGE = Path(ema_bench.__file__).resolve().parent
#: what branching on a suite version looks like (the names the two-suite code used)
VERSION_BRANCH = re.compile(r"is_v2_case|is_v2_board|suite_v2|parse_case|make_v2_problem|"
                            r"build_problem|best_known_for|scoring_frame|judged_for|"
                            # a command comparing --suite with a version's id
                            r"""(==|!=)\s*["']emafdi-v|["']emafdi-v\d+["']\s*(==|!=)|"""
                            r"SUITE_ID\s*(==|!=)|(==|!=)\s*(\w+\.)?SUITE_ID")


def test_no_suite_version_branch_outside_the_suites_package():
    hits = [f"{f.relative_to(PACKAGE)}:{i}: {line.strip()}"
            for f in sorted(PACKAGE.rglob("*.py")) if "suites" not in f.parts
            for i, line in enumerate(f.read_text().splitlines(), 1)
            if VERSION_BRANCH.search(line)]
    assert hits == []


def test_no_case_key_is_parsed_outside_the_suites_package():
    """The registry is the only place a case key is split into instance and condition
    (issue 43): elsewhere ``suites.instance(case)`` gives both."""
    split = re.compile(r"""(partition|split|index|find)\(\s*(["']@["']|CASE_SEP)""")
    hits = [f"{f.relative_to(PACKAGE)}: {line.strip()}"
            for f in sorted(PACKAGE.rglob("*.py")) if "suites" not in f.parts
            for line in f.read_text().splitlines() if split.search(line)]
    # a board's group label (``t7@no-prior``, scaling.group_label) is not a case key: its
    # inverse split_label is the one allowed
    assert hits == ['leaderboard/scaling.py: tier, _, cond = label.partition("@")']


def test_the_registry_parses_every_suites_keys_into_one_instance_shape():
    small = suites.instance("small")
    assert (small.suite.id, small.dim, small.group, small.ioh_function) == (
        "emafdi-v1", 4, None, "small")
    assert np.array_equal(small.truth, CASES["small"].x)
    assert np.array_equal(small.ranges, UPPER - LOWER)
    t12 = suites.instance("t12-s03@no-prior")
    # independent of the suite code: the tier's effects' bounds from the effect table
    tier = tier_instances(12)["t12-s03"]
    eff = [EFFECTS[EFFECT_INDEX[n]] for n in t12.augment]
    assert (t12.suite.id, t12.dim, t12.group, t12.prior, t12.budget) == (
        "emafdi-v2", 12, (12, "no-prior"), False, 12 * 1250)
    assert np.array_equal(t12.truth[:4], tier.faults)
    assert np.array_equal(t12.ranges[4:], [e.upper - e.lower for e in eff])
    assert t12.effects == {k: v for k, v in tier.effects.items() if v != 0.0}
    # the same instance under two conditions: one problem's data, another's prior
    assert suites.instance("small@prior").paper_case == "small"
    assert suites.instance("small@no-prior").paper_case == "small@no-prior"
    assert suites.find("seeded") is None and not suites.is_case("custom")
    assert suites.suite_of("seeded").id == "emafdi-v1"
    with pytest.raises(suites.SuiteError, match="unknown condition"):
        suites.instance("t7-s03@blind")
    with pytest.raises(suites.SuiteError, match="offered on tiers"):
        suites.instance("t12-s00@step-only")
    with pytest.raises(suites.SuiteError, match="unknown case"):
        suites.instance("t9-s00@prior")


def test_the_one_factory_labels_the_problem_with_its_case_key():
    p = ema_bench.make_problem("t7-s02@no-prior", track="twin", budget=None)
    assert (p.label, p.dim, p.budget, p.nominal) == ("t7-s02@no-prior", 7, 7 * 1250, None)
    q = ema_bench.make_problem("s03", track="twin", budget=3)
    assert (q.label, q.dim, q.budget) == ("s03", 4, 3)


def test_solve_takes_a_tier_12_case_and_writes_a_record_validate_accepts(tmp_path, capsys):
    assert main(["solve", "--case", "t12-s03@no-prior", "--solver", "cmaes", "--track",
                 "twin", "--budget", "24", "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert (rec["case"], rec["suite"], rec["evaluations"]) == ("t12-s03@no-prior",
                                                               "emafdi-v2", 24)
    assert len(rec["fitted_effects"]) == 8 and len(rec["trajectory"][0][2]) == 12
    assert validate([rec], complete=False) == []


def test_the_scipy_adapter_takes_a_tier_12_case_with_the_same_record():
    run = AdapterRun("scipy-nelder-mead", case="t12-s03@no-prior", track="twin", budget=20,
                     library="scipy")
    p = run.problem
    assert p.start is None   # no prior: the adapter's user draws the start
    x0 = p.from_unit(np.random.default_rng(run.solver_seed()).random(p.dim))
    res = minimize(p, method="Nelder-Mead", x0=x0, options={"initial_simplex": simplex(p, x0=x0)})
    rec = run.record(res.stop_reason)
    assert (rec["case"], rec["suite"], p.dim) == ("t12-s03@no-prior", "emafdi-v2", 12)
    assert validate([rec], complete=False) == []


def test_both_environment_versions_have_one_entry_point_and_the_vector_one():
    gym = pytest.importorskip("gymnasium")
    import ema_bench.env  # noqa: F401  (registers both ids)

    v1, v2 = gym.spec("EMAFault/Identify-v1"), gym.spec("EMAFault/Identify-v2")
    assert v1.entry_point == v2.entry_point == "ema_bench.env:EMAFaultEnv"
    assert v1.vector_entry_point == v2.vector_entry_point == "ema_bench.env:EMAFaultVectorEnv"
    envs = gym.make_vec("EMAFault/Identify-v2", num_envs=16,
                        vectorization_mode="vector_entry_point", tier=12, track="twin",
                        budget=32)
    obs, info = envs.reset(seed=1)
    p = envs.unwrapped.problem
    assert envs.action_space.shape == (16, 12) and p.label == "t12-s01@prior"
    U = np.random.default_rng(0).random((16, 12))
    calls, inner = [], p._log.evaluate_outputs   # the problem's one counted door
    p._log.evaluate_outputs = lambda X: calls.append(len(X)) or inner(X)
    obs, rewards, term, trunc, info = envs.step(U)
    # one batched call evaluated the population: 16 evaluations, the fitness of each point
    assert calls == [16] and p.evaluations == 16 and obs.shape[0] == 16
    assert np.allclose(-rewards, p.objective.evaluate(p.from_unit(U))[0])


def test_identify_v3_episodes_are_v2_problems_filed_under_v3_keys():
    gym = pytest.importorskip("gymnasium")
    import ema_bench.env  # noqa: F401  (registers the ids)
    from ema_bench.suites import SuiteError, suite_of

    assert gym.spec("EMAFault/Identify-v3").entry_point == "ema_bench.env:EMAFaultEnv"
    kw = dict(tier=7, condition="no-prior", track="reference", budget=4)
    e3, e2 = gym.make("EMAFault/Identify-v3", **kw), gym.make("EMAFault/Identify-v2", **kw)
    _, i3 = e3.reset(seed=3)
    _, i2 = e2.reset(seed=3)
    # the same measured data (the reference model's), the v3 label and v3's model version
    # (4): a run of it is judged on v3's targets
    assert (i3["case"], i2["case"]) == ("v3-t7-s03@no-prior", "t7-s03@no-prior")
    assert suite_of(i3["case"]).id == "emafdi-v3"
    assert np.array_equal(e3.unwrapped.problem.measured.stacked(),
                          e2.unwrapped.problem.measured.stacked())
    from ema_bench.params import DEFAULT_PARAMS, model_params
    assert e3.unwrapped.problem.objective.params == model_params("4")
    assert e2.unwrapped.problem.objective.params is DEFAULT_PARAMS
    assert e3.unwrapped.action_space.shape == (7,)
    # an instance named either way; a suite without tiers refuses tier=
    for name in ("t7-s05", "v3-t7-s05"):
        env = gym.make("EMAFault/Identify-v3", case=name, **kw)
        assert env.reset(seed=0)[1]["case"] == "v3-t7-s05@no-prior"
    with pytest.raises(SuiteError, match="has no tiers"):
        gym.make("EMAFault/Identify-v3", suite="emafdi-v1", **kw)


@pytest.mark.slow
def test_check_env_passes_on_every_tier_and_condition():
    gym = pytest.importorskip("gymnasium")
    from gymnasium.utils.env_checker import check_env

    import ema_bench.env  # noqa: F401  (registers both ids)
    from ema_bench.suites.v2 import CONDITIONS, TIERS

    pairs = [(d, c) for d in TIERS for c, o in CONDITIONS.items() if o.offered_on(d)]
    assert len(pairs) == 10
    for d, c in pairs:
        env = gym.make("EMAFault/Identify-v2", tier=d, condition=c, track="twin", budget=40)
        check_env(env.unwrapped, skip_render_check=True)
        assert env.unwrapped.action_space.shape == (d,)
