"""``EMAFault/Maintain-v0``: inspection and replacement of a degrading actuator."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from ema_bench.prognostics import maintain_env
from ema_bench.prognostics.campaign import get_spec
from ema_bench.prognostics.laws import unit_history
from ema_bench.seeding import as_seed_sequence, stream


def _make(**kw):
    return gym.make(maintain_env.ENV_ID, **kw)


def test_check_env_is_clean():
    env = _make(horizon=60).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env, skip_render_check=True)


def _episode(seed, actions, **kw):
    env = _make(**kw)
    obs, info = env.reset(seed=seed)
    out = [(obs, 0.0, info)]
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        assert not term
        out.append((obs, r, info))
        if trunc:
            break
    return out


def test_same_seed_same_episode_and_inspect_refreshes_the_traces():
    acts = [0, 1, 0, 2, 1]
    a, b = _episode(3, acts, horizon=200), _episode(3, acts, horizon=200)
    for (oa, ra, ia), (ob, rb, ib) in zip(a, b):
        assert ra == rb and ia == ib
        assert all(np.array_equal(oa[k], ob[k]) for k in oa)
    # continue keeps the last traces, inspect and replace refresh them
    assert np.array_equal(a[1][0]["traces"], a[0][0]["traces"])
    assert not np.array_equal(a[2][0]["traces"], a[1][0]["traces"])
    assert a[2][0]["since_inspection"][0] == 0 and a[3][0]["since_inspection"][0] == 10
    assert a[4][0]["age"][0] == 10            # replaced, then one block flown
    assert [r for _, r, _ in a[1:]] == [0.0, -0.5, 0.0, -40.0, -0.5]
    assert _episode(4, acts, horizon=200)[2][0]["traces"].tolist() != \
        a[2][0]["traces"].tolist()


def test_flying_on_fails_at_the_units_end_of_life():
    """Never replacing: the first failure is charged in the block holding the installed
    unit's end of life (computed here from the laws, independently of the env)."""
    seed, every = 5, 10
    unit = unit_history(stream(as_seed_sequence(seed), "instance", 0), get_spec("fleet-v1").laws)
    assert unit.eol is not None
    steps = _episode(seed, [0] * 200, horizon=2000, every=every)
    first = next(i for i, (_, r, info) in enumerate(steps) if info.get("failed"))
    assert (first - 1) * every < unit.eol <= first * every
    assert steps[first][1] == -400.0 and steps[first][2]["failures"] == 1
    assert steps[first][0]["age"][0] == 0      # the spare is installed
    assert steps[-1][2]["flight"] == 2000 and steps[-1][2]["failures"] >= 3


def test_replacing_every_block_never_fails_and_pays_each_time():
    steps = _episode(1, [2] * 30, horizon=300)
    assert all(info["failures"] == 0 for _, _, info in steps)
    assert [r for _, r, _ in steps[1:]] == [-40.0] * 30


@pytest.mark.parametrize("kw, match", [
    ({"track": "bench"}, "unknown track"),
    ({"horizon": 0}, "horizon"),
    ({"every": 2.5}, "every"),
    ({"failure_cost": float("nan")}, "failure_cost"),
    ({"campaign": "fleet-v9"}, "fleet-v9"),
])
def test_bad_configuration_is_a_clear_error(kw, match):
    with pytest.raises(ValueError, match=match):
        _make(**kw)


def test_bad_action_and_step_before_reset():
    env = _make(horizon=50)
    with pytest.raises(gym.error.ResetNeeded):
        env.unwrapped.step(0)
    env.reset(seed=0)
    for bad in (3, -1, 1.5):
        with pytest.raises(ValueError, match="continue"):
            env.step(bad)


def test_a_step_after_truncation_raises_like_identify_v1():
    """Flying on past the horizon would add flights, costs and failures to an episode that
    has ended: refused until reset, and reset starts a whole new horizon."""
    env = _make(horizon=30, every=10)
    env.reset(seed=2)
    truncs = [env.step(0)[3] for _ in range(3)]
    assert truncs == [False, False, True]
    flights = env.unwrapped._flight
    with pytest.raises(gym.error.ResetNeeded, match="horizon of 30 flights"):
        env.unwrapped.step(0)
    assert env.unwrapped._flight == flights == 30    # the refused step changed nothing
    env.reset(seed=2)
    assert not env.step(0)[3]
