"""Gymnasium interface to the identification problem: ``EMAFault/Identify-v1``, ``-v2``, ``-v3``.

Importing this module registers every version, one entry point (:class:`EMAFaultEnv`, vector
entry point :class:`EMAFaultVectorEnv`) with each version's keyword arguments
(:data:`VERSIONS`)::

    import gymnasium as gym
    import ema_bench.env  # noqa: F401  (registers the ids)

    env = gym.make("EMAFault/Identify-v1", case="small", track="reference", budget=500)
    obs, info = env.reset(seed=0)          # obs: the measured traces, stacked
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    env = gym.make("EMAFault/Identify-v2", tier=7, condition="no-prior", track="twin")

An episode is one :class:`~ema_bench.problem.Problem` (one actuator, one set of measured traces)
with a hard evaluation budget.  An action is a candidate vector in the normalised box
``[0, 1]^dim`` (the case's searched parameters: ``FAULT_NAMES``, then a v2 tier's effects,
mapped to physical units with the problem's ``from_unit``); each step costs one evaluation of
the problem's budget,
the reward is minus the fitness, and the episode truncates when the budget is spent.  It never
terminates: the environment cannot know that the truth was found.  The ids register no
``max_episode_steps``: the episode's length is its budget, which depends on the keyword
arguments (``tier=12`` runs 15,000 steps, ``tier=4`` 5,000), and a registered constant would
put a ``TimeLimit`` at the wrong step for every other tier; ``info["budget"]`` states it.

Observation (a float64 vector of ``N = sum over tests of n_samples * 4`` values, laid out as
:meth:`~ema_bench.traces.Traces.stacked`: test by test, signal by signal, sample by sample):

- on ``reset``: the measured traces;
- on ``step`` with ``observation="traces"``: the monitor model's traces of the candidate (clean,
  no noise), clipped to the observation box (each sensor's span widened by 1 %, as a
  saturating sensor would read them);
- on ``step`` with ``observation="residuals"``: the weighted residuals of the candidate
  (:meth:`~ema_bench.problem.Problem.residuals`, rearranged to the same layout, so element
  ``i`` is always the same test, signal and sample); ``sum(obs**2) == -reward``.

``info`` holds ``evaluations``, ``budget``, ``remaining``, ``best_fitness`` (``inf`` before any
evaluation), ``best_x`` (physical, ``name -> value``; after the first evaluation), ``case`` (the
case *label*), ``track``, and ``seed`` and ``root_seed``: the episode is run ``seed`` of the
seed tree (``ema_bench.seeding``), the problem ``ema-bench solve --root-seed R --seed k``
fits; never the true faults.  The problem itself, for the scorer after
the episode, is ``env.unwrapped.problem`` (``problem.score(x)``).

:class:`EMAFaultVectorEnv` (``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")``)
is the batch-evaluation interface for population methods: its ``num_envs`` "sub-environments"
are candidates for the *same* problem, and one step evaluates them all in one batched
:meth:`~ema_bench.problem.Problem.evaluate` call.

Version history (the id's version follows the benchmark suite, :mod:`ema_bench.suites`; a
change to the models or the instances is a new version, as with Gymnasium's own ids):

- ``v3`` (suite ``emafdi-v3``, :mod:`ema_bench.suites.v3`): v2's tiers, conditions and
  problems on model version 4 (the monitor that locates the commutation transfers) under
  v3's case keys (``info["case"]``: ``v3-t7-s03@no-prior``), so a run of an
  episode is filed and judged on v3's targets (parameter tolerances the noise allows, the
  21-target fitness ladder).  ``case`` with ``tier``: ``t7-s03`` or ``v3-t7-s03``.

- ``v2`` (suite ``emafdi-v2``, :mod:`ema_bench.suites.v2`): tiers of dimension (``tier=4,
  7, 12``: the faults, then effects fitted with them: the action's dimension) and conditions
  (``condition="prior"``, ``"no-prior"``, ``"step-only"``, ``"surface-current"``: what the
  problem hands out, the tests in the observation) as keyword arguments; ``case`` an
  instance of the tier (default: instance ``k mod n`` for reset seed ``k``); the budget
  defaults to the tier's (1250 x dim).  One class with ``v1`` and its vector entry point
  (it was a subclass without one); ``v1`` stays registered unchanged.
- ``v1`` (suite ``emafdi-v1``, model version 2, ema-bench 0.2.0): the reference model's
  hysteresis is analog, the monitor integrates without its 50 us discretisation bias; cases
  include the suite's seeded instances ``s00`` .. ``s19``.
- ``v0`` (model version 1, ema-bench 0.1.0): the first release; ``gymnasium.make`` of it now
  raises ``DeprecatedEnv`` naming ``v1``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .faults import FAULT_NAMES
from .objective import KNOWN_TESTS, PENALTY
from .physics.sensors import SENSORS
from .problem import Problem, ProblemError
from .protocol import STANDARD_TESTS
from .seeding import run_seed
from .suites import episode_cases, find
from .suites.problem import check_settings, make_problem
from .traces import SIGNALS

__all__ = ["ENV_ID", "ENV_ID_V2", "ENV_ID_V3", "OBSERVATIONS", "EMAFaultEnv", "EMAFaultVectorEnv",
           "register"]

ENV_ID = "EMAFault/Identify-v1"
ENV_ID_V2 = "EMAFault/Identify-v2"
ENV_ID_V3 = "EMAFault/Identify-v3"
#: The suite whose tiers each version's ``tier=``/``condition=`` episodes draw from.
ENV_SUITES = {ENV_ID_V2: "emafdi-v2", ENV_ID_V3: "emafdi-v3"}
#: Evaluations per episode of ``Identify-v1`` (``budget=None``: the case's suite budget).
DEFAULT_BUDGET = 1000
OBSERVATIONS = ("traces", "residuals")
_OPTIONS = ("case", "track")


def reset_options(options: Mapping[str, Any] | None) -> dict[str, Any]:
    """``reset``'s options as a dict; ValueError naming any it does not know."""
    options = dict(options or {})
    unknown = sorted(set(options) - set(_OPTIONS))
    if unknown:
        raise ValueError(f"unknown reset option(s) {unknown}; known: {list(_OPTIONS)}")
    return options
_SPAN_MARGIN = 0.01  # the traces box is each sensor's span widened by this fraction
# residual box: every |r| <= sqrt(sum r^2) <= sqrt(PENALTY) for a scored candidate
_RESIDUAL_BOUND = float(np.sqrt(PENALTY))


def observation_box(observation: str, tests: Sequence = STANDARD_TESTS) -> spaces.Box:
    """Finite bounds (check_env warns on infinite ones): sensor spans for traces; for residuals
    a box that also holds the traces returned by ``reset``.  ``tests``: the test specs of the
    layout (default the standard protocol's)."""
    sizes = [spec.n_samples() for spec in tests]
    lo = np.array([s.lo for s in SENSORS])
    hi = np.array([s.hi for s in SENSORS])
    margin = _SPAN_MARGIN * (hi - lo)
    low = np.concatenate([np.repeat(lo - margin, n) for n in sizes])
    high = np.concatenate([np.repeat(hi + margin, n) for n in sizes])
    if observation == "residuals":
        bound = max(_RESIDUAL_BOUND, float(np.abs(low).max()), float(high.max()))
        low = np.full_like(low, -bound)
        high = np.full_like(high, bound)
    return spaces.Box(low=low, high=high, dtype=np.float64)


def _actions_to_unit(actions: Any, shape: tuple[int, ...], names: Sequence[str]) -> np.ndarray:
    """Unit-box actions of ``shape`` ((dim,) or (n, dim)), checked and clipped into the box."""
    a = np.asarray(actions, dtype=np.float64)
    if a.shape != shape:
        raise ValueError(f"action must have shape {shape} (unit box [0, 1] per parameter "
                         f"{', '.join(names)}), got {a.shape}")
    bad = ~np.isfinite(a)
    if bad.any():
        idx = np.argwhere(bad.reshape(-1, len(names)))[0]
        row, j = int(idx[0]), int(idx[1])
        where = "" if len(shape) == 1 else f" in row {row}"
        raise ValueError(f"action for {names[j]} is not finite "
                         f"({a.reshape(-1, len(names))[row, j]}){where}; actions must be "
                         "numbers in [0, 1]")
    return np.clip(a, 0.0, 1.0)


class _EpisodeMixin:
    """Configuration, problem building and info shared by the single and the vector
    environment."""

    case: Any
    track: str
    budget: int
    observation: str
    normalise: bool
    heterogeneity: float
    _problem: Problem | None

    def _configure(self, case: Any, track: str, budget: int | None, observation: str,
                   normalise: bool, heterogeneity: float, render_mode: str | None,
                   root_seed: int, tier: int | str | None, condition: str | None,
                   suite: str) -> None:
        """The settings of both environments (:class:`EMAFaultEnv` documents them, in its
        signature's order): check every setting (a clear error at construction, not at
        the first reset) and derive the episodes' cases, the action's parameters and the
        observation's tests from the first case's suite instance (true faults, ``seeded``:
        the four faults, the standard tests)."""
        if render_mode is not None:
            raise ValueError(f"render_mode {render_mode!r} is not supported (no rendering)")
        run_seed(root_seed, 0)  # a valid root seed, checked now
        self.suite = suite
        self._pool = episode_cases(case, tier, condition, suite)  # SuiteError, a ValueError
        inst = find(self._pool[0])
        if budget is None:
            budget = inst.budget if inst is not None else DEFAULT_BUDGET
        if observation not in OBSERVATIONS:
            raise ValueError(f"unknown observation {observation!r}; known: "
                             f"{list(OBSERVATIONS)}")
        check_settings(self._pool[0], track, budget, heterogeneity)
        self.root_seed, self.case, self.track, self.budget = int(root_seed), case, track, \
            int(budget)
        self.tier = None if tier is None and condition is None else inst.dim
        self.condition = None if inst is None or inst.group is None else inst.group[1]
        self.observation, self.normalise = observation, bool(normalise)
        self.heterogeneity = float(heterogeneity)
        self.render_mode = None
        self._names = FAULT_NAMES if inst is None else inst.names
        tests = inst.tests if inst is not None and inst.tests else tuple(
            s.name for s in STANDARD_TESTS)
        self._tests = tuple(KNOWN_TESTS[n] for n in tests)
        self._single_spaces = (observation_box(observation, self._tests), spaces.Box(
            low=0.0, high=1.0, shape=(len(self._names),), dtype=np.float64))
        self._problem = None

    def _new_problem(self, rng: np.random.Generator, options: Mapping[str, Any] | None,
                     seed: int | None = None) -> None:
        options = reset_options(options)
        # the seed tree's run node: reset(seed=k) is run k of root_seed, the instance and noise
        # of `ema-bench solve --root-seed R --seed k`; a reset without a seed draws k from the
        # env's RNG (seeded by the last reset seed, as Gymnasium wants)
        k = int(rng.integers(0, 2**63 - 1)) if seed is None else seed
        self._episode_seed = k
        pool = (self._pool if "case" not in options else
                episode_cases(options["case"], self.tier, self.condition, self.suite))
        problem = make_problem(pool[k % len(pool)], track=options.get("track", self.track),
                               seed=run_seed(self.root_seed, k), budget=self.budget,
                               normalise=self.normalise, heterogeneity=self.heterogeneity)
        # the observation layout: the configured tests
        layout = sum(spec.n_samples() for spec in self._tests) * len(SIGNALS)
        if problem.measured.stacked().shape != (layout,) or problem.dim != len(self._names):
            raise ProblemError("the case's problem does not fit the environment's spaces "
                               f"({len(self._names)} parameters, {layout} observations)")
        self._problem = problem

    def _require_problem(self) -> Problem:
        if self._problem is None:
            raise ResetNeeded("call reset() before step()")
        return self._problem

    def _info(self) -> dict[str, Any]:
        p = self._require_problem()
        info: dict[str, Any] = {"evaluations": p.evaluations, "budget": p.budget,
                                "remaining": p.remaining, "best_fitness": float("inf"),
                                "case": p.label, "track": p.track,
                                "seed": self._episode_seed, "root_seed": self.root_seed}
        if p.evaluations:
            x, f = p.best
            info["best_fitness"], info["best_x"] = f, dict(zip(p.names, map(float, x)))
        if self.tier is not None:
            info.update(tier=self.tier, condition=self.condition)
        return info

    @property
    def problem(self) -> Problem:
        """The current episode's problem (for the scorer: ``problem.score(x)``)."""
        return self._require_problem()

    def _observe(self, p: Problem, outputs: Mapping[str, np.ndarray],
                 fitness: np.ndarray) -> np.ndarray:
        """Observations (n, N) of evaluated candidates: their monitor traces or their weighted
        residuals, both in ``Traces.stacked`` layout (the objective's), clipped into the
        single observation box."""
        if self.observation == "residuals":
            obs = p.objective.residuals(outputs, fitness)
        else:
            obs = p.objective.stack(outputs)
        space = self._single_spaces[0]
        obs = np.nan_to_num(obs, nan=0.0, posinf=space.high, neginf=space.low)
        return np.clip(obs, space.low, space.high)

    def render(self) -> None:
        return None


class EMAFaultEnv(_EpisodeMixin, gym.Env):
    """Fault identification as an episodic Gymnasium environment (see the module docstring).

    Parameters
    ----------
    case : str, mapping or array
        A case of any suite (v1 instance ``small``, ``s03``; v2 ``t7-s03@no-prior``),
        ``"seeded"`` (a random instance per episode, drawn from the reset seed with
        ``heterogeneity``) or explicit true faults; with ``tier``: an instance of the tier
        (``t7-s03``), default (None) the tier's instance ``k mod n`` for reset seed ``k``.
        ``reset(options={"case": ...})`` overrides it for one episode.
    tier, condition : optional
        Suites emafdi-v2 and -v3 (``Identify-v2``, ``-v3``): the tier (4, 7, 12: the action's
        dimension) and the condition (``prior``, ``no-prior``, ``step-only``,
        ``surface-current``: what the problem hands out and the tests in the observation).
    suite : str
        The suite whose tiers ``tier``/``condition`` draw from (``emafdi-v2``, ``emafdi-v3``;
        each registered id sets its own).
    track : {"reference", "twin"}
        Where the measured traces come from (``options={"track": ...}`` overrides it).
    budget : int, optional
        Evaluations (steps) per episode; None: the case's suite budget.
    observation : {"traces", "residuals"}
        What ``step`` observes.
    normalise : bool
        Normalised (default) or raw fitness.
    root_seed : int
        Root of the seed tree: ``reset(seed=k)`` builds run ``k`` of it, the problem that
        ``ema-bench solve --root-seed R --seed k`` fits (``info["seed"]`` names the run).
    """

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(self, case: Any = "small", track: str = "reference",
                 budget: int | None = DEFAULT_BUDGET, observation: str = "traces",
                 normalise: bool = True, heterogeneity: float = 1.0,
                 render_mode: str | None = None, root_seed: int = 0,
                 tier: int | str | None = None, condition: str | None = None,
                 suite: str = ENV_SUITES[ENV_ID_V2]) -> None:
        self._configure(case, track, budget, observation, normalise, heterogeneity,
                        render_mode, root_seed, tier, condition, suite)
        self.observation_space, self.action_space = self._single_spaces

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self._new_problem(self.np_random, options, seed)
        return self._problem.measured.stacked(), self._info()

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        p = self._require_problem()
        if p.remaining <= 0:
            raise ResetNeeded(f"the episode's budget of {p.budget} evaluations is spent "
                              "(truncated); call reset() to start a new episode")
        x = p.from_unit(_actions_to_unit(action, (p.dim,), p.names))
        f, outputs = p.evaluate_outputs(x[None, :])         # one evaluation, one simulation
        fitness = float(f[0])
        obs = self._observe(p, outputs, f)[0]
        return obs, -fitness, False, p.remaining == 0, self._info()


class EMAFaultVectorEnv(_EpisodeMixin, VectorEnv):
    """``num_envs`` candidates for one shared problem, evaluated in one batched call per step.

    ``step(actions)`` takes actions of shape ``(num_envs, dim)`` in the unit box, evaluates them
    with a single :meth:`Problem.evaluate` (``num_envs`` evaluations) and returns observations
    ``(num_envs, N)``, rewards ``-fitness`` ``(num_envs,)``, terminations (always False) and
    truncations (all True once the budget cannot take another full batch).  All
    sub-environments share the problem, so they truncate together; the next ``step`` then
    resets them together to a new instance drawn from the environment's RNG (``NEXT_STEP``
    autoreset: that step ignores its actions and returns zero rewards).

    Takes the keyword arguments of :class:`EMAFaultEnv`; ``budget`` must be at least
    ``num_envs``.
    """

    metadata: dict[str, Any] = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, case: Any = "small", track: str = "reference",
                 budget: int | None = DEFAULT_BUDGET, observation: str = "traces",
                 normalise: bool = True, heterogeneity: float = 1.0,
                 render_mode: str | None = None, root_seed: int = 0,
                 tier: int | str | None = None, condition: str | None = None,
                 suite: str = ENV_SUITES[ENV_ID_V2]) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, int | np.integer) \
                or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        self._configure(case, track, budget, observation, normalise, heterogeneity,
                        render_mode, root_seed, tier, condition, suite)
        if self.budget < num_envs:
            raise ProblemError(f"budget {self.budget} cannot take one batch of {num_envs} "
                               "candidates")
        self.num_envs = int(num_envs)
        self.single_observation_space, self.single_action_space = self._single_spaces
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._autoreset = False

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        return self._reset(options, seed)

    def _reset(self, options: Mapping[str, Any] | None, seed: int | None = None
               ) -> tuple[np.ndarray, dict[str, Any]]:
        self._new_problem(self.np_random, options, seed)
        self._autoreset = False
        obs = np.tile(self._problem.measured.stacked(), (self.num_envs, 1))
        return obs, self._vector_info(self._info())

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                          dict[str, Any]]:
        p = self._require_problem()
        n = self.num_envs
        if self._autoreset:
            obs, info = self._reset(None)
            return obs, np.zeros(n), np.zeros(n, dtype=np.bool_), np.zeros(n, dtype=np.bool_), \
                info
        X = p.from_unit(_actions_to_unit(actions, (n, p.dim), p.names))
        fitness, outputs = p.evaluate_outputs(X)                # one call, n evaluations
        obs = self._observe(p, outputs, fitness)
        truncated = p.remaining < n
        self._autoreset = truncated
        return (obs, -fitness, np.zeros(n, dtype=np.bool_), np.full(n, truncated),
                self._vector_info(self._info()))

    def _vector_info(self, info: dict[str, Any]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for i in range(self.num_envs):
            out = self._add_info(out, info, i)
        return out


#: The registered versions: one entry point, the version's keyword arguments (v2, v3: a
#: tier and a condition of the version's suite, whose budget is the default).
VERSIONS: dict[str, dict[str, Any]] = {ENV_ID: {}} | {
    env_id: {"tier": 4, "condition": "prior", "case": None, "budget": None, "suite": suite}
    for env_id, suite in ENV_SUITES.items()}


def register() -> None:
    """Register ``EMAFault/Identify-v1``, ``-v2`` and ``-v3`` with Gymnasium (idempotent)."""
    for env_id, kwargs in VERSIONS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point="ema_bench.env:EMAFaultEnv",
                         vector_entry_point="ema_bench.env:EMAFaultVectorEnv",
                         kwargs=kwargs)


register()
