"""``ema-bench`` run inside the test process: what a subprocess gives, without its start-up.

A fresh interpreter costs about a second per command (imports, the solver zoo's entry points,
numba's cache look-ups) and redoes the numba dispatch warm-up the test process already paid;
the CLI tests spawned 68 of them.  :func:`run_cli` calls :func:`ema_bench.cli.main` with the
arguments a user types and returns what :func:`subprocess.run` would: the exit code (2 for an
argparse error, 0 after ``--help``, 1 with a traceback on stderr for an uncaught exception),
stdout and stderr as text, Python's warnings on stderr as an interpreter prints them.

Keep a real subprocess where the fresh interpreter is the point: entry-point plugins installed
by pip, kills and signals, the console script itself, environment variables read at start-up.
"""

from __future__ import annotations

import contextlib
import io
import logging
import os
import traceback
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

# the interpreter's filters, before pytest's per-test ones (conftest imports this module at
# start-up): a subprocess prints its warnings on stderr, where a one-line check sees them
_STARTUP_FILTERS = list(warnings.filters)


@dataclass
class CliRun:
    """The outcome of one command, named like :class:`subprocess.CompletedProcess`."""

    args: list[str]
    returncode: int
    stdout: str
    stderr: str

    def check_returncode(self) -> None:
        if self.returncode != 0:
            raise AssertionError(f"ema-bench {' '.join(self.args)} exited with "
                                 f"{self.returncode}:\n{self.stderr}")


def run_cli(*args: str | os.PathLike, cwd: str | os.PathLike | None = None,
            env: Mapping[str, str] | None = None, check: bool = False) -> CliRun:
    """Run ``ema-bench ARGS`` in this process.

    Parameters
    ----------
    *args
        The command line after ``ema-bench`` (paths are turned into strings).
    cwd
        Working folder of the command (restored afterwards).
    env
        Variables set for the command's duration on top of the current environment (only
        those read while the command runs take effect; start-up behaviour needs a subprocess).
    check
        Raise ``AssertionError`` with stderr when the exit code is not 0.
    """
    from ema_bench.cli import main

    argv = [os.fspath(a) for a in args]
    out, err = io.StringIO(), io.StringIO()
    # a subprocess's stdout is a pipe: argparse wraps its help at COLUMNS or else 80, never at
    # the width of the terminal pytest may run in (pytest -s)
    env = {"COLUMNS": os.environ.get("COLUMNS", "80"), **(env or {})}
    with _state_kept(cwd, env), warnings.catch_warnings(record=True) as caught:
        warnings.filters[:] = _STARTUP_FILTERS
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(argv)
            except SystemExit as exc:   # argparse: 2 on a usage error, 0 after --help
                code = exc.code
            except (KeyboardInterrupt, GeneratorExit):
                raise
            except BaseException:       # what the interpreter does with an uncaught one
                traceback.print_exc()
                code = 1
        for w in caught:
            err.write(warnings.formatwarning(w.message, w.category, w.filename, w.lineno,
                                             w.line))
    if code is None:
        code = 0
    elif not isinstance(code, int):     # sys.exit("message"): printed, exit code 1
        err.write(f"{code}\n")
        code = 1
    run = CliRun(argv, code, out.getvalue(), err.getvalue())
    if check:
        run.check_returncode()
    return run


@contextlib.contextmanager
def _state_kept(cwd: str | os.PathLike | None, env: Mapping[str, str] | None) -> Iterator[None]:
    """Working folder, environment and the ``ema_bench`` logger as they were before: the
    CLI's ``configure_logging`` stops propagation, which would hide later logs from caplog."""
    log = logging.getLogger("ema_bench")
    logger_state = (log.level, list(log.handlers), log.propagate)
    here = Path.cwd()
    saved = {k: os.environ.get(k) for k in env or {}}
    try:
        if cwd is not None:
            os.chdir(cwd)
        os.environ.update(env or {})
        yield
    finally:
        os.chdir(here)
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
        log.setLevel(logger_state[0])
        log.handlers[:], log.propagate = logger_state[1:]
