"""The CSV reader: files written by :meth:`Traces.save` and plain measured CSV files."""

from __future__ import annotations

import csv
import json
import math
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from .container import _RESERVED_NAMES, _TEST_NAME_RE, SIGNALS
from .errors import _fail, _unnamed_test
from .units import _Raw, _time_factor, _time_label, _TimeLabel, _unit_factor

_TIME_NAMES = ("time", "t")

_CSV_MAGIC_RE = re.compile(r"#\s*ema-bench traces v(\S+)\s*$")
_META_RE = re.compile(r"#\s*meta\s*=\s*(.*)$")
_HEADER_RE = re.compile(r"^(?P<name>[^\[\]]*?)\s*(?:\[\s*(?P<unit>[^\[\]]*?)\s*\])?$")


def _read_csv(path: Path, test: str | None) -> tuple[_Raw, dict[str, Any], _TimeLabel]:
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
    header = next(_csv_rows(path, h, lines[h: h + 1]))[1]
    columns = _parse_header(path, h + 1, header)
    rows: list[list[str]] = []
    line_numbers: list[int] = []
    for lineno, row in _csv_rows(path, h + 1, lines[h + 1:]):
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
    time_name, time_unit = _split_label(header[time_col].strip())  # unit checked by the header
    time_label = _time_label(str(time_unit), "the time column", f"'{time_name} [{{}}]'")

    if test_col is None:
        if test is None:
            raise _unnamed_test(path, "no 'test' column")
        return {test: (values[:, time_col], values[:, sig_cols])}, meta, time_label
    names = [row[test_col].strip() for row in rows]
    names_arr = np.array(names)
    raw: _Raw = {}
    for name in dict.fromkeys(names):   # in order of first appearance
        if not _TEST_NAME_RE.match(name) or name in _RESERVED_NAMES:
            raise _fail(path, f"line {line_numbers[names.index(name)]}: invalid test name "
                              f"{name!r} in column 'test'")
        idx = np.flatnonzero(names_arr == name)
        raw[name] = (values[idx, time_col], values[np.ix_(idx, sig_cols)])
    return raw, meta, time_label


def _csv_rows(path: Path, first: int, lines: list[str]) -> Iterator[tuple[int, list[str]]]:
    """CSV records of ``lines`` (line ``first + 1`` onwards) with the number of their last
    line; a quoting error or an oversized field is a TracesError naming the line."""
    reader = csv.reader(lines)
    while True:
        try:
            row = next(reader)
        except StopIteration:
            return
        except csv.Error as exc:  # e.g. a stray quote that swallows the rest of the file
            raise _fail(path, f"line {first + reader.line_num}: malformed CSV: {exc}") from None
        yield first + reader.line_num, row


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
    except (ValueError, RecursionError) as exc:  # also too deep nesting, too long integers
        raise _fail(path, f"line {lineno}: meta is not valid JSON: {exc}") from exc
    if not isinstance(meta, dict):
        raise _fail(path, f"line {lineno}: meta must be a JSON object")
    return meta


def _split_label(label: str) -> tuple[str, str | None]:
    """``"omega_m [rpm]"`` -> ``("omega_m", "rpm")``; no unit -> None."""
    m = _HEADER_RE.match(label)
    return (m.group("name"), m.group("unit")) if m else (label, None)


def _parse_header(path: Path, lineno: int, header: list[str]) -> list[tuple[str, float]]:
    """Column names ('test', 'time' or a signal) with the factor to canonical units."""
    known = ["test", "time [s|ms]", "t [s|ms]", *(f"{s} [unit]" for s in SIGNALS)]
    columns: list[tuple[str, float]] = []
    for raw_label in header:
        label = raw_label.strip()
        name, unit = _split_label(label)
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
