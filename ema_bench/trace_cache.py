"""On-disk cache of reference-model traces (the measured data of the standard instances).

The reference model takes about 0.2 s per instance; a command-line solve, a leaderboard task or
a test would otherwise pay it every time.  An entry is keyed by everything that decides the
traces: :data:`MODEL_VERSION`, a hash of the physics source, the faults, the effects, the
noise seed, the tests and the parameters.  An entry that cannot be read, is not finite, has the
wrong shape or carries another key is rebuilt, never trusted; writes are atomic, so a crash or
a concurrent writer never leaves a half-written file behind.

An entry holds the traces and the public part of their record only (:data:`PUBLIC_META`), on
a miss as on a hit: the folder is readable by any solver, and the data maker's record (faults,
effects, seed) is the hidden truth.  Entries of earlier versions (``reference/``, which held
it) are deleted when the cache is next written.

Location: ``$EMA_BENCH_CACHE``, else ``$XDG_CACHE_HOME/ema-bench``, else ``~/.cache/ema-bench``.
Set ``EMA_BENCH_CACHE=off`` to disable it.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import tempfile
from collections.abc import Callable, Sequence
from functools import lru_cache
from pathlib import Path

import numpy as np

from .traces import Traces, load_traces

log = logging.getLogger(__name__)

#: Version of the two models' equations.  Bump it when either model's outputs change: cached
#: traces and committed leaderboards of another version are not comparable, unless
#: :data:`COMPATIBLE_VERSIONS` says why they are.
MODEL_VERSION = "3"

#: Earlier model versions whose records stay comparable with this one, and why.  Version 3
#: replaced libm's sine and cosine in eccentricity and cogging by one polynomial
#: (:mod:`ema_bench.physics.trig`, within 2.2e-16 of libm): outputs with neither effect on (suite
#: emafdi-v1, v2's tiers 4 and 7, the campaigns) are identical to the bit, those with one on
#: move at the rounding level.  Comparable is not the same: a finite-difference solver
#: magnifies a rounding-level change into another path, so a record is re-run on its own
#: version, which stays buildable (``params.model_params("2")``, the flag ``libm_trig``, the
#: old code's outputs to the bit): replay and re-evaluation build its problem on it
#: (:func:`ema_bench.leaderboard.derive.params_of`), its f* is that version's entry, and the
#: judge accepts version 2 for the committed records only (a new run is made on this
#: version).  The committed emafdi-v2 board validates and replays on it (CHANGELOG).
COMPATIBLE_VERSIONS: dict[str, str] = {
    "2": "libm sin/cos in eccentricity and cogging (libm_trig); identical outputs without "
         "either; replayed on its own parameters, accepted for the committed records only",
}


def is_comparable(version: str, current: str = MODEL_VERSION) -> bool:
    """Whether records and tables of model ``version`` compare with those of model
    ``current`` (default this installation's; a suite on another version, emafdi-v3, passes
    its own: :data:`COMPATIBLE_VERSIONS` are earlier versions of the default)."""
    return str(version) == str(current) or (str(current) == MODEL_VERSION
                                            and str(version) in COMPATIBLE_VERSIONS)

# the modules whose source decides the traces (the cache key hashes them, so an edited model
# never reads traces cached before the edit, even without a version bump)
_MODEL_SOURCES = ("params.py", "effects.py", "protocol.py", "reference.py", "monitor.py",
                  "physics")


@lru_cache(maxsize=1)
def source_hash() -> str:
    """SHA-256 (16 hex digits) of the model source files of this installation."""
    root = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for name in _MODEL_SOURCES:
        path = root / name
        files = sorted(path.glob("*.py")) if path.is_dir() else [path]
        for f in files:
            h.update(f.name.encode())
            h.update(f.read_bytes())
    return h.hexdigest()[:16]


#: What of a data maker's record the cache stores and returns: nothing a solver could use to
#: recover the truth (no faults, effects or seed).
PUBLIC_META = ("model", "noise", "adc")
#: The entries' folder under the cache (``reference/`` held the data makers' records).
ENTRIES, LEGACY = "measured", "reference"


def _public(traces: Traces) -> Traces:
    return Traces(data=traces.data, dt=traces.dt,
                  meta={k: v for k, v in traces.meta.items() if k in PUBLIC_META})


def cache_dir() -> Path | None:
    """The cache folder, or None when caching is off."""
    env = os.environ.get("EMA_BENCH_CACHE")
    if env is not None:
        return None if env.strip().lower() in ("", "off", "0", "no") else Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "ema-bench"


def cache_key(**parts: object) -> str:
    """Key of an entry: SHA-256 of the model version, the source hash and ``parts`` (JSON)."""
    doc = {"model_version": MODEL_VERSION, "source": source_hash(), **parts}
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()


def _valid(traces: Traces, key: str, shapes: dict[str, tuple[int, int]]) -> bool:
    return (traces.meta.get("cache_key") == key
            and {t: traces.data[t].shape for t in traces.tests} == shapes
            and all(np.isfinite(v).all() for v in traces.data.values()))


def cached_traces(make: Callable[[], Traces], key: str, shapes: dict[str, tuple[int, int]],
                  folder: Path | None = None) -> Traces:
    """``make()``, or the traces cached under ``key`` if a valid entry exists; either way with
    the public part of their record only (:data:`PUBLIC_META`).

    Parameters
    ----------
    make : callable
        Builds the traces (on a miss, or when the entry is broken or stale).
    key : str
        :func:`cache_key` of everything that decides the traces.
    shapes : dict
        Test name -> expected array shape; an entry with other tests or shapes is rebuilt.
    folder : Path, optional
        Cache folder; default :func:`cache_dir` (None there: no caching).
    """
    folder = cache_dir() if folder is None else folder
    if folder is None:
        return _public(make())
    path = folder / ENTRIES / f"{key[:32]}.npz"
    if path.is_file():
        try:
            traces = load_traces(path)
            if _valid(traces, key, shapes):
                return _public(traces)
            log.warning("stale or mismatched trace cache entry %s: rebuilding", path)
        except Exception as exc:   # any unreadable entry is rebuilt, whatever broke it
            log.warning("unreadable trace cache entry %s (%s): rebuilding", path, exc)
    traces = _public(make())
    try:
        shutil.rmtree(folder / LEGACY, ignore_errors=True)   # entries that held the truth
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(suffix=".npz", dir=path.parent)
        os.close(fd)
        traces.with_meta(cache_key=key).save(tmp)
        os.replace(tmp, path)
    except OSError as exc:   # a read-only or full disk costs speed, never the result
        log.warning("cannot write trace cache %s: %s", path, exc)
    return traces


def expected_shapes(tests: Sequence) -> dict[str, tuple[int, int]]:
    """Expected trace shapes of protocol tests (``TestSpec``)."""
    return {t.name: (t.n_samples(), 4) for t in tests}
