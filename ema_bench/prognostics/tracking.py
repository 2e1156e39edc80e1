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

:func:`track_campaign` runs a tracker over a campaign and writes ``OUT/track.jsonl`` (one line
per unit and inspection, appended as each finishes; rerunning resumes) and
``OUT/manifest.json``; :func:`read_track` reads it back.
"""

from __future__ import annotations

import functools
import importlib
import json
import logging
import math
import os
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..faults import FAULT_NAMES
from ..jsonio import plain, write_atomic
from ..plugins import PluginRegistry
from ..seeding import SEED_SCHEME, run_seed, solver_seed
from ..sweep.executors import Job
from ..sweep.schema import opt, req
from ..traces import Traces
from .track_worker import TrackerSpec, UnitInput, UnitSource

if TYPE_CHECKING:
    from ..problem import Problem
    from .campaign import Campaign

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


# --- records ---------------------------------------------------------------------------------

def _key(unit: str, index: int | str) -> str:
    return f"{unit}/{index:03d}" if isinstance(index, int) else f"{unit}/{index}"


def step_record(inspection: Inspection, step: TrackStep) -> dict:
    """The JSON line of a step: ``{"key", "unit", "index", "flight", **TrackStep}`` with
    infinite RULs as null and floats as plain floats."""
    d = asdict(step)
    for k in ("estimate", "low", "high"):
        d[k] = {n: float(d[k][n]) for n in FAULT_NAMES}
    for k in INFINITE_FIELDS:
        v = float(d[k])
        d[k] = v if math.isfinite(v) else None
    d["replace"] = bool(d["replace"])
    d["evaluations"] = int(d["evaluations"])
    d["flight"] = int(d["flight"])
    d["extra"] = plain(d["extra"], default=str)
    if d["rul_quantiles"]:   # infinite quantiles as null; absent when not given
        from .distributions import check_quantiles
        d["rul_quantiles"] = {k: (v if math.isfinite(v) else None)
                              for k, v in check_quantiles(d["rul_quantiles"]).items()}
    else:
        del d["rul_quantiles"]
    if d["profile_rul"] is None:   # not given: not written
        del d["profile_rul"]
    else:
        d["profile_rul"] = float(d["profile_rul"]) if math.isfinite(d["profile_rul"]) else None
    return {"key": _key(inspection.unit, inspection.index), "unit": inspection.unit,
            "index": inspection.index, **d}


def error_record(unit: str, index: int, flight: int, exc: BaseException) -> dict:
    """The line of a unit whose tracker raised or answered nonsense at inspection ``index``."""
    return {"key": _key(unit, "error"), "unit": unit, "index": index, "flight": flight,
            "status": "error", "error": f"{type(exc).__name__}: {exc}"}


def _restore(record: dict) -> dict:
    """A step line as the tracker answered it: null RULs back to ``inf``."""
    r = dict(record)
    for k in INFINITE_FIELDS:
        if r.get(k, 0) is None:
            r[k] = math.inf
    if "profile_rul" in r and r["profile_rul"] is None:
        r["profile_rul"] = math.inf
    if r.get("rul_quantiles"):
        r["rul_quantiles"] = {q: math.inf if v is None else v
                              for q, v in r["rul_quantiles"].items()}
    return r


#: The fields of a step line, by JSON type (a hand-edited ``"replace": "no"`` is refused,
#: not read as true).
STEP_SCHEMA = {"key": req("str"), "unit": req("str"), "index": req("int"),
               "flight": req("int"), "estimate": req("dict", values="number|null"),
               "low": req("dict", values="number|null"),
               "high": req("dict", values="number|null"), "rul": req("number|null"),
               "rul_low": req("number|null"), "rul_high": req("number|null"),
               "failing_fault": req("str|null"),
               "replace": req("bool"), "evaluations": req("int"), "extra": opt("dict"),
               "rul_quantiles": opt("dict", values="number|null"),
               "profile_rul": opt("number|null")}
#: The fields of the error line of a unit whose tracker failed.
ERROR_SCHEMA = {"key": req("str"), "unit": req("str"), "index": req("int"),
                "flight": req("int"), "status": req("str"), "error": req("str")}


def _schema(record: dict) -> dict:
    return ERROR_SCHEMA if record.get("status") == "error" else STEP_SCHEMA


@dataclass
class TrackLog:
    """A tracking run read back (:func:`read_track`).

    ``steps``: unit -> its step records in inspection order (RULs ``inf`` where the file says
    null); ``failed``: unit -> its error record
    (its steps before the failure stay in ``steps``); ``manifest``: the run's manifest."""

    steps: dict[str, list[dict]]
    failed: dict[str, dict]
    manifest: dict


def read_track(out: Path | str) -> TrackLog:
    """Read ``OUT/track.jsonl`` and ``OUT/manifest.json`` of :func:`track_campaign` (every
    line type-checked: :data:`STEP_SCHEMA`)."""
    from ..sweep.store import read_records

    out = Path(out)
    mpath = out / MANIFEST_FILE
    if not mpath.is_file():
        raise TrackerError(f"{out}: not a tracking run (no {MANIFEST_FILE}; run "
                           "'ema-bench campaign track' first)")
    manifest = json.loads(mpath.read_text(encoding="utf-8"))
    if manifest.get("format") != FORMAT:
        raise TrackerError(f"{mpath}: not a tracking run's manifest (format "
                           f"{manifest.get('format')!r}, expected {FORMAT!r})")
    steps, failed = regroup(read_records(out / TRACK_FILE, schema=_schema))
    return TrackLog(steps, failed, manifest)


def campaign_path(out: Path | str, manifest: Mapping) -> Path:
    """The campaign folder of the tracking run in ``out`` (its manifest stores it relative to
    ``out``)."""
    return Path(out) / manifest["campaign"]


def regroup(records: list[dict]) -> tuple[dict[str, list[dict]], dict[str, dict]]:
    """Step lines by unit (inspection order, null RULs back to ``inf``) and error lines by
    unit, as :class:`TrackLog` holds them."""
    steps: dict[str, dict[int, dict]] = {}
    failed: dict[str, dict] = {}
    for r in records:
        if r.get("status") == "error":
            failed[r["unit"]] = r
        else:
            steps.setdefault(r["unit"], {})[int(r["index"])] = _restore(r)
    out = {unit: [by_index[i] for i in sorted(by_index)] for unit, by_index in steps.items()}
    return out, failed


def _unit_done(campaign: Campaign):
    """record -> the unit it completes (a failure, or the step of its last inspection), or
    ``None``: a unit tracked part of the way (by a run before steps were written unit by
    unit) is tracked again."""
    last = {u: len(rows) - 1 for u, rows in campaign.units.items()}

    def task_of(record: dict) -> str | None:
        unit = record["unit"]
        if record.get("status") == "error" or record["index"] == last.get(unit):
            return unit
        return None
    return task_of


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

def _unit_inputs(campaign: Campaign, unit: str) -> tuple[dict, list[Inspection]]:
    """The published settings and the unit's inspections (traces read): what its worker
    gets, read in the process that holds the campaign."""
    return campaign.info(), [
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
                                 functools.partial(_unit_inputs, campaign, u)))
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
    with Store(out / TRACK_FILE, task_of=_unit_done(camp), schema=_schema,
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
