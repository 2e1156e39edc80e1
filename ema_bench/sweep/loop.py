"""The one sweep loop: skip what is recorded, claim, execute, append each task's records as
it finishes, retry what failed for reasons outside the task.

Every long-running command (``leaderboard``, ``blind``, ``coverage``, ``campaign track``,
``targets``) is a list of tasks run through :func:`run_sweep`, so each survives the same
faults the same way:

- a task recorded in the stores is skipped (a rerun completes exactly what is missing);
- each task is claimed (:mod:`.claims`) just before it starts: a task another process
  claimed is left to it, and waited for at the end (run here after all if its claimer dies
  first), so sweeps sharing a folder split the work and run nothing twice;
- a task's records are appended, in one piece, as it finishes (:class:`~.store.Store`);
- a task whose worker died is run again here (up to ``retries`` times), never recorded as
  the task's own result, like a full disk (the store's ``OSError``) or an interrupt; a task
  whose worker dies every time is most likely killing it itself: recorded through
  ``on_error`` where the command scores failures (so a solver cannot drop its hard runs
  from a board by killing its worker; a resume runs it again), else left unrecorded and
  named by :class:`SweepIncomplete`;
- a task that raised is the task's own failure: recorded through ``on_error`` where the
  command scores failures (the leaderboard), else reported by :class:`TaskFailed` after the
  other tasks have finished and been recorded.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Hashable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from ..progress import Progress, progress
from .claims import Claim, holder, try_claim
from .executors import Failure, Outcome, Runner, Task, execute
from .store import Store

log = logging.getLogger("ema_bench")

#: How many times a task whose worker died is run again in the same sweep.
RETRIES = 2


class SweepError(RuntimeError):
    """A sweep that ended without every task recorded: one line for the user."""


class SweepIncomplete(SweepError):
    """Some tasks could not run for reasons outside them (their worker kept dying); a rerun
    of the same command runs them again."""


class TaskFailed(SweepError):
    """A task raised (its traceback is logged); the other tasks were run and recorded."""


@dataclass
class SweepReport:
    """What :func:`run_sweep` did: ``ran`` tasks executed here, their ``records`` in
    completion order, and the tasks ``lost`` (their worker kept dying)."""

    ran: int = 0
    records: list[dict] = field(default_factory=list)
    lost: list[Task] = field(default_factory=list)
    failed: list[tuple[Task, Failure]] = field(default_factory=list)


def _route_first(record: dict) -> int:
    return 0


@dataclass
class _Sweep:
    stores: Sequence[Store]
    folder: Path | None
    route: Callable[[dict], int]
    on_error: Callable[[Task, Failure], dict] | None
    describe: Callable[[Outcome], str]
    bar: Progress | None
    report: SweepReport

    def claim_id(self, task: Task) -> tuple:
        """What the claim of ``task`` is taken on: the first store's file name and the task
        (two sweeps of other files in one folder never wait for each other)."""
        return self.stores[0].path.name, task.identity

    def pending(self, task: Task) -> bool:
        return not self.stores or any(task.identity not in s.done for s in self.stores)

    def settled(self, task: Task) -> bool:
        return bool(self.stores) and all(s.settled(task.identity) for s in self.stores)

    def refresh(self) -> None:
        for s in self.stores:
            s.refresh()

    def record(self, outcome: Outcome) -> None:
        """Append a finished task's records, one piece per store."""
        records = outcome.records
        if outcome.failure is not None:
            records = [self.on_error(outcome.task, outcome.failure)]
        groups: dict[int, list[dict]] = {}
        for r in records if self.stores else ():   # without stores: the report alone
            groups.setdefault(self.route(r), []).append(r)
        for i, group in groups.items():
            self.stores[i].append(group)
        self.report.records.extend(records)


def run_sweep(tasks: Sequence[Task], runner: Runner, stores: Sequence[Store] = (), *,
              executor: str = "serial", workers: int | None = 1,
              scheduler: str | None = None, route: Callable[[dict], int] = _route_first,
              on_error: Callable[[Task, Failure], dict] | None = None,
              describe: Callable[[Outcome], str] | None = None, label: str = "sweep",
              unit: str = "task", quiet: bool = True, retries: int = RETRIES,
              poll_s: float = 0.5) -> SweepReport:
    """Run the ``tasks`` not yet recorded in ``stores``, appending each one's records as it
    finishes.

    Parameters
    ----------
    tasks : sequence
        Picklable objects with a ``key`` (str) and an ``identity`` (hashable: the value the
        stores' ``task_of`` gives for the task's records).
    runner : callable
        task -> its record or list of records (picklable for ``processes`` and ``dask``).
    stores : sequence of Store
        Where the records go (``route(record)`` picks the store; default the first).  A task
        is done when every store has it.  Claims live beside the first store.  Without
        stores every task runs and the records come back in the report alone.
    executor, workers, scheduler
        :func:`~.executors.execute`.
    on_error : callable, optional
        (task, failure) -> the error record of a task that raised; without it such tasks
        raise :class:`TaskFailed` once the others are done.
    describe : callable, optional
        outcome -> the progress line of a finished task (default its key).
    label, unit, quiet
        The progress bar (:func:`~ema_bench.progress.progress`).
    retries : int
        Times a task whose worker died is run again before it is given up (recorded through
        ``on_error``, or named by :class:`SweepIncomplete`).

    Returns
    -------
    SweepReport
    """
    folder = stores[0].path.parent if stores else None
    report = SweepReport()
    sweep = _Sweep(stores, folder, route, on_error, describe or (lambda o: o.task.key),
                   None, report)
    pending = [t for t in tasks if sweep.pending(t)]
    with progress(len(pending), label, unit, quiet=quiet) as sweep.bar:
        tries: dict[Hashable, int] = {}
        while pending:
            elsewhere: list[Task] = []
            again = _run_claimed(pending, sweep, elsewhere, executor, workers, scheduler,
                                 runner)
            retry = []
            for t, failure in again:
                tries[t.identity] = tries.get(t.identity, 0) + 1
                if tries[t.identity] <= retries:
                    retry.append(t)
                elif on_error is not None:   # scored as a failure, run again by a resume
                    sweep.record(Outcome(t, failure=failure))
                    report.ran += 1
                    sweep.bar.update(f"{t.key} FAILED ({failure.error_type})")
                else:
                    report.lost.append(t)
            pending = retry + _wait_for_others(elsewhere, sweep, poll_s)
    if report.failed:
        for task, failure in report.failed:
            log.warning("%s %s failed: %s\n%s", unit, task.key, failure.line(),
                        failure.traceback)
        task, failure = report.failed[0]
        raise TaskFailed(f"{len(report.failed)} {unit}(s) failed ({task.key}: "
                         f"{failure.line()}); the others are recorded")
    if report.lost:
        raise SweepIncomplete(
            f"{len(report.lost)} {unit}(s) not done ({', '.join(t.key for t in report.lost[:3])}"
            f"{', ...' if len(report.lost) > 3 else ''}): their worker process died "
            f"{retries + 1} times; rerun the same command to run them again")
    return report


def _run_claimed(tasks: list[Task], sweep: _Sweep, elsewhere: list[Task], executor: str,
                 workers: int | None, scheduler: str | None, runner: Runner
                 ) -> list[tuple[Task, Failure]]:
    """Run the ``tasks`` this process can claim, recording what they give; returns those
    whose worker died (to run again), with their failure."""
    claims: dict[Hashable, Claim] = {}
    again: list[tuple[Task, Failure]] = []
    try:
        feed = _claimed(tasks, sweep, claims, elsewhere)
        for outcome in execute(feed, runner, executor, workers, scheduler):
            task, failure = outcome.task, outcome.failure
            if failure is not None and failure.infrastructure:
                again.append((task, failure))
                sweep.bar.note(f"{task.key}: {failure.line()}; it will run again")
            elif failure is not None and sweep.on_error is None:
                sweep.report.failed.append((task, failure))
            else:
                sweep.record(outcome)
                sweep.report.ran += 1
            claim = claims.pop(task.identity, None)
            if claim is not None:
                claim.release()
            if failure is None or not failure.infrastructure:
                sweep.bar.update(sweep.describe(outcome) + (
                    f" FAILED ({failure.error_type})" if failure is not None else ""))
    finally:
        for claim in claims.values():
            claim.release()
    return again


def _claimed(tasks: list[Task], sweep: _Sweep, claims: dict[Hashable, Claim],
             elsewhere: list[Task]) -> Iterator[Task]:
    """The tasks this process claims, as the executor asks for them; those another process
    holds go to ``elsewhere``, those recorded meanwhile are dropped."""
    for t in tasks:
        if sweep.folder is None:
            yield t
            continue
        claim = try_claim(sweep.folder, sweep.claim_id(t), t.key)
        if claim is None:
            elsewhere.append(t)
            continue
        claims[t.identity] = claim   # from now on the caller releases it, come what may
        sweep.refresh()   # another sweep may have recorded it since we listed the work
        if sweep.settled(t):
            claims.pop(t.identity).release()
            sweep.bar.update(f"{t.key} (run by another process)")
            continue
        yield t


def _wait_for_others(tasks: list[Task], sweep: _Sweep, poll_s: float) -> list[Task]:
    """Wait until some of ``tasks`` (claimed by other processes) are released; return those
    still unrecorded (their claimer died: run them here).  Holds no claim while waiting, so
    two sweeps never wait for each other."""
    noted = False
    while tasks:
        sweep.refresh()
        for t in tasks:
            if sweep.settled(t):
                sweep.bar.update(f"{t.key} (run by another process)")
        tasks = [t for t in tasks if not sweep.settled(t)]
        if any(_is_free(sweep, t) for t in tasks):
            return tasks
        if tasks and not noted:
            who = sorted({holder(sweep.folder, sweep.claim_id(t)) for t in tasks} - {""})
            sweep.bar.note(f"waiting for {len(tasks)} tasks claimed by another process "
                           f"({', '.join(who) or 'unknown'})")
            noted = True
        if tasks:
            time.sleep(poll_s)
    return tasks


def _is_free(sweep: _Sweep, task: Task) -> bool:
    claim = try_claim(sweep.folder, sweep.claim_id(task), task.key)
    if claim is None:
        return False
    claim.release()
    return True
