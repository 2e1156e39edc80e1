"""Where tasks execute: in this process, in local worker processes, or on a Dask cluster.

Every executor pulls tasks from the iterable it is given only when a worker is free (so the
caller can claim each task just before it starts, see :mod:`.claims`) and hands each task's
:class:`Outcome` back to this process, which alone writes the store, in completion order.  A
task that raises yields an outcome with its :class:`Failure`; one whose worker process dies
(or a Dask worker lost) yields a failure marked ``infrastructure``: not the task's doing, so
:func:`~ema_bench.sweep.loop.run_sweep` never records it as the task's result.  One failing
task never stops the others.  Records do not depend on the executor (each task carries its
own seeds; numba threads never mix candidates), only their timings do.

A task is any picklable object with a ``key`` (a label, str) and an ``identity`` (hashable);
a runner is a picklable callable (a module-level function or a ``functools.partial`` of
one) taking a task and returning its record or a list of records.

Worker processes started here exit when this process dies, SIGKILL included
(:func:`_exit_with_parent`); the workers of an existing Dask cluster (``--scheduler``) are
the cluster's, not ours, and are left alone.

The ``isolated`` executor (one task per fresh process, for submitted code: replay) spawns each
worker, or, given ``preload`` (names of trusted modules: the package's own, never a plugin),
forks each one from a server that imported them once (multiprocessing's ``forkserver``): a
fork is a fresh process holding nothing of another task, and it skips the interpreter's start,
the imports and numba's loading of cached kernels that a spawned worker pays per task.  The
server is stopped (and reaped: its CPU and its children's count as this process's children's)
when the run ends.
"""

from __future__ import annotations

import functools
import hashlib
import itertools
import os
import signal
import sys
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Hashable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

EXECUTORS = ("serial", "processes", "dask")

#: How often a worker checks that its parent is alive (where the kernel cannot tell it).
WATCH_S = 0.5
_PR_SET_PDEATHSIG = 1

Task = Any
Runner = Callable[[Any], "dict | list[dict]"]


@dataclass(frozen=True)
class Job:
    """A task for commands that need no class of their own: a label, the identity its
    records complete (:class:`~.store.Store`'s ``task_of``) and what the runner needs."""

    key: str
    identity: Hashable
    data: Any = None


class WorkerDied(RuntimeError):
    """The worker process running a task died (killed, out of memory, ``os._exit``)."""


@dataclass(frozen=True)
class Failure:
    """Why a task gave no records: the exception's type, message and traceback (formatted in
    the worker, where the frames are), the seconds it ran, and whether the cause lies outside
    the task (its worker died): such a failure is retried, not recorded as the task's own
    (:func:`~ema_bench.sweep.loop.run_sweep` says what happens when it recurs)."""

    error_type: str
    error: str
    traceback: str = ""
    wall_s: float = 0.0
    infrastructure: bool = False

    @classmethod
    def of(cls, exc: BaseException, wall_s: float = 0.0, infrastructure: bool = False
           ) -> Failure:
        return cls(type(exc).__name__, str(exc) or repr(exc),
                   "".join(traceback.format_exception(exc))[-4000:], wall_s, infrastructure)

    def line(self) -> str:
        return f"{self.error_type}: {self.error}"


@dataclass
class Outcome:
    """A finished task: its records, or the :class:`Failure` that stopped it."""

    task: Task
    records: list[dict] = field(default_factory=list)
    failure: Failure | None = None


def run_guarded(runner: Runner, task: Task) -> Outcome:
    """``runner(task)`` as an :class:`Outcome`: its records, or the failure it raised (caught
    in the worker, where the traceback is)."""
    t0 = time.perf_counter()
    try:
        out = runner(task)
    except Exception as exc:
        return Outcome(task, failure=Failure.of(exc, time.perf_counter() - t0))
    return Outcome(task, [out] if isinstance(out, dict) else list(out))


def _died(task: Task) -> Outcome:
    return Outcome(task, failure=Failure.of(WorkerDied(
        "the worker process running this task died (killed, out of memory or os._exit)"),
        infrastructure=True))


def _exit_with_parent(parent_pid: int) -> None:
    """Make this worker process exit as soon as ``parent_pid`` is no longer its parent.

    On Linux the kernel kills it with its parent (``PR_SET_PDEATHSIG``; it acts even while
    numba holds the GIL; the "parent" is the thread that started the worker, which lives as
    long as the pool); everywhere, a daemon thread polls ``os.getppid()``."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
        except (OSError, AttributeError):  # pragma: no cover - exotic libc
            pass
    if os.getppid() != parent_pid:  # the parent died before the line above
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(WATCH_S)
        os._exit(1)

    threading.Thread(target=watch, name="ema-bench-parent-watch", daemon=True).start()


def worker_init(parent_pid: int | None = None) -> None:
    """Set up a worker process: one numba thread (the processes are the parallelism) and,
    given the pid of the process that started it, exit with that process.  The initializer of
    the package's only process pool (:func:`execute`)."""
    import numba

    numba.set_num_threads(1)
    if parent_pid is not None:
        _exit_with_parent(parent_pid)


def _forked_worker_init() -> None:
    """:func:`worker_init` of a worker forked from the fork server: it exits with the server,
    its parent, which exits when the process that started it does."""
    worker_init(os.getppid())


def _serial(tasks: Iterator[Task], workers: int, scheduler: str | None, runner: Runner
            ) -> Iterator[Outcome]:
    for t in tasks:
        yield run_guarded(runner, t)


def _processes(tasks: Iterator[Task], workers: int, scheduler: str | None, runner: Runner,
               fresh: bool = False, preload: tuple[str, ...] = ()) -> Iterator[Outcome]:
    """A process pool that survives a worker's death: the pool is started again, the tasks
    that were in flight run again one at a time, and the one whose worker dies alone comes
    back as an infrastructure failure (so a task that kills its worker does not take its
    neighbours with it).  ``fresh``: every task in a new process (no memory crosses tasks:
    the ``isolated`` executor of replay, which runs submitted code), forked from a server that
    imported ``preload`` when given."""
    from concurrent.futures import FIRST_COMPLETED, wait

    pool = _Pool(workers, fresh, preload)
    suspects: deque[Task] = deque()   # in flight when a worker died: rerun one at a time
    waiting: deque[Task] = deque()    # taken from ``tasks`` but not started (pool broke)
    running: dict = {}
    try:
        while True:
            limit = 1 if suspects else workers
            broken = False
            while len(running) < limit and not broken:
                queue = suspects or waiting   # the one to put ``t`` back into
                t = queue.popleft() if queue else next(tasks, None)
                if t is None:
                    break
                fut = pool.submit(runner, t)
                if fut is None:   # a worker died since the last look
                    queue.appendleft(t)
                    broken = True
                else:
                    running[fut] = t
            if not running and not broken:
                return
            done = wait(running, return_when=FIRST_COMPLETED)[0] if running else set()
            if broken or any(_Pool.is_broken(f) for f in done):
                done = wait(running)[0]   # every future of a broken pool fails now
            lost = []
            for fut in done:
                t = running.pop(fut)
                if _Pool.is_broken(fut):
                    lost.append(t)
                else:
                    exc = fut.exception()   # the runner or its result could not be pickled
                    yield Outcome(t, failure=Failure.of(exc)) if exc is not None \
                        else fut.result()
            if lost or broken:
                pool.restart()
            if len(lost) == 1:
                yield _died(lost[0])
            else:
                suspects.extend(lost)
    finally:
        pool.shutdown()


class _Pool:
    """A process pool started again after a worker's death (which breaks it for good)."""

    def __init__(self, workers: int, fresh: bool = False, preload: tuple[str, ...] = ()
                 ) -> None:
        self.workers, self.fresh, self.preload = workers, fresh, preload
        self.pool = self._start()

    def _start(self):
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        if self.preload:
            # forked from a server that imported the preload only: it never started numba's
            # threads (which do not survive a fork), each worker starts its own
            ctx = mp.get_context("forkserver")
            ctx.set_forkserver_preload(list(self.preload))
            return ProcessPoolExecutor(max_workers=self.workers, mp_context=ctx,
                                       initializer=_forked_worker_init,
                                       max_tasks_per_child=1 if self.fresh else None)
        # "spawn": numba's threading layers and fork do not mix well
        return ProcessPoolExecutor(max_workers=self.workers, mp_context=mp.get_context("spawn"),
                                   initializer=worker_init, initargs=(os.getpid(),),
                                   max_tasks_per_child=1 if self.fresh else None)

    def submit(self, runner: Runner, task: Task):
        """The future of ``task``, or ``None`` when the pool is broken."""
        from concurrent.futures.process import BrokenProcessPool

        try:
            return self.pool.submit(run_guarded, runner, task)
        except BrokenProcessPool:
            return None

    @staticmethod
    def is_broken(fut) -> bool:
        from concurrent.futures.process import BrokenProcessPool

        return isinstance(fut.exception(), BrokenProcessPool)

    def restart(self) -> None:
        self.pool.shutdown(wait=True)
        self.pool = self._start()

    def shutdown(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)
        if self.preload:
            _stop_fork_server()


def _stop_fork_server() -> None:
    """Stop multiprocessing's fork server and reap it (a later run starts a fresh one, with
    its own preload)."""
    from multiprocessing import forkserver

    # private, but the one way to stop it (CPython's own tests use it); 3.11 to 3.13
    stop = getattr(forkserver._forkserver, "_stop", None)
    if stop is not None:
        stop()


def _dask(tasks: Iterator[Task], workers: int, scheduler: str | None, runner: Runner
          ) -> Iterator[Outcome]:
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise RuntimeError("the dask executor needs 'pip install ema-bench[dask]'") from exc
    cluster = None
    if scheduler:
        client = Client(scheduler)
    else:
        # its worker processes are children of this process (the nannies run here)
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None)
        client = Client(cluster)
    try:
        if cluster is None:
            client.run(worker_init)   # a shared cluster: set up its workers, leave no hook
        else:   # our cluster: every worker, also one the nanny restarts, exits with us
            client.register_worker_callbacks(functools.partial(worker_init, os.getpid()))
        slots = workers if cluster is not None else max(1, sum(client.nthreads().values()))
        # a task whose worker dies is rescheduled by the scheduler (up to its
        # allowed-failures, 3 by default), then fails with KilledWorker: not the task's doing
        futures = as_completed()
        running: dict[str, Task] = {}
        for t in itertools.islice(tasks, slots):
            _dask_submit(client, futures, running, runner, t)
        for fut in futures:
            t = running.pop(fut.key)
            try:
                rec = fut.result()
            except Exception as exc:   # KilledWorker, or a runner that could not be sent
                rec = Outcome(t, failure=Failure.of(
                    exc, infrastructure=type(exc).__name__ == "KilledWorker"))
            fut.release()
            yield rec
            if (t := next(tasks, None)) is not None:
                _dask_submit(client, futures, running, runner, t)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


_SUBMITTED = itertools.count()


def _dask_submit(client, futures, running: dict, runner: Runner, t: Task) -> None:
    # a key unique to this submission: a retried task must not meet its old future's key
    digest = hashlib.sha1(repr(t.identity).encode()).hexdigest()[:12]
    fut = client.submit(run_guarded, runner, t, key=f"ema-{digest}-{os.getpid()}-"
                        f"{next(_SUBMITTED)}", pure=False)
    running[fut.key] = t
    futures.add(fut)


_RUNNERS: dict[str, Callable[[Iterator[Task], int, str | None, Runner],
                              Iterator[Outcome]]] = {
    "serial": _serial, "processes": _processes, "dask": _dask,
    # one task per fresh process, for code that must not share memory across tasks (replay);
    # not a sweep's choice (EXECUTORS)
    "isolated": functools.partial(_processes, fresh=True),
}


def execute(tasks: Iterable[Task], runner: Runner, executor: str = "processes",
            workers: int | None = None, scheduler: str | None = None,
            preload: Iterable[str] = ()) -> Iterator[Outcome]:
    """Run ``tasks`` (each through ``runner``) and yield their :class:`Outcome` as they
    finish.

    ``tasks`` is read lazily, one task per free worker; nothing starts (no pool, no cluster)
    when it is empty.  ``preload`` (the ``isolated`` executor's only): modules the fork server
    imports once, of which each worker is a fork; trusted code only (the package's own)."""
    if executor not in _RUNNERS:
        raise ValueError(f"unknown executor {executor!r}; known: {list(EXECUTORS)}")
    run = _RUNNERS[executor]
    if preload := tuple(preload):
        if executor != "isolated":
            raise ValueError(f"preload is the isolated executor's, not {executor!r}'s")
        run = functools.partial(run, preload=preload)
    workers = workers or os.cpu_count() or 1
    feed = iter(tasks)
    first = next(feed, None)
    if first is None:
        return
    yield from run(itertools.chain([first], feed), workers, scheduler, runner)
