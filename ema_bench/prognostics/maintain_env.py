"""Gymnasium environment ``EMAFault/Maintain-v0``: when to inspect and when to replace.

Importing this module registers the environment::

    import gymnasium as gym
    import ema_bench.prognostics.maintain_env  # noqa: F401  (registers the id)

    env = gym.make("EMAFault/Maintain-v0", track="twin", horizon=2000)
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(1)      # fly, then inspect

An episode follows one actuator position of an aircraft for ``horizon`` flights.  The actuator
in it degrades by the campaign's laws (:mod:`~ema_bench.prognostics.laws`, fleet
``fleet-v1``); every step flies a block of ``every`` flights (default 10, the campaign's
inspection spacing) after the action:

- ``0`` continue: fly the block;
- ``1`` inspect: fly the block, then run the step and sine tests (the observation's traces are
  refreshed; otherwise they are those of the last inspection);
- ``2`` replace: install a new actuator (drawn from the fleet's laws, tested on installation,
  so the traces are refreshed), then fly the block.

A fault crossing its failure threshold during a block is a failure in service: the actuator is
removed unplanned and replaced at the end of the block (its acceptance test refreshes the
traces; ``info["failed"]`` says so).

Reward: minus the cost of the step, in units of one flight's revenue (keyword arguments):
``inspect_cost`` 0.5 (a ground test slot), ``replace_cost`` 40 (the part, a planned shop
visit and one lost flight), ``failure_cost`` 400 (an unplanned removal: aircraft on ground,
delays, an in-service event).  Replacing early wastes useful life, late risks failures; a
policy is judged by its mean cost per flight over the horizon.  The task is continuing: it
never terminates, and truncates at ``horizon``.

Observation (a dict): ``traces`` (the last inspection's measured traces in
:meth:`~ema_bench.traces.Traces.stacked` layout, the box of ``EMAFault/Identify-v1``'s
observations), ``since_inspection`` and ``age`` (flights since the last inspection and since
installation, as one-element arrays).  ``info``: ``flight``, ``age``, ``failed`` (this step),
``inspections``, ``replacements``, ``failures`` (episode totals), ``seed``; never the true
faults.

Seeds: ``reset(seed=k)`` makes the episode's root ``SeedSequence(k)``; actuator ``j`` of the
episode is drawn from its ``("instance", j)`` stream and inspection ``i`` of it gets the noise
of ``("noise", j, i)`` (:mod:`~ema_bench.seeding`), so the same seed and actions give the same
episode.

Version history: ``v0`` (model version 2, fleet ``fleet-v1``, ema-bench 0.2.0): the first.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ..env import observation_box
from ..faults import LOWER, UPPER
from ..instances import TRACKS
from ..protocol import STANDARD_TESTS
from ..seeding import as_seed_sequence, stream
from .campaign import get_spec, simulate_inspection
from .laws import UnitHistory, unit_history
from .policy import FAILURE_COST, INSPECT_COST, REPLACE_COST

ENV_ID = "EMAFault/Maintain-v0"
CONTINUE, INSPECT, REPLACE = 0, 1, 2


class MaintainEnv(gym.Env):
    """Inspection and replacement of a degrading actuator (see the module docstring)."""

    metadata = {"render_modes": []}

    def __init__(self, track: str = "twin", horizon: int = 2000, every: int = 10,
                 campaign: str = "fleet-v1", inspect_cost: float = INSPECT_COST,
                 replace_cost: float = REPLACE_COST, failure_cost: float = FAILURE_COST) -> None:
        if track not in TRACKS:
            raise ValueError(f"unknown track {track!r}; known: {list(TRACKS)}")
        for name, v in (("horizon", horizon), ("every", every)):
            if isinstance(v, bool) or int(v) != v or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        costs = {"inspect_cost": inspect_cost, "replace_cost": replace_cost,
                 "failure_cost": failure_cost}
        for name, v in costs.items():
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"{name} must be a finite cost >= 0, got {v!r}")
        self.track, self.horizon, self.every = track, int(horizon), int(every)
        self.spec_ = get_spec(campaign)
        self.costs = {k: float(v) for k, v in costs.items()}
        self.tests = tuple(t for t in STANDARD_TESTS if t.name in self.spec_.tests)
        self.action_space = spaces.Discrete(3)
        self.observation_space = spaces.Dict({
            "traces": observation_box("traces"),
            "since_inspection": spaces.Box(0.0, float(self.horizon), (1,), np.float64),
            "age": spaces.Box(0.0, float(self.horizon), (1,), np.float64),
        })
        self._root: np.random.SeedSequence | None = None

    # --- the actuator ------------------------------------------------------------------------

    def _install(self) -> None:
        """A new actuator from the fleet's laws, tested on installation."""
        self._units += 1
        self._unit: UnitHistory = unit_history(stream(self._root, "instance", self._units),
                                               self.spec_.laws)
        self._age = 0
        self._n_insp = 0
        self._inspect()

    def _inspect(self) -> None:
        f = min(self._age, self._unit.faults.shape[0] - 1)
        x = np.clip(self._unit.faults[f], LOWER, UPPER)
        tr = simulate_inspection(x, self._unit.effects(f),
                                 stream(self._root, "noise", self._units, self._n_insp),
                                 self.tests, self.track)
        self._n_insp += 1
        self._traces = np.clip(tr.stacked(), self.observation_space["traces"].low,
                               self.observation_space["traces"].high)
        self._since = 0

    def _obs(self) -> dict[str, np.ndarray]:
        return {"traces": self._traces.copy(),
                "since_inspection": np.array([min(self._since, self.horizon)], float),
                "age": np.array([min(self._age, self.horizon)], float)}

    def _info(self, failed: bool = False) -> dict[str, Any]:
        return {"flight": self._flight, "age": self._age, "failed": failed,
                "inspections": self._inspections, "replacements": self._replacements,
                "failures": self._failures, "seed": self._seed}

    # --- Gymnasium ---------------------------------------------------------------------------

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if options:
            raise ValueError(f"unknown reset option(s) {sorted(options)}; this env takes none")
        # the episode's root: the reset seed, or a draw of the env's RNG (seeded by the last
        # reset seed, as Gymnasium wants)
        self._seed = int(self.np_random.integers(0, 2**63 - 1)) if seed is None else int(seed)
        self._root = as_seed_sequence(self._seed)
        self._flight = 0
        self._units = -1
        self._inspections = self._replacements = self._failures = 0
        self._install()
        return self._obs(), self._info()

    def step(self, action: Any):
        if self._root is None:
            raise gym.error.ResetNeeded("call reset() before step()")
        if self._flight >= self.horizon:
            # like Identify-v1 after its budget: a step past the end would fly on silently
            raise gym.error.ResetNeeded(f"the episode reached its horizon of {self.horizon} "
                                        "flights (truncated); call reset() to start a new "
                                        "episode")
        if not self.action_space.contains(action):
            raise ValueError(f"action must be 0 (continue), 1 (inspect) or 2 (replace), "
                             f"got {action!r}")
        action = int(action)
        cost = 0.0
        if action == REPLACE:
            cost += self.costs["replace_cost"]
            self._replacements += 1
            self._install()
        block = min(self.every, self.horizon - self._flight)
        eol = self._unit.eol
        failed = eol is not None and self._age < eol <= self._age + block
        self._flight += block
        self._age += block
        self._since += block
        if failed:
            cost += self.costs["failure_cost"]
            self._failures += 1
            self._install()
        elif action == INSPECT:
            cost += self.costs["inspect_cost"]
            self._inspections += 1
            self._inspect()
        truncated = self._flight >= self.horizon
        return self._obs(), -cost, False, truncated, self._info(failed)


def register() -> None:
    """Register ``EMAFault/Maintain-v0`` with Gymnasium (idempotent)."""
    if ENV_ID not in gym.registry:
        gym.register(id=ENV_ID, entry_point="ema_bench.prognostics.maintain_env:MaintainEnv")


register()
