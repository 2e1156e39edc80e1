"""Red team: every way we found to get a score without earning it, refused or made harmless.

Forgeries of a submitter (who edits ``runs.jsonl``) are refused by ``validate``'s
re-derivation with a one-line message naming the field and both values; a solver (which runs
in our process) gets a view with no path to the truth, and one that reads memory it was not
given is caught by replay; names from plugins are refused or escaped.  Real records: the
committed legacy quick board (v1, schema 1), and real runs of the zoo.
"""

from __future__ import annotations

import copy
import csv
import json
import types
from pathlib import Path

import evidence
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ema_bench import register_solver
from ema_bench.escape import check_name, csv_value, markdown
from ema_bench.faults import FAULT_NAMES, faults_to_dict
from ema_bench.leaderboard.anytime import anytime_scores
from ema_bench.leaderboard.replay import replay
from ema_bench.leaderboard.report import write_leaderboards
from ema_bench.leaderboard.scores import score_records
from ema_bench.leaderboard.tasks import Task, error_record, run_task
from ema_bench.leaderboard.validate import check_record
from ema_bench.problem import Problem, SolverView
from ema_bench.registry import SolverError, SolveResult, run_solver
from ema_bench.scoring import Score
from ema_bench.seeding import run_seed
from ema_bench.suites.problem import make_problem
from ema_bench.suites.v1 import instance_names

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def legacy() -> list[dict]:
    """The committed quick board's records of one instance (v1, legacy, schema 1; the main
    board is emafdi-v2 in schema 2 since issue 33)."""
    with open(ROOT / "leaderboards" / "quick" / "runs.jsonl") as fh:
        recs = [json.loads(line) for line in fh if '"case": "s00"' in line]
    return recs


@pytest.fixture(scope="module")
def fresh() -> dict:
    """A real schema-2 record (random search, 40 evaluations)."""
    return evidence.real_run("random", "s00", "twin", 0, 40)


def _one(legacy: list[dict], solver: str, track: str = "reference") -> dict:
    return copy.deepcopy(next(r for r in legacy if r["solver"] == solver and r["track"] == track
                              and r["seed"] == 0))


# --- a submitter's forgeries ------------------------------------------------------------------
def test_the_issue_forgery_claimed_targets_on_a_random_run_is_refused(legacy):
    r = _one(legacy, "random")
    assert max(r["range_error"].values()) > 0.1          # far from the truth: no hit is real
    assert check_record(r) == []                          # the honest record passes
    r["targets"]["fitness"] = dict.fromkeys(r["targets"]["fitness"], 1)
    r["targets"]["parameters"] = dict.fromkeys(r["targets"]["parameters"], 1)
    found = check_record(r)
    assert found[0].startswith("targets.fitness.0.1: claimed 1, re-derived ")
    # the scores never read the claims: the forged record scores as the honest one
    honest = _one(legacy, "random")
    assert anytime_scores([r])[0].area == anytime_scores([honest])[0].area


def test_claimed_parameter_hits_alone_are_refused_at_the_start_point(legacy):
    r = _one(legacy, "random")
    r["targets"]["parameters"] = dict.fromkeys(r["targets"]["parameters"], 1)
    (msg,) = check_record(r)
    assert msg == ("targets.parameters.0.1: claimed 1, re-derived '> 1' (evaluation 1 was "
                   "the start point)")


def test_claimed_success_is_refused_and_not_scored(legacy):
    r = _one(legacy, "random")
    r.update(success=True, evals_to_success=1, accuracy=dict.fromkeys(FAULT_NAMES, 100.0))
    found = check_record(r, reevaluate=False)
    assert "success: claimed True, re-derived False" in found
    assert "evals_to_success: claimed 1, re-derived None" in found
    assert any(m.startswith("accuracy: claimed {") for m in found)
    assert score_records([r])[0].successes == 0


def test_a_legacy_claim_of_an_earlier_fitness_hit_than_the_trace_allows_is_refused(legacy):
    r = _one(legacy, "cmaes")
    k, h = next((k, h) for k, h in r["targets"]["fitness"].items() if h and h > 2)
    r["targets"]["fitness"][k] = 1
    (msg,) = check_record(r, reevaluate=False)
    assert msg.startswith(f"targets.fitness.{k}: claimed 1, re-derived ") and str(h) in msg


def test_an_error_record_that_claims_success_is_refused_and_counts_as_a_miss(fresh):
    err = error_record(Task("random", "s00", "twin", 1, 40), RuntimeError("boom"))
    assert check_record(err) == []
    forged = {**err, "success": True, "evals_to_success": 1}
    assert check_record(forged) == ["error record carries a score: success=True"]
    # ERT of two runs, one a success at its derived evaluation, the other the forged error
    ok = fresh
    s_honest = score_records([ok, err])[0]
    s_forged = score_records([ok, forged])[0]
    assert s_forged.ert == s_honest.ert and s_forged.successes == s_honest.successes


def test_a_trajectory_fitness_its_vector_does_not_have_is_refused(fresh):
    r = copy.deepcopy(fresh)
    assert check_record(r) == []
    e, f, _ = r["trajectory"][0]
    r["trajectory"][0][1] = f * 1.001             # a plausible lie, still decreasing after
    r["trace"][0][1] = r["trajectory"][0][1]
    (msg,) = check_record(r)
    assert msg.startswith(f"fitness at evaluation {e}: claimed {f * 1.001!r}, re-derived ")
    assert msg.endswith("(re-evaluated from its vector)")


def test_a_vector_moved_under_its_fitness_is_refused(fresh):
    r = copy.deepcopy(fresh)
    r["trajectory"][-1][2][1] *= 1.01
    (msg,) = check_record(r)
    assert msg.startswith("x: claimed {")


def test_indices_beyond_the_budget_and_a_shuffled_trajectory_are_refused(fresh):
    r = copy.deepcopy(fresh)
    r["trajectory"][-1][0] = r["budget"] + 1     # the trace left as it was
    assert check_record(r) == [
        f"trajectory: evaluation {r['budget'] + 1} beyond the run's {r['evaluations']} "
        f"evaluations (budget {r['budget']})"]
    r = copy.deepcopy(fresh)
    assert len(r["trajectory"]) >= 3
    r["trajectory"][1], r["trajectory"][2] = r["trajectory"][2], r["trajectory"][1]
    (msg,) = check_record(r)
    assert msg.startswith("trajectory: evaluations not increasing (")


def test_a_hit_moved_earlier_on_fresh_evidence_is_refused_or_caught_by_replay(fresh):
    r = copy.deepcopy(fresh)
    # claims edited alone: refused by re-derivation
    r["best_at"][0][1] *= 0.5
    (msg,) = check_record(r)
    assert msg.startswith("best_at: claimed [[10, ")
    # evidence edited consistently (the best point claimed at evaluation 1): every vector
    # re-evaluates, so only replay can tell
    best = fresh["trajectory"][-1]
    r = evidence.record([(1, best[1], best[2])], solver="random", case="s00", track="twin",
                        seed=0, budget=fresh["budget"], evaluations=fresh["evaluations"])
    assert check_record(r) == []
    (res,) = replay([r], None, 0)
    assert res.finding is not None and res.finding.startswith("trace at evaluation 1: ")


# --- a solver's attempts -----------------------------------------------------------------------
SEEN: list[SolverView] = []


@register_solver("test-view-capture", description="keeps its view (for the walk)",
                 library="numpy")
def _capture(problem, budget, seed):
    SEEN.append(problem)
    problem.evaluate(problem.nominal)
    return SolveResult("test-view-capture", problem.nominal, 0.0, 1, "done", 0.0, {})


def _walk(root: object, limit: int = 300_000):
    """Every object reachable from ``root`` through attributes, slots, container items,
    closures, ``__self__``, ``__func__``, ``__wrapped__`` and the ``__globals__`` of ema_bench's
    functions (module objects themselves are not entered; the ema_bench classes found are)."""
    seen, stack = {}, [root]     # id -> object: kept alive, so no id is reused meanwhile
    while stack and len(seen) < limit:
        obj = stack.pop()
        if id(obj) in seen or isinstance(obj, types.ModuleType | str | bytes):
            continue
        seen[id(obj)] = obj
        yield obj
        if isinstance(obj, int | float):
            continue
        if isinstance(obj, type):
            if obj.__module__.startswith("ema_bench"):
                stack += list(vars(obj).values())
            continue
        if isinstance(obj, np.ndarray):
            continue
        if isinstance(obj, types.CellType) and _filled(obj):
            stack.append(obj.cell_contents)
        if isinstance(obj, dict):
            stack += list(obj.keys()) + list(obj.values())
        elif isinstance(obj, list | tuple | set | frozenset):
            stack += list(obj)
        if isinstance(obj, types.FunctionType):
            stack += [c.cell_contents for c in obj.__closure__ or () if _filled(c)]
            if (obj.__module__ or "").startswith("ema_bench"):   # not the whole universe
                stack += list(obj.__globals__.values())
        for name in ("__self__", "__func__", "__wrapped__"):
            stack.append(getattr(obj, name, None))
        attrs = getattr(obj, "__dict__", None)
        if isinstance(attrs, dict) and not isinstance(obj, types.FunctionType):
            stack += list(attrs.values())
        for cls in type(obj).__mro__:
            for slot in getattr(cls, "__slots__", ()):
                if hasattr(obj, slot):
                    stack.append(getattr(obj, slot))
        if type(obj).__module__.startswith("ema_bench"):
            stack.append(type(obj))
            for name in dir(obj):       # bound methods and properties' values
                if not name.startswith("__"):
                    try:
                        stack.append(getattr(obj, name))
                    except Exception:   # a property that needs an evaluation first
                        pass


def _filled(cell) -> bool:
    try:
        return cell.cell_contents is not cell   # an empty cell raises
    except ValueError:
        return False


def test_the_solver_view_reaches_no_truth_no_score_and_no_problem():
    problem = make_problem("seeded", track="twin", seed=run_seed(0, 5), budget=5)
    truth = np.array([problem.score(problem.nominal).truth[n] for n in FAULT_NAMES])
    f_truth = problem.fitness_at_truth()
    SEEN.clear()
    run_solver("test-view-capture", problem, 5, seed=run_seed(0, 5))
    (view,) = SEEN
    assert isinstance(view, SolverView) and problem.evaluations == 1   # it shares the log
    for name in ("score", "first_success", "parameter_hits", "fitness_at_truth",
                 "has_truth", "objective", "simulate", "meta", "label"):
        assert not hasattr(view, name), name
    n = 0
    for obj in _walk(view):
        n += 1
        assert not isinstance(obj, Problem | Score), obj
        if isinstance(obj, np.ndarray) and obj.size >= 4 and obj.dtype.kind == "f":
            assert not np.allclose(obj.ravel()[:4], truth), "the truth is reachable"
        if isinstance(obj, dict):
            assert "truth" not in obj or not isinstance(obj["truth"], dict)
        assert not (isinstance(obj, float) and obj == f_truth)
    assert n > 1000    # the walk went through the package, not just the view


def test_the_walk_finds_a_truth_planted_anywhere_it_goes():
    """The walk above is not vacuous: a problem hidden in a closure, a bound method or a
    cell, or the truth hidden in an ema_bench module's globals, is found."""
    problem = make_problem("seeded", track="twin", seed=run_seed(0, 6), budget=5)
    view = problem.view()

    def closure(q):
        return lambda: q

    for plant in (closure(problem), problem.score, closure(problem.score).__closure__):
        view._log.plant = plant
        assert any(isinstance(o, Problem) for o in _walk(view)), plant
    del view._log.plant
    import ema_bench.objective as module
    module._PLANTED = {"truth": problem.score(problem.nominal).truth}
    try:
        assert any(isinstance(o, dict) and isinstance(o.get("truth"), dict)
                   for o in _walk(view))
    finally:
        del module._PLANTED


# a solver that reads memory is caught by replay in its own process: tests/test_judge.py


def test_a_real_short_sweep_is_reproduced_by_replay(fresh):
    recs = [fresh, run_task(Task("nelder-mead", "small", "twin", 1, 60))]
    assert [r.finding for r in replay(recs, None, 0)] == [None, None]


# --- names -------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["=HYPERLINK(\"http://x\")", "+1", "-cmd", "@SUM(A1)",
                                  "a/b", "..\\x", "new\nline", "bell\x07", "", " pad"])
def test_register_solver_refuses_unsafe_names(name):
    with pytest.raises(SolverError):
        register_solver(name, description="x", library="numpy")(_capture)


def test_register_tracker_refuses_unsafe_names():
    from ema_bench.prognostics.tracking import TrackerError, register_tracker

    with pytest.raises(TrackerError, match="control characters"):
        register_tracker("t\r\n", description="x")(lambda **kw: None)
    assert check_name("particle-512", "tracker") == "particle-512"


def test_every_table_writer_escapes_a_malicious_name(fresh, tmp_path):
    evil = "<img src=x onerror=alert(1)>|x\n[y](javascript:1)"
    formula = '=HYPERLINK("http://e")'
    recs = [{**copy.deepcopy(fresh), "solver": evil}, {**copy.deepcopy(fresh), "solver": formula},
            fresh]
    write_leaderboards(recs, tmp_path, "header")
    md = (tmp_path / "leaderboard_twin.md").read_text()
    assert "<img" not in md and "](" not in md
    assert "&lt;img src=x onerror=alert\\(1)&gt;\\|x [y]\\(javascript:1)" in md
    header = next(line for line in md.splitlines() if line.startswith("| rank |"))
    row = next(line for line in md.splitlines() if "&lt;img" in line)
    # the name's "|" is escaped: the row has as many column breaks as the header
    assert row.replace("\\|", "").count("|") == header.count("|")
    with open(tmp_path / "leaderboard_twin.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    solvers = {row["solver"] for row in rows}
    assert "'" + formula in solvers and formula not in solvers
    assert not any("\n" in s for s in solvers)
    for row in rows:   # plain numbers everywhere a number is
        for k in ("runs", "ecdf_area", "ecdf_area_lo", "ert_p0.01_hi", "ert_f0.1_lo"):
            if row.get(k):
                float(row[k])
        assert "np.float64" not in "".join(row.values())


def test_the_escape_helper_by_hand():
    assert markdown("nelder-mead") == "nelder-mead"
    assert markdown("a|b\nc") == "a\\|b c"
    assert markdown("<b>&") == "&lt;b&gt;&amp;"
    assert markdown("[x](javascript:1)") == "[x]\\(javascript:1)"
    assert csv_value("=1+1") == "'=1+1" and csv_value("-x") == "'-x"
    assert csv_value(np.float64(0.25)) == "0.25" and csv_value(float("inf")) == "inf"
    assert csv_value(np.int64(3)) == "3" and csv_value(None) == ""


# --- validate accepts what the leaderboard writes ---------------------------------------------
@settings(max_examples=8, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(solver=st.sampled_from(["random", "nelder-mead", "cmaes", "powell"]),
       case=st.sampled_from(instance_names()),
       track=st.sampled_from(["twin", "reference"]),
       seed=st.integers(0, 9), budget=st.integers(2, 90))
def test_validate_accepts_every_record_the_leaderboard_writes(solver, case, track, seed,
                                                              budget):
    rec = run_task(Task(solver, case, track, seed, budget))
    assert check_record(json.loads(json.dumps(rec))) == []
    assert rec["x"] == faults_to_dict(np.array(rec["trajectory"][-1][2][:4]))


def test_a_claimed_fitness_at_the_truth_is_re_evaluated(fresh):
    r = {**copy.deepcopy(fresh), "fitness_at_truth": fresh["fitness_at_truth"] * 0.5}
    (msg,) = check_record(r)
    assert msg == (f"fitness_at_truth: claimed {r['fitness_at_truth']!r}, re-derived "
                   f"{fresh['fitness_at_truth']!r}")


def test_the_campaign_score_table_escapes_a_tracker_name():
    """A tracker's name reaches the campaign board's Markdown through ``score_table``: a pipe
    or a tag in it must not add a column or markup (same helper as the leaderboard's)."""
    from ema_bench.prognostics.scoring import HEADLINE
    from ema_bench.prognostics.tables import score_table

    h = {k: {"value": 0.5, "ci": [0.4, 0.6]} for k in HEADLINE}
    row = {"tracker": "evil|<img src=x onerror=alert(1)>", "track": "twin", "units": 3,
           "failing_units": 2, "headline": h, "campaign": "c", "scored_units": 2,
           "decisions": {"false_replacements": 0, "early_replacements": 0,
                         "failures_in_service": 1, "maintenance_cost": 1.0},
           "diagnostics": {"prognostic_horizon": 10.0, "prognostic_horizon_strict": 5.0}}
    head, rule, line = score_table([row])
    assert line.count(" | ") == head.count(" | ")   # the pipe did not open a column
    assert "<img" not in line and markdown(row["tracker"]) in line
