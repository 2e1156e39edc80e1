"""numba's on-disk cache, kept in step with every source file of the package.

numba checks a cached kernel against the modification time and size of the one file that
defines it, not of the files whose functions it inlines.  The kernels in ``monitor.py``,
``monitor_lanes.py`` and ``reference.py`` inline the physics blocks of ``physics/`` (and
constants such as the fault indices): after an edit of ``physics/mechanics.py`` alone, numba
would load the old monitor kernel and silently simulate the old physics.  :func:`ensure_fresh`,
run when the package is imported, drops the package's cached kernels whenever any of its
``.py`` files changed since the last check, so they are recompiled from the current sources.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from .jsonio import write_atomic

PACKAGE = Path(__file__).resolve().parent
STAMP = "numba-sources.stamp"
_CACHE_SUFFIXES = (".nbi", ".nbc")


def sources_stamp(package: Path = PACKAGE) -> str:
    """Digest of the path, modification time (ns) and size of every ``.py`` file under
    ``package``."""
    h = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        st = path.stat()
        h.update(f"{path.relative_to(package)}\0{st.st_mtime_ns}\0{st.st_size}\n".encode())
    return h.hexdigest()


def ensure_fresh(package: Path = PACKAGE) -> bool:
    """Remove numba's cache files under ``package`` if its sources changed since the last call.

    Returns True when it removed them.  Where the package folder cannot be written (numba
    then caches elsewhere, or not at all), it does nothing.
    """
    package = Path(package)
    stamp_file = package / "__pycache__" / STAMP
    stamp = sources_stamp(package)
    try:
        if stamp_file.read_text() == stamp:
            return False
    except OSError:
        pass
    try:
        for folder in package.rglob("__pycache__"):
            for f in folder.iterdir():
                if f.suffix in _CACHE_SUFFIXES:
                    f.unlink(missing_ok=True)
        stamp_file.parent.mkdir(exist_ok=True)
        write_atomic(stamp_file, stamp)
    except OSError:
        return False
    return True
