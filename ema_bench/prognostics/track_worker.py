"""One unit tracked in a process of its own: the tracker runs here, the campaign stays there.

``ema-bench campaign track`` and ``campaign score --replay`` send each unit to a fresh worker
process (the sweep engine's ``isolated`` executor: one unit per process, so no memory crosses
units).  The worker receives what a tracker may see and nothing else (:class:`UnitInput`): the
tracker's name, the campaign's published settings (:meth:`~.campaign.Campaign.info`: no
folder, no seed), the unit's inspections with their traces already read, and the unit's
one-way seed (:func:`~.tracking.unit_seed`, which gives neither the tracking run's root seed
nor the campaign's away); never the :class:`~.campaign.Campaign`, its folder or the
campaign's seed.  The inspections are read in the process that holds the campaign, when the
unit is sent (:class:`UnitSource`), one unit in flight per worker; the worker sends back the
unit's lines.  The process that holds the campaign imports no tracker plugin either (its
import could patch the harness there): what it needs of the tracker (its module and
registered configuration) comes from a worker too (:func:`tracker_spec`).
"""

from __future__ import annotations

import functools
import importlib
import json
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from .campaign import Campaign
    from .tracking import Inspection


@dataclass(frozen=True)
class TrackerSpec:
    """A registered tracker as values: its name, its factory's module and qualified name, its
    description and registered configuration (what the process that holds the campaign knows
    of it, and what a worker registers it again from when no import does: a configured
    variant registered in a script's function)."""

    name: str
    module: str
    factory: str
    description: str
    config: dict

    @property
    def manifest_config(self) -> dict:
        """The configuration as a tracking run's manifest records it (plain JSON)."""
        from ..jsonio import plain

        return plain(self.config, default=str)

    def info(self) -> Any:
        """The registered :class:`~.tracking.TrackerInfo` (in a worker): the module imported
        by name, else the factory registered again under this name and configuration."""
        from .tracking import _TRACKERS, get_tracker, register_tracker

        if self.name not in _TRACKERS.entries:
            try:
                factory = functools.reduce(getattr, self.factory.split("."),
                                           importlib.import_module(self.module))
            except (ImportError, AttributeError):
                factory = None   # an entry point's tracker: get_tracker finds it
            if self.name not in _TRACKERS.entries and callable(factory):
                register_tracker(self.name, description=self.description,
                                 **self.config)(factory)
        return get_tracker(self.name)


def _spec(info: Any) -> TrackerSpec:
    return TrackerSpec(info.name, info.factory.__module__, info.factory.__qualname__,
                       info.description, dict(info.config))


def spec_job(job: Any) -> dict:
    """The :class:`TrackerSpec` of tracker ``job.data`` as a dict (in a worker: its plugin is
    imported there)."""
    from dataclasses import asdict

    from .tracking import get_tracker

    return asdict(_spec(get_tracker(job.data)))


def tracker_spec(name: str) -> TrackerSpec:
    """The tracker ``name``: from this process's registry when something here registered it
    already (a script's or a test's own tracker), else looked up in a worker process, so that
    an entry point's plugin is never imported beside the campaign.  TrackerError (one line)
    for an unknown or broken tracker."""
    from ..sweep.executors import Job, execute
    from .tracking import _TRACKERS, TrackerError

    if name in _TRACKERS.entries:
        return _spec(_TRACKERS.entries[name])
    (o,) = list(execute([Job(name, name, name)], spec_job, "isolated", 1))
    if o.failure is not None:
        raise TrackerError(o.failure.error if o.failure.error_type == "TrackerError"
                           else o.failure.line())
    return TrackerSpec(**o.records[0])


@dataclass(frozen=True)
class UnitInput:
    """What the worker of one unit receives (pickled): nothing that leads to the campaign."""

    tracker: TrackerSpec
    settings: dict         # Campaign.info(): the published settings
    unit: str
    inspections: list[Inspection]
    seed: np.random.SeedSequence


@dataclass(frozen=True)
class UnitSource:
    """The parent's side of a :class:`UnitInput`: pickling it reads the unit's inspections
    and sends the :class:`UnitInput` alone (the campaign is never pickled)."""

    campaign: Campaign
    tracker: TrackerSpec
    unit: str
    seed: np.random.SeedSequence

    def load(self) -> UnitInput:
        """The unit's :class:`UnitInput`: its inspections read from the campaign."""
        from .tracking import Inspection

        c = self.campaign
        inspections = [Inspection(unit=self.unit, index=rec.index, flight=rec.flight,
                                  traces=c.traces(rec),
                                  conditions=json.loads(json.dumps(rec.conditions)),
                                  thresholds=dict(c.thresholds),
                                  inspection_every=c.inspection_every)
                       for rec in c.units[self.unit]]
        return UnitInput(self.tracker, c.info(), self.unit, inspections, self.seed)

    def __reduce__(self) -> tuple:
        u = self.load()
        return UnitInput, (u.tracker, u.settings, u.unit, u.inspections, u.seed)


def unit_job(job: Any) -> list[dict]:
    """Track one unit (``job.data``: a :class:`UnitInput`) and return its lines: its steps,
    and its error line if the tracker failed."""
    from .tracking import run_unit

    inp: UnitInput = job.data
    rows, _ = run_unit(inp.tracker.info(), inp.settings, inp.unit, inp.inspections, inp.seed)
    return rows
