"""What a tracker's worker process receives: one unit's inputs, and nothing that leads to the
campaign.

``ema-bench campaign track`` sends each unit to a worker process (the sweep engine's
``processes`` executor, ``--workers`` of them, as a leaderboard sweep runs solvers) and
``campaign score --replay`` each replayed unit to a fresh one (``isolated``: one unit per
process, as replay runs solvers, so a tracker that carries state from one unit to the next
does not replay); the worker runs :func:`~.track_run.unit_job`.  The worker receives a
:class:`UnitInput`: the tracker (:class:`TrackerSpec`), the campaign's published settings
(:meth:`~.campaign.Campaign.info`: no folder, no seed), the unit's inspections with their
traces already read, and the unit's one-way seed (:func:`~.track_run.unit_seed`, which gives
neither the tracking run's root seed nor the campaign's away); never the
:class:`~.campaign.Campaign`, its folder or the campaign's seed.  The inspections are read in
the process that holds the campaign, when the unit is sent (:class:`UnitSource`), one unit
in flight per worker.  That process imports no tracker plugin either (its import could
patch the harness there): what it needs of the tracker comes from a worker too
(:func:`~.tracking.tracker_spec`).  This module imports nothing of the run loop.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np


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


@dataclass(frozen=True)
class UnitInput:
    """What the worker of one unit receives (pickled): nothing that leads to the campaign."""

    tracker: TrackerSpec
    settings: dict         # Campaign.info(): the published settings
    unit: str
    inspections: list[Any]  # the unit's Inspection objects, traces read
    seed: np.random.SeedSequence


@dataclass(frozen=True)
class UnitSource:
    """The parent's side of a :class:`UnitInput`: pickling it calls ``read`` (in the process
    that holds the campaign: the settings and the unit's inspections) and sends the
    :class:`UnitInput` alone; ``read`` and the campaign it holds are never pickled."""

    tracker: TrackerSpec
    unit: str
    seed: np.random.SeedSequence
    read: Callable[[], tuple[dict, list[Any]]]

    def __reduce__(self) -> tuple:
        settings, inspections = self.read()
        return UnitInput, (self.tracker, settings, self.unit, inspections, self.seed)
