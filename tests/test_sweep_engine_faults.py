"""Fault injection on the five commands that run on the sweep engine (``leaderboard``,
``blind``, ``coverage``, ``campaign track``, ``targets``): a worker killed, the sweep's own
process killed, a full disk, a torn last line, a second process on the same folder.  After
each (and a rerun where the fault stopped the sweep) every task is recorded exactly once and
the records equal those of an uninterrupted run.

The sweeps are the tiny jobs of ``tests/sweep_jobs.py`` (4 tasks of about half a second);
the kills run it as a script, the rest in this process.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import sweep_jobs
from test_sweep_faults import _alive, _children, _cmdline

from ema_bench.diagnosis import blind
from ema_bench.suites import best_known
from ema_bench.sweep.store import Store

COMMANDS = ("leaderboard", "blind", "coverage", "track", "targets")
FILES = {"leaderboard": "runs.jsonl", "blind": "blind.jsonl", "coverage": "twin_laplace.jsonl",
         "track": "track.jsonl", "targets": "targets.json.partial.jsonl"}
#: Lines of a complete run: one per task, but one per inspection (4 units x 4) for tracking.
LINES = {"leaderboard": 4, "blind": 4, "coverage": 4, "track": 16, "targets": 4}
#: What may differ between runs of one task: timings, the numba threads of the process that
#: ran it (a run's manifest says how many; the results do not depend on it) and the checkout
#: its code was imported from (pytest run in a clone imports the clone's sources, the job
#: script an installed copy, which no commit vouches for).
VOLATILE = {"wall_s", "solver_wall_s", "cpu_s"}
PROCESS = {"threads", "git_commit", "git_dirty"}


def stable(record: dict) -> dict:
    out = {k: v for k, v in record.items() if k not in VOLATILE}
    if "manifest" in out:
        out["manifest"] = {k: v for k, v in out["manifest"].items() if k not in PROCESS}
    return out
JOB = [sys.executable, str(Path(__file__).with_name("sweep_jobs.py"))]

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")


@pytest.fixture(autouse=True)
def tiny_tasks(monkeypatch):
    """The jobs' cheap task bodies in this process too (the script sets them itself)."""
    monkeypatch.setattr(best_known, "STAGES", sweep_jobs.TINY_STAGES)
    monkeypatch.setattr(blind, "run_case", sweep_jobs.slow_perfect_case)


def run_here(command: str, out: Path) -> int:
    """The job in this process (serial)."""
    return sweep_jobs.run(command, out, 1)


def start(command: str, out: Path, workers: int) -> subprocess.Popen:
    return subprocess.Popen([*JOB, command, str(out), str(workers)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)


def records(command: str, out: Path) -> dict[str, dict]:
    """The records as written, by key, without timings; every line whole and each key once
    (no task recorded twice, no error line: no fault here is a task's own failure)."""
    data = (out / FILES[command]).read_bytes()
    assert data.endswith(b"\n"), "a partial last line"
    rows = [json.loads(line) for line in data.splitlines()]
    keys = [r["key"] for r in rows]
    assert len(keys) == len(set(keys)), f"recorded twice: {keys}"
    assert not [r for r in rows if r.get("status") == "error"]
    return {r["key"]: stable(r) for r in rows}


_REFERENCE: dict[str, dict[str, dict]] = {}
_REFERENCE_OUT: dict[str, Path] = {}


@pytest.fixture
def reference(tmp_path_factory):
    """The records of an uninterrupted serial run of a job (once per command)."""
    def get(command: str) -> dict[str, dict]:
        if command not in _REFERENCE:
            out = tmp_path_factory.mktemp(f"ref-{command}") / "out"
            assert run_here(command, out) == 0
            _REFERENCE[command] = records(command, out)
            _REFERENCE_OUT[command] = out
            assert len(_REFERENCE[command]) == LINES[command]
        return _REFERENCE[command]
    return get


def wait_for(pred, proc: subprocess.Popen, what: str, timeout: float = 300) -> None:
    deadline = time.time() + timeout
    while time.time() < deadline:
        if pred():
            return
        if proc.poll() is not None:
            pytest.fail(f"the sweep ended (rc {proc.returncode}) before {what}: "
                        f"{proc.stderr.read()[-2000:]}")
        time.sleep(0.02)
    pytest.fail(f"timed out waiting for {what}")


def first_line(command: str, out: Path):
    path = out / FILES[command]
    return lambda: path.exists() and path.stat().st_size > 0


def workers_of(proc: subprocess.Popen) -> list[int]:
    """The sweep's spawned workers (a scan of /proc: about 2 ms of CPU, so a wait checks the
    cheap condition, a first record, before it)."""
    return [k for k in _children(proc.pid) if "spawn_main" in _cmdline(k)]


# slow: starts worker processes (fast loop: the full-disk and torn-line faults, serial)
@pytest.mark.slow
@pytest.mark.parametrize("command", COMMANDS)
def test_a_killed_worker_is_replaced_and_its_task_run_again(tmp_path, command, reference):
    """SIGKILL one of two workers mid-sweep: the sweep goes on, runs the killed worker's task
    again, ends with rc 0 and no failure recorded."""
    out = tmp_path / "out"
    proc = start(command, out, 2)
    try:
        wait_for(lambda: first_line(command, out)() and len(workers_of(proc)) == 2, proc,
                 "two workers and a first record")
        victim = workers_of(proc)[0]
        os.kill(victim, signal.SIGKILL)
        _, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert records(command, out) == reference(command)


# slow: starts worker processes (fast loop: the full-disk and torn-line faults, serial)
@pytest.mark.slow
@pytest.mark.parametrize("command", COMMANDS)
def test_a_killed_sweep_leaves_no_worker_and_a_rerun_completes(tmp_path, command, reference):
    out = tmp_path / "out"
    proc = start(command, out, 2)
    try:
        wait_for(lambda: first_line(command, out)() and len(workers_of(proc)) == 2, proc,
                 "two workers and a first record")
        kids = _children(proc.pid)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    deadline = time.time() + 10
    while time.time() < deadline and any(map(_alive, kids)):
        time.sleep(0.05)
    orphans = [k for k in kids if _alive(k)]
    for k in orphans:
        os.kill(k, signal.SIGKILL)
    assert not orphans, f"processes left running after the sweep was killed: {orphans}"
    assert len(records(command, out)) < LINES[command]   # killed mid-sweep
    assert run_here(command, out) == 0
    assert records(command, out) == reference(command)


@pytest.mark.parametrize("command", COMMANDS)
def test_a_full_disk_stops_the_sweep_and_a_rerun_completes(tmp_path, command, reference,
                                                           monkeypatch):
    """The second append writes half its bytes, then the disk is full: the sweep stops (one
    line, rc 2, or the OSError), the half line is undone, no task is recorded as failed."""
    out = tmp_path / "out"
    real_write = Store._write
    writes = []

    def full_disk(self, data):
        writes.append(len(data))
        if len(writes) == 2:
            real_write(self, data[:len(data) // 2])
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real_write(self, data)

    monkeypatch.setattr(Store, "_write", full_disk)
    try:
        rc = run_here(command, out)
    except OSError as exc:
        assert exc.errno == errno.ENOSPC and FILES[command] in str(exc)
        rc = 2
    assert rc == 2
    first = records(command, out)
    assert 0 < len(first) < LINES[command]
    monkeypatch.setattr(Store, "_write", real_write)
    assert run_here(command, out) == 0
    assert records(command, out) == reference(command)


@pytest.mark.parametrize("command", COMMANDS)
def test_a_torn_last_line_is_cut_and_its_task_run_again(tmp_path, command, reference):
    want = reference(command)
    # a complete run's folder: a copy of the uninterrupted run's (with the track job's
    # campaign beside it), not the same job run again
    shutil.copytree(_REFERENCE_OUT[command].parent, tmp_path, dirs_exist_ok=True)
    out = tmp_path / "out"
    path = out / FILES[command]
    data = path.read_bytes()
    last = data.rstrip(b"\n").rfind(b"\n") + 1
    path.write_bytes(data[:last + (len(data) - last) // 2])   # killed mid-write
    assert run_here(command, out) == 0
    assert records(command, out) == want


# slow: starts worker processes (fast loop: the full-disk and torn-line faults, serial)
@pytest.mark.slow
@pytest.mark.parametrize("command", COMMANDS)
def test_two_processes_on_one_folder_run_each_task_once(tmp_path, command, reference):
    out = tmp_path / "out"
    if command == "track":   # the campaign is made once, not by both at once
        sweep_jobs.campaign(tmp_path / "campaign")
    procs = [start(command, out, 1) for _ in range(2)]
    errs = [p.communicate(timeout=180)[1] for p in procs]
    assert [p.returncode for p in procs] == [0, 0], errs
    assert records(command, out) == reference(command)


# slow: starts worker processes (fast loop: the full-disk and torn-line faults, serial)
@pytest.mark.slow
def test_a_tracker_that_kills_its_worker_gets_no_failure_line_and_no_pass(tmp_path):
    """A tracker whose worker dies on a unit (every time) is not recorded as failed there
    (that is for a tracker's own error): the unit is left untracked, named in one line
    (exit 2), and stays untracked on a rerun: the campaign's scoring counts a unit without
    a step at its cut as a miss, so killing a worker earns nothing."""
    out = tmp_path / "out"
    res = subprocess.run([*JOB, "track-exit", str(out), "2"], capture_output=True, text=True,
                         timeout=180)
    assert res.returncode == 2, res.stderr
    err = res.stderr.strip().splitlines()
    assert len(err) == 1 and "1 unit(s) not done (u001)" in err[0] and "rerun" in err[0]
    rows = [json.loads(line) for line in (out / "track.jsonl").read_text().splitlines()]
    assert sorted({r["unit"] for r in rows}) == ["u000", "u002", "u003"]
    assert len(rows) == 12 and not [r for r in rows if r.get("status") == "error"]


def test_no_pool_executor_or_jsonl_append_outside_the_engine():
    """Process pools, Dask clients and JSON-lines appends live in ``ema_bench/sweep/``
    alone: every other module runs its tasks through :func:`~ema_bench.sweep.loop.run_sweep`
    and writes records through :class:`~ema_bench.sweep.store.Store`."""
    import re

    import ema_bench

    root = Path(ema_bench.__file__).parent
    forbidden = re.compile(r"ProcessPoolExecutor|multiprocessing|\bPool\(|dask\.distributed|"
                           r"\bClient\(|open\([^)]*['\"]a['\"]|O_APPEND")
    found = [f"{p.relative_to(root)}:{i}: {line.strip()}"
             for p in sorted(root.rglob("*.py")) if "sweep" not in p.relative_to(root).parts
             for i, line in enumerate(p.read_text().splitlines(), 1) if forbidden.search(line)]
    assert found == []
    # and the consumers import nothing of the leaderboard (consumer-to-consumer arrows)
    for pkg in ("diagnosis", "prognostics", "uncertainty"):
        for p in sorted((root / pkg).rglob("*.py")):
            assert "leaderboard" not in "".join(
                line for line in p.read_text().splitlines()
                if line.lstrip().startswith(("from ", "import "))), p
