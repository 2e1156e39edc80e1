"""The effect intervals' calibration table: read it, and the factor it gives.

The reader only, in a module of its own: the workflow (:func:`~ema_bench.diagnosis.fitting.
interval`) reads the factor, while :mod:`~ema_bench.diagnosis.effect_interval_calibration`,
which makes the table, runs the workflow and the blind suite; neither imports the other's side.  The
shipped table is ``interval_calibration.json`` beside this module; a user table (``ema-bench
blind --calibrate --out DIR`` writes DIR/interval_calibration.json) is read only when named
(``--calibration FILE`` or ``EMA_BENCH_INTERVAL_CALIBRATION``,
:mod:`ema_bench.interval_calibration_files`).
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path

from ..interval_calibration_files import TABLES, active, check_table, describe
from ..uncertainty.conformal import conformal_quantile

TABLE = TABLES["interval_calibration.json"]
#: The shipped table.
PATH = TABLE.shipped


@lru_cache(maxsize=4)
def read(path: Path) -> dict:
    """The table in ``path`` (no scores when absent); ValueError (one line) when ``path`` is
    not a table of scored intervals."""
    if not path.exists():
        return {"scores": [], "effect_cases": 0}
    try:
        data = json.loads(path.read_text())
        scores = tuple(float(r["score"]) for r in data["scores"])
    except (UnicodeDecodeError, json.JSONDecodeError, TypeError, KeyError, ValueError) as exc:
        raise ValueError(f"{path}: not an interval calibration table ({exc!r})") from None
    check_table(TABLE.name, data, str(path))   # every score finite and non-negative
    return {**data, "scores": scores}


def active_table() -> dict:
    """The table in use: the shipped one, or the user file named in the environment."""
    return read(active(TABLE)[0])


def factor(level: float = 0.95) -> float:
    """The factor every effect interval's half-widths are multiplied by at ``level`` (1 when
    the active table has no scores)."""
    s = active_table()["scores"]
    return max(1.0, conformal_quantile(s, level)) if s else 1.0


def source() -> str:
    """The active table as command output names it: ``shipped, 58 effect cases`` or
    ``user file PATH, 1 effect case``."""
    return describe(TABLE, int(active_table().get("effect_cases", 0)))
