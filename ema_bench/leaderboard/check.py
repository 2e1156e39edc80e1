"""``--check``: is a (quick) run worse than the committed leaderboard?

The committed records hold every run's first-success evaluation and best-so-far trace, so
they can be re-scored at the quick run's budget and seeds: a fair reference for a cheaper run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .scores import Score, score_records


@dataclass(frozen=True)
class Regression:
    track: str
    case: str
    solver: str
    what: str
    committed: float
    now: float

    def __str__(self) -> str:
        return (f"{self.track:<9} {self.case:<8} {self.solver:<14} {self.what:<12} "
                f"committed {self.committed:.4g} -> now {self.now:.4g}")


def truncate(records: list[dict], budget: int, seeds: int) -> list[dict]:
    """Committed records as if they had been run with ``budget`` on the first ``seeds``."""
    out = []
    for r in records:
        if r["seed"] >= seeds:
            continue
        r = dict(r)
        ok = r["success"] and r.get("evals_to_success") and r["evals_to_success"] <= budget
        r["success"] = bool(ok)
        r["budget"] = min(budget, r["budget"])
        out.append(r)
    return out


def compare(now: list[dict], committed: list[dict], success_tol: float = 0.34,
            ert_factor: float = 2.0) -> list[Regression]:
    """Regressions of ``now`` against ``committed`` (already truncated) per (track, case,
    solver) present in both: success rate lower by more than ``success_tol`` or ERT worse
    by more than ``ert_factor``."""
    def index(scores: list[Score]) -> dict:
        return {(s.track, s.case, s.solver): s for s in scores}

    a, b = index(score_records(committed)), index(score_records(now))
    bad = []
    for key in sorted(set(a) & set(b)):
        old, new = a[key], b[key]
        if new.success_rate < old.success_rate - success_tol:
            bad.append(Regression(*key, "success", old.success_rate, new.success_rate))
        if math.isfinite(old.ert) and new.ert > ert_factor * old.ert:
            bad.append(Regression(*key, "ERT", old.ert, new.ert))
    return bad
