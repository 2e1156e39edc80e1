"""The :class:`Traces` container: the four signals, their units and the output period,
the rules for test names and meta; :meth:`Traces.save` writes ``.csv`` and ``.npz``."""

from __future__ import annotations

import dataclasses
import io
import json
import math
import os
import re
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from ..jsonio import numpy_default
from .errors import TracesError

SIGNALS: tuple[str, ...] = ("theta_u", "theta_m", "omega_m", "i_eq")
UNITS: Mapping[str, str] = MappingProxyType(
    {"theta_u": "rad", "theta_m": "rad", "omega_m": "rad/s", "i_eq": "A"}
)
DESCRIPTIONS: Mapping[str, str] = MappingProxyType(
    {
        "theta_u": "control-surface (user) position, measured by the position sensor",
        "theta_m": "motor rotor angle, unwrapped (resolver)",
        "omega_m": "motor rotor angular speed",
        "i_eq": "equivalent (torque-producing) motor phase current",
    }
)
OUTPUT_DT = 1e-3  # s; model output period (1 kHz), each sample the mean over its window

_CSV_MAGIC = "# ema-bench traces v1"
_ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)   # the earliest zip time stamp: fixed, so saves repeat

# Test names become CSV cells, NPZ keys and MATLAB variable parts: keep them plain, and keep
# them apart from the other key names so that file keys stay unambiguous.
_TEST_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*\Z")  # \Z: no trailing newline
_RESERVED_NAMES = frozenset({"time", "t", "test", "units", "dt", "meta_json", *SIGNALS})


@dataclass(frozen=True, eq=False)
class Traces:
    """Recorded signals of one or more actuator tests.

    Parameters
    ----------
    data : Mapping[str, ndarray]
        Test name -> array of shape ``(n_samples, 4)``, columns in :data:`SIGNALS` order, in the
        canonical :data:`UNITS` (rad, rad, rad/s, A).  Stored as read-only float64 copies.
    dt : float, optional
        Sample period in s (default :data:`OUTPUT_DT`).
    meta : Mapping[str, Any], optional
        JSON-serialisable description (model, case, faults, effects, seed, ...).  Stored as a
        read-only view of a JSON-normalised copy (tuples become lists), so it survives a
        save/load round trip unchanged.

    Notes
    -----
    Traces compare by identity; use :meth:`allclose` to compare values.
    """

    data: Mapping[str, np.ndarray]
    dt: float = OUTPUT_DT
    meta: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.data, Mapping) or len(self.data) == 0:
            raise TracesError("traces need at least one test (a non-empty mapping name -> array)")
        dt = _check_positive("dt", self.dt)
        blocks = {}
        for name, values in self.data.items():
            _check_test_name(name)
            blocks[name] = _frozen_block(name, values)
        # frozen dataclass: bypass __setattr__ once to store the validated copies
        object.__setattr__(self, "data", MappingProxyType(blocks))
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "meta", MappingProxyType(_normalise_meta(self.meta)))

    def __repr__(self) -> str:
        sizes = ", ".join(f"{t}={self.n_samples(t)}" for t in self.tests)
        return f"Traces(n_samples: {sizes}; dt={self.dt!r} s; meta keys={list(self.meta)})"

    def __reduce__(self) -> tuple[Any, ...]:
        # mappingproxy cannot be copied or sent to worker processes; rebuild from plain dicts
        return (type(self), (dict(self.data), self.dt, dict(self.meta)))

    @property
    def tests(self) -> tuple[str, ...]:
        """Test names, in insertion order."""
        return tuple(self.data)

    def n_samples(self, test: str) -> int:
        """Number of samples of ``test``."""
        return int(self._block(test).shape[0])

    def time(self, test: str) -> np.ndarray:
        """Sample times of ``test`` in s: window centres ``(k + 0.5) * dt``."""
        return (np.arange(self.n_samples(test), dtype=np.float64) + 0.5) * self.dt

    def signal(self, test: str, name: str) -> np.ndarray:
        """One signal of one test as a read-only 1-D array, in its canonical unit."""
        if name not in SIGNALS:
            raise TracesError(f"unknown signal {name!r}; known: {', '.join(SIGNALS)}")
        return self._block(test)[:, SIGNALS.index(name)]

    def stacked(self) -> np.ndarray:
        """All values as one 1-D float64 array: test by test (``tests`` order), then signal by
        signal (``SIGNALS`` order), then sample by sample."""
        return np.concatenate([self.data[t].T.ravel() for t in self.tests])

    def with_meta(self, **kw: Any) -> Traces:
        """A copy with ``meta`` updated by the keyword arguments."""
        return dataclasses.replace(self, meta={**self.meta, **kw})

    def allclose(self, other: Traces, rtol: float = 0.0, atol: float = 0.0) -> bool:
        """True when ``other`` has the same tests (same order), shapes and ``dt`` and every value
        satisfies ``|a - b| <= atol + rtol * |b|``.  ``meta`` is not compared."""
        if not isinstance(other, Traces) or self.tests != other.tests or self.dt != other.dt:
            return False
        return all(
            self.data[t].shape == other.data[t].shape
            and np.allclose(self.data[t], other.data[t], rtol=rtol, atol=atol)
            for t in self.tests
        )

    #: The file types :meth:`save` writes.
    SAVE_SUFFIXES = (".csv", ".npz")

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the traces to ``path``; the format follows the suffix, ``.csv`` or ``.npz``.

        Floats are written exactly (shortest round-trip repr in CSV), so :func:`load_traces`
        gives back bit-identical values.
        """
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix == ".csv":
            self._save_csv(path)
        elif suffix == ".npz":
            self._save_npz(path)
        else:
            raise TracesError(f"{path}: cannot save as {suffix or 'no suffix'!r}; use .csv or .npz")

    def _block(self, test: str) -> np.ndarray:
        try:
            return self.data[test]
        except KeyError:
            raise TracesError(f"no test {test!r}; tests: {', '.join(self.tests)}") from None

    def _save_csv(self, path: Path) -> None:
        lines = [
            _CSV_MAGIC,
            f"# dt = {self.dt!r} s",
            f"# meta = {json.dumps(dict(self.meta))}",
            ",".join(["test", "time [s]", *(f"{s} [{UNITS[s]}]" for s in SIGNALS)]),
        ]
        for test in self.tests:
            times = self.time(test).tolist()
            for t, row in zip(times, self.data[test].tolist(), strict=True):
                # repr of a Python float is the shortest string that parses back to it exactly
                lines.append(",".join([test, repr(t), *map(repr, row)]))
        with open(path, "w", encoding="utf-8", newline="") as fh:
            fh.write("\n".join(lines) + "\n")

    def _save_npz(self, path: Path) -> None:
        arrays: dict[str, np.ndarray] = {}
        for test in self.tests:
            arrays[f"time/{test}"] = self.time(test)
            for j, name in enumerate(SIGNALS):
                arrays[f"{test}/{name}"] = np.ascontiguousarray(self.data[test][:, j])
        arrays["units"] = np.array(["time=s", *(f"{s}={UNITS[s]}" for s in SIGNALS)])
        arrays["dt"] = np.array(self.dt)
        arrays["meta_json"] = np.array(json.dumps(dict(self.meta)))
        # numpy.savez_compressed's layout with fixed time stamps (same traces, same bytes,
        # whatever the Python), into a temporary file renamed into place (an interrupted save
        # leaves no broken file).
        tmp = path.with_name(path.name + ".tmp")
        try:
            with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as z:
                for key, arr in arrays.items():
                    buf = io.BytesIO()
                    np.lib.format.write_array(buf, arr, allow_pickle=False)
                    info = zipfile.ZipInfo(key + ".npy", date_time=_ZIP_EPOCH)
                    info.compress_type = zipfile.ZIP_DEFLATED
                    info.external_attr = 0o600 << 16   # rw for the owner, as numpy writes
                    z.writestr(info, buf.getvalue())
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)


def _check_positive(what: str, value: float) -> float:
    """``value`` as a float of seconds; TracesError unless it is a positive, finite number."""
    try:
        value = float(value)
    except (TypeError, ValueError) as exc:
        raise TracesError(f"{what} must be a number of seconds, got {value!r}") from exc
    if not (math.isfinite(value) and value > 0.0):
        raise TracesError(f"{what} must be positive and finite, got {value!r} s")
    return value


def _check_test_name(name: Any) -> None:
    if not isinstance(name, str) or not _TEST_NAME_RE.match(name):
        raise TracesError(
            f"invalid test name {name!r}: use letters, digits, '_', '.', '-' "
            "(starting with a letter or digit)"
        )
    if name in _RESERVED_NAMES:
        reserved = ", ".join(sorted(_RESERVED_NAMES))
        raise TracesError(f"invalid test name {name!r}: reserved ({reserved})")


def _frozen_block(test: str, values: Any) -> np.ndarray:
    arr = np.asarray(values)
    if arr.dtype.kind not in "fiu":
        raise TracesError(f"test {test!r}: values must be real numbers, got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape[1] != len(SIGNALS) or arr.shape[0] == 0:
        raise TracesError(
            f"test {test!r}: expected shape (n_samples >= 1, {len(SIGNALS)}) with columns "
            f"{', '.join(SIGNALS)}; got shape {arr.shape}"
        )
    block = np.array(arr, dtype=np.float64, copy=True)
    bad = ~np.isfinite(block)
    if bad.any():
        k, j = np.argwhere(bad)[0]
        raise TracesError(
            f"test {test!r}, signal {SIGNALS[j]!r}: non-finite value {float(block[k, j])!r} "
            f"at sample {k}"
        )
    block.flags.writeable = False
    return block


def _normalise_meta(meta: Any) -> dict[str, Any]:
    if not isinstance(meta, Mapping):
        raise TracesError(f"meta must be a mapping, got {type(meta).__name__}")
    try:
        # numpy scalars and arrays are common in meta (seeds, parameter vectors)
        text = json.dumps(dict(meta), allow_nan=False, default=numpy_default)
    except (TypeError, ValueError, RecursionError) as exc:
        raise TracesError(f"meta is not JSON-serialisable: {exc}") from exc
    return json.loads(text)
