"""Session set-up: the reference-trace cache lives in a fresh folder for the test run (child
processes of CLI tests inherit it), so tests neither read nor fill the user's cache; OpenBLAS's
idle threads sleep at once instead of spinning and dask's workers do not profile themselves
(children inherit both).

Under mutmut (docs/mutation-testing.md) two more things, before anything imports numba or the
solver zoo:

* numba's ``workqueue`` threading layer: mutmut forks one child per mutant from a process that
  has already run the parallel monitor kernel, and GNU OpenMP (numba's default layer here)
  kills such a child with SIGTERM at its first parallel call ("fork() called from a process
  already using GNU OpenMP"), which mutmut counts as "suspicious".  ``workqueue`` restarts
  its threads after a fork.
* ``ema_bench_solvers`` is the mutated copy ``mutants/solvers``, imported as ``solvers``:
  mutmut names a mutant after its file's path and activates it only in the module of that
  name, while the editable install would map ``ema_bench_solvers`` to the unmutated
  ``solvers/`` folder.
"""

import atexit
import importlib
import os
import pkgutil
import shutil
import sys
import tempfile
from pathlib import Path

import pytest
from inprocess import run_cli

# OpenBLAS's idle threads spin (sched_yield) for about 2**28 cycles after each threaded call
# before they sleep: CPU time spent on nothing, in this process and in every child that
# inherits the variable (about a tenth of a diagnosis's CPU time on a loaded 2-core machine).
# The shortest wait (2**4 cycles) keeps the number of threads, and with it every number, as
# it is; it must be set before numpy loads OpenBLAS (no plugin imports numpy before this
# file); a user's own setting wins.
os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")
# dask's workers sample their own stacks every 10 ms for the dashboard's profile, which no
# test reads (and the executor starts no dashboard): off for the clusters the tests start
os.environ.setdefault("DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED", "False")

if "EMA_BENCH_CACHE" not in os.environ:
    # removed when the session that made it ends (a fork, e.g. a mutmut child, inherits the
    # exit hook but not the ownership); each run used to leave its traces behind (11 GB
    # of /tmp after one day of mutation runs)
    _cache, _owner = tempfile.mkdtemp(prefix="ema-bench-test-cache-"), os.getpid()
    os.environ["EMA_BENCH_CACHE"] = _cache
    atexit.register(lambda: os.getpid() == _owner and shutil.rmtree(_cache, ignore_errors=True))


def _under_mutmut() -> None:
    os.environ.setdefault("NUMBA_THREADING_LAYER", "workqueue")
    root = Path(__file__).resolve().parent.parent
    if (root / "solvers" / "__init__.py").is_file() and "ema_bench_solvers" not in sys.modules:
        solvers = importlib.import_module("solvers")
        sys.modules["ema_bench_solvers"] = solvers
        for module in pkgutil.iter_modules(solvers.__path__):
            name = module.name
            sys.modules[f"ema_bench_solvers.{name}"] = importlib.import_module(f"solvers.{name}")


if "mutmut" in sys.modules:
    _under_mutmut()


@pytest.fixture(scope="session")
def cli():
    """``ema-bench`` in the test process: ``cli(*args, cwd=, env=, check=)`` returns the exit
    code, stdout and stderr a subprocess would (tests/inprocess.py says when a real subprocess
    is still needed)."""
    return run_cli


#: Set in the child that :func:`made_under` starts, so the child runs the test itself.
_KERNEL_CHILD = "EMA_BENCH_TEST_KERNEL_CHILD"


@pytest.fixture
def made_under(request):
    """``made_under("openblas SkylakeX")``: the test compares bit for bit with results made
    under that OpenBLAS kernel.  Under it, the test runs here; under another, it runs again
    in a child pytest started with ``OPENBLAS_CORETYPE`` set to it (OpenBLAS picks its kernel
    once, when it loads) and this one ends there; where this CPU cannot run that kernel
    (SkylakeX needs AVX-512), the test is skipped with both kernels named."""
    import subprocess

    from ema_bench.leaderboard.replay import _cpu_runs
    from ema_bench.manifest import blas_kernel

    def check(made: str) -> bool:
        """True: run the test body here; False: it ran (and passed) in the child."""
        here = blas_kernel()
        if here is None or made == here or os.environ.get(_KERNEL_CHILD):
            return True
        kernel = made.partition(" ")[2]
        if not _cpu_runs(kernel):
            pytest.skip(f"made under BLAS kernel {made}, this machine's is {here} and its CPU "
                        "cannot run the other")
        env = {**os.environ, "OPENBLAS_CORETYPE": kernel, _KERNEL_CHILD: "1"}
        proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:randomly",
                               "-p", "no:cacheprovider", request.node.nodeid],
                              cwd=request.config.rootpath, env=env, capture_output=True,
                              text=True)
        assert proc.returncode == 0, (f"under OPENBLAS_CORETYPE={kernel}:\n"
                                      + proc.stdout[-3000:] + proc.stderr[-2000:])
        return False

    return check
