"""``--check``: is a (quick) run worse than the committed leaderboard?

The baseline for a check at budget B and S seeds is, per (solver, case, track, seed), the
committed record run at exactly B (a committed quick run, e.g. ``leaderboards/quick/``: same
seeds give the same runs, so only a code change moves the result), or else the committed
record of the smallest budget above B, re-scored as if it had stopped at B (optimistic for
solvers that plan their search around the budget, e.g. multi-start splits).

Regressions are judged per solver and track over all checked cases: a success rate lower by
more than a tolerance, or an ERT worse by more than a factor.  With two seeds a single case
is too coarse a unit (one run flipping across the 1 % success line moves its rate by 0.5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from .scores import ALL, score_records
from .store import RUNS_FILE, is_current, read_records, run_identity


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


def run_id(r: dict) -> tuple:
    """What identifies a run apart from its budget (and model version): a committed run at a
    larger budget can be re-scored at a smaller one."""
    ident = run_identity(r)
    return ident[:4] + ident[5:6]


def committed_files(folder: str | Path) -> list[Path]:
    """The run files of a committed leaderboard: ``DIR/runs.jsonl`` and those one folder
    down (a quick baseline, a supplementary sweep)."""
    folder = Path(folder)
    return [p for p in [folder / RUNS_FILE, *sorted(folder.glob(f"*/{RUNS_FILE}"))]
            if p.is_file()]


def baseline(records: list[dict], budget: int, seeds: int, keys: set[tuple] | None = None
             ) -> tuple[list[dict], dict]:
    """Per (solver, case, track, seed, root seed) (those in ``keys`` when given) the record
    run at exactly ``budget``, else the one of the smallest larger budget truncated to
    ``budget``; and how many of each were used."""
    best: dict[tuple, dict] = {}
    stale = 0
    for r in records:
        if not is_current(r):   # another model version: not comparable
            stale += 1
            continue
        k = run_id(r)
        if r["seed"] >= seeds or r["budget"] < budget or (keys is not None and k not in keys):
            continue
        if k not in best or r["budget"] < best[k]["budget"]:
            best[k] = r
    exact = [r for r in best.values() if r["budget"] == budget]
    larger = [r for r in best.values() if r["budget"] > budget]
    return exact + truncate(larger, budget, seeds), {"same_budget": len(exact),
                                                     "re_scored": len(larger),
                                                     "other_model_version": stale}


def compare(now: list[dict], committed: list[dict], success_tol: float = 0.34,
            ert_factor: float = 2.0) -> list[Regression]:
    """Regressions of ``now`` against ``committed`` (a :func:`baseline`) per (track, solver)
    over the cases both hold: success rate lower by more than ``success_tol`` or ERT worse
    by more than ``ert_factor``."""
    shared = set(map(run_id, now)) & set(map(run_id, committed))

    def index(rs: list[dict]) -> dict:
        rs = [r for r in rs if run_id(r) in shared]
        return {(s.track, s.solver): s for s in score_records(rs) if s.case == ALL}

    a, b = index(committed), index(now)
    bad = []
    for key in sorted(set(a) & set(b)):
        old, new = a[key], b[key]
        if new.success_rate < old.success_rate - success_tol:
            bad.append(Regression(key[0], ALL, key[1], "success", old.success_rate,
                                  new.success_rate))
        if math.isfinite(old.ert) and new.ert > ert_factor * old.ert:
            bad.append(Regression(key[0], ALL, key[1], "ERT", old.ert, new.ert))
    return bad


def load_baseline(folder: str | Path, budget: int, seeds: int, keys: set[tuple] | None = None
                  ) -> tuple[list[dict], dict]:
    """:func:`baseline` over every committed run file under ``folder``."""
    records = [r for p in committed_files(folder) for r in read_records(p)]
    return baseline(records, budget, seeds, keys)
