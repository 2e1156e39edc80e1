"""Blind test of the workflow: hidden cases it must diagnose without seeing the answer.

Each case hides random faults and one of: a library effect at a random magnitude above its
detection threshold (log-uniform in [detect, 4 detect], capped at its bound, random sign for
two-sided effects), nothing (null case), or a decoy outside the library.  Scores: naming
accuracy (top-1), false alarms on null cases, held-out gap closed, parameter error, and what
became of the decoys.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..effects import DECOYS, EFFECT_NAMES, EFFECTS, LIBRARY
from ..faults import faults_to_dict, random_faults
from ..leaderboard.store import RunStore, is_current, read_records
from ..progress import progress
from ..protocol import HOLDOUT_TESTS, STANDARD_TESTS
from ..reference import simulate_reference
from ..seeding import run_seed, stream
from ..trace_cache import MODEL_VERSION
from .workflow import Settings, diagnose

DRAWABLE = tuple(n for n in LIBRARY if math.isfinite(EFFECTS[EFFECT_NAMES.index(n)].detect))
SHARE_NULL = 0.2
SHARE_DECOY = 0.15


@dataclass(frozen=True)
class BlindCase:
    index: int
    kind: str                 # "effect" | "null" | "decoy"
    effect: str | None
    value: float
    faults: dict[str, float]


def draw_cases(n: int, seed: int) -> list[BlindCase]:
    """``n`` hidden cases of the suite of root seed ``seed``; kinds are laid out in fixed
    shares, effects cycle through the drawable library so every effect appears.

    The layout (kinds, effect order, magnitudes) comes from the root's ``plan`` stream; case
    ``i``'s faults from the ``instance`` stream of run ``i`` (``run_seed(seed, i)``)."""
    n_null = max(1, round(SHARE_NULL * n))
    n_decoy = max(1, round(SHARE_DECOY * n))
    kinds = ["null"] * n_null + ["decoy"] * n_decoy + ["effect"] * (n - n_null - n_decoy)
    rng = np.random.default_rng(stream(seed, "plan"))
    rng.shuffle(kinds)
    cases, k_eff, k_dec = [], 0, 0
    order = [str(n) for n in rng.permutation(DRAWABLE)]
    for i, kind in enumerate(kinds):
        faults = faults_to_dict(random_faults(stream(run_seed(seed, i), "instance"), 1.0))
        name, value = None, 0.0
        if kind != "null":
            if kind == "effect":
                name = order[k_eff % len(order)]
                k_eff += 1
            else:
                name = DECOYS[k_dec % len(DECOYS)]
                k_dec += 1
            spec = EFFECTS[EFFECT_NAMES.index(name)]
            hi = min(4.0 * spec.detect, max(abs(spec.lower), spec.upper))
            value = float(math.exp(rng.uniform(math.log(spec.detect), math.log(hi))))
            if spec.lower < 0.0 and rng.random() < 0.5 and -value >= spec.lower:
                value = -value
        cases.append(BlindCase(i, kind, name, value, faults))
    return cases


def case_record(case: BlindCase, seed: int) -> dict:
    """What identifies a case's record: its key, run (root seed, seed), model version and the
    hidden truth."""
    return {"key": f"case{case.index}", "root_seed": int(seed), "seed": case.index,
            "model_version": MODEL_VERSION, **asdict(case)}


def run_case(case: BlindCase, seed: int, settings: Settings) -> dict:
    """Simulate a hidden case, diagnose it blind, and score the answer.

    Case ``i`` of root ``seed`` is run ``i`` of the seed tree: the traces of ``ema-bench
    simulate --root-seed R --seed i`` and the diagnosis of ``ema-bench diagnose --root-seed R
    --seed i``."""
    t0 = time.perf_counter()
    effects = {case.effect: case.value} if case.effect else {}
    x = np.array(list(case.faults.values()))
    node = run_seed(seed, case.index)
    measured = simulate_reference(x, effects, tests=STANDARD_TESTS + HOLDOUT_TESTS,
                                  seed=stream(node, "noise"))
    # the workflow sees the traces only
    d = diagnose(measured.with_meta(faults=None, effects=None), settings,
                 seed=stream(node, "diagnosis"))
    named = [e.name for e in d.effects]
    rec = {**case_record(case, seed), "verdict": d.verdict, "named": named,
           "partial": d.gap.get("partial"), "gap_closed": d.gap.get("closed", 0.0),
           "gap_before": d.gap["before"], "gap_after": d.gap["after"],
           "message": d.message, "evaluations": d.evaluations,
           "wall_s": time.perf_counter() - t0}
    if case.kind == "effect":
        rec["correct"] = bool(named) and named[0] == case.effect
        rec["named_partial"] = bool(d.effects) and d.effects[0].partial
        if rec["correct"]:
            est = d.effects[0].params[case.effect]
            rec["estimate"] = est
            rec["param_error"] = abs(est - case.value) / abs(case.value)
            rec["interval"] = [float(v) for v in d.effects[0].interval]
            rec["interval_covers"] = bool(rec["interval"][0] <= case.value
                                          <= rec["interval"][1])
    elif case.kind == "null":
        rec["false_alarm"] = d.verdict != "none"
    else:
        rec["decoy_ok"] = d.verdict in ("unexplained", "none") or bool(d.gap.get("partial"))
    return rec


def summarise(records: list[dict]) -> dict[str, object]:
    eff = [r for r in records if r["kind"] == "effect"]
    null = [r for r in records if r["kind"] == "null"]
    dec = [r for r in records if r["kind"] == "decoy"]
    closed = [r["gap_closed"] for r in eff if r.get("correct")]
    perr = [r["param_error"] for r in eff if "param_error" in r]
    covers = [r["interval_covers"] for r in eff if "interval_covers" in r]
    per_effect: dict[str, list[int]] = {}
    for r in eff:
        per_effect.setdefault(r["effect"], [0, 0])
        per_effect[r["effect"]][0] += int(r["correct"])
        per_effect[r["effect"]][1] += 1
    return {
        "cases": len(records),
        "effect_cases": len(eff), "naming_accuracy": (sum(r["correct"] for r in eff) / len(eff)
                                                      if eff else math.nan),
        "null_cases": len(null), "false_alarms": sum(r["false_alarm"] for r in null),
        # a decoy is handled when no library effect is claimed as the whole answer
        "decoy_cases": len(dec), "decoys_unexplained_or_partial": sum(r["decoy_ok"]
                                                                      for r in dec),
        "decoys_by_outcome": {
            "unexplained": sum(r["verdict"] == "unexplained" for r in dec),
            "named_partial": sum(r["verdict"] == "effect" and bool(r.get("partial"))
                                 for r in dec),
            "not_detected": sum(r["verdict"] == "none" for r in dec),
            "named": sum(r["verdict"] == "effect" and not r.get("partial") for r in dec)},
        # correct names whose model still leaves the envelopes (e.g. at heavy stiction)
        "named_partial": sum(bool(r.get("named_partial")) for r in eff if r.get("correct")),
        "median_heldout_gap_closed": float(np.median(closed)) if closed else math.nan,
        "median_param_error": float(np.median(perr)) if perr else math.nan,
        # how often the named effect's 95 % interval contains its true value
        "interval_coverage": (f"{sum(covers)}/{len(covers)}" if covers else None),
        "per_effect": {k: f"{v[0]}/{v[1]}" for k, v in sorted(per_effect.items())},
        "wall_s": float(sum(r["wall_s"] for r in records)),
    }


def run_blind(n: int, seed: int, out: str | Path | None = None,
              settings: Settings | None = None, quiet: bool = True) -> dict[str, object]:
    """Run (or resume, with ``out``) a blind suite of ``n`` cases and summarise it; progress
    as :func:`~ema_bench.progress.progress` shows it unless ``quiet``."""
    settings = settings or Settings()
    cases = draw_cases(n, seed)
    records: list[dict] = []
    store = RunStore(Path(out) / "blind.jsonl") if out else None
    # cases of another model version are stale: run again, recorded beside the old ones
    done = {r["key"]: r for r in read_records(store.path) if is_current(r)} if store else {}
    try:
        with progress(len(cases), "blind", "case", quiet=quiet) as bar:
            for case in cases:
                rec = done.get(f"case{case.index}")
                if rec is None:
                    rec = run_case(case, seed, settings)
                    if store:
                        store.append(rec)
                else:
                    _check_resumed(rec, case, seed, store.path)
                records.append(rec)
                bar.update(f"case{case.index} {rec['verdict']}")
    finally:
        if store:
            store.close()
    return {"seed": seed, "summary": summarise(records), "records": records}


def _check_resumed(rec: dict, case: BlindCase, seed: int, path: Path) -> None:
    """A recorded case reused on resume must be the case drawn now, of the same root seed."""
    drawn = {**asdict(case), "root_seed": seed}
    if any(rec.get(k) != v for k, v in drawn.items()):
        raise ValueError(f"{path}: case{case.index} there is not the case drawn for this "
                         "seed and number of cases; use another --out for another suite")
