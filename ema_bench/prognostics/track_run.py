"""Running a tracker over a campaign: one worker process per unit (:mod:`.track_worker`),
lines appended as units finish, a rerun resumes (:func:`track_campaign`).  The tracker API is
:mod:`.tracking`, the files :mod:`.track_io`."""

from __future__ import annotations

import functools
import importlib
import json
import logging
import os
import time
from collections.abc import Mapping
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..jsonio import write_atomic
from ..seeding import SEED_SCHEME, run_seed, solver_seed
from ..sweep.executors import Job
from .track_worker import TrackerSpec, UnitInput, UnitSource

if TYPE_CHECKING:
    from .campaign import Campaign

from .track_io import error_record, line_schema, step_record, unit_done
from .tracking import (
    _TRACKERS,
    FORMAT,
    MANIFEST_FILE,
    TRACK_FILE,
    VERSION,
    Inspection,
    TrackerError,
    TrackerInfo,
    check_step,
    get_tracker,
    register_tracker,
)

log = logging.getLogger("ema_bench")


# --- running a tracker over a campaign -------------------------------------------------------

def unit_seed(seed: int, k: int, scheme: int = SEED_SCHEME) -> np.random.SeedSequence:
    """The tracker's seed for the ``k``-th unit of the manifest: the solver seed
    (:func:`~ema_bench.seeding.solver_seed`, a one-way hash in ``scheme`` 2) of run node
    ``(seed, k)`` (a tracker is that unit's solver), as the campaign's unit ``k`` is run
    ``k`` of its own root seed.  Scheme 1 (the spawned stream) replays the committed runs."""
    return solver_seed(run_seed(seed, k), scheme)


def _manifest(campaign: Campaign, info: TrackerSpec, seed: int, out: Path) -> dict:
    from ..registry import library_versions
    from ..trace_cache import MODEL_VERSION
    from ..version import __version__

    return {"format": FORMAT, "version": VERSION, "tracker": info.name,
            "description": info.description, "config": info.manifest_config,
            "seed": seed, "seed_scheme": SEED_SCHEME,
            # relative to the run folder: the two move together (a committed leaderboard)
            "campaign": os.path.relpath(Path(campaign.root).resolve(), Path(out).resolve()),
            "campaign_name": campaign.name, "track": campaign.track, "split": campaign.split,
            "campaign_seed": campaign.seed, "model_version": MODEL_VERSION,
            "package_version": __version__, "versions": library_versions("scipy", "cma")}


_SAME_RUN = ("format", "tracker", "config", "seed", "seed_scheme", "campaign", "campaign_name",
             "track", "split", "campaign_seed")


def _prepare(out: Path, manifest: dict) -> None:
    """Create ``out`` with its manifest, or check that the run already there is this one."""
    out.mkdir(parents=True, exist_ok=True)
    mpath = out / MANIFEST_FILE
    if mpath.exists():
        try:
            old = json.loads(mpath.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError):
            raise TrackerError(f"{mpath}: broken manifest; give another output folder") from None
        diff = [k for k in _SAME_RUN if old.get(k) != manifest.get(k)]
        if diff:
            raise TrackerError(
                f"{out}: holds another tracking run (tracker {old.get('tracker')!r}, seed "
                f"{old.get('seed')!r}, campaign {old.get('campaign')!r}; differs in {diff}); "
                "give another output folder")
        return
    if (out / TRACK_FILE).exists():
        raise TrackerError(f"{out}: has a {TRACK_FILE} but no {MANIFEST_FILE}; give another "
                           "output folder")
    # two runs starting on one folder both write it: each through a file of its own
    write_atomic(mpath, json.dumps(manifest, indent=1) + "\n")


def run_unit(info: TrackerInfo, settings: Mapping, unit: str, inspections: list[Inspection],
             seed: np.random.SeedSequence) -> tuple[list[dict], str]:
    """Track one unit from its first inspection (in the unit's worker process,
    :mod:`.track_worker`): its lines and ``"replaced"`` (a replacement was called at some
    inspection; the unit is still tracked to its cut), ``"tracked"`` or ``"failed"``.  A
    tracker that raises, or answers something :func:`check_step` refuses, is recorded as an
    error line: the unit has failed, the run goes on."""
    rows: list[dict] = []
    index, flight = 0, inspections[0].flight if inspections else 0
    replaced = False
    try:
        step_fn = info.start(settings, seed)
        for insp in inspections:
            index, flight = insp.index, insp.flight
            step = check_step(step_fn(insp), insp)
            rows.append(step_record(insp, step))
            replaced = replaced or step.replace
    except Exception as exc:  # one unit's failure must not stop the fleet
        rows.append(error_record(unit, index, flight, exc))
        return rows, "failed"
    return rows, "replaced" if replaced else "tracked"


# --- one unit in a worker process of its own (:mod:`.track_worker`) ----------------------------

def unit_inputs(campaign: Campaign, unit: str, scheme: int = SEED_SCHEME
                ) -> tuple[dict, list[Inspection]]:
    """The published settings and the unit's inspections (traces read): what its worker
    gets, read in the process that holds the campaign.  A run of another seed ``scheme`` (the
    committed scheme-1 runs, replayed) adds ``seed_scheme`` to the settings: the baselines'
    fits seeded their solver runs by it, and give their lines again only so."""
    info = campaign.info()
    if scheme != SEED_SCHEME:
        info["seed_scheme"] = int(scheme)
    return info, [
        Inspection(unit=unit, index=rec.index, flight=rec.flight, traces=campaign.traces(rec),
                   conditions=json.loads(json.dumps(rec.conditions)),
                   thresholds=dict(campaign.thresholds),
                   inspection_every=campaign.inspection_every)
        for rec in campaign.units[unit]]


def unit_jobs(campaign: Campaign, spec: TrackerSpec, units: list[str], seed: int,
              scheme: int = SEED_SCHEME) -> list[Job]:
    """One job per unit of ``units`` for :func:`unit_job`: its inputs read from ``campaign``
    only when sent to its worker, its seed :func:`unit_seed` ``(seed, k)`` (``k``: the unit's
    place in the manifest)."""
    order = list(campaign.units)
    return [Job(u, u, UnitSource(spec, u, unit_seed(seed, order.index(u), scheme),
                                 functools.partial(unit_inputs, campaign, u, scheme)))
            for u in units]


def _spec(info: TrackerInfo) -> TrackerSpec:
    return TrackerSpec(info.name, info.factory.__module__, info.factory.__qualname__,
                       info.description, dict(info.config))


def registered(spec: TrackerSpec) -> TrackerInfo:
    """The tracker of ``spec`` (in a worker): its module imported by name, else its factory
    registered again under its name and configuration (a variant registered in a function)."""
    if spec.name not in _TRACKERS.entries:
        try:
            factory = functools.reduce(getattr, spec.factory.split("."),
                                       importlib.import_module(spec.module))
        except (ImportError, AttributeError):
            factory = None   # an entry point's tracker: get_tracker finds it
        if spec.name not in _TRACKERS.entries and callable(factory):
            register_tracker(spec.name, description=spec.description, **spec.config)(factory)
    return get_tracker(spec.name)


def unit_job(job: Job) -> list[dict]:
    """Track one unit in a worker process (``job.data``: a
    :class:`~.track_worker.UnitInput`): its lines, and its error line if the tracker failed."""
    inp: UnitInput = job.data
    return run_unit(registered(inp.tracker), inp.settings, inp.unit, inp.inspections,
                    inp.seed)[0]


def spec_job(job: Job) -> dict:
    """The :class:`~.track_worker.TrackerSpec` of tracker ``job.data``, as a dict (in a
    worker: its plugin is imported there)."""
    return asdict(_spec(get_tracker(job.data)))


def tracker_spec(name: str) -> TrackerSpec:
    """The tracker ``name``: from this process's registry when something here registered it
    already (a script's or a test's own tracker), else looked up in a worker process, so that
    an entry point's plugin is never imported beside the campaign.  TrackerError (one line)
    for an unknown or broken tracker."""
    from ..sweep.executors import execute

    if name in _TRACKERS.entries:
        return _spec(_TRACKERS.entries[name])
    (o,) = list(execute([Job(name, name, name)], spec_job, "isolated", 1))
    if o.failure is not None:
        raise TrackerError(o.failure.error if o.failure.error_type == "TrackerError"
                           else o.failure.line())
    return TrackerSpec(**o.records[0])


def track_campaign(campaign: Campaign | Path | str, tracker: str, out: Path | str,
                   seed: int = 0, workers: int = 1, quiet: bool = True) -> Path:
    """Run ``tracker`` over every unit of ``campaign`` and write ``out``.

    Parameters
    ----------
    campaign : Campaign or path
        A campaign (:func:`~ema_bench.prognostics.campaign.load_campaign` reads a path).
    tracker : str
        A registered tracker (:func:`available_trackers`).
    out : path
        Output folder: ``track.jsonl`` (one line per unit and inspection, ``{"key", "unit",
        "index", "flight", **TrackStep}``, written as each step finishes; RULs that are
        infinite are null) and ``manifest.json`` (tracker, seed, campaign, versions).
    seed : int
        Root seed: unit ``k`` of the manifest gets :func:`unit_seed` ``(seed, k)``.
    workers : int
        Worker processes (units tracked at once); the tracker never runs in this process.
    quiet : bool
        No progress bar or lines.

    Notes
    -----
    Runs on the sweep engine (:func:`~ema_bench.sweep.loop.run_sweep`): a unit's lines are
    appended in one piece when it is tracked to its end, so a killed run, a dead worker or a
    full disk leaves whole units only, never a failure that is not the tracker's; a rerun
    (or a second process on the same folder) tracks exactly the units missing.  Units
    already complete (every inspection tracked, or a failure recorded) are skipped; a unit
    tracked part of the way is tracked again from its first inspection (a tracker's state is
    not saved), and its lines already written are not written twice.  A unit is tracked to
    its last inspection (the cut) even after a step with ``replace`` (the first is its
    maintenance decision).  A unit whose tracker failed is not retried; delete its lines to
    retry it.
    """
    from ..sweep.loop import run_sweep
    from ..sweep.store import Store
    from .campaign import load_campaign
    info = tracker_spec(tracker)   # its plugin is not imported here
    if isinstance(seed, bool) or int(seed) != seed or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    if isinstance(workers, bool) or int(workers) != workers or workers < 1:
        raise ValueError(f"workers must be a positive integer, got {workers!r}")
    camp = campaign if not isinstance(campaign, str | Path) else load_campaign(campaign)
    out = Path(out)
    _prepare(out, _manifest(camp, info, int(seed), out))
    tasks = unit_jobs(camp, info, list(camp.units), int(seed))
    t0 = time.perf_counter()
    with Store(out / TRACK_FILE, task_of=unit_done(camp), schema=line_schema,
               retry_errors=False) as store:
        # the tracker never runs here: in worker processes, each unit's inputs sent alone
        # (replay re-tracks a unit in a fresh process: state carried across units shows)
        report = run_sweep(tasks, unit_job, [store], executor="processes",
                           workers=int(workers), label=f"track {tracker}", unit="unit",
                           quiet=quiet, describe=functools.partial(_status, info.name))
    log.debug("tracked %d unit(s) in %.1f s", report.ran, time.perf_counter() - t0)
    return out


def _status(tracker: str, outcome) -> str:
    """A unit's progress line: its name and how its tracking ended (a failure logged)."""
    recs = outcome.records
    for r in recs:
        if r.get("status") == "error":
            log.warning("tracker %s failed on unit %s at inspection %d (flight %d): %s",
                        tracker, r["unit"], r["index"], r["flight"], r["error"])
    status = ("failed" if any(r.get("status") == "error" for r in recs) else
              "replaced" if any(r.get("replace") for r in recs) else "tracked")
    return f"{outcome.task.key} {status}"
