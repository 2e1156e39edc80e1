"""The sweep engine's loop and store on their own (in this process, milliseconds each): what
is skipped, what is recorded, what is raised."""

from __future__ import annotations

import errno
import json
import os

import pytest

from ema_bench.sweep.executors import Job
from ema_bench.sweep.loop import TaskFailed, run_sweep
from ema_bench.sweep.store import Store, read_records

CALLS: list[str] = []


def square(job: Job) -> dict:
    CALLS.append(job.key)
    if job.data == "boom":
        raise ValueError(f"cannot square {job.key}")
    return {"key": job.key, "value": job.identity ** 2}


def jobs(*items) -> list[Job]:
    return [Job(f"j{i}", i, item) for i, item in enumerate(items)]


def test_without_stores_every_task_runs_and_the_records_come_back():
    CALLS.clear()
    report = run_sweep(jobs(None, None, None), square)
    assert sorted(r["value"] for r in report.records) == [0, 1, 4]
    assert report.ran == 3 and CALLS == ["j0", "j1", "j2"]


def test_a_task_that_raises_stops_nothing_and_is_named_in_one_line(tmp_path):
    """Without ``on_error`` (blind, coverage, targets) a raising task is not recorded: the
    others are, then one line names it; a rerun runs it alone."""
    path = tmp_path / "r.jsonl"
    CALLS.clear()
    with Store(path, task_of=lambda r: int(r["key"][1:])) as store, \
            pytest.raises(TaskFailed, match=r"^1 task\(s\) failed \(j1: ValueError: "
                                            r"cannot square j1\); the others are recorded$"):
        run_sweep(jobs(None, "boom", None), square, [store])
    assert sorted(r["key"] for r in read_records(path)) == ["j0", "j2"]
    CALLS.clear()
    with Store(path, task_of=lambda r: int(r["key"][1:])) as store:
        report = run_sweep(jobs(None, None, None), square, [store])
    assert CALLS == ["j1"] and report.ran == 1
    assert [r["value"] for r in read_records(path)] == [0, 4, 1]


def test_with_on_error_a_failure_is_recorded_and_a_resume_runs_it_again(tmp_path):
    path = tmp_path / "r.jsonl"

    def error(job, failure):
        return {"key": job.key, "status": "error", "error": failure.line()}

    task_of = lambda r: int(r["key"][1:])   # noqa: E731
    with Store(path, task_of=task_of) as store:
        assert run_sweep(jobs(None, "boom"), square, [store], on_error=error).ran == 2
    assert read_records(path)[1]["error"] == "ValueError: cannot square j1"
    CALLS.clear()
    with Store(path, task_of=task_of) as store:   # errors are retried by default
        run_sweep(jobs(None, None), square, [store], on_error=error)
    assert CALLS == ["j1"] and read_records(path)[1] == {"key": "j1", "value": 1}
    CALLS.clear()
    with Store(path, task_of=task_of, retry_errors=False) as store:
        store.append({"key": "j2", "status": "error", "error": "final"})
        run_sweep(jobs(None, None, None), square, [store], on_error=error)
    assert CALLS == []   # a failure that is the task's result (a tracker's) is done


def test_a_tasks_records_are_written_in_one_piece_or_not_at_all(tmp_path, monkeypatch):
    path = tmp_path / "r.jsonl"
    store = Store(path)
    store.append([{"key": "a"}, {"key": "b"}])
    before = path.read_bytes()
    real = Store._write

    def short_then_full(self, data):
        real(self, data[:5])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(Store, "_write", short_then_full)
    with pytest.raises(OSError, match="No space left on device"):
        store.append([{"key": "c"}, {"key": "d"}])
    assert path.read_bytes() == before
    monkeypatch.undo()
    assert store.append([{"key": "a"}, {"key": "c"}]) == 1   # "a" is there already
    store.close()
    assert [json.loads(s)["key"] for s in path.read_text().splitlines()] == ["a", "b", "c"]


def test_routed_records_go_to_their_store_and_a_task_is_done_when_all_have_it(tmp_path):
    """Coverage's shape: one task, one record per method, one file per method."""
    def both(job: Job) -> list[dict]:
        CALLS.append(job.key)
        return [{"key": job.key, "m": m} for m in ("a", "b")]

    stores = [Store(tmp_path / f"{m}.jsonl", task_of=lambda r: r["key"]) for m in "ab"]
    route = lambda r: "ab".index(r["m"])   # noqa: E731
    tasks = [Job(k, k) for k in ("x", "y")]
    stores[1].append({"key": "x", "m": "b"})        # b has x: x must still run for a
    CALLS.clear()
    run_sweep(tasks, both, stores, route=route)
    assert CALLS == ["x", "y"]
    for s in stores:
        s.close()
    for m in "ab":
        rows = [json.loads(s) for s in (tmp_path / f"{m}.jsonl").read_text().splitlines()]
        assert sorted(r["key"] for r in rows) == ["x", "y"] and {r["m"] for r in rows} == {m}


def test_coverage_in_memory_keeps_each_settings_records_apart():
    """Two settings of one method (a noise-scale study) without files: each gets its own
    records (one dict for both gave the first settings the second's records)."""
    from ema_bench.uncertainty.coverage import Settings, run_methods

    one, two = run_methods([Settings(budget=60), Settings(budget=60, noise_scale=2.0)], 1,
                           [None, None], quiet=True)
    assert one[0]["settings"]["noise_scale"] == 1.0
    assert two[0]["settings"]["noise_scale"] == 2.0
