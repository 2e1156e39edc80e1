"""The versioned suite (ema_bench.suites.v1): its instances, its shipped best-known optima, the
Gymnasium id that follows it, and the anytime fields of run records built on them."""

from __future__ import annotations

import json
import math

import gymnasium as gym
import numpy as np
import pytest

import ema_bench.env  # noqa: F401  (registers the environment)
from ema_bench.faults import CASES, FAULT_NAMES, LOWER, UPPER
from ema_bench.leaderboard.tasks import Task, run_task
from ema_bench.registry import run_solver
from ema_bench.seeding import run_seed
from ema_bench.suites.best_known import MARGIN, STAGES, all_keys
from ema_bench.suites.problem import make_problem
from ema_bench.suites.targets import SUITE_MODEL_VERSION, fitness_targets
from ema_bench.suites.v1 import (
    N_SEEDED,
    SUITE_ID,
    best_known,
    expand_cases,
    instance_faults,
    instance_names,
    seeded_instances,
    shipped_targets,
)
from ema_bench.trace_cache import MODEL_VERSION


def xvec(d: dict) -> np.ndarray:
    return np.array([d[n] for n in FAULT_NAMES])


def test_suite_is_tied_to_the_installed_models():
    # a physics change must bump the suite (and the Gymnasium id): its targets are stale
    assert SUITE_MODEL_VERSION == MODEL_VERSION


def test_seeded_instances_stratify_every_fault_over_its_whole_range():
    x = np.array(list(seeded_instances().values()))
    assert x.shape == (N_SEEDED, 4)
    u = (x - LOWER) / (UPPER - LOWER)
    # Latin hypercube: for each fault, exactly one instance in each twentieth of its range
    for j in range(4):
        assert sorted(np.floor(u[:, j] * N_SEEDED).astype(int).tolist()) == list(range(20))
    # so heavy friction is in the suite: two instances in the top tenth of the Fst range
    assert (u[:, 1] >= 0.9).sum() == 2
    assert list(seeded_instances()) == [f"s{i:02d}" for i in range(20)]


def test_instances_are_fixed_and_their_truth_reaches_the_problem_only_hidden():
    assert instance_names("paper") == tuple(CASES)
    assert instance_names()[:4] == tuple(CASES) and len(instance_names()) == 24
    p = make_problem("s05", track="twin", seed=run_seed(0, 0), budget=10)
    assert p.label == "s05"
    np.testing.assert_array_equal(np.array(list(p.score(instance_faults("s05")).x.values())),
                                  instance_faults("s05"))
    assert p.score(instance_faults("s05")).success
    assert "s05" not in json.dumps(dict(p.measured.meta)) and "truth" not in p.meta
    with pytest.raises(ValueError, match="unknown case 's99'"):
        make_problem("s99")


def test_case_groups_expand_in_order_without_repeats():
    assert expand_cases(["quick"]) == ["nominal", "small", "full", "random", "s00", "s01",
                                       "s02", "s03"]
    assert expand_cases(["small", "paper", "s03"]) == ["small", "nominal", "full", "random",
                                                       "s03"]
    assert expand_cases(["lhs"]) == [f"s{i:02d}" for i in range(20)]
    # "seeded" is not a group but the random instance of each run seed
    assert expand_cases(["seeded", "small"]) == ["seeded", "small"]
    with pytest.raises(ValueError, match="unknown case"):
        expand_cases(["smal"])


def test_gymnasium_id_follows_the_suite_and_the_old_one_is_deprecated():
    assert ema_bench.env.ENV_ID == "EMAFault/Identify-v1"
    assert "v1" in ema_bench.env.__doc__ and SUITE_ID in ema_bench.env.__doc__
    # v0 is gone; Gymnasium points at the newest id (v3, suite emafdi-v3); v1 is kept
    with pytest.raises(gym.error.DeprecatedEnv, match="Identify-v3"), \
            pytest.warns(DeprecationWarning, match="Identify-v0 is out of date"):
        gym.make("EMAFault/Identify-v0")
    with pytest.warns(DeprecationWarning, match="Identify-v1 is out of date.*v3"):
        env = gym.make("EMAFault/Identify-v1", case="s02", track="twin", budget=3)
    obs, info = env.reset(seed=0)
    assert info["case"] == "s02"


# --- the shipped best-known optima ---------------------------------------------------------
def test_shipped_targets_cover_the_suite_and_describe_themselves():
    data = shipped_targets()
    assert (data["suite"], data["model_version"]) == (SUITE_ID, MODEL_VERSION)
    assert sorted(data["entries"]) == sorted(all_keys())
    assert data["method"]["stages"] == [list(s) for s in STAGES]
    for key, e in data["entries"].items():
        case = key.split("|")[0]
        assert e["f_star"] <= e["fitness_at_truth"] * (1 + 1e-9), key   # polished from truth
        assert e["f_star"] < e["f_nominal"], key
        err = np.abs(xvec(e["x_star"]) - instance_faults(case)) / \
            (UPPER - LOWER)
        assert e["bias_range_error"] == pytest.approx(err.max()), key
    assert best_known("nominal", "twin", 0) is None          # the sanity case: no targets
    assert best_known("small", "twin", 0, root_seed=1) is None


@pytest.mark.parametrize("key", ["small|reference|1", "s02|twin|3"])
def test_a_short_rerun_does_not_beat_a_shipped_optimum(key):
    case, track, seed = key.split("|")
    e = best_known(case, track, int(seed))
    # another solver and start than the polishing stages: CMA-ES would need ~1500
    p = make_problem(case, track=track, seed=run_seed(0, int(seed)), budget=401,
                     start=xvec(e["x_star"]))
    p.limit(400)
    run_solver("nelder-mead", p, 400, seed=7)
    assert p.best[1] >= e["f_star"] - MARGIN * (e["f_nominal"] - e["f_star"])
    # and the shipped value is what this installation computes for its x*
    q = make_problem(case, track=track, seed=run_seed(0, int(seed)), budget=1)
    assert float(q.evaluate(xvec(e["x_star"]))) == \
        pytest.approx(e["f_star"], rel=1e-9)


def test_fitness_target_ladder():
    assert fitness_targets(1.0, 11.0) == pytest.approx([2.0, 1.1, 1.01, 1.001])
    with pytest.raises(ValueError, match="not above"):
        fitness_targets(1.0, 1.0)


def test_a_record_carries_suite_manifest_and_targets_consistent_with_its_trace():
    rec = run_task(Task("powell", "small", "twin", 0, 300))
    assert rec["suite"] == SUITE_ID and rec["manifest"]["ema_bench"]
    known = best_known("small", "twin", 0)
    t = rec["targets"]
    assert (t["f_star"], t["f_nominal"]) == (known["f_star"], known["f_nominal"])
    levels = fitness_targets(known["f_star"], known["f_nominal"])
    # the trace holds every improvement here (fewer than 200): the first trace point at or
    # below each level is the hit
    for key, level in zip(("0.1", "0.01", "0.001", "0.0001"), levels):
        first = next((e for e, f in rec["trace"] if f <= level), None)
        assert t["fitness"][key] == first, key
    # best_at: the trace's best-so-far at each checkpoint
    for b, f in rec["best_at"]:
        assert f == max((p for p in rec["trace"] if p[0] <= b), key=lambda p: p[0])[1]
    assert rec["evals_to_success"] is None or rec["evals_to_success"] == \
        t["parameters"]["0.01"]
    assert not math.isnan(rec["fitness"])
