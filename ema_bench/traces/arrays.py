"""Named arrays (NPZ keys, MATLAB variables) grouped into tests, and the size limits of one
array and of all the arrays a file may declare."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from .container import _RESERVED_NAMES, _TEST_NAME_RE, SIGNALS, UNITS
from .errors import TracesError, _fail, _unnamed_test
from .units import _Raw, _time_factor, _time_label, _TimeLabel, _unit_factor

# Largest array a file may declare, in bytes (256 MiB: 33 million float64 samples, about an
# hour of one signal at 10 kHz).  Checked before allocation, against crafted headers.
MAX_ARRAY_BYTES = 2**28
# Largest total a file's arrays may hold, in bytes (64 MiB; the three standard tests at 100
# times the output rate, every column, take about 17 MB), and most arrays it may hold: with
# the limit per array alone, many members just under it made a 2 MB file fill 2.4 GB.
MAX_FILE_BYTES = 2**26
MAX_FILE_ARRAYS = 512
# names that are not a test's array
_OTHER_KEYS = frozenset({"units", "dt", "meta_json"})


def check_keys(path: Path, keys: list[str], sep: str, what: str) -> None:
    """Refuse, before any array is read, a file with more than :data:`MAX_FILE_ARRAYS` arrays,
    a name twice, or a name that is not one of a traces file (the layouts of
    :func:`_arrays_to_raw`)."""
    if len(keys) > MAX_FILE_ARRAYS:
        raise _fail(path, f"{len(keys)} {what}s, more than the limit of {MAX_FILE_ARRAYS} per "
                          "file")
    seen: set[str] = set()
    for key in keys:
        if key in seen:
            raise _fail(path, f"{what} {key!r} is in the file twice")
        seen.add(key)
        if key not in _OTHER_KEYS and key != "time" and key not in SIGNALS:
            _test_key(path, key, sep, what, f"'time{sep}<test>', '<test>{sep}<signal>'")


def _test_key(path: Path, key: str, sep: str, what: str, pattern: str) -> tuple[str, str]:
    """(test, part) of ``<test><sep><signal>`` or ``time<sep><test>``; TracesError else."""
    sig = next((s for s in SIGNALS if key.endswith(sep + s)), None)
    if sig is not None:
        name, part = key[: -len(sep + sig)], sig
    elif key.startswith("time" + sep):
        name, part = key[len("time" + sep):], "time"
    else:
        raise _unknown_key(path, key, what, pattern)
    if not _TEST_NAME_RE.match(name) or name in _RESERVED_NAMES:
        raise _fail(path, f"{what} {key!r}: invalid test name {name!r}")
    return name, part


def _arrays_to_raw(
    path: Path, arrays: dict[str, np.ndarray], sep: str, what: str, test: str | None
) -> tuple[_Raw, dict[str, Any], _TimeLabel]:
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
            raise _unnamed_test(path, f"plain 'time' + signal {what}s hold one unnamed test")
        layout[test] = {}
        for key in arrays:
            if key != "time" and key not in SIGNALS:
                raise _unknown_key(path, key, what, pattern)
            layout[test][key] = key
    else:
        for key in arrays:
            name, part = _test_key(path, key, sep, what, pattern)
            layout.setdefault(name, {})[part] = key

    for s in SIGNALS:
        if s not in units:
            raise _fail(path, f"'units' {what} has no entry for {s!r}; add '{s}={UNITS[s]}'")
    time_unit = units.get("time", "s")
    time_factor = _time_factor(path, time_unit, "'units' entry for time")
    time_label = _time_label(time_unit, "time", "'time={}' in 'units'")
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
    return raw, meta, time_label


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
    except (ValueError, RecursionError) as exc:  # also too deep nesting, too long integers
        raise _fail(path, f"meta_json is not valid JSON: {exc}") from exc
    if not isinstance(meta, dict):
        raise _fail(path, "meta_json must hold a JSON object")
    return meta
