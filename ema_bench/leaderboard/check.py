"""``--check``: is a (quick) run worse than the committed leaderboard?

The baseline for a check at budget B and S seeds is, per (solver, case, track, seed), the
committed record run at exactly B (a committed quick run, e.g. ``leaderboards/quick/``: same
seeds give the same runs, so only a code change moves the result), or else the committed
record of the smallest budget above B, re-scored as if it had stopped at B (optimistic for
solvers that plan their search around the budget, e.g. multi-start splits).

The test, per solver and track over the runs both hold (sanity case excluded): a one-sided
Mann-Whitney U test (``scipy.stats.mannwhitneyu``, ``alternative="less"``) of the runs' ECDF
areas (:func:`~.anytime.run_area`: every fitness and parameter target, credited by how early
it was reached) now against committed, at a family-wise significance level ``ALPHA`` split
over the comparisons (Bonferroni).  Identical runs never alarm; a rerun in which every run is
a fresh draw alarms with a measured rate of at most ``ALPHA``
(``benchmarks/check_false_alarms.py``, ``leaderboards/README.md``).  Records of another suite
version are refused: the targets differ.
"""

from __future__ import annotations

import importlib.metadata
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from scipy import stats

from ..suites import DEFAULT, suite_of
from ..suites.v1 import SANITY_CASES
from .anytime import run_area
from .run_store import RUNS_FILE, is_current, run_identity
from .scores import ALL

#: Family-wise false-alarm level of one check (all solvers and tracks together).
ALPHA = 0.05
#: where the wheel installs the committed quick baseline, under its data prefix
#: (pyproject.toml, ``[tool.setuptools.data-files]``)
PACKAGED_BASELINE = "share/ema-bench/leaderboards"


def check_suites(records: list[dict], where: str, suite: str = DEFAULT.id) -> None:
    """ValueError naming both versions when ``records`` are of another suite version than
    ``suite`` (a record written before suite versions: ``"none"``)."""
    other = sorted({str(r.get("suite", "none")) for r in records} - {suite})
    if other:
        raise ValueError(f"{where} holds runs of suite version {', '.join(other)}; this is "
                         f"{suite}: their targets differ and they cannot be compared "
                         "(regenerate the baseline with this version, leaderboards/README.md)")


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


def budget_of(budget: int | Callable[[str], int], case: str) -> int:
    """The budget of a case: one number, or (suite emafdi-v2) per case (x its tier)."""
    return int(budget(case)) if callable(budget) else int(budget)


def truncate(records: list[dict], budget: int | Callable[[str], int], seeds: int
             ) -> list[dict]:
    """Committed records as if they had been run with ``budget`` (per case where callable)
    on the first ``seeds``: their ``budget`` is lowered, and the scores re-derive them from
    their evidence up to it (:func:`~.derive.derive`: every target reached after
    ``budget`` is dropped)."""
    return [{**r, "budget": min(budget_of(budget, r["case"]), r["budget"])} for r in records
            if r["seed"] < seeds]


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


def baseline(records: list[dict], budget: int | Callable[[str], int], seeds: int,
             keys: set[tuple] | None = None) -> tuple[list[dict], dict]:
    """Per (solver, case, track, seed, root seed) (those in ``keys`` when given) the record
    run at exactly ``budget`` (per case where callable: v2's per-dimension budget), else
    the one of the smallest larger budget truncated to ``budget``; and how many of each
    were used."""
    best: dict[tuple, dict] = {}
    stale = 0
    for r in records:
        if not is_current(r):   # another model version: not comparable
            stale += 1
            continue
        k = run_id(r)
        if (r["seed"] >= seeds or r["budget"] < budget_of(budget, r["case"])
                or (keys is not None and k not in keys)):
            continue
        if k not in best or r["budget"] < best[k]["budget"]:
            best[k] = r
    exact = [r for r in best.values() if r["budget"] == budget_of(budget, r["case"])]
    larger = [r for r in best.values() if r["budget"] > budget_of(budget, r["case"])]
    return exact + truncate(larger, budget, seeds), {"same_budget": len(exact),
                                                     "re_scored": len(larger),
                                                     "other_model_version": stale}


def compare(now: list[dict], committed: list[dict], alpha: float = ALPHA
            ) -> list[Regression]:
    """Regressions of ``now`` against ``committed`` (a :func:`baseline`): per (track, solver)
    over the non-sanity runs both hold, a one-sided Mann-Whitney U test of the runs' ECDF
    areas (now smaller) significant at ``alpha`` / number of comparisons.  Both sides must
    be runs of one suite version, that of ``now``'s cases (v1, or emafdi-v2 for v2 case
    keys); ValueError otherwise."""
    suites = sorted({suite_of(r["case"]).id for r in now}) or [DEFAULT.id]
    if len(suites) > 1:
        raise ValueError(f"this run mixes suites {', '.join(suites)}: check each apart")
    check_suites(committed, "the baseline", suites[0])
    check_suites(now, "this run", suites[0])
    shared = set(map(run_id, now)) & set(map(run_id, committed))

    def areas(rs: list[dict]) -> dict[tuple[str, str], list[float]]:
        out: dict[tuple[str, str], list[float]] = {}
        for r in sorted(rs, key=run_id):
            if run_id(r) in shared and r["case"] not in SANITY_CASES:
                out.setdefault((r["track"], r["solver"]), []).append(run_area(r))
        return out

    a, b = areas(committed), areas(now)
    keys = sorted(set(a) & set(b))
    bad = []
    for key in keys:
        old, new = a[key], b[key]
        if sorted(old) == sorted(new):
            continue   # the same results (a deterministic rerun): nothing to test
        p = float(stats.mannwhitneyu(new, old, alternative="less").pvalue)
        if p < alpha / len(keys):
            bad.append(Regression(key[0], ALL, key[1], f"ECDF area (p={p:.2g})",
                                  sum(old) / len(old), sum(new) / len(new)))
    return bad


def packaged_baseline() -> Path | None:
    """The committed leaderboard folder this installation can compare with: the checkout's
    ``leaderboards/`` when running from one, else the quick baseline installed with the
    package (``leaderboards/quick/runs.jsonl`` as data under ``<prefix>/share/ema-bench/``);
    None when neither is there."""
    checkout = Path(__file__).resolve().parents[2] / "leaderboards"
    if (checkout / "quick" / RUNS_FILE).is_file():
        return checkout
    try:
        files = importlib.metadata.files("ema-bench") or []
    except importlib.metadata.PackageNotFoundError:
        return None
    for f in files:
        if f.as_posix().endswith(f"{PACKAGED_BASELINE}/quick/{RUNS_FILE}"):
            path = Path(str(f.locate()))
            if path.is_file():
                return path.parent.parent
    return None


def require_baseline(folder: str | Path) -> Path:
    """``folder`` if it holds committed run files (:func:`committed_files`); else a
    ValueError saying so, raised before any run starts."""
    folder = Path(folder)
    if not committed_files(folder):
        packaged = packaged_baseline()
        hint = (f"; the baseline installed with this package is {packaged} (--check with no "
                "folder uses it)" if packaged else
                "; this installation has no baseline (install the wheel, or use a checkout)")
        raise ValueError(f"--check {folder}: no committed runs there ({RUNS_FILE} or "
                         f"*/{RUNS_FILE}){hint}")
    return folder


def load_baseline(folder: str | Path, budget: int | Callable[[str], int], seeds: int,
                  keys: set[tuple] | None = None) -> tuple[list[dict], dict]:
    """:func:`baseline` over every committed run file under ``folder``, of the records the
    judge admits (:func:`~.judge.admitted`; the committed quick baseline is legacy, schema
    1: admitted as a labelled legacy view, it compares the zoo with itself)."""
    from .judge import admitted, read_runs

    lines = read_runs(committed_files(folder))
    mine = [r for r in lines if is_current(r) and r["seed"] < seeds
            and (keys is None or run_id(r) in keys)]
    base, used = baseline(admitted(mine, "--check baseline", complete=False, legacy=True),
                          budget, seeds, keys)
    return base, {**used, "other_model_version": sum(not is_current(r) for r in lines)}
