"""Actuator test traces: the four recorded signals of each standard test, in canonical units.

A :class:`Traces` holds, for each test (``"step"``, ``"sine"``, ...), an array of shape
``(n_samples, 4)`` whose columns follow :data:`SIGNALS`.  Each sample is the mean of its signal
over one output window of ``dt`` seconds (1 ms by default), so sample ``k`` is stamped at the
window centre ``(k + 0.5) * dt``.

Files
-----
:meth:`Traces.save` writes ``.csv`` (long format, readable by people, pandas and Excel) or
``.npz``; :func:`load_traces` reads those, MATLAB ``.mat`` files and "plain measured" CSV files
(no comment lines, any supported unit, finer sample rates are block-averaged down to ``dt``).
Files are never unpickled.

CSV layout (read it with ``pandas.read_csv(path, comment="#")``)::

    # ema-bench traces v1
    # dt = 0.001 s
    # meta = {"model": "reference", "case": "nominal"}
    test,time [s],theta_u [rad],theta_m [rad],omega_m [rad/s],i_eq [A]
    step,0.0005,0.0,0.0,0.0,0.0

NPZ keys: ``"<test>/<signal>"`` and ``"time/<test>"`` (float arrays), ``"units"`` (strings
``"signal=unit"``), ``"dt"`` and ``"meta_json"`` (0-d string).  MATLAB variables use the same names
with ``_`` in place of ``/`` (``step_theta_u``, ``time_step``); a file holding only ``time`` and
signal-named variables is one test, named by the ``test=`` argument of :func:`load_traces`.
"""

from __future__ import annotations

import csv
import dataclasses
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

__all__ = [
    "DESCRIPTIONS",
    "OUTPUT_DT",
    "SIGNALS",
    "UNITS",
    "UNIT_CONVERSIONS",
    "Traces",
    "TracesError",
    "load_traces",
]

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

# Multiply a value in the key unit by the factor to get the canonical unit.
UNIT_CONVERSIONS: Mapping[str, Mapping[str, float]] = MappingProxyType(
    {
        "rad": MappingProxyType({"rad": 1.0, "deg": math.pi / 180.0, "mrad": 1e-3}),
        "rad/s": MappingProxyType({"rad/s": 1.0, "rpm": 2.0 * math.pi / 60.0,
                                   "deg/s": math.pi / 180.0}),
        "A": MappingProxyType({"A": 1.0, "mA": 1e-3}),
    }
)
_TIME_UNITS = {"s": 1.0, "ms": 1e-3}
_TIME_NAMES = ("time", "t")

_CSV_MAGIC = "# ema-bench traces v1"
_CSV_MAGIC_RE = re.compile(r"#\s*ema-bench traces v(\S+)\s*$")
_META_RE = re.compile(r"#\s*meta\s*=\s*(.*)$")
_HEADER_RE = re.compile(r"^(?P<name>[^\[\]]*?)\s*(?:\[\s*(?P<unit>[^\[\]]*?)\s*\])?$")
_MIN_SAMPLES = 10
_RATE_TOL = 1e-6  # relative tolerance on time-step jitter and on the dt / step ratio

# Test names become CSV cells, NPZ keys and MATLAB variable parts: keep them plain, and keep
# them apart from the other key names so that file keys stay unambiguous.
_TEST_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
_RESERVED_NAMES = frozenset({"time", "t", "test", "units", "dt", "meta_json", *SIGNALS})


class TracesError(ValueError):
    """Invalid traces or traces file; the message names the file, test and column at fault."""


# --------------------------------------------------------------------------------------------
# the container
# --------------------------------------------------------------------------------------------


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
        try:
            dt = float(self.dt)
        except (TypeError, ValueError) as exc:
            raise TracesError(f"dt must be a number of seconds, got {self.dt!r}") from exc
        if not (math.isfinite(dt) and dt > 0.0):
            raise TracesError(f"dt must be positive and finite, got {dt!r} s")
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
        # a file object keeps numpy from appending its own suffix
        with open(path, "wb") as fh:
            np.savez_compressed(fh, allow_pickle=False, **arrays)


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


def _json_default(obj: Any) -> Any:
    # numpy scalars and arrays are common in meta (seeds, parameter vectors)
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"object of type {type(obj).__name__} is not JSON serialisable")


def _normalise_meta(meta: Any) -> dict[str, Any]:
    if not isinstance(meta, Mapping):
        raise TracesError(f"meta must be a mapping, got {type(meta).__name__}")
    try:
        text = json.dumps(dict(meta), allow_nan=False, default=_json_default)
    except (TypeError, ValueError) as exc:
        raise TracesError(f"meta is not JSON-serialisable: {exc}") from exc
    return json.loads(text)


# --------------------------------------------------------------------------------------------
# loading
# --------------------------------------------------------------------------------------------

# test name -> (times in s as written in the file, values (n, 4) in canonical units)
_Raw = dict[str, tuple[np.ndarray, np.ndarray]]


def load_traces(
    path: str | os.PathLike[str],
    *,
    test: str | None = None,
    dt: float = OUTPUT_DT,
    min_duration: float | None = None,
) -> Traces:
    """Read traces from a ``.csv``, ``.npz`` or MATLAB ``.mat`` file.

    Parameters
    ----------
    path : str or PathLike
        File to read.  CSV files may be written by :meth:`Traces.save` or be "plain measured"
        files: a header ``time [s]`` (or ``t [s]``, ``time [ms]``) plus one ``name [unit]``
        column per signal, and optionally a ``test`` column.  Every column but ``test`` must
        state its unit; convertible units (deg, mrad, rpm, deg/s, mA) are converted.
    test : str, optional
        Name of the test held by a file without test names (a CSV without ``test`` column, a
        ``.npz``/``.mat`` of plain ``time`` and signal variables).  For a file that names its
        tests, load only this one.
    dt : float, optional
        Output sample period in s (default :data:`OUTPUT_DT`).  Data sampled at an integer
        sub-multiple of ``dt`` (e.g. 10 kHz) are block-averaged to ``dt``: each output sample
        is the mean over its window, as in the model; a trailing partial window is dropped.
    min_duration : float, optional
        Minimum duration in s (``n_samples * dt``) required of every test after resampling.

    Returns
    -------
    Traces
        The traces at period ``dt``.  Times in the file only fix the sample step and count; the
        result uses its own window-centre times ``(k + 0.5) * dt``.

    Raises
    ------
    TracesError
        If the file is missing, unreadable, of an unsupported kind, empty or malformed; lacks a
        signal or has an unknown column; has a missing or unknown unit; has non-monotonic,
        repeated or non-uniform times, NaN gaps, an unsupported sample rate; or is too short.
    """
    path = Path(path)
    dt = _check_positive("dt", dt)
    if min_duration is not None:
        min_duration = _check_positive("min_duration", min_duration)
    if not path.exists():
        raise TracesError(f"{path}: file not found")
    if not path.is_file():
        raise TracesError(f"{path}: not a regular file")
    suffix = path.suffix.lower()
    readers = {".csv": _read_csv, ".npz": _read_npz, ".mat": _read_mat}
    if suffix not in readers:
        raise TracesError(
            f"{path}: unsupported file type {suffix or '(no suffix)'!r}; use .csv, .npz or .mat"
        )
    if path.stat().st_size == 0:
        raise TracesError(f"{path}: file is empty")
    raw, meta = readers[suffix](path, test)
    raw = _select_test(path, raw, test)
    data = {name: _regularise(path, name, t, x, dt, min_duration) for name, (t, x) in raw.items()}
    try:
        return Traces(data, dt=dt, meta=meta)
    except TracesError as exc:
        raise TracesError(f"{path}: {exc}") from exc


def _check_positive(what: str, value: float) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError) as exc:
        raise TracesError(f"{what} must be a number of seconds, got {value!r}") from exc
    if not (math.isfinite(value) and value > 0.0):
        raise TracesError(f"{what} must be positive and finite, got {value!r} s")
    return value


def _fail(path: Path, message: str) -> TracesError:
    return TracesError(f"{path}: {message}")


def _unit_factor(path: Path, signal: str, unit: str, where: str) -> float:
    canonical = UNITS[signal]
    accepted = UNIT_CONVERSIONS[canonical]
    if unit not in accepted:
        raise _fail(
            path,
            f"{where}: unit {unit!r} not accepted for {signal} (canonical {canonical}; "
            f"accepted: {', '.join(accepted)})",
        )
    return accepted[unit]


def _time_factor(path: Path, unit: str, where: str) -> float:
    if unit not in _TIME_UNITS:
        raise _fail(path, f"{where}: time unit {unit!r} not accepted; accepted: "
                          f"{', '.join(_TIME_UNITS)}")
    return _TIME_UNITS[unit]


def _select_test(path: Path, raw: _Raw, test: str | None) -> _Raw:
    if not raw:
        raise _fail(path, "no data")
    if test is None or list(raw) == [test]:
        return raw
    if test not in raw:
        raise _fail(path, f"test {test!r} not in file; found: {', '.join(raw)}")
    return {test: raw[test]}


def _regularise(
    path: Path, test: str, t: np.ndarray, x: np.ndarray, dt: float, min_duration: float | None
) -> np.ndarray:
    """Check times and values of one test and bring it to period ``dt``."""
    n = t.shape[0]
    if n < 2:
        raise _fail(path, f"test {test!r}: too short, {n} sample(s); need at least "
                          f"{_MIN_SAMPLES} at {1.0 / dt:.6g} Hz")
    bad_t = np.flatnonzero(~np.isfinite(t))
    if bad_t.size:
        raise _fail(path, f"test {test!r}: time is missing or not finite at sample index "
                          f"{bad_t[0]}")
    step_k = np.diff(t)
    bad = np.flatnonzero(step_k <= 0.0)
    if bad.size:
        i = int(bad[0]) + 1
        kind = "repeated" if step_k[bad[0]] == 0.0 else "non-monotonic (decreasing)"
        raise _fail(path, f"test {test!r}: {kind} time at sample index {i}: "
                          f"t = {t[i]:.9g} s after t = {t[i - 1]:.9g} s")
    gaps = ~np.isfinite(x)
    if gaps.any():
        k, j = np.argwhere(gaps)[0]
        kind = "NaN gap (missing value)" if np.isnan(x[k, j]) else "infinite value"
        raise _fail(path, f"test {test!r}, signal {SIGNALS[j]!r}: {kind} starting at "
                          f"t = {t[k]:.9g} s (sample index {k})")
    step = (t[-1] - t[0]) / (n - 1)
    jitter = np.abs(step_k - step)
    k = int(np.argmax(jitter))
    if jitter[k] > _RATE_TOL * step:
        raise _fail(path, f"test {test!r}: non-uniform sampling: step {step_k[k]:.9g} s at "
                          f"sample index {k + 1} differs from the mean step {step:.9g} s by more "
                          f"than {_RATE_TOL:g} relative")
    ratio = dt / step
    if abs(ratio - 1.0) > _RATE_TOL:
        m = round(ratio)
        rates = f"file rate {1.0 / step:.6g} Hz, expected {1.0 / dt:.6g} Hz"
        if ratio < 1.0:
            raise _fail(path, f"test {test!r}: sample rate too low ({rates}); "
                              "data coarser than dt cannot be used")
        if m < 2 or abs(ratio - m) > _RATE_TOL * ratio:
            raise _fail(path, f"test {test!r}: sample rate is not an integer multiple of the "
                              f"expected rate ({rates})")
        n_out = n // m
        # block average: each output sample is the mean over its dt window, as in the model
        x = x[: n_out * m].reshape(n_out, m, x.shape[1]).mean(axis=1)
    n_out = x.shape[0]
    if n_out < _MIN_SAMPLES:
        raise _fail(path, f"test {test!r}: too short, {n_out} sample(s) at {1.0 / dt:.6g} Hz; "
                          f"need at least {_MIN_SAMPLES}")
    # a relative margin keeps e.g. 0.5 s from failing on 500 * 0.001 rounding
    if min_duration is not None and n_out * dt < min_duration * (1.0 - 1e-9):
        raise _fail(path, f"test {test!r}: too short, lasts {n_out * dt:.6g} s ({n_out} samples); "
                          f"min_duration is {min_duration:.6g} s")
    return x


# ---- CSV -----------------------------------------------------------------------------------


def _read_csv(path: Path, test: str | None) -> tuple[_Raw, dict[str, Any]]:
    try:
        # utf-8-sig: spreadsheet programs often prepend a byte-order mark
        lines = path.read_text(encoding="utf-8-sig").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise _fail(path, f"cannot read file: {exc}") from exc
    meta: dict[str, Any] = {}
    h = 0
    while h < len(lines) and (not lines[h].strip() or lines[h].lstrip().startswith("#")):
        meta.update(_parse_comment(path, h + 1, lines[h].strip()))
        h += 1
    if h == len(lines):
        raise _fail(path, "file is empty (no header line)")
    header = next(csv.reader([lines[h]]))
    columns = _parse_header(path, h + 1, header)
    rows: list[list[str]] = []
    line_numbers: list[int] = []
    reader = csv.reader(lines[h + 1:])
    for row in reader:
        lineno = h + 1 + reader.line_num
        if not row or (len(row) == 1 and not row[0].strip()) or row[0].lstrip().startswith("#"):
            continue
        if len(row) != len(columns):
            raise _fail(path, f"line {lineno}: malformed row, expected {len(columns)} fields, "
                              f"found {len(row)}")
        rows.append(row)
        line_numbers.append(lineno)
    if not rows:
        raise _fail(path, "file is empty (header but no data rows)")

    values = np.empty((len(rows), len(columns)), dtype=np.float64)
    test_col = None
    for c, (name, factor) in enumerate(columns):
        if name == "test":
            test_col = c
            continue
        for i, row in enumerate(rows):
            cell = row[c].strip()
            try:
                # an empty cell is a gap, reported with its time once times are checked
                values[i, c] = float(cell) if cell else math.nan
            except ValueError:
                raise _fail(path, f"line {line_numbers[i]}, column {header[c].strip()!r}: "
                                  f"non-numeric value {cell!r}") from None
        if factor != 1.0:
            values[:, c] *= factor
    time_col = next(c for c, (name, _) in enumerate(columns) if name == "time")
    sig_cols = [next(c for c, (name, _) in enumerate(columns) if name == s) for s in SIGNALS]

    if test_col is None:
        if test is None:
            raise _fail(path, "no 'test' column; pass test=<name> to name the single test")
        return {test: (values[:, time_col], values[:, sig_cols])}, meta
    names = [row[test_col].strip() for row in rows]
    raw: _Raw = {}
    order = list(dict.fromkeys(names))
    for name in order:
        if not _TEST_NAME_RE.match(name) or name in _RESERVED_NAMES:
            i = names.index(name)
            raise _fail(path, f"line {line_numbers[i]}: invalid test name {name!r} in column "
                              "'test'")
    names_arr = np.array(names)
    for name in order:
        idx = np.flatnonzero(names_arr == name)
        raw[name] = (values[idx, time_col], values[np.ix_(idx, sig_cols)])
    return raw, meta


def _parse_comment(path: Path, lineno: int, line: str) -> dict[str, Any]:
    magic = _CSV_MAGIC_RE.match(line)
    if magic and magic.group(1) != "1":
        raise _fail(path, f"line {lineno}: unsupported traces format version "
                          f"{magic.group(1)!r} (this reader knows v1)")
    m = _META_RE.match(line)
    if not m:
        return {}  # other comments (including the dt line) are informative only
    try:
        meta = json.loads(m.group(1))
    except json.JSONDecodeError as exc:
        raise _fail(path, f"line {lineno}: meta is not valid JSON: {exc}") from exc
    if not isinstance(meta, dict):
        raise _fail(path, f"line {lineno}: meta must be a JSON object")
    return meta


def _parse_header(path: Path, lineno: int, header: list[str]) -> list[tuple[str, float]]:
    """Column names ('test', 'time' or a signal) with the factor to canonical units."""
    known = ["test", "time [s|ms]", "t [s|ms]", *(f"{s} [unit]" for s in SIGNALS)]
    columns: list[tuple[str, float]] = []
    for raw_label in header:
        label = raw_label.strip()
        m = _HEADER_RE.match(label)
        name, unit = (m.group("name"), m.group("unit")) if m else (label, None)
        where = f"line {lineno}, column {label!r}"
        if name == "test":
            if unit is not None:
                raise _fail(path, f"{where}: the 'test' column takes no unit")
            columns.append(("test", 1.0))
            continue
        if name not in _TIME_NAMES and name not in SIGNALS:
            raise _fail(path, f"{where}: unknown column; known columns: {', '.join(known)}")
        if not unit:
            raise _fail(path, f"{where}: column has no unit; write it as '{name} [unit]'")
        if name in _TIME_NAMES:
            columns.append(("time", _time_factor(path, unit, where)))
        else:
            columns.append((name, _unit_factor(path, name, unit, where)))
    found = [name for name, _ in columns]
    for name in set(found):
        if found.count(name) > 1:
            raise _fail(path, f"line {lineno}: duplicate column {name!r}")
    if "time" not in found:
        raise _fail(path, f"line {lineno}: missing time column 'time [s]'; found: "
                          f"{', '.join(h.strip() for h in header)}")
    missing = [s for s in SIGNALS if s not in found]
    if missing:
        raise _fail(path, f"line {lineno}: missing signal column(s) {', '.join(missing)}; "
                          f"found: {', '.join(h.strip() for h in header)}")
    return columns


# ---- NPZ / MAT -----------------------------------------------------------------------------


def _read_npz(path: Path, test: str | None) -> tuple[_Raw, dict[str, Any]]:
    try:
        archive = np.load(path, allow_pickle=False)
    except Exception as exc:  # numpy raises many kinds for a corrupt file
        raise _fail(path, f"cannot read as .npz: {exc}") from exc
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise _fail(path, "not an .npz archive (a single .npy array?)")
    arrays: dict[str, np.ndarray] = {}
    with archive:
        for key in archive.files:
            try:
                arrays[key] = archive[key]
            except ValueError as exc:
                if "pickle" in str(exc) or "Object arrays" in str(exc):
                    raise _fail(path, f"key {key!r} holds an object array (pickled data); "
                                      "refusing to unpickle, store plain numeric arrays") from exc
                raise _fail(path, f"key {key!r}: cannot read: {exc}") from exc
            except (OSError, EOFError, zipfile.BadZipFile) as exc:
                raise _fail(path, f"key {key!r}: cannot read: {exc}") from exc
    if not arrays:
        raise _fail(path, "file is empty (no arrays)")
    return _arrays_to_raw(path, arrays, "/", "key", test)


def _read_mat(path: Path, test: str | None) -> tuple[_Raw, dict[str, Any]]:
    import scipy.io  # only .mat files need scipy.io; keep the module import light

    try:
        content = scipy.io.loadmat(path, squeeze_me=False, chars_as_strings=True)
    except NotImplementedError as exc:
        raise _fail(path, f"MATLAB v7.3 (HDF5) files are not supported; save with '-v7': "
                          f"{exc}") from exc
    except Exception as exc:  # scipy raises many kinds for a corrupt file
        raise _fail(path, f"cannot read as .mat: {exc}") from exc
    arrays = {k: v for k, v in content.items() if not k.startswith("__")}
    if not arrays:
        raise _fail(path, "file is empty (no variables)")
    return _arrays_to_raw(path, arrays, "_", "variable", test)


def _arrays_to_raw(
    path: Path, arrays: dict[str, np.ndarray], sep: str, what: str, test: str | None
) -> tuple[_Raw, dict[str, Any]]:
    """Group named arrays (NPZ keys or MATLAB variables) into tests, in canonical units."""
    arrays = dict(arrays)
    if "units" not in arrays:
        raise _fail(path, f"no 'units' {what}: add strings 'signal=unit', e.g. 'omega_m=rad/s'")
    units = _parse_units(path, _strings(path, "units", arrays.pop("units"), what), what)
    arrays.pop("dt", None)  # informative only; the time vectors fix the step
    meta: dict[str, Any] = {}
    if "meta_json" in arrays:
        meta = _parse_meta_json(path, _strings(path, "meta_json", arrays.pop("meta_json"), what))

    # test -> {"time" or signal -> name of the array}
    layout: dict[str, dict[str, str]] = {}
    pattern = f"'time{sep}<test>', '<test>{sep}<signal>'"
    if "time" in arrays or any(s in arrays for s in SIGNALS):
        # plain layout: one unnamed test
        pattern = "'time', " + ", ".join(f"'{s}'" for s in SIGNALS)
        if test is None:
            raise _fail(path, f"plain 'time' + signal {what}s hold one unnamed test; "
                              "pass test=<name>")
        layout[test] = {}
        for key in arrays:
            if key != "time" and key not in SIGNALS:
                raise _unknown_key(path, key, what, pattern)
            layout[test][key] = key
    else:
        for key in arrays:
            sig = next((s for s in SIGNALS if key.endswith(sep + s)), None)
            if sig is not None:
                name, part = key[: -len(sep + sig)], sig
            elif key.startswith("time" + sep):
                name, part = key[len("time" + sep):], "time"
            else:
                raise _unknown_key(path, key, what, pattern)
            if not _TEST_NAME_RE.match(name) or name in _RESERVED_NAMES:
                raise _fail(path, f"{what} {key!r}: invalid test name {name!r}")
            layout.setdefault(name, {})[part] = key

    for s in SIGNALS:
        if s not in units:
            raise _fail(path, f"'units' {what} has no entry for {s!r}; add '{s}={UNITS[s]}'")
    time_factor = _time_factor(path, units.get("time", "s"), "'units' entry for time")
    factors = [_unit_factor(path, s, units[s], f"'units' entry {s}={units[s]}") for s in SIGNALS]

    raw: _Raw = {}
    for name, parts in layout.items():
        for part in ("time", *SIGNALS):
            if part not in parts:
                found = ", ".join(parts.values())
                raise _fail(path, f"test {name!r}: missing {part!r} {what}; found: {found}")
        t = _vector(path, parts["time"], arrays[parts["time"]], what) * time_factor
        columns = []
        for s, factor in zip(SIGNALS, factors, strict=True):
            v = _vector(path, parts[s], arrays[parts[s]], what)
            if v.shape != t.shape:
                raise _fail(path, f"test {name!r}, signal {s!r}: {what} {parts[s]!r} has "
                                  f"{v.size} samples but the time has {t.size}")
            columns.append(v * factor if factor != 1.0 else v)
        raw[name] = (t, np.column_stack(columns))
    return raw, meta


def _unknown_key(path: Path, key: str, what: str, pattern: str) -> TracesError:
    return _fail(path, f"unknown {what} {key!r}; expected {pattern}, 'units', 'dt', 'meta_json' "
                       f"(signals: {', '.join(SIGNALS)})")


def _vector(path: Path, key: str, arr: np.ndarray, what: str) -> np.ndarray:
    arr = np.asarray(arr)
    if arr.dtype.kind not in "fiu":
        raise _fail(path, f"{what} {key!r}: expected real numbers, got dtype {arr.dtype}")
    # MATLAB stores vectors as (1, n) or (n, 1)
    if arr.ndim == 0 or arr.size != max(arr.shape):
        raise _fail(path, f"{what} {key!r}: expected a 1-D vector, got shape {arr.shape}")
    return np.asarray(arr, dtype=np.float64).ravel()


def _strings(path: Path, key: str, arr: np.ndarray, what: str) -> list[str]:
    arr = np.asarray(arr)
    if arr.dtype.kind == "U":
        return [str(s).strip() for s in arr.ravel()]
    if arr.dtype.kind == "S":
        return [s.decode("utf-8", errors="replace").strip() for s in arr.ravel()]
    if arr.dtype.kind == "O":  # a MATLAB cell array of char rows (loadmat, never unpickled)
        out: list[str] = []
        for item in arr.ravel():
            out.extend(_strings(path, key, item, what))
        return out
    raise _fail(path, f"{what} {key!r}: expected strings, got dtype {arr.dtype}")


def _parse_units(path: Path, entries: list[str], what: str) -> dict[str, str]:
    units: dict[str, str] = {}
    for entry in entries:
        name, eq, unit = (part.strip() for part in entry.partition("="))
        if not eq:
            raise _fail(path, f"'units' {what}: entry {entry!r} is not 'signal=unit'")
        if name != "time" and name not in SIGNALS:
            raise _fail(path, f"'units' {what}: unknown signal {name!r} in {entry!r}; known: "
                              f"time, {', '.join(SIGNALS)}")
        if name in units:
            raise _fail(path, f"'units' {what}: duplicate entry for {name!r}")
        units[name] = unit
    return units


def _parse_meta_json(path: Path, entries: list[str]) -> dict[str, Any]:
    try:
        meta = json.loads("".join(entries))
    except json.JSONDecodeError as exc:
        raise _fail(path, f"meta_json is not valid JSON: {exc}") from exc
    if not isinstance(meta, dict):
        raise _fail(path, "meta_json must hold a JSON object")
    return meta
