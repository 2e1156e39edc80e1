"""Red team, second pass (issue 48): forged files and submitted code against the judge.

Every record that reaches a number goes through :mod:`ema_bench.leaderboard.judge`, which
refuses what ``validate`` refuses and more (legacy records, duplicates, torn files,
incomplete suites); replay runs each solver in a process of its own and counts the model's
evaluations there; samples come from fresh entropy.  Real records (the committed boards, real
runs of the zoo), real files and real command lines.
"""

from __future__ import annotations

import ast
import copy
import json
import math
import subprocess
import sys
from pathlib import Path

import evidence
import pytest

from ema_bench.cli import main
from ema_bench.escape import code_span, terminal
from ema_bench.leaderboard.judge import JudgeError, admitted, judge, read_runs
from ema_bench.leaderboard.replay import replay
from ema_bench.leaderboard.tasks import Task, error_record, run_task
from ema_bench.sampling import escape_chance, sample_indices, sample_seed

ROOT = Path(__file__).resolve().parents[1]
PLUGIN = Path(__file__).resolve().parent / "redteam"


def _lines(path: Path, needle: str) -> list[dict]:
    with open(path) as fh:
        return [json.loads(line) for line in fh if needle in line]


@pytest.fixture(scope="module")
def legacy() -> list[dict]:
    """The committed quick board's records of s00 (suite v1, schema 1)."""
    return _lines(ROOT / "leaderboards" / "quick" / "runs.jsonl", '"case": "s00"')


@pytest.fixture(scope="module")
def fresh() -> dict:
    """A real schema-2 record (random search, 40 evaluations)."""
    return evidence.real_run("random", "s00", "twin", 0, 40)


@pytest.fixture
def redteam(monkeypatch):
    """The red-team plugin installed (its folder on sys.path: worker processes inherit it)."""
    monkeypatch.syspath_prepend(str(PLUGIN))


def _write(path: Path, records: list[dict], newline: bool = True) -> Path:
    path.write_text("\n".join(json.dumps(r) for r in records) + ("\n" if newline else ""))
    return path


# --- attack 1: legacy records scored -----------------------------------------------------------
def test_a_legacy_record_is_refused_for_ranking_and_admitted_only_to_a_labelled_view(legacy):
    r = copy.deepcopy(legacy[0])
    v = judge([r], reevaluate=False, complete=False)
    assert [f.problem.split(" (")[0] for f in v.findings] == ["legacy record"]
    assert judge([r], reevaluate=False, complete=False, legacy=True).findings == []


def test_export_and_report_only_refuse_legacy_records_in_one_line(legacy, tmp_path, capsys):
    runs = _write(tmp_path / "runs.jsonl", legacy[:2])
    rc = main(["export", "--format", "ioh", str(runs), "--out", str(tmp_path / "ioh")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert "export: 2 finding(s) in 2 records, nothing written" in err and "legacy" in err
    assert not (tmp_path / "ioh").exists() or not any((tmp_path / "ioh").iterdir())


# --- attack 3: one suite's record switched another's completeness off --------------------------
def test_completeness_is_checked_per_suite(legacy):
    v2 = _lines(ROOT / "leaderboards" / "runs.jsonl", '"solver": "random"')[:1]
    v1 = [r for r in legacy if r["solver"] == "random"][:1]
    v1[0] = {**v1[0], "track": v2[0]["track"]}   # same solver and track as the v2 record
    found = judge(v1 + v2, reevaluate=False, legacy=True, per_tier=8).findings
    lacking = [f.problem for f in found if "lacks" in f.problem]
    # v1's instances are required of the v1 run (and v2's of the v2 run): both suites checked
    assert any("s01/" in p for p in lacking), lacking
    assert any("@prior/" in p for p in lacking), lacking
    # one finding per suite, in the suites' order (emafdi-v1, then emafdi-v2)
    assert len(lacking) == 2 and "s01/" in lacking[0] and "@prior/" in lacking[1]


# --- attack 4: duplicates chosen by file order --------------------------------------------------
def test_two_finished_records_of_one_run_are_a_finding_not_a_choice(fresh):
    forged = {**copy.deepcopy(fresh), "solver": "random"}
    found = judge([forged, fresh], reevaluate=False, complete=False).findings
    assert [f.problem.split(" (")[0] for f in found] == ["two records of one run identity"]
    err = error_record(Task("random", "s00", "twin", 0, 40), RuntimeError("boom"))
    # an error record then its retry's record is a resume, not a duplicate
    assert judge([err, fresh], reevaluate=False, complete=False).records == [fresh]


# --- attack 5: writers that re-evaluated nothing ----------------------------------------------
def test_export_refuses_a_record_validate_refuses(fresh, tmp_path, capsys):
    r = copy.deepcopy(fresh)
    r["trajectory"][-1][1] *= 0.5            # a fitness its vector does not have
    r["trace"][-1][1] = r["fitness"] = r["trajectory"][-1][1]
    with pytest.raises(JudgeError, match=r"^export: \d+ finding"):
        admitted([r], "export", complete=False)
    runs = _write(tmp_path / "runs.jsonl", [r])
    assert main(["export", "--format", "ioh", str(runs), "--out", str(tmp_path / "o")]) == 2
    assert "nothing written" in capsys.readouterr().err


# --- door: a last line without its newline -----------------------------------------------------
@pytest.mark.parametrize("command", [["validate", "--partial"],
                                     ["export", "--format", "ioh", "--out", "OUT"]])
def test_a_last_line_without_a_newline_is_refused_not_dropped(fresh, tmp_path, capsys,
                                                                 command):
    runs = _write(tmp_path / "runs.jsonl", [fresh, {**fresh, "seed": 1}], newline=False)
    with pytest.raises(JudgeError) as exc:
        read_runs([runs])
    assert str(exc.value) == (f"{runs}, line 2: incomplete last line (no newline at its end, "
                              "or not JSON: a torn write or an edit); complete or remove it")
    argv = [str(tmp_path / "o") if a == "OUT" else a for a in command] + [str(runs)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "incomplete last line" in err


def test_a_replay_key_that_matches_nothing_is_an_error(fresh, tmp_path, capsys):
    runs = _write(tmp_path / "runs.jsonl", [fresh])
    assert main(["validate", "--partial", "--replay-key", "nope|x|y|0", str(runs)]) == 2
    assert "--replay-key 'nope|x|y|0': no record of that key" in capsys.readouterr().err


def test_record_keys_with_control_characters_reach_the_terminal_inert(fresh):
    r = {**copy.deepcopy(fresh), "key": "a\x1b[2Jb\nc", "success": True}
    (f,) = judge([r], reevaluate=False, complete=False).findings
    assert f.key == "a [2Jb c" and "\x1b" not in str(f)
    assert terminal("x\u202ey") == "x y"


def test_a_backtick_cannot_end_the_command_code_span():
    assert code_span("ema-bench `rm -rf` x") == "``ema-bench `rm -rf` x``"
    assert code_span("`a") == "`` `a ``"
    assert code_span("plain") == "`plain`"


# --- attack 2: predictable samples --------------------------------------------------------------
def test_samples_come_from_fresh_entropy_and_repeat_from_the_printed_seed():
    seeds = {sample_seed() for _ in range(8)}
    assert len(seeds) == 8 and all(0 <= s < 2**63 for s in seeds)
    s = seeds.pop()
    assert sample_indices(100, 12, s) == sample_indices(100, 12, s)
    assert len(set(sample_indices(100, 12, s))) == 12
    assert sample_indices(5, 12, s) == [0, 1, 2, 3, 4]


def test_the_escape_chance_is_the_hypergeometric_one():
    assert escape_chance(10, 3) == pytest.approx(7 / 10)
    assert escape_chance(10, 3, forged=2) == pytest.approx(56 / 120)   # C(8,3)/C(10,3)
    assert escape_chance(1920, 12) == pytest.approx(1 - 12 / 1920)
    assert escape_chance(4, 4) == 0.0
    assert math.isclose(escape_chance(50, 10, 5), math.comb(45, 10) / math.comb(50, 10))



def test_sample_seeds_span_63_bits_and_a_given_seed_is_checked():
    """A fresh seed is a 63-bit number (64 draws: one at least 2**62, each below 2**63); a
    maintainer's seed is returned as a plain int, and anything but a non-negative integer is
    refused in one line."""
    import numpy as np

    seeds = [sample_seed() for _ in range(64)]
    assert max(seeds) >= 2**62 and max(seeds) < 2**63
    assert sample_seed(0) == 0 and type(sample_seed(np.int64(5))) is int
    assert type(sample_seed(5.0)) is int and sample_seed(5.0) == 5
    for bad in (-1, 1.5, True):
        with pytest.raises(ValueError) as exc:
            sample_seed(bad)
        assert str(exc.value) == f"sample seed must be a non-negative integer, got {bad!r}"


def test_a_sample_is_the_documented_draw_of_its_seed():
    """``k`` distinct indices, sorted: numpy's ``choice`` without replacement from the seed's
    SeedSequence (the recipe a maintainer can repeat by hand), all of them for None or
    ``k >= n``."""
    import numpy as np

    want = np.random.default_rng(np.random.SeedSequence(2024)).choice(100, 50, replace=False)
    got = sample_indices(100, 50, 2024)
    assert got == sorted(int(i) for i in want) and len(set(got)) == 50
    assert all(type(i) is int for i in got)
    assert sample_indices(100, 50, 2025) != got
    assert sample_indices(7, None, 3) == sample_indices(7, 7, 3) == list(range(7))
    assert sample_indices(3, 0, 3) == []


def test_the_escape_chance_at_its_edges():
    # one item, sampled: no escape; a sample larger than the file holds everything; more
    # forged items than records are all the records; an empty file hides nothing
    assert escape_chance(1, 1) == 0.0 and escape_chance(1, 0) == 1.0
    assert escape_chance(5, 12) == 0.0
    assert escape_chance(5, 2, forged=10) == 0.0
    assert escape_chance(5, 0, forged=10) == 1.0
    assert escape_chance(0, 3) == 1.0 and escape_chance(-1, 3) == 1.0
    assert escape_chance(2, 1) == 0.5

# --- attacks 6 and 8: submitted code in the verdict's process; a private objective --------------
def test_replay_runs_the_solver_in_its_own_process_and_catches_a_memory_reader(redteam):
    rec = run_task(Task("rt-truth-peeker", "seeded", "twin", 3, 5))
    assert rec["success"] and rec["evaluations"] == 1     # it cheated, and its vector is real
    (res,) = replay([rec], None, 0)
    assert res.finding is not None and res.finding.startswith("trace at evaluation 1: ")


def test_replay_counts_a_private_copy_of_the_objective(redteam):
    rec = run_task(Task("rt-private-objective", "s00", "twin", 0, 5))
    assert rec["evaluations"] == 1
    (res,) = replay([rec], None, 0)
    assert res.finding == ("the replayed run made 7 model evaluations, 1 of them counted: a "
                           "solver that evaluates the model outside its budget")


# --- attack 7: the solver's seed gives its run node away -----------------------------------------
def test_a_solver_cannot_rebuild_a_seeded_instance_from_its_seed(redteam):
    """Under seed scheme 1 the seed walker draws the truth from its seed and hits it at
    evaluation 1 (replay, which derives the same seed, reproduces the cheat); under the
    one-way scheme of every new run it draws another vector."""
    from ema_bench.registry import run_solver
    from ema_bench.seeding import run_seed
    from ema_bench.suites.problem import make_problem

    def walk(**scheme) -> float:
        p = make_problem("seeded", track="twin", seed=run_seed(0, 5), budget=1)
        run_solver("rt-seed-walker", p, 1, seed=run_seed(0, 5), **scheme)
        return max(p.score(p.best[0]).range_error.values())

    assert walk(seed_scheme=1) == 0.0           # the attack is real: the truth exactly
    assert walk() > 0.05 and walk(seed_scheme=2) == walk()
    rec = run_task(Task("rt-seed-walker", "seeded", "twin", 5, 1))
    assert rec["seed_scheme"] == 2 and not rec["success"]
    assert replay([rec], None, 0)[0].finding is None     # a new run replays as it ran


def test_the_solver_seed_is_the_documented_hash_of_the_node():
    """Computed here from the recipe (SHA-256 of the node's entropy, spawn key, pool size),
    not by the package: no spawn key, no root seed, the same on every call."""
    import hashlib

    import numpy as np

    from ema_bench.seeding import run_seed, solver_seed

    text = json.dumps(["ema-bench one-way seed", "solver", 7, [3], 4])
    want = int.from_bytes(hashlib.sha256(text.encode()).digest(), "big")
    got = solver_seed(run_seed(7, 3))
    assert got.entropy == want and got.spawn_key == ()
    assert (np.random.default_rng(got).random(3) ==
            np.random.default_rng(solver_seed(run_seed(7, 3))).random(3)).all()
    assert solver_seed(run_seed(7, 3), 1).spawn_key == (3, 2)      # the old one: a child
    with pytest.raises(ValueError, match="unknown seed scheme 3"):
        solver_seed(run_seed(7, 3), 3)


def test_a_record_claiming_the_old_seed_scheme_is_refused_unless_committed(legacy, fresh):
    """Seed scheme 1 is accepted for the committed boards' records only: leaving the field
    out of a new record, writing 1, or editing any field of a committed record (its solver:
    a run filed under another) is refused; the committed records themselves are not."""
    assert fresh["seed_scheme"] == 2
    old = copy.deepcopy(fresh)
    del old["seed_scheme"]
    claimed = {**fresh, "seed_scheme": 1}
    moved = {**legacy[0], "solver": "random", "key": "random|s00|reference|0"}
    for r in (old, claimed, moved):
        found = [str(f) for f in judge([r], reevaluate=False, complete=False,
                                       legacy=True).findings]
        assert found[0] == (f"{r['key']}: seed scheme 1 (the solver seed spawned from the run "
                            "node, which gives the node away) is accepted for the committed "
                            "boards' records only: rerun with this version (seed_scheme 2)")
        # the committed records are model version 2's, accepted for them only too
        assert found[1:] == ([f"{r['key']}: {_V2_REFUSED}"] if r is moved else []), found
    assert judge(legacy, reevaluate=False, complete=False, legacy=True).findings == []
    (f,) = judge([{**fresh, "seed_scheme": 3}], reevaluate=False, complete=False).findings
    assert str(f).endswith("seed scheme 3, expected one of [1, 2]")


_V2_REFUSED = ("model version 2 (earlier, compatible) is accepted for the committed boards' "
               "records only: rerun with this version (3)")


def test_the_earlier_model_version_is_accepted_for_committed_records_only(legacy, fresh):
    """A new run labelled model version 2 (which a submitter could make on
    ``model_params("2")`` and replay would reproduce there) is refused: otherwise a
    submitter could run every task on both models and file the better run.  The committed
    records, all of version 2, are accepted."""
    assert {r["model_version"] for r in legacy} == {"2"}
    assert judge(legacy, reevaluate=False, complete=False, legacy=True).findings == []
    assert fresh["model_version"] == "3"
    found = judge([{**fresh, "model_version": "2"}], reevaluate=False, complete=False)
    assert [str(f) for f in found.findings] == [f"{fresh['key']}: {_V2_REFUSED}"]


def test_committed_records_replay_under_their_own_seed_scheme(legacy):
    """A committed run of a stochastic solver (scheme 1) replays as recorded; read as scheme 2
    it does not: replay derives the solver's seed by the record's scheme."""
    r = next(x for x in legacy if x["solver"] == "random" and x["track"] == "twin")
    assert "seed_scheme" not in r
    ok, other = replay([r, {**r, "seed_scheme": 2, "key": r["key"] + "|2"}], None, 0)
    assert ok.finding is None
    assert other.finding is not None and other.finding.startswith("trace at evaluation")


def test_the_grandfathered_list_is_the_committed_files():
    """The shipped list of seed-scheme-1 digests is exactly what the committed files give
    (a committed record edited, or a list edited by hand, fails here)."""
    out = subprocess.run([sys.executable, "-m", "ema_bench.grandfather", "--check"],
                         capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stdout + out.stderr
    # 13 tracking runs: the reference fleet-bayes-cut run was tracked again under scheme 2
    assert "matches the committed files (3056 records, 13 tracking runs)" in out.stdout


def test_an_honest_run_replays_with_as_many_model_evaluations_as_it_declares(fresh):
    (res,) = replay([fresh], None, 0)
    assert res.finding is None


def test_validate_and_export_import_no_plugin(fresh, tmp_path):
    """The verdict's process runs no submitted code: after validate and export, no module of
    a solver plugin is loaded (the zoo's are plugins too)."""
    runs = _write(tmp_path / "runs.jsonl", [fresh])
    code = (
        "import sys\nfrom ema_bench.cli import main\n"
        f"rc = main(['validate', '--partial', {str(runs)!r}])\n"
        f"rc += main(['export', '--format', 'ioh', {str(runs)!r}, '--out', "
        f"{str(tmp_path / 'ioh')!r}])\n"
        "bad = [m for m in sys.modules if m.startswith(('ema_bench_solvers', "
        "'ema_bench_trackers', 'ema_bench_redteam'))]\n"
        "print(rc, bad)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env={"PYTHONPATH": str(PLUGIN), "PATH": "/usr/bin"})
    assert out.stdout.strip().splitlines()[-1] == "0 []"


#: Modules that compute a verdict, a score or an export.
JUDGES = ("leaderboard/judge.py", "leaderboard/validate.py", "leaderboard/derive.py",
          "leaderboard/replay.py", "leaderboard/scores.py", "leaderboard/anytime.py",
          "leaderboard/report.py", "leaderboard/ioh.py", "leaderboard/check.py",
          "leaderboard/page.py", "sampling.py", "cli/validate.py", "cli/export.py")
LOADER = {"get_solver", "run_solver", "available_solvers", "get_tracker", "PluginRegistry",
          "available_trackers"}


@pytest.mark.parametrize("module", JUDGES)
def test_no_judging_module_imports_the_plugin_loader(module):
    tree = ast.parse((ROOT / "ema_bench" / module).read_text())
    imported = {a.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)
                for a in node.names}
    assert not imported & LOADER, f"{module} imports {imported & LOADER}"


def test_an_adapter_run_validates_and_replay_says_it_cannot_be_replayed():
    from ema_bench.adapters.run import AdapterRun
    from ema_bench.adapters.scipy import minimize, simplex
    from ema_bench.leaderboard.validate import check_record

    run = AdapterRun("scipy-nelder-mead", case="small", track="twin", budget=30,
                     library="scipy")
    res = minimize(run.problem, method="Nelder-Mead",
                   options={"initial_simplex": simplex(run.problem)})
    record = run.record(res.stop_reason)
    assert check_record(record) == []
    (r,) = replay([record], None, 0)
    assert r.finding.startswith("not replayable: solver 'scipy-nelder-mead' is not an "
                                "installed plugin (an adapter's run")


def test_no_counted_entry_point_is_called_inside_compiled_code():
    """The replay worker wraps the model's entry points in Python; one called inside a
    compiled function (as ``_candidate`` is by ``monitor_batch_parallel``) would stop its
    caller compiling in a fresh process (6 of 12 committed records were refused so)."""
    import importlib

    import ema_bench.monitor  # noqa: F401  (loads the kernels' modules)
    from ema_bench.leaderboard.replay_worker import _ENTRY_POINTS

    wrapped = {n for entries in _ENTRY_POINTS.values() for n in entries}
    for mod_name in _ENTRY_POINTS:
        importlib.import_module(mod_name)
    compiled = [(name, obj) for name, mod in list(sys.modules.items())
                if name.startswith("ema_bench") for obj in vars(mod).values()
                if hasattr(obj, "py_func")]
    assert len(compiled) > 10
    calls = {(n, f) for n, obj in compiled for f in obj.py_func.__code__.co_names
             if f in wrapped}
    assert calls == set()


def test_the_replay_worker_sends_back_the_log_and_counts_every_model_evaluation(fresh,
                                                                                 monkeypatch):
    """The worker's job run here, in the test's process (replay runs it in a fresh one): the
    honest run's log comes back whole, the kernels' count equals the declared evaluations,
    and the comparison finds nothing; scopes come from the registry, ``unclassified`` for a
    name nothing registers."""
    import importlib

    from ema_bench.faults import FAULT_NAMES
    from ema_bench.leaderboard.replay import _finding, _job
    from ema_bench.leaderboard.replay_worker import _ENTRY_POINTS, replay_job, scopes_job
    from ema_bench.registry import get_solver
    from ema_bench.sweep.executors import Job

    for mod_name, entries in _ENTRY_POINTS.items():     # the wrappers are undone afterwards
        mod = importlib.import_module(mod_name)
        for name in entries:
            monkeypatch.setattr(mod, name, getattr(mod, name))
    import time

    t0 = time.perf_counter()
    out = replay_job(_job(3, fresh))
    assert 0 < out["wall_s"] <= time.perf_counter() - t0
    assert out["key"] == "3" and out["evaluations"] == fresh["evaluations"] == 40
    assert out["model_evaluations"] == 40
    assert len(out["fitness"]) == len(out["best"]) == len(out["x_hist"]) == 40
    assert out["best"][-1] == fresh["fitness"] and out["wall_s"] > 0
    assert out["x"][:len(FAULT_NAMES)] == [fresh["x"][n] for n in FAULT_NAMES]
    assert _finding(fresh, out) is None
    assert _finding(fresh, {**out, "model_evaluations": 41}).startswith(
        "the replayed run made 41 model evaluations, 40 of them counted")
    # the record's seed scheme reaches the solver: read as scheme 1, the run is another
    job = _job(3, fresh)
    old = replay_job(Job(job.key, job.identity, (*job.data[:4], 1)))
    assert _finding(fresh, old) is not None and old["evaluations"] == 40
    scopes = scopes_job(Job("scopes", "scopes", ["random", "no-such-solver"]))
    assert scopes == {"random": get_solver("random").scope, "no-such-solver": "unclassified"}


# --- the judge's refusals, one by one ------------------------------------------------------------
def test_read_runs_refuses_what_is_not_a_file_of_run_records(fresh, tmp_path):
    def refusal(path) -> str:
        with pytest.raises(JudgeError) as exc:
            read_runs([path])
        return str(exc.value)

    assert refusal(tmp_path / "none.jsonl") == f"{tmp_path / 'none.jsonl'}: no such file"
    assert refusal(tmp_path) == (f"{tmp_path}: not a file (give the runs.jsonl inside a "
                                 "leaderboard folder)")
    typed = tmp_path / "typed.jsonl"
    typed.write_text(json.dumps({**fresh, "solver": 1}) + "\n")
    assert refusal(typed) == (f"{typed}, line 1: field 'solver' must be str, got 1 (not a "
                              "file of run records: one JSON object per line, as 'ema-bench "
                              "leaderboard' writes)")
    broken = tmp_path / "broken.jsonl"
    broken.write_text("nope\n" + json.dumps(fresh) + "\n")
    assert refusal(broken).startswith(f"{broken}: not a file of run records ({broken}: "
                                      "broken record at byte 0 (")
    # every line of every file, in order, nothing dropped or merged
    a = _write(tmp_path / "a.jsonl", [fresh, fresh])
    b = _write(tmp_path / "b.jsonl", [{**fresh, "seed": 1}])
    assert [r["seed"] for r in read_runs([a, b])] == [0, 0, 1]
    assert read_runs([]) == []


def test_judge_keeps_one_record_per_run_and_names_the_copy(fresh):
    err = error_record(Task("random", "s00", "twin", 0, 40), RuntimeError("boom"))
    retry = error_record(Task("random", "s00", "twin", 0, 40), RuntimeError("again"))
    # a finished run followed by an error record of its identity: the run stands
    v = judge([fresh, err], reevaluate=False, complete=False)
    assert v.records == [fresh] and v.accepted
    # two error records: the later one (the last attempt) is kept, no finding
    v = judge([err, retry], reevaluate=False, complete=False)
    assert v.records == [retry] and v.findings == [] and v.legacy == 0
    copy_ = {**fresh, "key": "the copy"}
    (f,) = judge([fresh, copy_], reevaluate=False, complete=False).findings
    assert str(f) == ("the copy: two records of one run identity (a run is recorded once; "
                      "remove the copy that is not the run's)")
    # a record without a key is named by its place among the kept records
    nokey = {k: v for k, v in fresh.items() if k != "key"}
    other = error_record(Task("random", "s00", "twin", 5, 40), RuntimeError("boom"))
    (f,) = judge([other, {**nokey, "success": not fresh["success"]}],
                 reevaluate=False, complete=False).findings
    assert f.key == "record 1" and f.problem.startswith("success: claimed ")


def test_judge_counts_legacy_records_and_checks_error_records_for_their_fields(legacy):
    v = judge(legacy[:3], reevaluate=False, complete=False)
    assert v.legacy == 3 and not v.accepted and len(v.findings) == 3
    assert str(v.findings[0]) == (f"{legacy[0]['key']}: legacy record (schema 1, no "
                                  "trajectory vectors): its hits cannot be proven, so it is "
                                  "not ranked (rerun it, or --legacy for a labelled legacy "
                                  "view)")
    v = judge(legacy[:3], reevaluate=False, complete=False, legacy=True)
    assert v.legacy == 3 and v.accepted and v.records == legacy[:3]
    # an error record (no seed scheme, no schema) is no legacy record and needs no scheme
    err = error_record(Task("random", "s00", "twin", 0, 40), RuntimeError("boom"))
    err.pop("seed_scheme", None)
    v = judge([err], reevaluate=False, complete=False)
    assert v.accepted and v.legacy == 0
    (f,) = judge([{**err, "success": True}], reevaluate=False, complete=False).findings
    assert str(f) == f"{err['key']}: error record carries a score: success=True"


def test_admitted_passes_its_options_on_and_names_the_first_finding(fresh, legacy):
    assert admitted([fresh], "export", complete=False) == [fresh]
    with pytest.raises(JudgeError) as exc:                  # complete by default
        admitted([fresh], "report")
    assert str(exc.value).startswith("report: 1 finding(s) in 1 records, nothing written "
                                     "(first: *: random on the twin track lacks ")
    assert str(exc.value).endswith("); 'ema-bench validate' lists them")
    assert admitted(legacy[:2], "check", complete=False, legacy=True) == legacy[:2]
    # per_tier reaches the completeness check: the first 8 of each v2 tier asked (7 lacking
    # beside the one run), not every instance (22 lacking)
    v2 = _lines(ROOT / "leaderboards" / "runs.jsonl", '"solver": "random"')[:1]
    for per_tier, lacking in ((8, 7), (None, 22)):
        (f,) = judge(v2, reevaluate=False, per_tier=per_tier).findings
        assert f.problem.startswith(f"random on the reference track lacks {lacking} runs ")


def test_is_suite_case_names_the_instances_a_suite_ranks():
    from ema_bench.leaderboard.judge import is_suite_case

    assert is_suite_case("s00") and is_suite_case("small")
    assert not is_suite_case("seeded") and not is_suite_case(None) and not is_suite_case(3)


def test_keyless_records_are_named_by_their_place_and_judged_as_asked(legacy, fresh):
    nokey = {k: v for k, v in legacy[0].items() if k != "key"}
    (f,) = judge([nokey], reevaluate=False, complete=False).findings
    assert f.key == "record 0" and f.problem.startswith("legacy record (schema 1")
    old = {k: v for k, v in fresh.items() if k not in ("key", "seed_scheme")}
    (f,) = judge([old], reevaluate=False, complete=False).findings
    assert f.key == "record 0" and f.problem.startswith("seed scheme 1 ")
    # a new run on the earlier model version, second in its file, is named by its place too
    v2 = {k: v for k, v in fresh.items() if k != "key"} | {"model_version": "2"}
    (f,) = judge([legacy[0], v2], reevaluate=False, complete=False, legacy=True).findings
    assert (f.key, f.problem) == ("record 1", _V2_REFUSED)
    # reevaluate=False reaches check_record: a fitness its vector does not have goes unseen
    r = copy.deepcopy(fresh)
    r["trajectory"][-1][1] *= 0.999
    r["fitness"] = r["trajectory"][-1][1]
    r["best_at"] = [[b, r["fitness"] if b >= r["trajectory"][-1][0] else f]
                    for b, f in r["best_at"]]
    r["trace"] = [[p[0], p[1]] for p in r["trajectory"]] + (
        [[r["evaluations"], r["fitness"]]] if r["trajectory"][-1][0] != r["evaluations"] else [])
    assert judge([r], reevaluate=False, complete=False).findings == []
    (f,) = judge([r], complete=False).findings
    assert f.problem.startswith(f"fitness at evaluation {r['trajectory'][-1][0]}: ")
