"""Loading: :func:`load_traces` and :func:`load_measured`, and the checks and block
averaging that bring each test of a file to the output period."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .container import OUTPUT_DT, SIGNALS, Traces, _check_positive
from .csv_format import _read_csv
from .errors import TracesError, _fail
from .mat_format import _read_mat
from .npz_format import _read_npz
from .units import _OTHER_TIME_UNIT, _TIME_UNITS, _Raw, _TimeLabel

_MIN_SAMPLES = 10
_RATE_TOL = 1e-6  # relative tolerance on time-step jitter and on the dt / step ratio

# Largest sample rate accepted, as a multiple of 1 / dt: 100 kHz at the default 1 ms, far above
# any actuator test (the controller runs at 20 kHz) and far below the 1000x of a time column
# in seconds labelled [ms], which is thus caught instead of averaged into a few samples.
MAX_OVERSAMPLING = 100


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
        sub-multiple of ``dt`` (e.g. 10 kHz), at most :data:`MAX_OVERSAMPLING` times finer, are
        block-averaged to ``dt``: each output sample is the mean over its window, as in the
        model; a trailing partial window is dropped.
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
        repeated or non-uniform times, NaN gaps, an unsupported sample rate (times in
        milliseconds labelled seconds, or the reverse, are named as such); declares an array
        larger than :data:`MAX_ARRAY_BYTES` or larger than the data it holds; or is too short.
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
    # huge values may overflow to inf on the way (unit factors, time steps, window means):
    # each non-finite result is then reported with its place, no numpy warning needed
    with np.errstate(over="ignore", invalid="ignore"):
        raw, meta, time_label = readers[suffix](path, test)
        raw = _select_test(path, raw, test)
        data = {name: _regularise(path, name, t, x, dt, min_duration, time_label)
                for name, (t, x) in raw.items()}
    try:
        return Traces(data, dt=dt, meta=meta)
    except TracesError as exc:
        raise TracesError(f"{path}: {exc}") from exc


def load_measured(
    paths: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
    tests: str | Sequence[str | None] | None = None,
    *,
    dt: float = OUTPUT_DT,
    min_duration: float | None = None,
) -> Traces:
    """Read the tests of one or more files (``.csv``, ``.npz``, ``.mat``) into one Traces.

    Parameters
    ----------
    paths : path or sequence of paths
        Files to read, each with :func:`load_traces`.
    tests : str or sequence of (str or None), optional
        One test name per file, in file order: the name of the single test of a file that does
        not name its tests (a plain CSV without ``test`` column, say), or the one test to take
        from a file that does; None takes all the tests a file names.  Default: None for every
        file.
    dt, min_duration : float, optional
        As for :func:`load_traces` (s); files sampled at other supported rates are all brought
        to ``dt``.

    Returns
    -------
    Traces
        Every test of every file, in file order; ``meta`` holds the entries on which the files
        do not disagree.

    Raises
    ------
    TracesError
        If no file is given, the numbers of files and test names differ, a test comes from two
        files, or a file fails to load (see :func:`load_traces`).
    """
    paths = [paths] if isinstance(paths, str | os.PathLike) else list(paths)
    if not paths:
        raise TracesError("no traces file given")
    names = ([None] * len(paths) if tests is None
             else [tests] if isinstance(tests, str) else list(tests))
    if len(names) != len(paths):
        raise TracesError(f"{len(paths)} file(s) but {len(names)} test name(s) "
                          f"({', '.join(map(str, names))}); give one test name per file")
    data: dict[str, np.ndarray] = {}
    origin: dict[str, Path] = {}
    metas = []
    for path, name in zip(paths, names, strict=True):
        traces = load_traces(path, test=name, dt=dt, min_duration=min_duration)
        for test in traces.tests:
            if test in origin:
                raise TracesError(f"test {test!r} is in both {origin[test]} and {path}; "
                                  "each test must come from one file")
            origin[test], data[test] = Path(path), traces.data[test]
        metas.append(traces.meta)
    return Traces(data, dt=dt, meta=_agreed_meta(metas))


def _agreed_meta(metas: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """The entries of the ``metas`` that no two of them give different values."""
    merged: dict[str, Any] = {}
    clashes: set[str] = set()
    for meta in metas:
        for key, value in meta.items():
            if merged.setdefault(key, value) != value:
                clashes.add(key)
    return {k: v for k, v in merged.items() if k not in clashes}


def _select_test(path: Path, raw: _Raw, test: str | None) -> _Raw:
    if not raw:
        raise _fail(path, "no data")
    if test is None or list(raw) == [test]:
        return raw
    if test not in raw:
        raise _fail(path, f"test {test!r} not in file; found: {', '.join(raw)}")
    return {test: raw[test]}


def _regularise(
    path: Path, test: str, t: np.ndarray, x: np.ndarray, dt: float, min_duration: float | None,
    time_label: _TimeLabel,
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
    step = float(t[-1] - t[0]) / (n - 1)  # a Python float: no numpy overflow warnings
    jitter = np.abs(step_k - step)
    k = int(np.argmax(jitter))
    if jitter[k] > _RATE_TOL * step:
        raise _fail(path, f"test {test!r}: non-uniform sampling: step {step_k[k]:.9g} s at "
                          f"sample index {k + 1} differs from the mean step {step:.9g} s by more "
                          f"than {_RATE_TOL:g} relative")
    m = _block_size(dt, step)
    if m is None:
        raise _rate_error(path, test, dt, step, time_label)
    if m > 1:
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


def _block_size(dt: float, step: float) -> int | None:
    """Samples per output window of ``dt`` s for a file step of ``step`` s: an integer from 1
    to :data:`MAX_OVERSAMPLING`, or None when the file rate is not supported."""
    if not 0.0 < step < math.inf:  # a step of 0 or inf after underflow or overflow
        return None
    ratio = dt / step
    if not ratio < MAX_OVERSAMPLING + 0.5:  # also inf (a subnormal step)
        return None
    m = round(ratio)
    return m if m >= 1 and abs(ratio - m) <= _RATE_TOL * ratio else None


def _rate_error(
    path: Path, test: str, dt: float, step: float, time_label: _TimeLabel
) -> TracesError:
    """The error for an unsupported sample rate, naming a seconds/milliseconds mix-up."""
    if not 0.0 < step < math.inf:  # times spanning more than a float: no rate to speak of
        return _fail(path, f"test {test!r}: unusable time step {step!r} s")
    # read in the other unit, would the step be a supported one?  then the label is wrong
    factor = _TIME_UNITS[_OTHER_TIME_UNIT[time_label.unit]] / _TIME_UNITS[time_label.unit]
    if _block_size(dt, step * factor) is not None:
        return _fail(path, f"test {test!r}: {time_label.mixup}")
    rates = f"file rate {1.0 / step:.6g} Hz, expected {1.0 / dt:.6g} Hz"
    if dt / step < 1.0:
        return _fail(path, f"test {test!r}: sample rate too low ({rates}); data coarser than "
                           "dt cannot be used")
    if dt / step > MAX_OVERSAMPLING + 0.5:
        return _fail(path, f"test {test!r}: sample rate too high ({rates}); at most "
                           f"{MAX_OVERSAMPLING} times the expected rate is supported")
    return _fail(path, f"test {test!r}: sample rate is not an integer multiple of the "
                       f"expected rate ({rates})")
