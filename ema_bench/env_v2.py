"""``EMAFault/Identify-v2``: the Gymnasium interface to suite ``emafdi-v2``.

Registered by importing :mod:`ema_bench.env` (beside ``v1``)::

    env = gym.make("EMAFault/Identify-v2", tier=7, condition="no-prior", track="twin")
    obs, info = env.reset(seed=3)

As ``v1`` (:mod:`ema_bench.env`: observations, rewards, truncation, the seed tree), except:

- ``tier`` (4, 7, 12) sets the action's dimension (the faults, then the tier's effects, each
  in ``[0, 1]``) and the default budget (:func:`~ema_bench.suite_v2.budget`);
- ``condition`` (``prior``, ``no-prior``, ``step-only``, ``surface-current``) sets what the
  episode's problem hands out (no nominal vector or start without prior) and the tests in
  the observation (``step-only``: the step test alone, a shorter observation;
  ``surface-current``: the same shape, ``theta_m`` and ``omega_m`` zeroed and unweighted);
- ``case`` None (default) picks the tier's instance from the reset seed: run ``k`` fits
  instance ``k mod n`` of the tier (:func:`~ema_bench.suite_v2.instance_names`).

``info`` never holds the truth, the nominal vector or the start.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .env import OBSERVATIONS, EMAFaultEnv, observation_box, reset_options
from .objective import KNOWN_TESTS
from .protocol import STANDARD_TESTS
from .seeding import run_seed
from .suite_v2 import condition as _condition
from .suite_v2 import instance, instance_names
from .suite_v2 import tier as _tier

ENV_ID_V2 = "EMAFault/Identify-v2"


class EMAFaultEnvV2(EMAFaultEnv):
    """One v2 instance per episode (see the module docstring).

    Parameters
    ----------
    tier : int
        The suite's tier (dimension of the action).
    condition : str
        ``prior``, ``no-prior``, ``step-only`` or ``surface-current``.
    case : str, optional
        An instance of the tier (``t7-s03``; tier 4: v1's names); default: from the seed.
    track, observation, normalise, root_seed
        As :class:`~ema_bench.env.EMAFaultEnv`.
    budget : int, optional
        Evaluations per episode; default the tier's budget.
    """

    def __init__(self, tier: int = 4, condition: str = "prior", case: str | None = None,
                 track: str = "reference", budget: int | None = None,
                 observation: str = "traces", normalise: bool = True,
                 render_mode: str | None = None, root_seed: int = 0) -> None:
        t, c = _tier(tier), _condition(condition)   # SuiteError (a ValueError) if unknown
        if not c.offered_on(t.dim):
            raise ValueError(f"condition {condition!r} is offered on tiers {list(c.tiers)}")
        if case is not None and case not in instance_names(t.dim):
            raise ValueError(f"unknown tier-{t.dim} instance {case!r}; known: "
                             f"{list(instance_names(t.dim))}")
        super().__init__(case="small", track=track, budget=t.budget if budget is None
                         else budget, observation=observation, normalise=normalise,
                         render_mode=render_mode, root_seed=root_seed)
        self.tier, self.condition, self.case = t.dim, c.name, case
        self._tests = c.tests or tuple(s.name for s in STANDARD_TESTS)
        self.observation_space = observation_box(observation,
                                                 tuple(KNOWN_TESTS[n] for n in self._tests))
        self.action_space = spaces.Box(low=0.0, high=1.0, shape=(t.dim,), dtype=np.float64)

    def _new_problem(self, rng: np.random.Generator, options: Mapping[str, Any] | None,
                     seed: int | None = None) -> None:
        from .suite_v2 import make_v2_problem

        options = reset_options(options)
        k = int(rng.integers(0, 2**63 - 1)) if seed is None else seed
        self._episode_seed = k
        names = instance_names(self.tier)
        case = options.get("case", self.case) or names[k % len(names)]
        instance(case, self.tier)   # a clear error for a name of another tier
        self._problem = make_v2_problem(case, cond=self.condition,
                                        track=options.get("track", self.track),
                                        seed=run_seed(self.root_seed, k), budget=self.budget)

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        p = self._require_problem()
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (p.dim,) or not np.all(np.isfinite(a)):
            raise ValueError(f"action must be {p.dim} finite numbers in [0, 1] "
                             f"({', '.join(p.names)}), got {a!r}")
        if p.remaining <= 0:
            raise gym.error.ResetNeeded(f"the episode's budget of {p.budget} evaluations is "
                                        "spent (truncated); call reset()")
        from .env import _observe

        f, outputs = p.evaluate_outputs(p.from_unit(np.clip(a, 0.0, 1.0))[None, :])
        obs = self._clip(_observe(p, outputs, f, self.observation)[0])
        return obs, -float(f[0]), False, p.remaining == 0, self._info()

    def _info(self) -> dict[str, Any]:
        info = super()._info()
        p = self._require_problem()
        if p.evaluations:   # every searched parameter, not only the faults
            info["best_x"] = dict(zip(p.names, map(float, p.best[0])))
        info.update(tier=self.tier, condition=self.condition)
        return info


__all__ = ["ENV_ID_V2", "OBSERVATIONS", "EMAFaultEnvV2"]
