"""The in-process CLI fixture (tests/inprocess.py) answers as the console script does: the
CLI tests that use it instead of a subprocess check what a user sees."""

from __future__ import annotations

import logging
import os
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from ema_bench.cli import CLIError


def _script() -> list[str]:
    exe = shutil.which("ema-bench", path=str(Path(sys.executable).parent))
    return [exe] if exe else [sys.executable, "-m", "ema_bench.cli"]


@pytest.mark.parametrize("argv", [
    ["params", "--json"],                     # success, JSON on stdout
    ["simulate", "--no-such-option"],         # argparse: usage on stderr, exit code 2
    ["params", "--help"],                     # argparse: help on stdout, exit code 0
    ["diagnose", "no-such-file.csv"],         # a user error: one line, exit code 2
])
def test_gives_what_the_console_script_gives(cli, argv, tmp_path):
    real = subprocess.run([*_script(), *argv], capture_output=True, text=True, cwd=tmp_path,
                          timeout=120)
    here = cli(*argv, cwd=tmp_path)
    assert (here.returncode, here.stdout, here.stderr) == (real.returncode, real.stdout,
                                                           real.stderr)
    assert real.returncode == {"--json": 0, "--no-such-option": 2, "--help": 0,
                               "no-such-file.csv": 2}[argv[-1]]


def test_an_uncaught_exception_is_a_traceback_and_exit_code_1(cli, monkeypatch):
    import ema_bench.cli.params as params

    def broken(args):
        raise ZeroDivisionError("a bug")

    # build_parser calls each command module's register: this one installs the broken handler
    monkeypatch.setattr(params, "register", _register_with(broken))
    run = cli("params")
    assert run.returncode == 1 and run.stdout == ""
    assert run.stderr.startswith("Traceback (most recent call last):")
    assert run.stderr.rstrip().endswith("ZeroDivisionError: a bug")
    with pytest.raises(AssertionError, match="a bug"):
        cli("params", check=True)


def _register_with(handler):
    def register(sub):
        p = sub.add_parser("params")
        p.set_defaults(func=handler)
    return register


def test_sys_exit_with_a_message_and_a_warning_reach_stderr(cli, monkeypatch):
    import ema_bench.cli.params as params

    def exits(args):
        warnings.warn("careful", UserWarning, stacklevel=1)
        sys.exit("stopped here")

    monkeypatch.setattr(params, "register", _register_with(exits))
    run = cli("params")
    assert run.returncode == 1
    assert "stopped here\n" in run.stderr and "UserWarning: careful" in run.stderr


def test_folder_environment_and_logger_are_restored(cli, tmp_path, monkeypatch):
    import ema_bench.cli.params as params

    seen = {}

    def look(args):
        seen["cwd"], seen["env"] = Path.cwd(), dict(os.environ)
        logging.getLogger("ema_bench").info("a log line")
        raise CLIError("refused")

    monkeypatch.setattr(params, "register", _register_with(look))
    monkeypatch.delenv("EMA_BENCH_TEST_VARIABLE", raising=False)
    before = (Path.cwd(), logging.getLogger("ema_bench").propagate)
    run = cli("params", cwd=tmp_path, env={"EMA_BENCH_TEST_VARIABLE": "1"})
    assert run.returncode == 2 and run.stderr.endswith("ema-bench params: error: refused\n")
    assert "a log line" in run.stderr                      # the CLI's log goes to stderr
    assert seen["cwd"] == tmp_path and seen["env"]["EMA_BENCH_TEST_VARIABLE"] == "1"
    assert (Path.cwd(), logging.getLogger("ema_bench").propagate) == before
    assert "EMA_BENCH_TEST_VARIABLE" not in os.environ
