"""``ema-bench validate``: third-party records are accepted only when they are what they claim
(suite, manifest, budget, every trajectory vector re-evaluated, every figure re-derived).
tests/test_integrity.py holds the forgeries."""

from __future__ import annotations

import json
from pathlib import Path

import evidence
import pytest
from inprocess import CliRun, run_cli

from ema_bench.leaderboard.tasks import Task, error_record
from ema_bench.leaderboard.validate import check_complete, check_record, validate
from ema_bench.suites import DEFAULT

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def records() -> list[dict]:
    # real runs: a seeded instance and a paper case on both tracks
    return [evidence.real_run("powell", c, t, 0, 60) for c in ("s01", "small")
            for t in ("twin", "reference")]


def cli(*args: str) -> CliRun:
    return run_cli(*args, cwd=ROOT)


def write(path: Path, recs: list[dict]) -> Path:
    path.write_text("".join(json.dumps(r) + "\n" for r in recs))
    return path


def test_real_records_are_accepted(records):
    assert validate(records, complete=False) == []


def test_a_fitness_that_its_vector_does_not_have_is_refused(records):
    r = dict(records[0])
    # a plausible lie: a slightly better fitness, the trace doctored to agree with it
    f = records[0]["fitness"] * 0.999
    tj = [list(p) for p in records[0]["trajectory"]]
    tj[-1] = [tj[-1][0], f, tj[-1][2]]
    r.update(fitness=f, trajectory=tj, trace=[[p[0], p[1]] for p in tj])
    if records[0]["trace"][-1][0] != tj[-1][0]:
        r["trace"].append([records[0]["trace"][-1][0], f])
    for b in r["best_at"]:
        if b[0] >= tj[-1][0]:
            b[1] = f
    (msg,) = check_record(r)
    assert msg.startswith(f"fitness at evaluation {tj[-1][0]}: claimed {f!r}, re-derived ")
    assert msg.endswith("(re-evaluated from its vector)")
    # a vector moved, its fitness kept: also caught (x must be the trajectory's last vector)
    r2 = {**records[1], "x": {**records[1]["x"], "Fst": records[1]["x"]["Fst"] * 1.01}}
    assert any(m.startswith("x: claimed ") for m in check_record(r2))


def test_wrong_versions_missing_manifest_and_overspent_budget_are_refused(records):
    r = records[0]
    assert any("suite version 'emafdi-v0'" in m
               for m in check_record({**r, "suite": "emafdi-v0"}, reevaluate=False))
    assert any("model version" in m
               for m in check_record({**r, "model_version": "1"}, reevaluate=False))
    no_man = {k: v for k, v in r.items() if k != "manifest"}
    assert any("missing field(s) ['manifest']" in m for m in check_record(no_man))
    thin = {**r, "manifest": {k: v for k, v in r["manifest"].items() if k != "cpu"}}
    assert any("manifest lacks ['cpu']" in m for m in check_record(thin, reevaluate=False))
    over = {**r, "evaluations": r["budget"] + 1}
    assert any("with a budget of" in m for m in check_record(over, reevaluate=False))
    lie = {**r, "truth": {**r["truth"], "Fst": 0.5}}
    assert any(m.startswith("truth: claimed {") for m in check_record(lie, reevaluate=False))
    late = {**r, "targets": {**r["targets"], "parameters": {"0.1": r["budget"] + 5,
                                                            "0.03": None, "0.01": None}}}
    assert any(m.startswith("targets.parameters: claimed {'0.1': 65")
               for m in check_record(late, reevaluate=False))
    unknown = {**r, "case": "s42"}
    assert any("not an instance of suite" in m for m in check_record(unknown))


def test_fitness_targets_reached_out_of_order_are_refused(records):
    r = records[0]
    fit = dict(r["targets"]["fitness"])
    fit["0.0001"], fit["0.1"] = 5, None      # the finest reached, the coarsest not
    bad = {**r, "targets": {**r["targets"], "fitness": fit}}
    (msg,) = check_record(bad, reevaluate=False)
    assert msg == f"targets.fitness: claimed {fit!r}, re-derived {r['targets']['fitness']!r}"


def test_error_records_pass_and_a_submission_must_cover_the_suite(records):
    err = error_record(Task("powell", "s02", "twin", 0, 60), RuntimeError("boom"))
    assert check_record(err) == []
    (finding,) = [f for f in check_complete(records) if "twin" in f.problem]
    assert finding.key == "*"
    # 23 non-sanity instances, 2 run on seed 0: 21 lacking
    assert "powell on the twin track lacks 21 runs" in finding.problem


def test_cli_exit_codes(records, tmp_path):
    good = write(tmp_path / "good.jsonl", records)
    res = cli("validate", str(good), "--partial", "--json")
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    assert out["accepted"] and out["records"] == 4
    bad = write(tmp_path / "bad.jsonl", [{**records[0], "suite": "emafdi-v0"}])
    res = cli("validate", str(bad), "--partial")
    assert res.returncode == 1 and "REFUSED" in res.stdout and "emafdi-v0" in res.stdout
    res = cli("validate", str(good))                 # incomplete without --partial
    assert res.returncode == 1 and "lacks" in res.stdout
    res = cli("validate", str(tmp_path / "missing.jsonl"))
    assert res.returncode == 2 and "no such file" in res.stderr


def test_a_fitness_below_the_best_known_is_refused_beyond_its_tolerance():
    # f* - 2e-4 of the gap: refused; f* - 0.5e-4 of the gap: within the 1e-4 tolerance
    x = evidence.vector("small", 0.3)
    below = evidence.record([(1, evidence.level("small", "twin", 0, 0.5), x),
                             (5, evidence.level("small", "twin", 0, -2e-4), x)])
    (msg,) = check_record(below, reevaluate=False)
    assert msg.startswith("fitness ") and "beats the suite's best known" in msg
    near = evidence.record([(1, evidence.level("small", "twin", 0, 0.5), x),
                            (5, evidence.level("small", "twin", 0, -0.5e-4), x)])
    assert check_record(near, reevaluate=False) == []


# --- legacy records: claims against the bounds of their trace and final vector ---------------
@pytest.fixture(scope="module")
def quick_legacy() -> dict[str, dict]:
    """The committed quick board's records of seed 0, twin track (legacy, schema 1)."""
    with open(ROOT / "leaderboards" / "quick" / "runs.jsonl") as fh:
        recs = [json.loads(line) for line in fh]
    return {r["key"]: r for r in recs if r["track"] == "twin" and r["seed"] == 0}


def _legacy(quick_legacy, key: str, **change) -> dict:
    r = json.loads(json.dumps(quick_legacy[key]))
    for path, value in change.items():
        kind, _, level = path.partition("__")
        if level:
            r["targets"][kind][level.replace("_", ".")] = value
        else:
            r[kind] = value
    return r


def test_legacy_fitness_claims_must_lie_within_the_trace_bounds(quick_legacy):
    r = quick_legacy["cmaes|small|twin|0"]
    assert check_record(r, reevaluate=False) == []
    t = r["targets"]
    for p, key in ((0.1, "0.1"), (0.01, "0.01"), (1e-3, "0.001"), (1e-4, "0.0001")):
        level = t["f_star"] + p * (t["f_nominal"] - t["f_star"])
        lo = max((e for e, f in r["trace"] if f > level), default=0) + 1
        hi = next(e for e, f in r["trace"] if f <= level)
        want = hi if lo == hi else f"{lo}..{hi}"
        for h in (lo, hi):
            fit = {**t["fitness"], key: h}
            assert check_record({**r, "targets": {**t, "fitness": fit}},
                                reevaluate=False) == [], (key, h)
        for h in (lo - 1, hi + 1, None):
            fit = {**t["fitness"], key: h}
            assert check_record({**r, "targets": {**t, "fitness": fit}}, reevaluate=False) \
                == [f"targets.fitness.{key}: claimed {h!r}, re-derived {want!r} (from the "
                    "trace)"], (key, h)


def test_legacy_fitness_claims_where_the_suite_has_no_f_star(quick_legacy):
    r = quick_legacy["cmaes|nominal|twin|0"]
    bad = {**r, "targets": {**r["targets"], "fitness": {"0.1": 1}}}
    assert check_record(bad, reevaluate=False) == [
        "targets.fitness: claimed {'0.1': 1}, re-derived None (no f* here)"]


def test_legacy_parameter_claims_against_the_final_vector(quick_legacy):
    key = "nelder-mead|small|twin|0"     # final vector within 1 %, found at evaluation 206
    assert quick_legacy[key]["trace"][-2][0] == 206
    ok = check_record(_legacy(quick_legacy, key, parameters__0_01=206, evals_to_success=206),
                      reevaluate=False)
    assert ok == []
    for h in (0, 401):
        assert check_record(_legacy(quick_legacy, key, parameters__0_1=h), reevaluate=False) \
            == [f"targets.parameters.0.1: claimed {h}, re-derived '1..400'"]
    for h in (None, 207):
        found = check_record(_legacy(quick_legacy, key, parameters__0_01=h,
                                     evals_to_success=h), reevaluate=False)
        assert found[0] == (f"targets.parameters.0.01: claimed {h!r}, re-derived '1..206' "
                            "(the final vector is within the target)")
    # a finer target reached before a coarser one
    assert check_record(_legacy(quick_legacy, key, parameters__0_03=50), reevaluate=False) \
        == ["targets.parameters.0.03: claimed 50, re-derived '>= 89' (a finer target than 0.1)"]
    assert check_record(_legacy(quick_legacy, key, evals_to_success=96), reevaluate=False) \
        == ["evals_to_success: claimed 96, re-derived 'targets.parameters.0.01'"]


def test_legacy_parameter_claims_when_the_final_vector_is_not_within(quick_legacy):
    key = "de|small|twin|0"              # 23.5 % of range off at the end, found at 169
    assert check_record(_legacy(quick_legacy, key, parameters__0_1=168),
                        reevaluate=False) == []     # possible: it passed, then moved on
    assert check_record(_legacy(quick_legacy, key, parameters__0_1=169), reevaluate=False) \
        == ["targets.parameters.0.1: claimed 169, re-derived 'None or 1..168' (the final "
            "vector, found at evaluation 169, is not within the target)"]
    assert check_record(_legacy(quick_legacy, key, parameters__0_03=5), reevaluate=False) \
        == ["targets.parameters.0.03: claimed 5, re-derived '>= None' (a finer target than "
            "0.1)"]
    assert check_record(_legacy(quick_legacy, key, evals_to_success=5), reevaluate=False) \
        == ["evals_to_success: claimed 5, re-derived None"]


def test_legacy_best_at_claims_against_the_trace(quick_legacy):
    r = quick_legacy["cmaes|nominal|twin|0"]   # trace points 1, 322, ...: 200 lies between
    f1, f322 = r["trace"][0][1], r["trace"][1][1]
    assert r["trace"][1][0] == 322
    for f in (f322, f1):
        ba = [p if p[0] != 200 else [200, f] for p in r["best_at"]]
        assert check_record({**r, "best_at": ba}, reevaluate=False) == []
    low = f322 * (1 - 1e-9)
    ba = [p if p[0] != 200 else [200, low] for p in r["best_at"]]
    assert check_record({**r, "best_at": ba}, reevaluate=False) == [
        f"best_at.200: claimed {low!r}, re-derived '{f322}..{f1}' (from the trace)"]
    ba = [p if p[0] != 10 else [10, f1 * 0.5] for p in r["best_at"]]   # exact at trace point 1..
    assert check_record({**r, "best_at": ba}, reevaluate=False)[0].startswith(
        f"best_at.10: claimed {f1 * 0.5!r}, re-derived ")
    assert check_record({**r, "best_at": r["best_at"][:-1]}, reevaluate=False) == [
        f"best_at checkpoints: claimed {r['best_at'][:-1]!r}, re-derived [10, 20, 50, 100, 200]"]
    assert check_record({**r, "best_at": [[*p] for p in r["best_at"]][:4] + [[]]},
                        reevaluate=False)[0].startswith("best_at checkpoints: claimed ")


def test_the_exact_claims_of_a_schema_2_record_are_compared_one_by_one():
    x = evidence.vector("small", 0.3)
    r = evidence.record([(1, evidence.level("small", "twin", 0, 0.5), x)])
    assert check_record({**r, "evals_to_success": 5}, reevaluate=False) == [
        "evals_to_success: claimed 5, re-derived None"]
    moved = [[b, f * 0.5] for b, f in r["best_at"]]
    assert check_record({**r, "best_at": moved}, reevaluate=False) == [
        f"best_at: claimed {moved!r}, re-derived {r['best_at']!r}"]


def test_validate_names_each_record_and_passes_its_switches_on(records):
    r = {k: v for k, v in records[0].items() if k != "key"}
    forged = {**r, "success": not r["success"]}
    (f,) = validate([forged], complete=False)
    assert (f.key, f.problem) == ("record 0", f"success: claimed {forged['success']!r}, "
                                              f"re-derived {r['success']!r}")
    assert str(f) == f"record 0: {f.problem}"
    assert validate(records, reevaluate=False, complete=False) == []
    assert validate(records, complete=True)[0].key == "*"
    assert [x for x in validate(records + [{"key": "no solver"}], complete=True)
            if x.key == "*"] == validate(records, complete=True)


def test_a_submission_lacking_instances_names_five_of_them(records):
    (finding,) = [f for f in check_complete(records) if "reference" in f.problem]
    lacking = finding.problem.split("(e.g. ")[1].rstrip(")").split(", ")
    assert len(lacking) == 5 and lacking[0] == "full/0"


def test_the_truth_of_a_case_drawn_from_the_seed_is_the_runs_own_instance():
    # a "seeded" case is drawn from the run's node (root seed, seed): its truth is rebuilt
    # from them, never read from the record; a record without a root seed is root 0
    from ema_bench.faults import FAULT_NAMES
    from ema_bench.leaderboard.derive import truth_of
    from ema_bench.seeding import run_seed
    from ema_bench.suites.problem import make_problem

    def runs_truth(track, seed, root):
        p = make_problem("seeded", track=track, seed=run_seed(root, seed), budget=1)
        return [p.score(p.nominal).truth[n] for n in FAULT_NAMES]

    r = {"case": "seeded", "track": "twin", "seed": 3, "root_seed": 7,
         "truth": dict.fromkeys(FAULT_NAMES, 0.5)}
    assert truth_of(r).tolist() == runs_truth("twin", 3, 7)
    assert truth_of({**r, "seed": 4}).tolist() == runs_truth("twin", 4, 7)
    legacy = {k: v for k, v in r.items() if k != "root_seed"}
    assert truth_of(legacy).tolist() == runs_truth("twin", 3, 0)
    assert len({tuple(runs_truth("twin", s, k)) for s, k in [(3, 7), (4, 7), (3, 0)]}) == 3


@pytest.mark.parametrize("field, broken, message", [
    ("trajectory", [], "schema-2 record without a trajectory"),
    ("trajectory", "x", "schema-2 record without a trajectory"),
    ("trajectory", [[1]], "malformed trajectory (list index out of range)"),
    ("trace", [], "legacy record without a trace"),
    ("trace", "x", "legacy record without a trace"),
    ("trace", [[1]], "malformed trace (list index out of range)"),
])
def test_missing_or_malformed_evidence_is_one_clear_error(field, broken, message):
    from ema_bench.leaderboard.derive import DerivationError, derive

    r = evidence.record([(1, 1.0, evidence.vector("small", 0.3))])
    if field == "trace":                          # a legacy (schema 1) record: its trace only
        r = {k: v for k, v in r.items() if k not in ("schema", "trajectory")}
    with pytest.raises(DerivationError) as exc:
        derive({**r, field: broken})
    assert str(exc.value) == message


def test_edges_of_the_derived_figures():
    from ema_bench.leaderboard.derive import DerivationError, derive

    at = lambda p: evidence.level("small", "twin", 0, p)   # noqa: E731
    x = evidence.vector("small", 0.3)
    # a fitness exactly at the 1e-1 level reaches that target; best_at lists the budget
    d = derive(evidence.record([(1, at(0.5), x), (7, at(0.1), x)]))
    assert d.fitness_hits["0.1"] == 7 and d.fitness_hits["0.01"] is None
    assert [b for b, _ in d.best_at] == [10, 20, 50, 100]
    # a record without a root seed is root 0, whose f* the suite ships: still scored on f*
    r = evidence.record([(1, at(0.5), x), (7, at(0.1), x)])
    del r["root_seed"]
    assert derive(r).fitness_hits["0.1"] == 7
    # a legacy record whose final vector is unreadable: one clear error
    legacy = {k: v for k, v in r.items() if k not in ("schema", "trajectory")}
    with pytest.raises(DerivationError, match=r"^final vector x unreadable \("):
        derive({**legacy, "x": None})
    # a run that passed within 1 % of the truth and left it (its final vector 30 % off) has
    # the parameter hit but is no success, so no evaluations to success
    d = derive(evidence.record([(1, at(0.5), evidence.vector("small", 0.005)),
                                (20, at(0.1), x)]))
    assert d.parameter_hits["0.01"] == 1
    assert d.success is False and d.evals_to_success is None
    # an error record: no success, no hits, no checkpoints
    d = derive(evidence.record([], status="error"))
    assert (d.error, d.success, d.best_at) == (True, False, [])
    assert d.parameter_hits == {"0.1": None, "0.03": None, "0.01": None}


def test_a_legacy_trace_cut_before_its_final_vector_was_found_has_no_parameter_hit():
    # legacy evidence: the trace and the final vector (0.5 % of Na's range off: within every
    # parameter target), found at evaluation 60, the last improvement.  Re-scored at a
    # smaller budget (--check's truncation), the vector at the cut is known only if the cut
    # is at or after 60.
    from ema_bench.leaderboard.derive import derive

    at = lambda p: evidence.level("small", "twin", 0, p)   # noqa: E731
    x = evidence.vector("small", 0.005)
    r = evidence.record([(1, at(0.5), x), (20, at(0.1), x), (60, at(0.05), x)])
    legacy = {k: v for k, v in r.items() if k not in ("schema", "trajectory")}
    assert legacy["trace"][-1] == [100, at(0.05)]          # the repeated last evaluation
    for budget in (100, 60):
        d = derive({**legacy, "budget": budget})
        assert d.success is True and d.evals_to_success == 60
        assert d.parameter_hits == {"0.1": 60, "0.03": 60, "0.01": 60}
    d = derive({**legacy, "budget": 50})
    assert d.success is False and d.evals_to_success is None
    assert d.parameter_hits == {"0.1": None, "0.03": None, "0.01": None}
    # one improvement only, at evaluation 1: its vector is known at any cut
    one = evidence.record([(1, at(0.5), x)])
    one = {k: v for k, v in one.items() if k not in ("schema", "trajectory")}
    assert one["trace"] == [[1, at(0.5)], [100, at(0.5)]]
    d = derive({**one, "budget": 50})
    assert d.success is True and d.parameter_hits["0.01"] == 1


def test_a_vector_exactly_on_a_target_edge_reaches_it():
    # Gprop 1 % of its range off exactly (101000 for a truth of 100000: the range errors are
    # exact in binary): the targets and the success rule are "within", <= 1 %
    from ema_bench.leaderboard.derive import derive

    x = evidence.vector("small", 0.01, fault="Gprop")
    r = evidence.record([(1, evidence.level("small", "twin", 0, 0.5), x)])
    d = derive(r)
    assert d.range_error["Gprop"] == 0.01 and max(d.range_error.values()) == 0.01
    assert d.success is True and d.parameter_hits["0.01"] == 1 and d.evals_to_success == 1
    legacy = {k: v for k, v in r.items() if k not in ("schema", "trajectory")}
    d = derive(legacy)
    assert d.success is True and d.parameter_hits["0.01"] == 1


# --- every refusal of check_record, by its exact line ------------------------------------------
def _hand_made() -> dict:
    """A schema-2 record on ``small`` (twin, seed 0): improvements at evaluations 1 and 7,
    the last evaluation 100 of a budget of 100."""
    at = lambda p: evidence.level("small", "twin", 0, p)   # noqa: E731
    return evidence.record([(1, at(0.5), evidence.vector("small", 0.3)),
                            (7, at(0.1), evidence.vector("small", 0.3))])


def _with(r: dict, **change) -> dict:
    out = json.loads(json.dumps(r))
    out.update(change)
    return out


def test_each_malformed_field_is_refused_by_its_own_line():
    r = _hand_made()
    f1, f7 = r["trace"][0][1], r["trace"][1][1]
    tj = r["trajectory"]
    v = tj[0][2]
    check = lambda rec: check_record(rec, reevaluate=False)   # noqa: E731
    assert check(r) == [] and check([r]) == ["not a record: list"]
    assert check({k: x for k, x in r.items() if k not in ("trace", "fitness")}) == [
        "missing field(s) ['fitness', 'trace']"]
    assert check({k: x for k, x in r.items() if k != "trajectory"}) == [
        "missing field(s) ['trajectory']"]
    legacy = {k: x for k, x in r.items() if k not in ("schema", "trajectory")}
    assert check(legacy) == []
    # versions, schema and seed scheme: each named, all of them listed
    assert check(_with(r, suite="emafdi-v0", model_version="1", schema=3, seed_scheme=7)) == [
        "suite version 'emafdi-v0', expected 'emafdi-v1'",
        "model version '1', expected '3' (or a compatible '2')",
        "record schema 3, expected 2 (or legacy)",
        "seed scheme 7, expected one of [1, 2]"]
    for scheme in ("2", True, None):
        assert check(_with(r, seed_scheme=scheme)) == [
            f"seed scheme {scheme!r}, expected one of [1, 2]"]
    assert check(_with(r, model_version="2")) == []          # the compatible one
    where = ("(instances: " + ", ".join(DEFAULT.case_order()) + ", or instance@condition; "
             "tracks: reference, twin)")
    assert check(_with(r, case="s42", suite="emafdi-v0")) == [
        "suite version 'emafdi-v0', expected 'emafdi-v1'",
        f"not an instance of suite emafdi-v1 or emafdi-v2 or emafdi-v3: case 's42', track "
        f"'twin' {where}"]
    assert check(_with(r, track="moon"))[-1].endswith(f"case 'small', track 'moon' {where}")
    # an error record: its identity only, and no score (the first one named)
    err = evidence.record([], status="error")
    assert check(err) == [] and check(_with(err, success=False, x=None)) == []
    assert check({k: x for k, x in err.items() if k != "seed"}) == ["missing field(s) ['seed']"]
    assert check(_with(err, accuracy={"Na": 0.1}, success=True)) == [
        "error record carries a score: success=True"]
    assert check(_with(err, x={"Na": 1.0})) == ["error record carries a score: x={'Na': 1.0}"]
    # manifest and budget
    assert check(_with(r, manifest="x")) == [
        "manifest lacks ['ema_bench', 'python', 'numpy', 'scipy', 'numba', 'platform', 'cpu', "
        "'threads', 'libraries']"]
    assert check(_with(r, evaluations=0)) == [
        "0 evaluations with a budget of 100",
        "trace: evaluation 100 beyond the run's 0 evaluations (budget 100)"]
    assert check(_with(r, budget=90)) == [
        "100 evaluations with a budget of 90",
        "trace: evaluation 100 beyond the run's 100 evaluations (budget 90)"]
    assert check(_with(r, evaluations=50)) == [
        "trace: evaluation 100 beyond the run's 50 evaluations (budget 100)"]
    # the trace's and the trajectory's points
    for bad in ([[True, f1], [7, f7], [100, f7]], [[1, f1], [7, float("nan")], [100, f7]],
                [[1, f1], [7, "x"], [100, f7]], [[1.0, f1], [7, f7], [100, f7]],
                [[1, f1], [7, float("inf")], [100, f7]]):
        assert check(_with(r, trace=bad)) == [
            "trace: evaluations must be integers and fitness finite numbers"], bad
    assert check(_with(r, trace=[[2, f1], [7, f7], [100, f7]])) == [
        "trace: starts at evaluation 2, not 1 (the first evaluation is always an improvement)"]
    assert check(_with(r, trace=[[1, f1], [7, f7], [5, f7], [100, f7]])) == [
        "trace: evaluations not increasing (7 then 5)"]
    assert check(_with(r, trace=[[1, f1], [7, f7], [7, f7], [100, f7]])) == [
        "trace: evaluations not increasing (7 then 7)"]
    assert check(_with(r, trace=[[1, f7], [7, f1], [100, f1]], fitness=f1)) == [
        "trace: best-so-far fitness does not decrease"]
    assert check(_with(r, fitness=f7 * 1.01)) == [
        f"fitness: claimed {f7 * 1.01!r}, re-derived {f7!r} (the trace's best)"]
    assert check(_with(r, fitness=f7 * (1 + 1e-7))) == []   # within FITNESS_RTOL
    for bad in ("x", [], [[1]], [[1, f1, f1]]):
        assert check(_with(r, trace=bad)) == ["empty or malformed trace"], bad
        assert check(_with(r, trajectory=bad)) == ["empty or malformed trajectory"], bad
    assert check(_with(r, trajectory=[[1, f1, v], [7, f1, v]], trace=[[1, f1], [7, f1]],
                       fitness=f1)) == ["trajectory: best-so-far fitness does not decrease"]
    assert check(_with(r, trajectory=[[1, f1, v], [7, f7, v[:3]]])) == [
        "trajectory vectors of lengths [3, 4], the instance's of at least 4"]
    assert check(_with(r, trajectory=[[1, f1, v[:3]], [7, f7, v[:3]]])) == [
        "trajectory vectors of lengths [3], the instance's of at least 4"]
    # the trace is the trajectory's points, with or without the last evaluation
    assert check(_with(r, trace=r["trace"][:2])) == []
    assert check(_with(r, trace=[[1, f1], [7, f7], [99, f7]])) == [
        "trace: not the trajectory's evaluations and fitness (and the last evaluation)"]
    moved = {**r["x"], "Na": r["x"]["Na"] * 1.5}
    final = dict(zip(("Na", "Fst", "BLK", "Gprop"), tj[-1][2][:4]))
    assert check(_with(r, x=moved)) == [f"x: claimed {moved!r}, re-derived {final!r}"]
    assert check(_with(r, x=None)) == [f"x: claimed None, re-derived {final!r}"]


def _legacy_of(r: dict) -> dict:
    return {k: x for k, x in r.items() if k not in ("schema", "trajectory")}


def test_legacy_claims_at_the_edges_of_their_bounds():
    check = lambda rec: check_record(rec, reevaluate=False)   # noqa: E731
    at = lambda p: evidence.level("small", "twin", 0, p)      # noqa: E731
    x = evidence.vector("small", 0.3)                          # 30 % off: no parameter hit
    # a trace point exactly at the 0.1 level reaches it there (7), not one later
    r = _legacy_of(_hand_made())
    assert r["targets"]["fitness"]["0.1"] == 7 and check(r) == []
    # a first point already below the 0.1 level: its hit is evaluation 1 exactly
    below = _legacy_of(evidence.record([(1, at(0.05), x), (7, at(0.005), x)]))
    assert below["targets"]["fitness"]["0.1"] == 1 and check(below) == []
    assert check(_with(below, targets={**below["targets"],
                                       "fitness": {**below["targets"]["fitness"],
                                                   "0.1": 2}})) == [
        "targets.fitness.0.1: claimed 2, re-derived 1 (from the trace)"]
    # claims that are not a mapping are claims of nothing, refused where a hit is due
    assert check(_with(r, targets={**r["targets"], "fitness": None})) == [
        "targets.fitness.0.1: claimed None, re-derived '2..7' (from the trace)"]
    assert check(_with(r, targets={**r["targets"], "parameters": None})) == []
    # a parameter hit outside 1..evaluations: named, and every target still checked
    p = r["targets"]["parameters"]
    assert check(_with(r, targets={**r["targets"], "parameters": {**p, "0.1": 0, "0.03": 0}})) \
        == ["targets.parameters.0.1: claimed 0, re-derived '1..100'",
            "targets.parameters.0.03: claimed 0, re-derived '1..100'"]
    # at the last evaluation: within 1..evaluations, but after the final vector was found
    assert check(_with(r, targets={**r["targets"], "parameters": {**p, "0.1": 100}})) == [
        "targets.parameters.0.1: claimed 100, re-derived 'None or 1..6' (the final vector, "
        "found at evaluation 7, is not within the target)"]


def test_validate_re_evaluates_and_checks_completeness_by_default(records):
    r = dict(records[0])
    f = r["fitness"] * 0.999                  # a fitness its vector does not have
    r.update(fitness=f, trajectory=[*r["trajectory"][:-1], [*r["trajectory"][-1][:1], f,
                                                            r["trajectory"][-1][2]]])
    r["trace"] = [[p[0], p[1]] for p in r["trajectory"]]
    if records[0]["trace"][-1][0] != r["trace"][-1][0]:
        r["trace"].append([records[0]["trace"][-1][0], f])
    r["best_at"] = [[b, f if b >= r["trajectory"][-1][0] else v] for b, v in r["best_at"]]
    found = validate([r])
    assert [x.key for x in found] == [r["key"], "*"]
    assert found[0].problem.startswith(f"fitness at evaluation {r['trajectory'][-1][0]}: ")
    assert validate([r], reevaluate=False, complete=False) == []
    assert [x.key for x in validate([r], complete=False)] == [r["key"]]
    # completeness: a record without a track (a blind-suite case) counts for no solver
    blind = {"key": "case 3", "solver": "powell", "case": "s00", "seed": 0}
    assert check_complete([*records, blind]) == check_complete(records)
    # per_tier reaches the check: v2's first 8 instances of each tier, not all 23
    v2 = [json.loads(line) for line in open(ROOT / "leaderboards" / "runs.jsonl")
          if '"solver": "random"' in line][:1]
    for per_tier, lacking in ((8, 7), (None, 22)):
        for found in (check_complete(v2, per_tier),
                      validate(v2, reevaluate=False, per_tier=per_tier)):
            (x,) = [y for y in found if y.key == "*"]
            assert x.problem.startswith(f"random on the reference track lacks {lacking} runs ")


def test_a_trajectory_longer_than_the_default_budget_is_re_evaluated_whole():
    """1001 improvements (more than ``make_problem``'s default budget of 1000): every vector
    is re-evaluated, none refused for want of budget."""
    import numpy as np

    from ema_bench.faults import LOWER, UPPER
    from ema_bench.seeding import run_seed
    from ema_bench.suites.problem import make_problem

    p = make_problem("small", track="twin", seed=run_seed(0, 0), budget=2000)
    X = np.random.default_rng(5).uniform(LOWER, UPPER, (1001, len(LOWER)))
    f = p.evaluate(X)
    order = np.argsort(-f)
    assert np.all(np.diff(f[order]) < 0)                  # distinct: strictly improving
    r = evidence.record([(i + 1, f[j], X[j]) for i, j in enumerate(order)], budget=2000)
    assert len(r["trajectory"]) == 1001 and check_record(r) == []


def test_re_evaluation_of_a_one_point_trajectory_and_its_tolerances():
    """A run whose only improvement is its first evaluation (the start vector), its fitness
    computed here: accepted within FITNESS_RTOL (1e-6), refused beyond it with both values;
    the same for a claimed fitness at the truth; vectors of another dimension named."""
    from ema_bench.seeding import run_seed
    from ema_bench.suites.problem import make_problem

    p = make_problem("small", track="twin", seed=run_seed(0, 0), budget=10)
    x = [float(v) for v in p.start]
    f = float(p.evaluate(x))
    g = float(p.fitness_at_truth())
    one = lambda fit, **kw: evidence.record([(1, fit, x)], **kw)   # noqa: E731
    assert check_record(one(f)) == []
    assert check_record(one(f * (1 + 1e-7))) == []
    assert check_record(one(f * 1.01)) == [
        f"fitness at evaluation 1: claimed {f * 1.01!r}, re-derived {f!r} (re-evaluated "
        "from its vector)"]
    assert check_record({**one(f), "fitness_at_truth": g * (1 + 1e-7)}) == []
    assert check_record({**one(f), "fitness_at_truth": g * 1.01}) == [
        f"fitness_at_truth: claimed {g * 1.01!r}, re-derived {g!r}"]
    r = one(f)
    wide = _with(r, trajectory=[[1, f, [*x, 0.5]]])
    assert check_record(wide) == ["vectors of dimension 5, the problem's is 4"]
    for bad in (None, "1.0", True, [1.0]):
        assert check_record(_with(r, trajectory=[[1, f, [bad, *x[1:]]]])) == [
            "trajectory: vector entries must be numbers"], bad


def test_a_run_without_prior_that_holds_the_nominal_vector_is_refused():
    from ema_bench.faults import NOMINAL

    at = lambda p: evidence.level("small", "twin", 0, p)   # noqa: E731
    x, nom = evidence.vector("small", 0.3), [float(v) for v in NOMINAL]
    first = evidence.record([(1, at(0.5), nom), (3, at(0.2), nom), (7, at(0.1), x)])
    later = evidence.record([(1, at(0.5), x), (3, at(0.2), nom), (7, at(0.1), x)])
    v2 = lambda r, case: {**r, "case": case, "suite": "emafdi-v2"}   # noqa: E731
    assert check_record(v2(first, "small@no-prior"), reevaluate=False) == [
        "evaluation 1 is the nominal vector, which a run without prior is not given"]
    assert check_record(v2(later, "small@no-prior"), reevaluate=False) == [
        "evaluation 3 is the nominal vector, which a run without prior is not given"]
    # with a prior (v1's instances, v2's @prior) the nominal vector is the start it is given
    assert check_record(v2(first, "small@prior"), reevaluate=False) == []
    assert check_record(first, reevaluate=False) == []
    # a legacy record keeps no vectors but its final one: nothing to check here
    legacy = _legacy_of(v2(first, "small@no-prior"))
    assert check_record(legacy, reevaluate=False) == []


def test_a_legacy_start_point_fixes_the_parameter_hits_at_evaluation_1(quick_legacy):
    """The committed least-squares run on ``nominal`` (its start is the truth): its first
    trace point is the start (1e-9 apart, within FITNESS_RTOL), so every parameter target is
    hit at evaluation 1, not at 2 as a claim within the trace's bounds could say."""
    r = quick_legacy["least-squares|nominal|twin|0"]
    assert r["trace"][1][0] == 3 and check_record(r) == []
    late = {**r, "evals_to_success": 2,
            "targets": {**r["targets"], "parameters": {"0.1": 2, "0.03": 2, "0.01": 2}}}
    assert check_record(late, reevaluate=False) == []        # the bounds allow it
    assert check_record(late) == ["targets.parameters.0.1: claimed 2, re-derived 1 "
                                  "(evaluation 1 was the start point)"]


def test_claimed_figures_are_named_with_the_re_derived_values():
    r = _hand_made()
    check = lambda rec: check_record(rec, reevaluate=False)   # noqa: E731
    acc = {**r["accuracy"], "Na": 0.5}
    assert check(_with(r, accuracy=acc)) == [
        f"accuracy: claimed {acc!r}, re-derived {r['accuracy']!r}"]
    t = r["targets"]
    assert check(_with(r, targets=None)) == [
        f"targets.f_star: claimed None, re-derived {t['f_star']!r} (the suite's)",
        f"targets.f_nominal: claimed None, re-derived {t['f_nominal']!r} (the suite's)",
        f"targets.fitness: claimed None, re-derived {t['fitness']!r}",
        f"targets.parameters: claimed None, re-derived {t['parameters']!r}"]


def test_a_record_of_an_earlier_model_version_is_judged_on_its_own_entry():
    """Tier 12's best-known entries of model version 2 were superseded by version 3's: a
    version-2 record is held to the table's version-2 f*."""
    table = json.loads((ROOT / "ema_bench" / "suite_targets_v2.json").read_text())
    key = "t12-s00@prior|twin|0"
    old, new = table["superseded"]["2"][key]["f_star"], table["entries"][key]["f_star"]
    assert old != new
    r = _with(_hand_made(), case="t12-s00@prior", suite="emafdi-v2")
    r["targets"]["f_star"] = new
    # its vectors are of v1's four faults; the instance searches 12 parameters
    assert check_record(r, reevaluate=False) == [
        "trajectory vectors of lengths [4], the instance's of at least 12"]
    x_star = [float(v) for v in table["entries"][key]["x_star"].values()]
    for p in r["trajectory"]:
        p[2] = p[2] + x_star[len(p[2]):]
    claim = f"targets.f_star: claimed {new!r}, re-derived {old!r} (the suite's)"
    assert claim in check_record({**r, "model_version": "2"}, reevaluate=False)
    assert not any(m.startswith("targets.f_star") for m in check_record(r, reevaluate=False))


def test_a_suite_on_another_model_version_accepts_only_its_own():
    """Suite emafdi-v3 runs on model version 4 (``Suite.model_version``): its committed
    records validate, and a relabel to any other version is refused by the exact line, with
    no compatible version offered (those are earlier versions of the default suite's)."""
    with (ROOT / "leaderboards" / "v3" / "runs.jsonl").open() as f:
        r = json.loads(f.readline())
    assert (r["suite"], r["model_version"]) == ("emafdi-v3", "4")
    assert check_record(r, reevaluate=False) == []
    for label in ("3", "2"):
        assert check_record(_with(r, model_version=label), reevaluate=False) == [
            f"model version '{label}', expected '4'"]


def test_the_best_known_tolerance_at_its_edge():
    """Exactly 1e-4 of the f*-to-nominal gap below f*: within the tolerance; f* - 1e-4 of
    f_nominal (a little further, by 1e-4 of f*): beyond it, with both values named."""
    from ema_bench.suites.v1 import best_known

    k = best_known("small", "twin", 0)
    x = evidence.vector("small", 0.3)
    edge = evidence.record([(1, evidence.level("small", "twin", 0, 0.5), x),
                            (5, evidence.level("small", "twin", 0, -1e-4), x)])
    assert check_record(edge, reevaluate=False) == []
    f = k["f_star"] - 1e-4 * k["f_nominal"]
    past = evidence.record([(1, evidence.level("small", "twin", 0, 0.5), x), (5, f, x)])
    assert check_record(past, reevaluate=False) == [
        f"fitness {f:.10g} beats the suite's best known {k['f_star']:.10g}: confirm it "
        "(re-evaluation) and report it"]


def test_a_claimed_truth_must_be_the_instances_own():
    r = _hand_made()
    truth = r["truth"]
    check = lambda rec: check_record(rec, reevaluate=False)   # noqa: E731
    # Gprop (1e5): relative agreement 1e-12 decides, not numpy's absolute 1e-8
    assert check(_with(r, truth={**truth, "Gprop": truth["Gprop"] * (1 + 1e-13)})) == []
    for lie in ({**truth, "Gprop": truth["Gprop"] * (1 + 1e-8)},
                {n: v for n, v in truth.items() if n != "Na"}, [1.0]):
        assert check(_with(r, truth=lie)) == [f"truth: claimed {lie!r}, re-derived {truth!r}"]


@pytest.mark.slow
def test_a_trajectory_longer_than_the_suite_budget_is_re_evaluated_whole():
    """5001 points (more than the 5000 of v1's budget): every vector is re-evaluated (here
    the first point's claimed fitness is off, which only the re-evaluation can tell), none
    refused for want of budget.  About 5 CPU-s of simulations."""
    import numpy as np

    from ema_bench.faults import LOWER, UPPER

    X = np.random.default_rng(6).uniform(LOWER, UPPER, (5001, len(LOWER)))
    r = evidence.record([(i + 1, 1.0 - 1e-6 * i, x) for i, x in enumerate(X)], budget=6000)
    (msg,) = check_record(r)
    assert msg.startswith("fitness at evaluation 1: claimed 1.0, re-derived ")


def test_legacy_best_at_at_a_trace_point_and_past_the_last_one():
    at = lambda p: evidence.level("small", "twin", 0, p)   # noqa: E731
    x = evidence.vector("small", 0.3)
    r = _legacy_of(evidence.record([(1, at(0.5), x), (10, at(0.2), x), (30, at(0.1), x)]))
    r["trace"] = r["trace"][:3]                 # a trace may end at its last improvement
    f1, f10, f30 = (p[1] for p in r["trace"])
    assert r["best_at"] == [[10, f10], [20, f10], [50, f30], [100, f30]]
    assert check_record(r, reevaluate=False) == []
    # at checkpoint 10 a trace point stands: exactly its fitness, not the one before
    ba = [[10, f1], *r["best_at"][1:]]
    assert check_record({**r, "best_at": ba}, reevaluate=False) == [
        f"best_at.10: claimed {f1!r}, re-derived {f10!r} (from the trace)"]
    # past the last trace point (50, 100): the last fitness, exactly
    ba = [*r["best_at"][:2], [50, f10], r["best_at"][3]]
    assert check_record({**r, "best_at": ba}, reevaluate=False) == [
        f"best_at.50: claimed {f10!r}, re-derived {f30!r} (from the trace)"]


def test_claimed_accuracy_and_range_errors_within_their_tolerances():
    r = _hand_made()
    check = lambda rec: check_record(rec, reevaluate=False)   # noqa: E731
    re_ = r["range_error"]
    assert re_["Fst"] == 0.0 and re_["Na"] > 0.25
    # an exact zero claimed as 1e-13 is the same figure (absolute 1e-12); 0.5 off is not
    assert check(_with(r, range_error={**re_, "Fst": 1e-13})) == []
    off = {**re_, "Na": re_["Na"] + 0.5}
    assert check(_with(r, range_error=off)) == [
        f"range_error: claimed {off!r}, re-derived {re_!r}"]
    nothing = {**r["accuracy"], "Na": None}
    assert check(_with(r, accuracy=nothing)) == [
        f"accuracy: claimed {nothing!r}, re-derived {r['accuracy']!r}"]
    # a fault whose truth is 0 has no paper accuracy (None) once the estimate is not 0
    nom = evidence.record([(1, 1.0, evidence.vector("nominal", 0.3, fault="BLK"))],
                          case="nominal")
    assert nom["accuracy"]["BLK"] is None and check(nom) == []
    forged = {**nom["accuracy"], "BLK": 50.0}
    assert check(_with(nom, accuracy=forged)) == [
        f"accuracy: claimed {forged!r}, re-derived {nom['accuracy']!r}"]


def test_more_refusals_by_their_exact_line():
    check = lambda rec: check_record(rec, reevaluate=False)   # noqa: E731
    at = lambda p: evidence.level("small", "twin", 0, p)   # noqa: E731
    x = evidence.vector("small", 0.3)
    r = _hand_made()
    # a v2 instance filed under v1's suite id: the instance's own suite is named
    assert check(_with(r, case="small@prior"))[0] == (
        "suite version 'emafdi-v1', expected 'emafdi-v2'")
    assert check(_with(r, manifest="python numpy"))[0] == (
        "manifest lacks ['ema_bench', 'python', 'numpy', 'scipy', 'numba', 'platform', 'cpu', "
        "'threads', 'libraries']")
    # one evaluation of a budget of one is a run
    assert check(evidence.record([(1, at(0.5), x)], budget=1)) == []
    # the fitness named is the trace's last (its best), not another point's
    three = evidence.record([(1, at(0.5), x), (7, at(0.1), x), (9, at(0.05), x)])
    three["trace"] = three["trace"][:3]
    f9 = three["trace"][2][1]
    assert check(_with(three, fitness=f9 * 1.01)) == [
        f"fitness: claimed {f9 * 1.01!r}, re-derived {f9!r} (the trace's best)"]
    # a derivation that fails is the record's one line, after what was found before
    legacy = _legacy_of(r)
    (msg,) = check(_with(legacy, x=None))
    assert msg.startswith("final vector x unreadable (")
    found = check(_with(legacy, x=None, suite="emafdi-v0"))
    assert found[0] == "suite version 'emafdi-v0', expected 'emafdi-v1'" and found[1] == msg
