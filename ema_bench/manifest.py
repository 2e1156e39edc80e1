"""What a run record must carry to be reproducible: versions, machine, threads, git commit.

:func:`manifest` is called once per run record (thousands of times in a sweep), so what cannot
change while a process lives (versions, machine, the checkout's commit) is looked up once and
cached; the thread settings are read on every call, because a run may change them.
"""

from __future__ import annotations

import functools
import importlib.metadata
import os
import platform
import subprocess
from collections.abc import Iterable
from pathlib import Path

from .version import __version__

#: The keys a validator may demand of a record's manifest.
REQUIRED_MANIFEST_KEYS: tuple[str, ...] = (
    "ema_bench", "python", "numpy", "scipy", "numba", "platform", "cpu", "threads", "libraries",
)

#: The folder of the imported package: its git checkout, if any, is the code that ran.
PACKAGE_DIR = Path(__file__).resolve().parent

#: Environment settings that decide how many threads the compiled kernels use.
THREAD_VARIABLES = ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS")

GIT_TIMEOUT_S = 5.0


def manifest(libraries: Iterable[str] = ()) -> dict[str, object]:
    """The manifest of a run: what made it, for a record to be reproducible.

    Parameters
    ----------
    libraries
        Distribution names of the libraries a solver used, as it reports them (``"cma"``,
        ``"deap"``, ``"nevergrad"``; a comma-separated item names several); a module path such
        as ``"scipy.optimize"`` resolves to its top-level distribution.

    Returns
    -------
    dict
        ``ema_bench``, ``python``, ``numpy``, ``scipy``, ``numba`` (versions), ``libraries``
        (name -> version, ``None`` when not installed), ``platform``, ``machine``, ``cpu``
        (model name, or ``None``), ``cpu_count``, ``threads`` (numba's thread count and the
        thread environment variables that are set), ``git_commit`` and ``git_dirty`` (of the
        checkout the package is imported from; ``None`` when it is not one).  JSON-serialisable;
        a new dict on every call.
    """
    out = dict(_static())
    out["libraries"] = {name: library_version(name) for name in _names(libraries)}
    out["threads"] = _threads()
    return out


def _names(libraries: Iterable[str]) -> list[str]:
    """The names of ``libraries``, a comma-separated item split (the registry's
    ``library="nevergrad,numpy"``)."""
    names = []
    for item in libraries:
        if not isinstance(item, str):  # e.g. a {name: version} dict inside a list
            raise TypeError(f"library names must be strings, got {item!r}")
        names += [n.strip() for n in item.split(",") if n.strip()]
    return names


def library_version(name: str) -> str | None:
    """The installed version of distribution ``name`` (or of the part before its first dot),
    ``None`` when neither is installed."""
    return _version(name) or _version(name.partition(".")[0])


@functools.lru_cache(maxsize=256)
def _version(name: str) -> str | None:
    if not name:
        return None
    try:
        return importlib.metadata.version(name)
    except (importlib.metadata.PackageNotFoundError, ValueError):
        return None


@functools.lru_cache(maxsize=1)
def _static() -> dict[str, object]:
    """The part of the manifest that does not change while the process lives."""
    commit, dirty = git_state(PACKAGE_DIR)
    return {
        "ema_bench": __version__,
        "python": platform.python_version(),
        "numpy": _version("numpy"),
        "scipy": _version("scipy"),
        "numba": _version("numba"),
        "platform": platform.platform(),
        "machine": platform.machine(),
        "cpu": cpu_model(),
        "cpu_count": os.cpu_count(),
        "blas": blas_kernel(),
        "git_commit": commit,
        "git_dirty": dirty,
    }


def _threads() -> dict[str, object]:
    import numba  # a hard dependency, already loaded by any run

    threads: dict[str, object] = {"numba": numba.get_num_threads()}
    threads.update({v: os.environ[v] for v in THREAD_VARIABLES if v in os.environ})
    return threads


def blas_kernel() -> str | None:
    """NumPy's BLAS and the kernel it dispatched to for this CPU (``"openblas SkylakeX"``),
    or None where threadpoolctl is not installed.  Finite-difference solvers (lbfgsb,
    least-squares) amplify the last-bit differences between kernels, so a record replays
    bit-for-bit only under the kernel it was made with (``OPENBLAS_CORETYPE`` picks one)."""
    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        return None
    import numpy  # noqa: F401  (loads its BLAS, which threadpoolctl then finds)

    for lib in threadpool_info():
        if lib.get("user_api") == "blas":
            return f"{lib.get('internal_api')} {lib.get('architecture')}"
    return None


def cpu_model() -> str | None:
    """The CPU's model name from ``/proc/cpuinfo`` (Linux), else ``platform.processor()``,
    else ``None``."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                key, sep, value = line.partition(":")
                if sep and key.strip() == "model name" and value.strip():
                    return value.strip()
    except OSError:
        pass
    return platform.processor() or None


def git_state(folder: Path) -> tuple[str | None, bool | None]:
    """``(commit, dirty)`` of the git checkout ``folder`` belongs to, ``(None, None)`` when it
    is not in one, its package files are not tracked there, or git is missing or fails.

    ``dirty``: tracked files differ from the commit (untracked files do not count)."""
    # a non-editable install in a virtual environment inside a clone lies in that clone's
    # work tree, untracked: its code is not the commit's, so tracking is checked first
    if _git(folder, "ls-files", "--error-unmatch", "--", "__init__.py") is None:
        return None, None
    commit = _git(folder, "rev-parse", "HEAD")
    if not commit:
        return None, None
    status = _git(folder, "status", "--porcelain", "--untracked-files=no")
    return commit, (None if status is None else bool(status))


def _git(folder: Path, *args: str) -> str | None:
    """The stripped output of ``git -C folder ARGS``; ``None`` on any failure."""
    try:
        res = subprocess.run(["git", "-C", str(folder), *args], capture_output=True, text=True,
                             timeout=GIT_TIMEOUT_S, check=False)
    except (OSError, subprocess.SubprocessError, ValueError):
        return None
    return res.stdout.strip() if res.returncode == 0 else None
