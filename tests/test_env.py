"""Tests of the Gymnasium interface (ema_bench.env): EMAFault/Identify-v1 and its vector form."""

from __future__ import annotations

import inspect
import warnings
from collections.abc import Mapping

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode

import ema_bench  # noqa: F401  (registers the id)
from ema_bench.env import ENV_ID, EMAFaultEnv, EMAFaultVectorEnv, register
from ema_bench.faults import CASES, FAULT_NAMES, from_unit
from ema_bench.monitor import simulate_monitor
from ema_bench.physics.sensors import SENSORS
from ema_bench.problem import ProblemError
from ema_bench.protocol import STANDARD_TESTS
from ema_bench.suites.problem import make_problem

N_OBS = sum(s.n_samples() for s in STANDARD_TESTS) * 4


def true_vector(problem) -> np.ndarray:
    """The hidden truth, through the scorer's door."""
    return np.array(list(problem.score(problem.nominal).truth.values()))


def holds_truth(obj, truth: np.ndarray) -> bool:
    """True if ``obj`` holds the true vector anywhere: as a (.., 4) array / sequence or as a
    ``name -> value`` mapping of the four faults."""
    if isinstance(obj, Mapping):
        if set(obj) == set(FAULT_NAMES):
            try:
                vec = np.array([float(obj[n]) for n in FAULT_NAMES])
                if np.allclose(vec, truth, rtol=1e-9, atol=0.0):
                    return True
            except (TypeError, ValueError):
                pass
        return any(holds_truth(k, truth) or holds_truth(v, truth) for k, v in obj.items())
    if isinstance(obj, list | tuple | np.ndarray):
        arr = np.asarray(obj, dtype=object)
        try:
            num = np.asarray(obj, dtype=float)
        except (TypeError, ValueError):
            return any(holds_truth(v, truth) for v in arr.ravel())
        if num.ndim >= 1 and num.shape[-1] == 4:
            return bool(np.any(np.all(np.isclose(num.reshape(-1, 4), truth, rtol=1e-9,
                                                 atol=0.0), axis=1)))
        return False
    return False


def stacked_outputs(outputs, tests) -> np.ndarray:
    return np.concatenate([outputs[t][0].T.ravel() for t in tests])


# ---- registration and the Gymnasium checker ----------------------------------------------------


def test_registered_once_with_both_entry_points():
    spec = gym.spec(ENV_ID)
    assert spec.entry_point == "ema_bench.env:EMAFaultEnv"
    assert spec.vector_entry_point == "ema_bench.env:EMAFaultVectorEnv"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # re-registering would warn "Overriding environment"
        register()
        register()


@pytest.mark.parametrize("kwargs", [{}, {"observation": "residuals", "track": "twin",
                                         "budget": 5}])
def test_check_env_passes_without_warnings(kwargs):
    # making v1 warns only that v3 (suite emafdi-v3) is out, as Gymnasium does for an old id
    with pytest.warns(DeprecationWarning, match="out of date.*v3") as made:
        env = gym.make(ENV_ID, **kwargs)
    assert len(made) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
        env.close()


def test_spaces():
    env = EMAFaultEnv()
    assert env.observation_space.shape == (N_OBS,) == ((300 + 1000) * 4,)
    assert env.observation_space.dtype == np.float64
    assert np.all(np.isfinite(env.observation_space.low))
    assert env.action_space.shape == (4,) and env.action_space.dtype == np.float64
    np.testing.assert_array_equal(env.action_space.low, 0.0)
    np.testing.assert_array_equal(env.action_space.high, 1.0)
    assert env.metadata["render_modes"] == []


def test_bad_configuration_fails_at_construction():
    with pytest.raises(ProblemError, match="case"):
        EMAFaultEnv(case="huge")
    with pytest.raises(ProblemError, match="track"):
        EMAFaultEnv(track="lab")
    with pytest.raises(ValueError, match="observation"):
        EMAFaultEnv(observation="pixels")
    with pytest.raises(ProblemError, match="budget"):
        EMAFaultEnv(budget=0)
    with pytest.raises(ValueError, match="render_mode"):
        EMAFaultEnv(render_mode="human")


def test_both_environments_take_the_same_arguments_in_the_same_order():
    # one signature for both (issue 43): positional as before, the vector env after num_envs
    single = EMAFaultEnv("full", "twin", 7, "residuals", False, 0.5, None, 3)
    vector = EMAFaultVectorEnv(2, "full", "twin", 7, "residuals", False, 0.5, None, 3)
    for env in (single, vector):
        assert (env.case, env.track, env.budget, env.observation, env.normalise,
                env.heterogeneity, env.root_seed) == ("full", "twin", 7, "residuals", False,
                                                      0.5, 3)
    assert vector.num_envs == 2
    # the signature a user (help(), an IDE) sees names every setting, the same in both
    names = list(inspect.signature(EMAFaultEnv).parameters)
    assert names[:3] == ["case", "track", "budget"] and "suite" in names
    assert list(inspect.signature(EMAFaultVectorEnv).parameters) == ["num_envs", *names]
    with pytest.raises(TypeError, match="colour"):
        EMAFaultVectorEnv(2, colour="red")


# ---- reset ---------------------------------------------------------------------------------------


def test_reset_observation_is_the_measured_traces_and_is_seeded():
    env_a, env_b = gym.make(ENV_ID), gym.make(ENV_ID)
    obs_a, info = env_a.reset(seed=7)
    obs_b, _ = env_b.reset(seed=7)
    assert obs_a.dtype == np.float64 and obs_a.shape == (N_OBS,)
    np.testing.assert_array_equal(obs_a, obs_b)
    np.testing.assert_array_equal(obs_a, env_a.unwrapped.problem.measured.stacked())
    assert obs_a in env_a.observation_space
    assert info == {"evaluations": 0, "budget": 1000, "remaining": 1000,
                    "best_fitness": float("inf"), "case": "small", "track": "reference",
                    "seed": 7, "root_seed": 0}
    # unseeded resets continue the seeded RNG: same sequence on both envs, new noise each time
    next_a, _ = env_a.reset()
    next_b, _ = env_b.reset()
    np.testing.assert_array_equal(next_a, next_b)
    assert not np.array_equal(next_a, obs_a)
    # a different seed: same actuator, different sensor noise (differences at noise level)
    other, _ = env_a.reset(seed=8)
    diff = np.abs(other - obs_a)
    assert diff.max() > 0
    span = env_a.observation_space.high - env_a.observation_space.low
    assert np.all(diff <= 0.02 * span)


@pytest.mark.parametrize("case", ["seeded", "full"])
def test_reset_seed_k_is_run_k_of_the_seed_tree(case):
    """reset(seed=k) under root_seed R plays the problem `ema-bench solve --root-seed R
    --seed k` fits: same instance, same noise (one seed tree, issue 11)."""
    from ema_bench import make_problem
    from ema_bench.seeding import run_seed

    env = gym.make(ENV_ID, case=case, track="twin", root_seed=5)
    obs, info = env.reset(seed=3)
    assert (info["seed"], info["root_seed"]) == (3, 5)
    p = make_problem(case, track="twin", seed=run_seed(5, 3))
    np.testing.assert_array_equal(obs, p.measured.stacked())
    assert info["case"] == p.label
    obs_unseeded, info = env.reset()   # a drawn run number, reported so it can be replayed
    p2 = make_problem(case, track="twin", seed=run_seed(5, info["seed"]))
    np.testing.assert_array_equal(obs_unseeded, p2.measured.stacked())


def test_reset_options_override_case_and_track_for_one_episode():
    env = gym.make(ENV_ID, track="twin")
    _, info = env.reset(seed=1, options={"case": "full", "track": "reference"})
    assert (info["case"], info["track"]) == ("full", "reference")
    np.testing.assert_array_equal(true_vector(env.unwrapped.problem), CASES["full"].x)
    _, info = env.reset()
    assert (info["case"], info["track"]) == ("small", "twin")
    _, info = env.reset(options={"case": "seeded"})
    assert info["case"].startswith("seeded")
    with pytest.raises(ValueError, match="budget"):
        env.reset(options={"budget": 3})
    with pytest.raises(ProblemError, match="case"):
        env.reset(options={"case": "huge"})


# ---- the truth stays hidden ----------------------------------------------------------------------


@pytest.mark.parametrize("case", ["nominal", "small", "seeded"])
def test_info_never_contains_the_truth(case):
    env = gym.make(ENV_ID, case=case, track="twin", budget=6)
    env.action_space.seed(0)
    infos = [env.reset(seed=3)[1]]
    truth = true_vector(env.unwrapped.problem)
    for _ in range(6):
        infos.append(env.step(env.action_space.sample())[4])
    for info in infos:
        assert not holds_truth(info, truth), info
        assert not any("true" in str(k).lower() for k in info)
    # the helper does find the truth where it is
    assert holds_truth({"x": dict(zip(FAULT_NAMES, truth))}, truth)
    assert holds_truth({"x": [truth.tolist()]}, truth)


# ---- step ----------------------------------------------------------------------------------------


def test_step_reward_is_minus_the_problem_fitness_and_counts_once():
    env = gym.make(ENV_ID, budget=10)
    env.reset(seed=2)
    problem = env.unwrapped.problem
    # an independent problem on the same measured traces
    twin = make_problem(measured=problem.measured, budget=10)
    rng = np.random.default_rng(0)
    for k in range(1, 4):
        action = rng.random(4)
        x = from_unit(action)
        obs, reward, terminated, truncated, info = env.step(action)
        assert problem.evaluations == k  # exactly one evaluation per step
        assert isinstance(reward, float) and reward == -problem.history()["fitness"][-1]
        assert reward == pytest.approx(-twin.evaluate(x), rel=1e-12)
        assert terminated is False and truncated is False
        assert obs.shape == (N_OBS,) and obs.dtype == np.float64
        outputs, ok = simulate_monitor(x[None, :])
        assert ok[0]
        np.testing.assert_allclose(obs, stacked_outputs(outputs, problem.measured.tests),
                                   rtol=1e-12, atol=1e-12)
        best_x, best_f = problem.best
        assert info["best_fitness"] == best_f and info["evaluations"] == k
        assert info["best_x"] == dict(zip(FAULT_NAMES, best_x.tolist()))
        assert info["remaining"] == 10 - k


def test_actions_are_clipped_and_nan_is_refused():
    env = gym.make(ENV_ID, track="twin", budget=5).unwrapped
    env.reset(seed=0)
    env.step(np.array([-1.0, 2.0, 0.5, 0.25]))
    np.testing.assert_allclose(env.problem.history()["x"][-1],
                               from_unit(np.array([0.0, 1.0, 0.5, 0.25])), rtol=1e-15)
    with pytest.raises(ValueError, match="Fst.*not finite"):
        env.step(np.array([0.5, np.nan, 0.5, 0.5]))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.array([0.5, 0.5, 0.5]))
    assert env.problem.evaluations == 1  # refused actions cost nothing


def test_truncation_exactly_at_budget_then_step_raises():
    env = gym.make(ENV_ID, track="twin", budget=5)
    with pytest.raises(ResetNeeded):
        env.step(np.full(4, 0.5))  # before reset (OrderEnforcing)
    with pytest.raises(ResetNeeded, match="reset"):
        env.unwrapped.step(np.full(4, 0.5))  # and the env itself
    env.reset(seed=0)
    flags = [env.step(np.full(4, 0.1 * k))[3] for k in range(1, 6)]
    assert flags == [False, False, False, False, True]
    assert env.unwrapped.problem.evaluations == 5
    with pytest.raises(ResetNeeded, match="budget of 5 evaluations is spent"):
        env.step(np.full(4, 0.5))
    assert env.unwrapped.problem.evaluations == 5
    env.reset()
    assert env.unwrapped.problem.evaluations == 0


def test_residual_mode():
    env = gym.make(ENV_ID, observation="residuals", budget=4)
    obs0, _ = env.reset(seed=5)
    problem = env.unwrapped.problem
    np.testing.assert_array_equal(obs0, problem.measured.stacked())
    twin = make_problem(measured=problem.measured, budget=4)
    x_unit = np.array([0.3, 0.4, 0.2, 0.6])
    obs, reward, _, truncated, _ = env.step(x_unit)
    assert problem.evaluations == 1 and not truncated
    assert obs.shape == (N_OBS,) and obs in env.observation_space
    np.testing.assert_allclose(np.sum(obs**2), -reward, rtol=1e-10)
    # the same values as Problem.residuals: one layout, the stacked one (test by test, signal
    # by signal, sample by sample): the first 300 are the step test's surface position
    r = twin.residuals(from_unit(x_unit))
    np.testing.assert_allclose(obs, r, rtol=1e-12, atol=0)
    out, _ = twin.simulate(from_unit(x_unit))
    meas = problem.measured.data["step"][:, 0]
    w0 = 1.0 / max(np.ptp(meas), 10 * SENSORS[0].lsb) ** 2
    np.testing.assert_allclose(obs[:300], (out["step"][0, :, 0] - meas) * np.sqrt(w0 / 300),
                               rtol=1e-12, atol=1e-15)
    assert reward == pytest.approx(-twin.history()["fitness"][-1], rel=1e-12)


# ---- vector env ----------------------------------------------------------------------------------


def test_make_vec_uses_the_vector_entry_point():
    envs = gym.make_vec(ENV_ID, num_envs=8, vectorization_mode="vector_entry_point")
    assert isinstance(envs, EMAFaultVectorEnv) and envs.num_envs == 8
    assert envs.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    assert envs.observation_space.shape == (8, N_OBS)
    assert envs.action_space.shape == (8, 4)
    assert envs.single_action_space == EMAFaultEnv().action_space
    assert isinstance(gym.make_vec(ENV_ID, num_envs=2, budget=4), EMAFaultVectorEnv)


def _count_monitor_calls(monkeypatch) -> list:
    """Record the batch shape of every monitor simulation the objective runs."""
    import ema_bench.objective as objective_module

    calls, real = [], objective_module.simulate_monitor

    def counting(X, *args, **kwargs):
        calls.append(np.shape(X))
        return real(X, *args, **kwargs)

    monkeypatch.setattr(objective_module, "simulate_monitor", counting)
    return calls


@pytest.mark.parametrize("observation", ["traces", "residuals"])
def test_single_step_simulates_once(monkeypatch, observation):
    env = gym.make(ENV_ID, observation=observation, track="twin", budget=5)
    env.reset(seed=2)
    calls = _count_monitor_calls(monkeypatch)
    env.step(np.array([0.3, 0.4, 0.2, 0.6]))
    assert calls == [(1, 4)]   # one evaluation, one simulation (it used to simulate twice)


@pytest.mark.parametrize("observation", ["traces", "residuals"])
def test_vector_step_simulates_once(monkeypatch, observation):
    envs = gym.make_vec(ENV_ID, num_envs=6, vectorization_mode="vector_entry_point",
                        track="twin", budget=20, observation=observation)
    envs.reset(seed=2)
    calls = _count_monitor_calls(monkeypatch)
    envs.step(np.random.default_rng(0).random((6, 4)))
    assert calls == [(6, 4)]


def test_vector_step_is_one_batched_evaluation():
    n = 8
    envs = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point",
                        track="twin", budget=20)
    obs, info = envs.reset(seed=3)
    problem = envs.problem
    assert obs.shape == (n, N_OBS)
    np.testing.assert_array_equal(obs, np.tile(problem.measured.stacked(), (n, 1)))
    assert np.all(info["evaluations"] == 0) and np.all(info["_evaluations"])
    calls = []
    evaluate = problem.evaluate_outputs
    problem.evaluate_outputs = lambda X: (calls.append(np.shape(X)), evaluate(X))[1]

    rng = np.random.default_rng(1)
    actions = rng.random((n, 4))
    obs, rewards, terminated, truncated, info = envs.step(actions)
    assert calls == [(n, 4)] and problem.evaluations == n
    assert rewards.shape == (n,) and obs.shape == (n, N_OBS)
    np.testing.assert_array_equal(rewards, -problem.history()["fitness"])
    assert not terminated.any() and not truncated.any()
    assert np.all(info["evaluations"] == n)

    # a single env with the same seed plays the same problem: same rewards and observations
    single = gym.make(ENV_ID, track="twin", budget=20)
    single.reset(seed=3)
    for i in range(n):
        o, r, *_ = single.step(actions[i])
        np.testing.assert_allclose(r, rewards[i], rtol=1e-12)
        np.testing.assert_allclose(o, obs[i], rtol=1e-12, atol=1e-12)

    # 16 of 20 spent: another batch of 8 does not fit -> all truncate together
    _, _, _, truncated, _ = envs.step(rng.random((n, 4)))
    assert truncated.all() and problem.evaluations == 16 and len(calls) == 2
    # next-step autoreset: a fresh instance, no evaluation, zero rewards
    obs, rewards, terminated, truncated, info = envs.step(rng.random((n, 4)))
    assert envs.problem is not problem and envs.problem.evaluations == 0
    np.testing.assert_array_equal(rewards, 0.0)
    assert not truncated.any() and not terminated.any()
    np.testing.assert_array_equal(obs[0], envs.problem.measured.stacked())


def test_vector_residual_mode_matches_single_env():
    n = 3
    envs = EMAFaultVectorEnv(num_envs=n, observation="residuals", budget=6)
    single = EMAFaultEnv(observation="residuals", budget=6)
    envs.reset(seed=11)
    single.reset(seed=11)
    actions = np.random.default_rng(2).random((n, 4))
    obs, rewards, *_ = envs.step(actions)
    np.testing.assert_allclose(np.sum(obs**2, axis=1), -rewards, rtol=1e-10)
    for i in range(n):
        o, r, *_ = single.step(actions[i])
        np.testing.assert_allclose(o, obs[i], rtol=1e-9, atol=1e-15)
        assert r == pytest.approx(rewards[i], rel=1e-12)


def test_vector_env_refuses_bad_input():
    with pytest.raises(ProblemError, match="batch"):
        EMAFaultVectorEnv(num_envs=8, budget=4)
    envs = EMAFaultVectorEnv(num_envs=2, track="twin", budget=4)
    with pytest.raises(ResetNeeded):
        envs.step(np.zeros((2, 4)))
    envs.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        envs.step(np.zeros(4))
    with pytest.raises(ValueError, match="Gprop.*row 1"):
        envs.step(np.array([[0.5] * 4, [0.5, 0.5, 0.5, np.nan]]))
    assert envs.problem.evaluations == 0
