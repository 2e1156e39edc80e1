"""COCO-style scores of run records.

Success: the run's final vector has every parameter within 1 % of its range of the truth.
ERT (expected running time, Hansen et al., COCO): evaluations summed over all runs, a
successful run counted until its first successful evaluation and a failed one at its budget,
divided by the number of successes (infinite without success).

A run that failed with an error (``status: "error"``: the solver raised, or its worker died)
is an unsuccessful run at its budget: it counts in runs, success rate and ERT (a solver that
crashes is worse, not absent), and is left out of the medians of what finished runs measure
(fitness, accuracy, wall time); ``errors`` counts such runs.

Every figure comes from the record's re-derivation (:func:`.derive.derived`: success,
evaluations to success, accuracy and range errors from the evidence and the instance's
truth), never from what the record claims: a record scores here as ``validate`` derives it.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import asdict, dataclass

import numpy as np

from ..faults import FAULT_NAMES
from .anytime import ert as hit_ert
from .derive import derived
from .run_store import is_error

ALL = "all"


@dataclass(frozen=True)
class SolverScore:
    track: str
    case: str
    solver: str
    runs: int
    successes: int
    success_rate: float
    ert: float                     # evaluations; inf without success
    median_evals_to_success: float  # nan without success
    median_fitness: float
    median_wall_s: float
    accuracy: dict[str, float]      # median paper accuracy, % (nan where undefined)
    range_error: dict[str, float]   # median range-normalised error
    errors: int                     # runs that failed with an error (counted in runs)

    def row(self) -> dict[str, object]:
        d = asdict(self)
        for n in FAULT_NAMES:
            d[f"accuracy_{n}"] = d["accuracy"][n]
            d[f"range_error_{n}"] = d["range_error"][n]
        del d["accuracy"], d["range_error"]
        return d


def run_cost(rec: dict) -> int:
    """Evaluations a run counts for ERT: until first success, or its whole budget
    (re-derived: :func:`.derive.derived`)."""
    d = derived(rec)
    return int(d.evals_to_success) if d.success else int(rec["budget"])


def ert(records: list[dict]) -> float:
    """ERT of the success target (the one formula: :func:`.anytime.ert`)."""
    return hit_ert([run_cost(r) if derived(r).success else None for r in records],
                   [r["budget"] for r in records])


def _median(values) -> float:
    v = [x for x in values if x is not None and not (isinstance(x, float) and math.isnan(x))]
    return float(np.median(v)) if v else math.nan


def score_group(track: str, case: str, solver: str, records: list[dict]) -> SolverScore:
    ok = [r for r in records if derived(r).success]
    finished = [r for r in records if not is_error(r)]
    return SolverScore(
        track=track, case=case, solver=solver, runs=len(records), successes=len(ok),
        success_rate=len(ok) / len(records), ert=ert(records),
        median_evals_to_success=_median([run_cost(r) for r in ok]),
        median_fitness=_median([derived(r).fitness for r in finished]),
        median_wall_s=_median([r["wall_s"] for r in finished]),
        accuracy={n: _median([derived(r).accuracy[n] for r in finished])
                  for n in FAULT_NAMES},
        range_error={n: _median([derived(r).range_error[n] for r in finished])
                     for n in FAULT_NAMES},
        errors=len(records) - len(finished),
    )


def score_records(records: list[dict]) -> list[SolverScore]:
    """Scores per (track, case, solver) and per (track, all cases, solver), ranked within
    each (track, case) by ERT, ties by success rate."""
    groups: dict[tuple[str, str, str], list[dict]] = defaultdict(list)
    for r in records:
        groups[(r["track"], r["case"], r["solver"])].append(r)
        groups[(r["track"], ALL, r["solver"])].append(r)
    scores = [score_group(t, c, s, recs) for (t, c, s), recs in groups.items()]
    return sorted(scores, key=rank_key)


def rank_key(s: SolverScore) -> tuple:
    return (s.track, s.case != ALL, s.case, s.ert, -s.success_rate, s.median_fitness,
            s.solver)
