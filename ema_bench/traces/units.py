"""Units a traces file may state, their factors to the canonical units, and what a reader
returns: the raw tests and the time label of their file."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import NamedTuple

import numpy as np

from .container import UNITS
from .errors import _fail

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
_OTHER_TIME_UNIT = {"s": "ms", "ms": "s"}  # the unit a mislabelled time column really has
_TIME_UNIT_WORDS = {"s": "seconds", "ms": "milliseconds"}

# test name -> (times in s as written in the file, values (n, 4) in canonical units)
_Raw = dict[str, tuple[np.ndarray, np.ndarray]]


class _TimeLabel(NamedTuple):
    """The time unit a file states, with the advice for when its values are in the other."""

    unit: str   # "s" or "ms"
    mixup: str  # e.g. "the time column looks like milliseconds but is labelled [s]; ..."


def _time_label(unit: str, where: str, relabel: str) -> _TimeLabel:
    """``where`` states ``unit``; ``relabel`` spells a label, ``{}`` standing for the unit."""
    other = _OTHER_TIME_UNIT[unit]
    return _TimeLabel(unit, f"{where} looks like {_TIME_UNIT_WORDS[other]} but is labelled "
                            f"[{unit}]; relabel it {relabel.format(other)}")


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
