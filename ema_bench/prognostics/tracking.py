"""Trackers: follow a unit's faults inspection by inspection and predict its remaining life.

A tracker is a *factory* decorated with :func:`register_tracker`, in a module named by an entry
point of the group ``ema_bench.trackers``, exactly like solvers (:mod:`ema_bench.registry`)::

    # pyproject.toml of any package
    [project.entry-points."ema_bench.trackers"]
    my-tracker = "my_package.my_module"

``factory(campaign_info, seed, **config)`` is called once per unit (``campaign_info``:
:meth:`Campaign.info`, a fresh dict of the manifest's settings as plain JSON values, with no
folder in it; ``seed``: the unit's ``SeedSequence``) and returns a closure
``step(inspection) -> TrackStep`` that keeps the unit's state; it is called with the unit's
:class:`Inspection` objects (traces already read, logged conditions) in flight order, every
one of them up to the unit's last inspection (the cut), also after the tracker has called for
replacement: the call is recorded and scored as a maintenance decision, and the RUL headline
is judged at the cut for every tracker alike.  A tracker runs in worker processes
(:mod:`.track_worker`), which receive per unit those settings, the unit's inspections and its
one-way seed only: never the :class:`~.campaign.Campaign`, its folder or the campaign's seed
(``campaign track`` runs on a folder without the truth); replay re-tracks each unit in a
fresh process of its own.  The baselines
live in the
top-level ``trackers/`` folder (installed as ``ema_bench_trackers``) and register through
ema-bench's own entry points.

:func:`~.track_run.track_campaign` runs a tracker over a campaign and writes
``OUT/track.jsonl`` (one line per unit and inspection, appended as each finishes; rerunning
resumes) and ``OUT/manifest.json``; :func:`~.track_io.read_track` reads it back.  This module
is the tracker API (what a tracker sees and answers, the registry).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..faults import FAULT_NAMES
from ..plugins import PluginRegistry
from ..traces import Traces

if TYPE_CHECKING:
    from ..problem import Problem

log = logging.getLogger("ema_bench")

ENTRY_POINT_GROUP = "ema_bench.trackers"
TRACK_FILE = "track.jsonl"
MANIFEST_FILE = "manifest.json"
FORMAT = "ema-bench-track"
#: 2: every inspection is tracked, also after a replacement call (1 stopped there).
VERSION = 2
#: Fields of a step that may be infinite: JSON has no infinity, so they are written as null.
INFINITE_FIELDS = ("rul", "rul_low", "rul_high")


class TrackerError(LookupError):
    """Unknown tracker name, a broken plugin, a bad step or an output folder of another run."""


# --- what a tracker sees and answers ---------------------------------------------------------

@dataclass(frozen=True)
class Inspection:
    """One inspection of one unit, as a tracker gets it.

    Attributes
    ----------
    unit, index, flight
        Unit label, inspection number (0, 1, ...) and flight (flights since new).
    traces
        The measured step and sine traces.
    conditions
        What the operator logged (``ambient_temp_C``, ``winding_temp_C`` in degC,
        ``flights_since_last``, ``duty_since_last``).
    thresholds
        Failure threshold per failing fault, physical units (``Gprop`` has none).
    inspection_every
        Flights between inspections (the campaign's design).
    """

    unit: str
    index: int
    flight: int
    traces: Traces
    conditions: dict
    thresholds: dict[str, float]
    inspection_every: int

    def problem(self, start: np.ndarray | None = None, budget: int = 2000,
                effects: np.ndarray | None = None) -> Problem:
        """The identification problem of this inspection: its traces, warm-started at
        ``start`` (physical fault vector; default nominal), counting evaluations against
        ``budget``.

        ``effects`` (array (N_EFFECTS,), optional): effects switched on in the monitor for
        every candidate, e.g. the confounders a tracker infers from the logged ``conditions``
        (:func:`ema_bench.prognostics.laws.confounders`)."""
        if effects is None:
            from ..suites.problem import make_problem

            return make_problem(measured=self.traces, start=start, budget=budget)
        from ..problem import Problem

        return Problem(self.traces, budget, start=start,
                       monitor_effects=np.asarray(effects, dtype=float),
                       label=f"{self.unit}/i{self.index:03d}", track="measured")


@dataclass
class TrackStep:
    """A tracker's answer to one inspection.

    Attributes
    ----------
    flight : int
        The inspection's flight.
    estimate, low, high : dict
        Fault estimates and their 95 % interval ends, physical units, every fault.
    rul : float
        Median predicted remaining useful life, flights (``inf``: no failure in sight).
    rul_low, rul_high : float
        95 % interval of the RUL, flights (``rul_high`` may be ``inf``).
    failing_fault : str or None
        The fault predicted to cross its threshold first.
    replace : bool
        The tracker calls for replacement now (the first such call is the unit's maintenance
        decision; tracking goes on to the cut so that the RUL is judged there).
    evaluations : int
        Model runs this step cost.
    extra : dict
        Anything else the tracker wants recorded (JSON-friendly).
    rul_quantiles : dict
        Optional: quantiles of the predicted RUL, level -> flights (``inf`` allowed), e.g. at
        :data:`~ema_bench.prognostics.distributions.LEVELS`, scored by CRPS and interval
        scores; empty (the default): only the 95 % interval is scored.
    profile_rul : float or None
        Optional: the RUL *not* conditioned on this inspection being the cut, flights, when
        ``rul`` is (a cut-conditioned forecast is scored at the cut only; the prognostic
        horizon, alpha-lambda and monotonicity read this profile); None: ``rul`` is
        unconditioned.
    """

    flight: int
    estimate: dict[str, float]
    low: dict[str, float]
    high: dict[str, float]
    rul: float
    rul_low: float
    rul_high: float
    failing_fault: str | None
    replace: bool
    evaluations: int
    extra: dict[str, Any] = field(default_factory=dict)
    rul_quantiles: dict[str, float] = field(default_factory=dict)
    profile_rul: float | None = None


def check_step(step: object, inspection: Inspection) -> TrackStep:
    """``step`` if it is a sound answer to ``inspection``; :class:`TrackerError` naming the
    fault otherwise (not a TrackStep, a missing or non-finite estimate, a NaN or negative RUL,
    RUL ends out of order, an unknown failing fault)."""
    if not isinstance(step, TrackStep):
        raise TrackerError(f"a tracker must return a TrackStep, got {type(step).__name__}")
    for what in ("estimate", "low", "high"):
        d = getattr(step, what)
        missing = [n for n in FAULT_NAMES if n not in d]
        bad = [n for n in FAULT_NAMES if n in d and not math.isfinite(float(d[n]))]
        if missing or bad:
            raise TrackerError(f"step {what}: missing {missing} or not finite {bad}")
    ruls = [float(step.rul_low), float(step.rul), float(step.rul_high)]
    if any(math.isnan(r) or r < 0 for r in ruls) or not ruls[0] <= ruls[1] <= ruls[2]:
        raise TrackerError(f"step RUL must be >= 0 and rul_low <= rul <= rul_high, got {ruls}")
    if step.rul_quantiles:
        from .distributions import check_quantiles
        try:
            check_quantiles(step.rul_quantiles)
        except ValueError as exc:
            raise TrackerError(f"step {exc}") from None
    if step.profile_rul is not None and not float(step.profile_rul) >= 0:
        raise TrackerError(f"step profile_rul must be >= 0, got {step.profile_rul!r}")
    if step.failing_fault is not None and step.failing_fault not in inspection.thresholds:
        raise TrackerError(f"step failing_fault {step.failing_fault!r} has no threshold "
                           f"(thresholds: {list(inspection.thresholds)})")
    if int(step.flight) != inspection.flight:
        raise TrackerError(f"step flight {step.flight} is not the inspection's "
                           f"({inspection.flight})")
    return step


# --- the registry (the same structure as ema_bench.registry for solvers) ---------------------

StepFn = Callable[[Inspection], TrackStep]
Factory = Callable[..., StepFn]


@dataclass(frozen=True)
class TrackerInfo:
    name: str
    factory: Factory
    description: str
    config: dict[str, Any] = field(default_factory=dict)  # keywords passed to the factory

    def start(self, campaign_info: Mapping, seed: np.random.SeedSequence) -> StepFn:
        """A fresh closure for one unit."""
        return self.factory(dict(campaign_info), seed, **self.config)


_TRACKERS: PluginRegistry[TrackerInfo] = PluginRegistry(ENTRY_POINT_GROUP, "tracker",
                                                         TrackerError, lambda i: i.factory)


def register_tracker(name: str, /, *, description: str, **config: Any
                     ) -> Callable[[Factory], Factory]:
    """Decorator: make ``factory`` available as tracker ``name``.

    Keyword ``config`` is passed to the factory for every unit: one factory registers several
    configured variants (``register_tracker("particle-512", ..., n_particles=512)(factory)``).
    """
    def deco(factory: Factory) -> Factory:
        _TRACKERS.add(name, TrackerInfo(name, factory, description, dict(config)))
        return factory
    return deco


def available_trackers() -> dict[str, TrackerInfo]:
    """Every registered tracker, by name (sorted)."""
    return _TRACKERS.available()


def get_tracker(name: str) -> TrackerInfo:
    """The tracker registered as ``name`` (its plugin module only is imported; all of them
    when the name is unknown, for the error message, which lists the known ones)."""
    return _TRACKERS.get(name)
