"""A tracking run's files: the lines of ``OUT/track.jsonl`` (one per unit and inspection, or
an error line), their schema and their reading back (:func:`read_track`); the campaign a run
names.  The tracker API is :mod:`.tracking`, the run loop :mod:`.track_run`."""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ..faults import FAULT_NAMES
from ..jsonio import plain
from ..sweep.schema import opt, req

if TYPE_CHECKING:
    from .campaign import Campaign

from .tracking import (
    FORMAT,
    INFINITE_FIELDS,
    MANIFEST_FILE,
    TRACK_FILE,
    Inspection,
    TrackerError,
    TrackStep,
)

log = logging.getLogger("ema_bench")


# --- records ---------------------------------------------------------------------------------

def _key(unit: str, index: int | str) -> str:
    return f"{unit}/{index:03d}" if isinstance(index, int) else f"{unit}/{index}"


def step_record(inspection: Inspection, step: TrackStep) -> dict:
    """The JSON line of a step: ``{"key", "unit", "index", "flight", **TrackStep}`` with
    infinite RULs as null and floats as plain floats."""
    d = asdict(step)
    for k in ("estimate", "low", "high"):
        d[k] = {n: float(d[k][n]) for n in FAULT_NAMES}
    for k in INFINITE_FIELDS:
        v = float(d[k])
        d[k] = v if math.isfinite(v) else None
    d["replace"] = bool(d["replace"])
    d["evaluations"] = int(d["evaluations"])
    d["flight"] = int(d["flight"])
    d["extra"] = plain(d["extra"], default=str)
    if d["rul_quantiles"]:   # infinite quantiles as null; absent when not given
        from .distributions import check_quantiles
        d["rul_quantiles"] = {k: (v if math.isfinite(v) else None)
                              for k, v in check_quantiles(d["rul_quantiles"]).items()}
    else:
        del d["rul_quantiles"]
    if d["profile_rul"] is None:   # not given: not written
        del d["profile_rul"]
    else:
        d["profile_rul"] = float(d["profile_rul"]) if math.isfinite(d["profile_rul"]) else None
    return {"key": _key(inspection.unit, inspection.index), "unit": inspection.unit,
            "index": inspection.index, **d}


def error_record(unit: str, index: int, flight: int, exc: BaseException) -> dict:
    """The line of a unit whose tracker raised or answered nonsense at inspection ``index``."""
    return {"key": _key(unit, "error"), "unit": unit, "index": index, "flight": flight,
            "status": "error", "error": f"{type(exc).__name__}: {exc}"}


def _restore(record: dict) -> dict:
    """A step line as the tracker answered it: null RULs back to ``inf``."""
    r = dict(record)
    for k in INFINITE_FIELDS:
        if r.get(k, 0) is None:
            r[k] = math.inf
    if "profile_rul" in r and r["profile_rul"] is None:
        r["profile_rul"] = math.inf
    if r.get("rul_quantiles"):
        r["rul_quantiles"] = {q: math.inf if v is None else v
                              for q, v in r["rul_quantiles"].items()}
    return r


#: The fields of a step line, by JSON type (a hand-edited ``"replace": "no"`` is refused,
#: not read as true).
STEP_SCHEMA = {"key": req("str"), "unit": req("str"), "index": req("int"),
               "flight": req("int"), "estimate": req("dict", values="number|null"),
               "low": req("dict", values="number|null"),
               "high": req("dict", values="number|null"), "rul": req("number|null"),
               "rul_low": req("number|null"), "rul_high": req("number|null"),
               "failing_fault": req("str|null"),
               "replace": req("bool"), "evaluations": req("int"), "extra": opt("dict"),
               "rul_quantiles": opt("dict", values="number|null"),
               "profile_rul": opt("number|null")}
#: The fields of the error line of a unit whose tracker failed.
ERROR_SCHEMA = {"key": req("str"), "unit": req("str"), "index": req("int"),
                "flight": req("int"), "status": req("str"), "error": req("str")}


def line_schema(record: dict) -> dict:
    return ERROR_SCHEMA if record.get("status") == "error" else STEP_SCHEMA


@dataclass
class TrackLog:
    """A tracking run read back (:func:`read_track`).

    ``steps``: unit -> its step records in inspection order (RULs ``inf`` where the file says
    null); ``failed``: unit -> its error record
    (its steps before the failure stay in ``steps``); ``manifest``: the run's manifest."""

    steps: dict[str, list[dict]]
    failed: dict[str, dict]
    manifest: dict


def read_track(out: Path | str) -> TrackLog:
    """Read ``OUT/track.jsonl`` and ``OUT/manifest.json`` of :func:`track_campaign` (every
    line type-checked: :data:`STEP_SCHEMA`)."""
    from ..sweep.store import read_records

    out = Path(out)
    mpath = out / MANIFEST_FILE
    if not mpath.is_file():
        raise TrackerError(f"{out}: not a tracking run (no {MANIFEST_FILE}; run "
                           "'ema-bench campaign track' first)")
    manifest = json.loads(mpath.read_text(encoding="utf-8"))
    if manifest.get("format") != FORMAT:
        raise TrackerError(f"{mpath}: not a tracking run's manifest (format "
                           f"{manifest.get('format')!r}, expected {FORMAT!r})")
    steps, failed = regroup(read_records(out / TRACK_FILE, schema=line_schema))
    return TrackLog(steps, failed, manifest)


def campaign_path(out: Path | str, manifest: Mapping) -> Path:
    """The campaign folder of the tracking run in ``out`` (its manifest stores it relative to
    ``out``)."""
    return Path(out) / manifest["campaign"]


def regroup(records: list[dict]) -> tuple[dict[str, list[dict]], dict[str, dict]]:
    """Step lines by unit (inspection order, null RULs back to ``inf``) and error lines by
    unit, as :class:`TrackLog` holds them."""
    steps: dict[str, dict[int, dict]] = {}
    failed: dict[str, dict] = {}
    for r in records:
        if r.get("status") == "error":
            failed[r["unit"]] = r
        else:
            steps.setdefault(r["unit"], {})[int(r["index"])] = _restore(r)
    out = {unit: [by_index[i] for i in sorted(by_index)] for unit, by_index in steps.items()}
    return out, failed


def unit_done(campaign: Campaign):
    """record -> the unit it completes (a failure, or the step of its last inspection), or
    ``None``: a unit tracked part of the way (by a run before steps were written unit by
    unit) is tracked again."""
    last = {u: len(rows) - 1 for u, rows in campaign.units.items()}

    def task_of(record: dict) -> str | None:
        unit = record["unit"]
        if record.get("status") == "error" or record["index"] == last.get(unit):
            return unit
        return None
    return task_of
