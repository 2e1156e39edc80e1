"""The blind suite's summary: per category, what the workflow named, missed and misnamed,
against the hidden truth (:func:`summarise`; the categories: :mod:`.blind_categories`)."""

from __future__ import annotations

import math
import statistics
from collections import Counter
from collections.abc import Callable, Sequence

from ..sweep.schema import opt, req
from .blind_categories import (
    CATEGORIES,
    CHAIN_CATEGORIES,
    EFFECT_ACQUISITION,
    EXTRA_CATEGORIES,
    FOURTH_CATEGORIES,
    LOOP_CATEGORIES,
    OUTSIDE_CATEGORIES,
    OUTSIDE_KINDS,
)


def _rate(k: int, n: int) -> float:
    return k / n if n else math.nan


def _median(values: Sequence[float]) -> float:
    return float(statistics.median(values)) if values else math.nan


def _fraction(flags: Sequence[bool]) -> str | None:
    return f"{sum(flags)}/{len(flags)}" if flags else None


def _tally(pairs: Sequence[tuple[str, bool]]) -> dict[str, str]:
    """``label -> "hits/cases"``, sorted by label."""
    hits: dict[str, list[int]] = {}
    for label, ok in pairs:
        hits.setdefault(label, [0, 0])
        hits[label][0] += int(ok)
        hits[label][1] += 1
    return {k: f"{v[0]}/{v[1]}" for k, v in sorted(hits.items())}


#: The record field that says an effect case's truth was found, by category.
FOUND = {"single": "correct", "near_threshold": "correct", "two_effect": "both_named",
         "three_effect": "all_named", **{c: "effect_named" for c in EFFECT_ACQUISITION}}


def _found(r: dict) -> bool:
    """Whether an effect case's truth was found: named first, both of a pair or all three of
    a triple named, the effect beside an acquisition fault named."""
    return bool(r.get(FOUND[r["category"]]))


def _misnames(rs: list[dict]) -> int:
    """Cases with a confidently named suspect that is not there."""
    return sum(bool(r.get("misnamed")) for r in rs)


def _effect_block(rs: list[dict]) -> dict[str, object]:
    """Figures shared by the effect categories: gap, parameter error, interval coverage."""
    found = [r for r in rs if _found(r)]
    return {
        "named_partial": sum(bool(r.get("named_partial")) for r in found),
        "median_heldout_gap_closed": _median([r["gap_closed"] for r in found]),
        "median_param_error": _median([e for r in rs for e in r["param_errors"].values()]),
        "interval_coverage": _fraction([c for r in rs for c in r["interval_covers"].values()]),
    }


def _single_block(rs: list[dict]) -> dict[str, object]:
    correct = sum(r["correct"] for r in rs)
    return {"cases": len(rs), "correct": correct, "naming_accuracy": _rate(correct, len(rs)),
            "per_effect": _tally([(next(iter(r["effects"])), r["correct"]) for r in rs]),
            **_effect_block(rs)}


def _pair_block(rs: list[dict]) -> dict[str, object]:
    both, one = sum(r["both_named"] for r in rs), sum(r["one_named"] for r in rs)
    return {"cases": len(rs), "both_named": both, "both_named_rate": _rate(both, len(rs)),
            "one_named": one, "one_named_rate": _rate(one, len(rs)),
            "per_pair": _tally([("+".join(sorted(r["effects"])), r["both_named"])
                                for r in rs]),
            **_effect_block(rs)}


def _triple_block(rs: list[dict]) -> dict[str, object]:
    alln = sum(r["all_named"] for r in rs)
    return {"cases": len(rs), "all_named": alln, "all_named_rate": _rate(alln, len(rs)),
            "effects_named": f"{sum(r['n_named'] for r in rs)}/{3 * len(rs)}",
            "confident_misnames": _misnames(rs),
            "per_triple": _tally([("+".join(sorted(r["effects"])), r["all_named"])
                                  for r in rs]),
            **_effect_block(rs)}


def _effect_acquisition_block(rs: list[dict]) -> dict[str, object]:
    eff = sum(r["effect_named"] for r in rs)
    ok = sum(r["acquisition_ok"] for r in rs)
    return {"cases": len(rs), "effect_named": eff, "effect_named_rate": _rate(eff, len(rs)),
            "acquisition_named": sum(r["acquisition_named"] for r in rs),
            "acquisition_named_or_flagged": ok,
            "acquisition_named_or_flagged_rate": _rate(ok, len(rs)),
            "confident_misnames": _misnames(rs),
            "per_effect": _tally([(next(iter(r["effects"])), r["effect_named"]) for r in rs]),
            "per_acquisition": _tally([(r["decoy"], r["acquisition_ok"]) for r in rs]),
            **_effect_block(rs)}


def _null_block(rs: list[dict]) -> dict[str, object]:
    alarms = sum(r["false_alarm"] for r in rs)
    return {"cases": len(rs), "false_alarms": alarms, "false_alarm_rate": _rate(alarms, len(rs)),
            "by_verdict": dict(sorted(Counter(r["verdict"] for r in rs).items()))}


def _decoy_outcomes(rs: list[dict]) -> dict[str, int]:
    # named, but flagged partial (or the acquisition decoy itself named): handled
    partial = [r["verdict"] == "effect" and bool(r["decoy_ok"]) for r in rs]
    return {"unexplained": sum(r["verdict"] == "unexplained" for r in rs),
            "named_partial": sum(partial),
            "not_detected": sum(r["verdict"] == "none" for r in rs),
            "acquisition_named": sum(r["verdict"] == "acquisition" and bool(r["decoy_ok"])
                                     for r in rs),
            "named": sum(not r["decoy_ok"] for r in rs)}


def _decoy_block(rs: list[dict]) -> dict[str, object]:
    ok = sum(r["decoy_ok"] for r in rs)
    return {"cases": len(rs), "ok": ok, "ok_rate": _rate(ok, len(rs)),
            "by_outcome": _decoy_outcomes(rs),
            "ok_by_decoy": _tally([(r["decoy"], r["decoy_ok"]) for r in rs])}


def _outside_block(rs: list[dict]) -> dict[str, object]:
    """Outside-library physics: the right term named (equation and form), the gap closed
    when it is, and the outcome per physics."""
    right = [r for r in rs if r["right_term"]]
    return {"cases": len(rs), "right_term": len(right),
            "right_term_rate": _rate(len(right), len(rs)),
            "term_named": sum(r["term_named"] for r in rs),
            "median_gap_closed_when_named": _median(
                [r["gap_closed"] for r in right if r["term_named"]]),
            "right_by_physics": _tally([(next(iter(r["effects"])), r["right_term"])
                                        for r in rs]),
            "median_cpu_s": _median([r["cpu_s"] for r in rs if "cpu_s" in r])}


def _outside_null_block(rs: list[dict]) -> dict[str, object]:
    return {**_null_block(rs), "discoveries": sum(r["discoveries"] for r in rs)}


_BLOCKS: dict[str, Callable[[list[dict]], dict[str, object]]] = {
    "single": _single_block, "near_threshold": _single_block, "two_effect": _pair_block,
    "null": _null_block, "monitor_null": _null_block, "physical_decoy": _decoy_block,
    "acquisition_decoy": _decoy_block, "effect_acquisition": _effect_acquisition_block,
    "three_effect": _triple_block,
    **{c: _effect_acquisition_block for c in FOURTH_CATEGORIES + CHAIN_CATEGORIES},
    **{c: _outside_block for c in OUTSIDE_KINDS}, "outside_null": _outside_null_block,
    "outside_monitor_null": _outside_null_block,
}


#: A blind suite's ``OUT/summary.json`` (``ema-bench blind``), by JSON type: checked before it
#: is written, and the published JSON Schema (``ema-bench schema blind-summary``) is made from
#: it (``confident_misnames``: suites written before the third round lack it;
#: ``interval_calibration``: the table the intervals were calibrated with).
SUMMARY_SCHEMA = {
    "command": req("str"), "cases": req("int"), "categories": req("dict", values="int"),
    "effect_cases": req("int"), "naming_accuracy": req("number|null"),
    "per_effect": req("dict"), "null_cases": req("int"), "false_alarms": req("int"),
    "decoy_cases": req("int"), "decoys_unexplained_or_partial": req("int"),
    "decoys_by_outcome": req("dict"), "confident_misnames": opt("int"),
    "named_partial": req("int"), "median_heldout_gap_closed": req("number|null"),
    "median_param_error": req("number|null"), "interval_coverage": req("str|number|null"),
    "per_category": req("dict", values="dict"), "wall_s": req("number"),
    "interval_calibration": opt("str"),
}


def summarise(records: list[dict]) -> dict[str, object]:
    """The suite's figures: overall (naming accuracy over single and near-threshold cases,
    false alarms over both null kinds, decoys handled, gap closed over the found effect
    cases, parameter error and interval coverage over every found true effect) and one block
    per category (``per_category``)."""
    # the third round's categories appear when the suite has them
    present = {r["category"] for r in records}
    by = {c: [r for r in records if r["category"] == c]
          for c in (*CATEGORIES, *(c for c in (*EXTRA_CATEGORIES, *FOURTH_CATEGORIES,
                                                *CHAIN_CATEGORIES, *OUTSIDE_CATEGORIES,
                                                *LOOP_CATEGORIES) if c in present))}
    named = by["single"] + by["near_threshold"]
    effect = named + by["two_effect"] + by.get("three_effect", []) + [
        r for c in EFFECT_ACQUISITION for r in by.get(c, [])]
    null = by["null"] + by["monitor_null"]
    dec = by["physical_decoy"] + by["acquisition_decoy"]
    return {
        "cases": len(records),
        "categories": {c: len(rs) for c, rs in by.items()},
        "effect_cases": len(named),
        "naming_accuracy": _rate(sum(r["correct"] for r in named), len(named)),
        "per_effect": _tally([(next(iter(r["effects"])), r["correct"]) for r in named]),
        "null_cases": len(null), "false_alarms": sum(r["false_alarm"] for r in null),
        # a decoy is handled when no library effect is claimed as the whole answer
        "decoy_cases": len(dec), "decoys_unexplained_or_partial": sum(r["decoy_ok"]
                                                                      for r in dec),
        "decoys_by_outcome": _decoy_outcomes(dec),
        # a suspect named without a partial flag that the case does not hold
        "confident_misnames": _misnames(effect + dec),
        # found effects whose model still leaves the envelopes (e.g. at heavy stiction)
        **_effect_block(effect),
        "per_category": {c: _BLOCKS[c](rs) for c, rs in by.items()},
        "wall_s": float(sum(r["wall_s"] for r in records)),
    }


