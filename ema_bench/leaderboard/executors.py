"""Where runs execute: in this process, in local worker processes, or on a Dask cluster.

Every executor hands finished records back to this process, which alone writes the store, in
completion order.  Records do not depend on the executor (each task carries its own seeds;
numba threads never mix candidates), only ``wall_s`` does.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterable, Iterator

from tqdm import tqdm

from .tasks import Task, run_task

EXECUTORS = ("serial", "processes", "dask")


def _worker_init() -> None:
    # one numba thread per worker process: the processes are the parallelism
    import numba

    numba.set_num_threads(1)


Runner = Callable[[Task], dict]


def _serial(tasks: list[Task], workers: int, scheduler: str | None, runner: Runner
            ) -> Iterator[dict]:
    for t in tasks:
        yield runner(t)


def _processes(tasks: list[Task], workers: int, scheduler: str | None, runner: Runner
               ) -> Iterator[dict]:
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed

    # "spawn": numba's threading layers and fork do not mix well
    ctx = mp.get_context("spawn")
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx,
                             initializer=_worker_init) as pool:
        futures = [pool.submit(runner, t) for t in tasks]
        try:
            for fut in as_completed(futures):
                yield fut.result()
        finally:
            for fut in futures:
                fut.cancel()


def _dask(tasks: list[Task], workers: int, scheduler: str | None, runner: Runner
          ) -> Iterator[dict]:
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise RuntimeError("the dask executor needs 'pip install ema-bench[dask]'") from exc
    cluster = None
    if scheduler:
        client = Client(scheduler)
    else:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None)
        client = Client(cluster)
    try:
        client.run(_worker_init)
        # a task whose worker dies is rescheduled by the scheduler (up to its
        # allowed-failures, 3 by default); retries re-run a task that raised
        futures = [client.submit(runner, t, key=f"ema-{t.key}-{t.root_seed}-{t.budget}",
                                 pure=False, retries=3) for t in tasks]
        for fut in as_completed(futures):
            yield fut.result()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


_RUNNERS: dict[str, Callable[[list[Task], int, str | None, Runner], Iterator[dict]]] = {
    "serial": _serial, "processes": _processes, "dask": _dask,
}


def execute(tasks: list[Task], executor: str = "processes", workers: int | None = None,
            scheduler: str | None = None, progress: bool = True, runner: Runner = run_task
            ) -> Iterable[dict]:
    """Run ``tasks`` (each through ``runner``, :func:`run_task` unless a test injects a
    fault) and yield their records as they finish."""
    if executor not in _RUNNERS:
        raise ValueError(f"unknown executor {executor!r}; known: {list(EXECUTORS)}")
    workers = workers or os.cpu_count() or 1
    if not tasks:
        return
    bar = tqdm(total=len(tasks), desc=f"leaderboard ({executor})", unit="run",
               disable=not progress or not sys.stderr.isatty(), file=sys.stderr)
    try:
        for rec in _RUNNERS[executor](tasks, workers, scheduler, runner):
            bar.update(1)
            bar.set_postfix_str(rec["key"], refresh=False)
            yield rec
    finally:
        bar.close()
