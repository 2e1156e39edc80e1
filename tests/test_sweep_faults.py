"""Fault injection for leaderboard sweeps: a solver that raises, a worker that dies, a killed
sweep, a full disk, a torn last line, two sweeps on one folder, unwritable output.  After
each, a rerun of the same sweep completes with every run recorded exactly once.

Sweeps are tiny (the ``random`` solver, one track, budgets of 30 to 400) so the file runs in
about a minute on two cores.
"""

from __future__ import annotations

import csv
import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from inprocess import CliRun, run_cli

from ema_bench.cli import main
from ema_bench.leaderboard.run import run_tasks
from ema_bench.leaderboard.run_store import read_records, run_identity
from ema_bench.leaderboard.tasks import failure_record, make_tasks, run_task
from ema_bench.sweep.executors import execute
from ema_bench.sweep.store import Store
from ema_bench.trace_cache import MODEL_VERSION

CLI = [sys.executable, "-m", "ema_bench.cli"]
TINY = ["--solvers", "random", "--cases", "small", "--tracks", "twin", "--seeds", "3",
        "--budget", "30", "--no-plots"]
VOLATILE = {"wall_s", "solver_wall_s"}


def cli(*args: str, cwd: Path | None = None) -> CliRun:
    """In this process (tests/inprocess.py); the kill tests spawn their own subprocesses."""
    return run_cli(*args, cwd=cwd)


def raw_records(path: Path) -> list[dict]:
    """Every line of a runs file as written (no de-duplication); each must be whole JSON."""
    data = path.read_bytes()
    assert data.endswith(b"\n"), "the file ends in a partial line"
    return [json.loads(line) for line in data.splitlines()]


def assert_each_run_once(path: Path, n: int) -> list[dict]:
    """``n`` runs, each with exactly one successful record and no error left standing."""
    ok = [r for r in raw_records(path) if r.get("status") != "error"]
    idents = [run_identity(r) for r in ok]
    assert len(idents) == len(set(idents)) == n, idents
    records = read_records(path)
    assert len(records) == n and all(r.get("status") != "error" for r in records)
    return records


def stable(records: list[dict]) -> dict[str, dict]:
    return {r["key"]: {k: v for k, v in r.items() if k not in VOLATILE} for r in records}


# --- runners injected into workers (module level: spawned workers import them by name) ---

def raises_on_seed_1(task):
    if task.seed == 1:
        raise ValueError(f"solver blew up on {task.key}")
    return run_task(task)


def exits_on_seed_1(task):
    if task.seed == 1:
        os._exit(3)   # the worker process dies without a word
    return run_task(task)


# --- a run that fails --------------------------------------------------------------------

@pytest.mark.parametrize("executor", ["serial",
                                      pytest.param("processes", marks=pytest.mark.slow),
                                      pytest.param("dask", marks=pytest.mark.slow)])
def test_a_run_that_raises_is_recorded_and_the_others_go_on(executor):
    if executor == "dask":
        pytest.importorskip("dask.distributed")
    tasks = make_tasks(["random"], ["small"], ["twin"], 3, 30)
    outcomes = list(execute(tasks, raises_on_seed_1, executor, workers=2))
    records = {o.task.seed: failure_record(o.task, o.failure) if o.failure else o.records[0]
               for o in outcomes}
    assert sorted(records) == [0, 1, 2]
    bad = records[1]
    assert bad["status"] == "error" and bad["error_type"] == "ValueError"
    assert "solver blew up on random|small|twin|1" in bad["error"]
    assert "ValueError" in bad["traceback"]
    assert run_identity(bad) == tasks[1].identity
    assert "success" not in bad and "evals_to_success" not in bad   # an error carries no score
    assert all("status" not in records[k] and records[k]["evaluations"] == 30 for k in (0, 2))


# slow: starts process pools or a dask cluster (fast loop: the serial executor's tests)
@pytest.mark.slow
def test_a_run_whose_worker_always_dies_is_scored_as_failed_and_a_rerun_completes(tmp_path):
    """A run that kills its worker process breaks the whole pool; the runs that were in
    flight with it run again one at a time and are recorded; the culprit is run again twice
    more (a worker killed from outside is not the run's doing), then recorded as a
    ``WorkerDied`` error: scored as a failure (a solver cannot drop its hard runs from the
    board by killing its worker) and run again by a resume."""
    out = tmp_path / "lb"
    tasks = make_tasks(["random"], ["small"], ["twin"], 3, 30)
    assert run_tasks(tasks, out, "processes", workers=2, quiet=True,
                     runner=exits_on_seed_1) == 3
    records = {r["seed"]: r for r in raw_records(out / "runs.jsonl")}
    assert sorted(records) == [0, 1, 2] and len(raw_records(out / "runs.jsonl")) == 3
    assert records[1]["status"] == "error" and records[1]["error_type"] == "WorkerDied"
    assert all("status" not in records[k] for k in (0, 2))
    res = cli("leaderboard", *TINY, "--executor", "serial", "--out", str(out), "--json")
    assert res.returncode == 0, res.stderr
    summary = json.loads(res.stdout)
    assert summary["ran"] == 1 and summary["errors"] == []
    assert_each_run_once(out / "runs.jsonl", 3)


FLAKY = {"broken": True}


def _flaky_solver(problem, budget, seed):
    from ema_bench.registry import finish

    if FLAKY["broken"]:
        raise RuntimeError("flaky solver exploded")
    t0 = time.perf_counter()
    problem.evaluate(problem.nominal[None, :])
    return finish(problem, "test-flaky", "done", t0)


def test_a_failing_solver_is_listed_scored_as_a_failure_and_retried(tmp_path, capsys,
                                                                    monkeypatch):
    from ema_bench.registry import register_solver

    register_solver("test-flaky", description="raises while FLAKY['broken']",
                    library="numpy")(_flaky_solver)
    monkeypatch.setitem(FLAKY, "broken", True)
    out = tmp_path / "lb"
    args = ["leaderboard", "--solvers", "random,test-flaky", "--cases", "small", "--tracks",
            "twin", "--seeds", "2", "--budget", "30", "--executor", "serial", "--no-plots",
            "--quiet", "--out", str(out)]
    assert main(args + ["--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["ran"] == 4 and summary["runs"] == 4
    assert sorted(e["key"] for e in summary["errors"]) == ["test-flaky|small|twin|0",
                                                           "test-flaky|small|twin|1"]
    assert {e["error_type"] for e in summary["errors"]} == {"RuntimeError"}
    table = (out / "leaderboard_twin.md").read_text()
    # ranked last: no target reached (ECDF area 0), every ERT infinite, 2 runs, 2 failed
    (row,) = [line for line in table.splitlines() if line.startswith("| 2 | test-flaky |")]
    assert row.startswith("| 2 | test-flaky | 0 [0, 0] | 0 | 0 | inf [inf, inf] |")
    assert row.endswith("| 2 | 2 |")
    assert "2 runs failed with an error" in table
    # the plain summary lists them too; nothing new to run but the failures (retried)
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "2 runs FAILED" in printed and "RuntimeError: flaky solver exploded" in printed
    monkeypatch.setitem(FLAKY, "broken", False)
    assert main(args + ["--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["ran"] == 2 and summary["errors"] == [] and summary["runs"] == 4
    assert_each_run_once(out / "runs.jsonl", 4)


def _rec(seed: int, first: int | None = None, budget: int = 1000, **extra) -> dict:
    faults = ("Na", "Fst", "BLK", "Gprop")
    return {"solver": "a", "case": "small", "track": "twin", "seed": seed, "budget": budget,
            "root_seed": 0, "model_version": MODEL_VERSION, "success": first is not None,
            "evals_to_success": first, "fitness": 1e-4, "wall_s": 1.0,
            "accuracy": dict.fromkeys(faults, 99.0),
            "range_error": dict.fromkeys(faults, 0.001), **extra}


def test_one_record_per_run_on_read(tmp_path):
    """Files written by two sweeps or merged by hand: the first success of a run counts;
    an error counts only while no success supersedes it (the newest error then)."""
    path = tmp_path / "runs.jsonl"
    err = {"status": "error", "error": "x", "error_type": "E"}
    lines = [_rec(0, 10), _rec(0, 20), _rec(1, **err), _rec(1, 30), _rec(1, **err),
             _rec(2, **err), _rec(2, **{**err, "error": "newer"}), _rec(0, 10, budget=5)]
    path.write_text("".join(json.dumps(r) + "\n" for r in lines))
    got = read_records(path)
    assert [(r["seed"], r["budget"], r.get("evals_to_success"), r.get("error")) for r in got] \
        == [(0, 1000, 10, None), (1, 1000, 30, None), (2, 1000, None, "newer"),
            (0, 5, 10, None)]


# --- killed sweeps, full disks, torn files ------------------------------------------------

def _children(pid: int) -> list[int]:
    """Live (not zombie) child processes of ``pid``, from /proc."""
    kids = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        state, ppid = stat[stat.rindex(")") + 2:].split()[:2]
        if int(ppid) == pid and state != "Z":
            kids.append(int(entry))
    return kids


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rindex(")") + 2] != "Z"


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return ""


# slow: kills a sweep and its process pool (fast loop: the torn-line repair and full-disk tests)
@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
def test_workers_exit_when_the_sweep_is_killed_and_a_rerun_completes(tmp_path):
    out = tmp_path / "lb"
    # 12 runs of about 0.4 s: still under way when both workers have started
    args = ["leaderboard", "--solvers", "random", "--cases", "small,full", "--tracks", "twin",
            "--seeds", "6", "--budget", "400", "--executor", "processes", "--workers", "2",
            "--no-plots", "--quiet", "--out", str(out)]
    proc = subprocess.Popen([*CLI, *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        deadline = time.time() + 60
        workers: list[int] = []
        while time.time() < deadline and proc.poll() is None:
            # the cheap check first: a scan of /proc costs about 2 ms of CPU
            if (out / "runs.jsonl").exists() and (out / "runs.jsonl").stat().st_size:
                workers = [k for k in _children(proc.pid) if "spawn_main" in _cmdline(k)]
                if len(workers) == 2:
                    break   # both workers started and runs are under way
            time.sleep(0.05)
        kids = _children(proc.pid)  # the workers and multiprocessing's resource tracker
        assert len(workers) == 2 and set(workers) <= set(kids), (workers, kids)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    deadline = time.time() + 5
    while time.time() < deadline and any(map(_alive, kids)):
        time.sleep(0.05)
    orphans = [k for k in kids if _alive(k)]
    for k in orphans:   # do not leave them running if the test fails
        os.kill(k, signal.SIGKILL)
    assert not orphans, f"processes left running after the sweep was killed: {orphans}"
    res = cli(*args[:-1], str(out), "--executor", "serial")
    assert res.returncode == 0, res.stderr
    assert_each_run_once(out / "runs.jsonl", 12)


def test_a_full_disk_stops_the_sweep_with_one_line_and_a_rerun_completes(
        tmp_path, capsys, monkeypatch):
    out = tmp_path / "lb"
    args = ["leaderboard", *TINY, "--executor", "serial", "--quiet", "--out", str(out)]
    real_write = Store._write
    writes = []

    def full_disk(self, data):
        writes.append(len(data))
        if len(writes) == 2:  # a short write, then the disk is full
            real_write(self, data[:len(data) // 2])
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real_write(self, data)

    monkeypatch.setattr(Store, "_write", full_disk)
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "No space left on device" in err[0] and "runs.jsonl" in err[0]
    assert len(raw_records(out / "runs.jsonl")) == 1   # whole lines only
    monkeypatch.undo()
    assert main(args) == 0
    assert_each_run_once(out / "runs.jsonl", 3)


@pytest.mark.parametrize("tail", ["torn", "torn-newline", "garbage-line"])
def test_a_broken_last_line_is_repaired_on_rerun(tmp_path, tail):
    out = tmp_path / "lb"
    args = ["leaderboard", *TINY, "--executor", "serial", "--quiet", "--out", str(out)]
    assert cli(*args).returncode == 0
    runs = out / "runs.jsonl"
    first, second = runs.read_bytes().splitlines(keepends=True)[:2]
    want = stable(read_records(runs))
    broken = {"torn": second[:len(second) // 2],              # killed mid-write
              "torn-newline": second[:len(second) // 2] + b"\n",
              "garbage-line": b"\0" * 64 + b"\n"}[tail]   # e.g. a crash's zero-filled block
    runs.write_bytes(first + broken)
    res = cli(*args)
    assert res.returncode == 0, res.stderr
    assert stable(assert_each_run_once(runs, 3)) == want


# slow: two sweeps in fresh interpreters racing for one folder
@pytest.mark.slow
def test_two_sweeps_on_one_folder_run_each_run_once(tmp_path):
    out = tmp_path / "lb"
    args = ["leaderboard", "--solvers", "random", "--cases", "small,full", "--tracks", "twin",
            "--seeds", "4", "--budget", "400", "--executor", "serial", "--no-plots",
            "--quiet", "--json", "--out", str(out)]
    procs = [subprocess.Popen([*CLI, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for _ in range(2)]
    results = [p.communicate(timeout=120) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [e for _, e in results]
    summaries = [json.loads(o) for o, _ in results]
    assert sum(s["ran"] for s in summaries) == 8        # the work was split, not repeated
    assert [s["runs"] for s in summaries] == [8, 8]     # each waited for the other's runs
    assert_each_run_once(out / "runs.jsonl", 8)
    with open(out / "leaderboard_twin.csv") as fh:   # each run counted once
        runs = {row["cases"]: int(row["runs"]) for row in csv.DictReader(fh)}
    assert runs == {"all": 8, "small": 4, "full": 4}


# --- output folder, defaults and progress -------------------------------------------------

@pytest.mark.parametrize("command", ["leaderboard", "blind"])
def test_an_output_folder_that_is_a_file_fails_before_any_work(tmp_path, command):
    target = tmp_path / "taken"
    target.write_text("not a folder")
    extra = TINY if command == "leaderboard" else ["--cases", "2"]
    t0 = time.perf_counter()
    res = cli(command, *extra, "--out", str(target))
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "--out" in lines[0] and "not a folder" in lines[0], lines
    assert time.perf_counter() - t0 < 20       # nothing was computed
    assert target.read_text() == "not a folder"


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_a_read_only_output_folder_fails_before_any_work(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        res = cli("leaderboard", *TINY, "--out", str(ro / "lb"))
    finally:
        ro.chmod(0o755)
    assert res.returncode == 2 and "--out" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_leaderboard_needs_an_output_folder(tmp_path):
    res = cli("leaderboard", *TINY, cwd=tmp_path)
    assert res.returncode == 2 and "--out DIR is required" in res.stderr
    assert list(tmp_path.iterdir()) == []      # the committed leaderboards/ is not a default


def test_progress_is_one_line_per_run_when_not_a_terminal(tmp_path):
    res = cli("leaderboard", *TINY, "--executor", "serial", "--out", str(tmp_path / "a"))
    assert res.returncode == 0, res.stderr
    lines = [s for s in res.stderr.splitlines() if "leaderboard (serial):" in s]
    assert [s.split("leaderboard (serial): ")[1].split(" run ")[0] for s in lines] \
        == ["1/3", "2/3", "3/3"]
    quiet = cli("leaderboard", *TINY, "--executor", "serial", "--quiet", "--out",
                str(tmp_path / "b"))
    assert quiet.returncode == 0 and quiet.stderr == ""


def _fake_case(case, seed, settings):
    """A blind case's record without the minute of diagnosis behind it: a diagnosis that
    names the hidden effects exactly, says none on null cases and unexplained on decoys."""
    from types import SimpleNamespace

    from ema_bench.diagnosis.blind import case_record, score

    found = [SimpleNamespace(name=k, params={k: v}, interval=[v, v], partial=False)
             for k, v in case.effects.items()] if case.kind == "effect" else []
    verdict = "effect" if found else "unexplained" if case.kind == "decoy" else "none"
    d = SimpleNamespace(verdict=verdict, effects=found, gap={"partial": None})
    return {**case_record(case, seed), "verdict": verdict, "named": [e.name for e in found],
            "partial": None, "gap_closed": 1.0 if found else 0.0, "gap_before": 1.0,
            "gap_after": 0.0 if found else 1.0, "message": "", "evaluations": 0,
            **score(case, d), "wall_s": 0.0}


def test_blind_writes_to_a_resumable_folder_by_default(tmp_path, monkeypatch, capsys):
    import ema_bench.diagnosis.blind as blind

    calls = []
    monkeypatch.setattr(blind, "run_case", lambda *a: calls.append(a) or _fake_case(*a))
    monkeypatch.chdir(tmp_path)
    assert main(["blind", "--cases", "4", "--seed", "5"]) == 0
    err = capsys.readouterr().err
    assert [s.split("blind: ")[1].split(" case ")[0] for s in err.splitlines()
            if "blind: " in s and " case " in s] == ["1/4", "2/4", "3/4", "4/4"]
    folder = tmp_path / "ema-bench-blind-seed5-n4"
    assert len(read_records(folder / "blind.jsonl")) == 4 and calls
    assert (folder / "summary.json").is_file()
    calls.clear()
    assert main(["blind", "--cases", "4", "--seed", "5", "--quiet"]) == 0
    assert calls == [] and capsys.readouterr().err == ""   # resumed: nothing run again
    # another suite in the same folder is refused, not mixed in
    assert main(["blind", "--cases", "4", "--seed", "6", "--out", str(folder), "-q"]) == 2
    assert "not the case drawn" in capsys.readouterr().err
