"""pytest plugin: CPU seconds of every test phase, the test process's and its waited-for
children's (user + sys), where ``--durations`` gives wall time only (a test that spawns a
worker pool or a CLI subprocess spends its CPU outside the test process).

Usage, from the checkout::

    PYTHONPATH=benchmarks .venv/bin/python -m pytest -q -p pytest_cpu [tests ...]

It prints the total and the 15 costliest phases and writes every row, ``[cpu_s, wall_s,
phase, node id]``, to ``$PYTEST_CPU_OUT`` (default ``pytest_cpu.json``).  Run it serially
(not under ``-n``): the children of a parallel worker are not this process's.
"""

from __future__ import annotations

import json
import os
import resource
import time

import pytest

_ROWS: list[tuple[float, float, str, str]] = []


def _cpu() -> float:
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(
        resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def _timed(phase: str):
    @pytest.hookimpl(hookwrapper=True)
    def hook(item):
        cpu, wall = _cpu(), time.perf_counter()
        yield
        _ROWS.append((_cpu() - cpu, time.perf_counter() - wall, phase, item.nodeid))
    return hook


pytest_runtest_setup = _timed("setup")
pytest_runtest_call = _timed("call")
pytest_runtest_teardown = _timed("teardown")


def pytest_terminal_summary(terminalreporter) -> None:
    tr = terminalreporter
    tr.write_sep("=", f"CPU seconds: {sum(r[0] for r in _ROWS):.1f} in test phases, "
                      f"{_cpu():.1f} for the whole process")
    for cpu, wall, phase, node in sorted(_ROWS, reverse=True)[:15]:
        tr.write_line(f"{cpu:8.1f} CPU-s {wall:8.1f} s  {phase:<8} {node}")
    with open(os.environ.get("PYTEST_CPU_OUT", "pytest_cpu.json"), "w") as fh:
        json.dump(_ROWS, fh)
