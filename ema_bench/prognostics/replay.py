"""Replay of tracking runs (``ema-bench campaign score --replay K``): re-track sampled units
with the registered tracker and compare every line.

``campaign score`` re-derives every figure from a run's steps and the campaign's truth, so
it cannot be handed a figure; but the steps themselves are the submitter's.  A
``track.jsonl`` whose RULs were written from the truth, or moved toward it, scores as
submitted, and one kept below the oracle looks plausible.  A tracker is deterministic given
its unit's seed (:func:`~ema_bench.prognostics.track_run.unit_seed`), so re-tracking a unit
from the campaign's traces gives its lines again: replay picks ``K`` of the tracked units
(a sample drawn from fresh entropy, its seed reported, or the ones named), tracks each from
its first inspection in a fresh worker process of its own (:mod:`.track_worker`, with the
run's seed scheme), exactly as ``campaign track`` did, and compares every field of every line
(numbers to :data:`REPLAY_RTOL`, the rest exactly).  A
forged line in a sampled unit is found; forging few units leaves them unsampled with a
probability the report states (replay more, or ``--replay-unit`` the suspicious ones).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from ..grandfather import accepted_track
from ..sampling import escape_chance, sample_indices, sample_seed
from ..seeding import SEED_SCHEMES
from ..sweep.executors import execute
from .campaign import load_campaign
from .track_io import campaign_path, read_track, regroup
from .track_run import tracker_spec, unit_job, unit_jobs
from .tracking import TrackerError

#: Relative agreement of a replayed number with the recorded one (the trackers are
#: deterministic; this leaves room for another CPU's floating-point rounding only, as the
#: solver replay of ``ema-bench validate`` does).
REPLAY_RTOL = 1e-6


class ReplayError(TrackerError):
    """A run whose replayed lines differ from its track file (one line: not judged)."""


@dataclass
class TrackReplay:
    """What a replay found: the ``units`` re-tracked and one line per disagreement."""

    run: str
    tracker: str
    units: list[str]
    tracked: int
    findings: list[str] = field(default_factory=list)
    seed: int | None = None   # of the sample (None: the units were named)

    @property
    def ok(self) -> bool:
        return not self.findings

    @property
    def escape_chance(self) -> float:
        """Chance that a run with one forged unit passes a sample of this size (drawn from
        fresh entropy: nobody knew beforehand which units it would hold)."""
        return escape_chance(self.tracked, len(self.units))

    def record(self) -> dict:
        """What was replayed, for a JSON output (``replay`` of a costed or scored run)."""
        return {"units": self.units, "tracked": self.tracked, "sample_seed": self.seed,
                "escape_chance": self.escape_chance}

    def summary(self) -> str:
        """One line: what was re-tracked (units, the sample's seed) and what was found."""
        return (f"{self.run}: {self.tracker}, {len(self.units)} of {self.tracked} units "
                f"re-tracked ({', '.join(self.units)}"
                + (f"; sample seed {self.seed}" if self.seed is not None else "") + "): "
                + ("every line agrees" if self.ok else f"{len(self.findings)} difference(s)")
                + (f"; a single forged unit escapes a sample this size with probability "
                   f"{self.escape_chance:.2f}" if self.ok and self.seed is not None else ""))


def _differences(got: object, want: object, where: str) -> list[str]:
    if isinstance(want, dict) and isinstance(got, dict):
        out = [f"{where}.{k}: {'missing' if k not in got else 'not recorded'}"
               for k in sorted(set(want) ^ set(got))]
        return out + [d for k in sorted(set(want) & set(got))
                      for d in _differences(got[k], want[k], f"{where}.{k}")]
    numbers = (int, float)
    if (isinstance(want, numbers) and isinstance(got, numbers) and not isinstance(want, bool)
            and not isinstance(got, bool)):
        same = (want == got or (math.isnan(want) and math.isnan(got))
                or math.isclose(got, want, rel_tol=REPLAY_RTOL))
    else:
        same = got == want
    return [] if same else [f"{where}: recorded {want!r}, replayed {got!r}"]


def replay_track(run: Path | str, k: int = 2, units: list[str] | None = None,
                 seed: int | None = None, workers: int = 1) -> TrackReplay:
    """Re-track ``k`` sampled units (or ``units``) of the tracking run in ``run`` and compare.

    Parameters
    ----------
    run : path
        A tracking run folder (``campaign track``): its manifest names the tracker, its root
        seed and the campaign, whose traces must be there.
    k : int
        Units sampled (without replacement, from the units the run tracked) with ``seed``.
    units : list of str, optional
        Replay these units instead of a sample.
    seed : int, optional
        Seed of the sample (default: fresh entropy, :func:`~ema_bench.sampling.sample_seed`;
        the report holds it, to repeat the check).
    workers : int
        Units re-tracked at once (each in a fresh worker process).

    Returns
    -------
    TrackReplay
        ``ok`` when every line of every replayed unit agrees.
    """
    log = read_track(run)
    m = log.manifest
    info = tracker_spec(m["tracker"])   # TrackerError naming the known ones; not imported here
    camp = load_campaign(campaign_path(run, m))
    order = list(camp.units)
    tracked = [u for u in order if u in log.steps or u in log.failed]
    if units is None:
        seed = sample_seed(seed)
        units = [tracked[i] for i in sample_indices(len(tracked), int(k), seed)]
    else:
        seed = None
    unknown = [u for u in units if u not in tracked]
    if unknown:
        raise TrackerError(f"{run}: no tracked unit {unknown[0]!r}; tracked: "
                           f"{', '.join(tracked[:5])}{', ...' if len(tracked) > 5 else ''}")
    report = TrackReplay(str(run), info.name, list(units), len(tracked), seed=seed)
    scheme = m.get("seed_scheme", 1)
    if type(scheme) is not int or scheme not in SEED_SCHEMES:
        report.findings.append(f"seed scheme {scheme!r}, expected one of {sorted(SEED_SCHEMES)}")
        return report
    if not accepted_track(run):
        report.findings.append("seed scheme 1 (the tracker's seed spawned from its run node, "
                               "which gives the node away) is accepted for the committed "
                               "campaign runs only: track again with this version "
                               "(seed_scheme 2)")
        return report
    if info.manifest_config != m.get("config", {}):
        report.findings.append(f"the run's tracker config {m.get('config')} is not the "
                               f"registered {info.name!r}'s {info.manifest_config}")
        return report
    jobs = unit_jobs(camp, info, list(units), int(m["seed"]), scheme)
    replayed = {}
    for o in execute(jobs, unit_job, "isolated", max(1, int(workers))):
        if o.failure is not None:   # a worker that died is a finding, not a crash
            report.findings.append(f"{o.task.key}: replay failed: {o.failure.line()}")
        else:
            replayed[o.task.key] = o.records
    for unit in (u for u in units if u in replayed):
        steps, failed = regroup(replayed[unit])
        want = {"steps": log.steps.get(unit, []), "failed": log.failed.get(unit)}
        got = {"steps": steps.get(unit, []), "failed": failed.get(unit)}
        if len(got["steps"]) != len(want["steps"]):
            report.findings.append(f"{unit}: {len(want['steps'])} steps recorded, "
                                   f"{len(got['steps'])} replayed")
            continue
        for i, (g, w) in enumerate(zip(got["steps"], want["steps"])):
            # fields added later (quantiles, the unconditioned profile): a run tracked before
            # its tracker gave them is compared on the fields it has
            g = {k: v for k, v in g.items() if k in w or k not in ("rul_quantiles",
                                                                    "profile_rul")}
            report.findings += _differences(g, w, f"{unit} inspection {w.get('index', i)}")
        report.findings += _differences(got["failed"], want["failed"], f"{unit} failure")
    return report



def verified_runs(runs: list[Path | str], k: int = 2, units: list[str] | None = None,
                  workers: int = 1, what: str = "costed") -> list[TrackReplay]:
    """Replay every run (:func:`replay_track`) before anything is judged on its lines, and
    refuse the first whose lines differ: what ``campaign policy`` and ``campaign sealed`` run
    before tuning, costing or scoring (one code path).

    Parameters
    ----------
    runs : list of path
        Tracking run folders.
    k : int
        Units sampled per run (at least 1).
    units : list of str, optional
        Replay these units of every run instead of a sample.
    workers : int
        Units re-tracked at once.
    what : str
        What the refusal says the run is not (``"costed"``, ``"scored or costed"``).

    Returns
    -------
    list of TrackReplay
        One per run, in order, every one ``ok``.

    Raises
    ------
    ReplayError
        One line naming the run, what was replayed and the first difference.
    """
    if units is None and int(k) < 1:
        raise ReplayError(f"replay at least 1 unit per run, not {k}")
    checked = []
    for run in runs:
        r = replay_track(run, k=k, units=units, workers=workers)
        if not r.ok:
            raise ReplayError(f"replay of {r.summary()}, first {r.findings[0]}: the track "
                              f"file is not what its tracker gives, not {what}")
        checked.append(r)
    return checked


def replayed_lines(checked: list[TrackReplay], before: str) -> list[str]:
    """The lines a table ends with: per run what was replayed ``before`` judging it."""
    return [f"Replayed before {before}: {r.summary()}." for r in checked]
