"""Replay's workers are forks of a server that preloaded the package and its kernels (issue
48: replay in workers at the CPU of replay in one process), and stay what replay needs: a
fresh process per record, no plugin in the server, no memory from one record to the next.
Real worker processes, the real red-team plugin."""

from __future__ import annotations

import importlib
import os
import sys
from pathlib import Path

import pytest

from ema_bench.leaderboard.replay import SERVER_PRELOAD, replay
from ema_bench.leaderboard.tasks import Task, run_task
from ema_bench.sweep.executors import Job, execute

PLUGIN = Path(__file__).resolve().parent / "redteam"
#: modules of plugins (the zoo's, the red team's) and of the zoo's own libraries
_PLUGINS = ("ema_bench_solvers", "ema_bench_trackers", "ema_bench_redteam", "nevergrad", "cma")


@pytest.fixture
def redteam(monkeypatch):
    """The red-team plugin installed (its folder on sys.path: worker processes inherit it)."""
    monkeypatch.syspath_prepend(str(PLUGIN))


def probe(job: Job) -> dict:
    """What a worker holds when its task starts (the plugin modules, the server's modules,
    the monitor kernels loaded), then what it loads running the monitor on 12 candidates
    (a group of 8 lanes, 4 in the scalar kernel); then it imports the red-team plugin and
    leaves a mark in its module global."""
    import numba
    import numpy as np

    from ema_bench.faults import NOMINAL
    from ema_bench.monitor import monitor_batch_parallel, monitor_batch_serial, simulate_monitor
    from ema_bench.monitor_lanes import lanes_parallel, lanes_serial

    held = {"pid": os.getpid(), "ppid": os.getppid(),
            "plugins": sorted(m for m in sys.modules if m.split(".")[0] in _PLUGINS),
            "server": SERVER_PRELOAD[0] in sys.modules,
            "serial": [len(monitor_batch_serial.signatures), len(lanes_serial.signatures)]}
    simulate_monitor(np.tile(NOMINAL, (12, 1)))
    held["parallel"] = len(monitor_batch_parallel.signatures) + len(lanes_parallel.signatures)
    held["threads"] = numba.get_num_threads()
    plugin = importlib.import_module("ema_bench_redteam")
    held["marks"] = len(plugin._EARLIER_RUNS)
    plugin._EARLIER_RUNS.append(job.key)
    return held


def test_each_worker_is_a_fork_of_a_server_that_holds_the_kernels_and_no_plugin(redteam):
    importlib.import_module("ema_bench_redteam")   # the verdict's process holds a plugin
    out = [o.records[0] for o in execute([Job("a", "a"), Job("b", "b")], probe, "isolated", 1,
                                         preload=SERVER_PRELOAD)]
    assert len(out) == 2 and out[0]["pid"] != out[1]["pid"]
    for held in out:
        # a fork of the server (not a child of this process, not of another record's worker)
        # that imported the package and loaded its serial kernels, and no plugin
        assert held["ppid"] != os.getpid() and held["ppid"] not in (o["pid"] for o in out)
        assert held["plugins"] == [] and held["server"] and min(held["serial"]) >= 1
        # one numba thread: the serial kernels only, none loaded in the worker
        assert held["threads"] == 1 and held["parallel"] == 0
        assert held["marks"] == 0    # the plugin the first record imported is gone
    with pytest.raises(ProcessLookupError):   # the server is stopped with the run
        os.kill(out[0]["ppid"], 0)


def test_a_plugin_remembering_earlier_runs_is_caught_by_replay(redteam):
    """Two runs of a solver that keeps its earlier runs' results in a module global: the
    second run differs (two evaluations).  Each record replays in a fresh process, so the
    second one is not reproduced."""
    first = run_task(Task("rt-remembers", "s00", "twin", 0, 2))
    second = run_task(Task("rt-remembers", "s00", "twin", 1, 2))
    assert (first["evaluations"], second["evaluations"]) == (1, 2)   # the memory is real
    ok, caught = replay([first, second], None, 0, workers=1)
    assert ok.finding is None
    assert caught.finding == "evaluations: recorded 2, replayed 1"


def test_only_the_isolated_executor_takes_a_preload():
    with pytest.raises(ValueError, match="preload is the isolated executor's"):
        next(execute([Job("a", "a")], probe, "processes", 1, preload=SERVER_PRELOAD))


def test_the_monitor_runs_on_numba_threads_only_when_it_has_several():
    """On one thread (a worker) the serial kernels, whatever the batch; on several, the
    parallel ones from one unit of work per thread."""
    import numba

    from ema_bench.monitor import _parallel

    threads = numba.get_num_threads()
    assert _parallel(10**6) is (threads > 1)
    assert not _parallel(threads - 1)


def test_the_server_loads_the_serial_scalar_kernel_and_the_lanes_and_no_parallel_one(
        monkeypatch):
    """What the server runs before it forks (:func:`~ema_bench.leaderboard.replay_server.warm`):
    the nominal faults once through the scalar kernel and once through a full group of lanes,
    both serial (a parallel kernel would start numba's threads, whose state no fork keeps),
    and they succeed (an exception would stop the server's import, hence every replay)."""
    import numpy as np

    from ema_bench.faults import NOMINAL
    from ema_bench.leaderboard import replay_server
    from ema_bench.monitor_lanes import LANES

    calls = []
    real = replay_server.simulate_monitor

    def spy(X, *args, **kw):
        calls.append((np.array(X), args, kw))
        return real(X, *args, **kw)

    monkeypatch.setattr(replay_server, "simulate_monitor", spy)
    assert replay_server.warm() is None
    assert [(x.shape, a, k) for x, a, k in calls] == [
        ((1, len(NOMINAL)), (), {"parallel": False, "lanes": False}),
        ((LANES, len(NOMINAL)), (), {"parallel": False, "lanes": True})]
    for x, _, _ in calls:
        assert (x == np.asarray(NOMINAL, float)).all()
