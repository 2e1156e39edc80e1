"""Suite emafdi-v2, stage 2: the information condition ``surface-current`` (fewer outputs in
the fitness), the v2 best-known table (``ema-bench targets --suite emafdi-v2``, the judged
parameters from the clean-data fit) and a tiny v2 board through ``--check``, ``export``
(IOH, read by iohinspector) and ``validate --replay``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ema_bench import suites
from ema_bench.cli import main
from ema_bench.leaderboard.ioh import read_ioh
from ema_bench.objective import Objective, ProblemError
from ema_bench.seeding import run_seed
from ema_bench.suites import v2
from ema_bench.suites.problem import make_problem
from ema_bench.suites.targets import SuiteError, target_key
from ema_bench.suites.v2 import (
    CONDITIONS,
    MAX_TARGET_BIAS,
    TIERS,
    instance,
)
from ema_bench.traces import SIGNALS, Traces

SC = CONDITIONS["surface-current"]
MASKED = [SIGNALS.index(n) for n in SIGNALS if n not in SC.signals]
KEPT = [SIGNALS.index(n) for n in SC.signals]


def _perturbed(measured: Traces, cols: list[int], rng: np.random.Generator) -> Traces:
    """``measured`` with the ``cols`` outputs replaced by other numbers of their scale."""
    data = {}
    for t, v in measured.data.items():
        v = v.copy()
        v[:, cols] += rng.normal(0.0, 0.05, (v.shape[0], len(cols))) * np.ptp(v[:, cols], 0)
        data[t] = v
    return Traces(data, dt=measured.dt)


# --- the information condition ------------------------------------------------------------
def test_the_masked_outputs_do_not_move_the_fitness_and_the_kept_ones_do():
    """Fitness under the surface-current weights of data whose theta_m, omega_m are replaced
    by other numbers: the same, to the bit; replacing theta_u or i_eq changes it.  The
    problem's own fitness (its data carry zeros there) is that fitness too."""
    full = make_problem("t7-s04@prior", track="twin", seed=run_seed(0, 0),
                           budget=1).measured
    p = make_problem("t7-s04@surface-current", track="twin", seed=run_seed(0, 0),
                        budget=3)
    rng = np.random.default_rng(5)
    X = np.vstack([instance("t7-s04").truth, p.nominal,
                   p.from_unit(rng.uniform(0.2, 0.8, p.dim))])
    base = Objective(full, p.space, signals=SC.signals).evaluate(X)[0]
    moved = Objective(_perturbed(full, MASKED, rng), p.space, signals=SC.signals).evaluate(X)[0]
    assert np.array_equal(base, moved)
    for col in KEPT:
        other = Objective(_perturbed(full, [col], rng), p.space,
                          signals=SC.signals).evaluate(X)[0]
        assert np.all(np.abs(other - base) > 1e-6 * base), SIGNALS[col]
    assert np.array_equal(p.evaluate(X), base)
    # with every output weighed (the prior condition) the masked ones do count
    every = Objective(full, p.space).evaluate(X)[0]
    assert np.all(every > base)


def test_a_solver_is_not_given_the_withheld_outputs_and_cannot_weigh_them_back():
    """The view's data (and the objective behind its log) carry zeros for theta_m and
    omega_m, the residuals a least-squares solver gets are 0 there, and the weights are
    read-only."""
    p = make_problem("s05@surface-current", track="reference", seed=0, budget=2)
    v = p.view()
    for data in (v.measured.data, v._log.objective.measured.data):
        for block in data.values():
            assert not block[:, MASKED].any() and block[:, KEPT].any()
    r = v.residuals(v.start)
    idx = p.objective.signal_index
    assert not r[np.isin(idx, MASKED)].any() and r[np.isin(idx, KEPT)].any()
    with pytest.raises(ValueError):
        p.objective.mask[1] = 1.0
    assert p.objective.signals == ("theta_u", "i_eq")
    with pytest.raises(ProblemError, match="distinct outputs"):
        Objective(p.measured, signals=("theta_u", "current"))
    # the Gymnasium observation is that data: the withheld outputs' blocks are zeros
    import gymnasium as gym

    import ema_bench.env  # noqa: F401  (registers the ids)

    env = gym.make("EMAFault/Identify-v2", tier=7, condition="surface-current",
                   track="twin", budget=2)
    obs, _ = env.reset(seed=1)
    prob = env.unwrapped.problem
    assert np.array_equal(obs, prob.measured.stacked()) and prob.objective.signals == SC.signals
    assert not obs[np.isin(prob.objective.signal_index, MASKED)].any()


def test_surface_current_is_offered_where_the_report_keeps_every_parameter():
    """The identifiability report (docs/suite-v2.md, benchmarks/v2_identifiability.py)
    finds every parameter identifiable under surface-current on tiers 4, 7 and 12: each is
    offered and listed by the sweep; step-only stays tier 4 only.  The Laplace interval the
    report is made of uses the condition's weights: at the truth of a tier-12 instance it
    is the same whatever the withheld outputs hold (the problem's zeros, the real data,
    other numbers) and differs from the prior's; every parameter stays within 5 %."""
    from ema_bench.uncertainty.methods import intervals

    assert SC.tiers == tuple(TIERS) and SC.prior and SC.tests is None
    assert [SC.offered_on(d) for d in TIERS] == [True] * len(TIERS)
    assert v2.cases([4, 7, 12], ["surface-current", "step-only"], 1) == [
        "small@surface-current", "small@step-only", "t7-s00@surface-current",
        "t12-s00@surface-current"]
    with pytest.raises(SuiteError, match="offered on tiers"):
        make_problem("t12-s00@step-only", track="twin")
    truth = instance("t12-s02").truth

    def width(objective: Objective) -> np.ndarray:
        iv = intervals(objective, truth, method="laplace", track="twin", polish=False,
                       calibrate=False)
        assert iv.identifiability["non_identifiable"] == [] and not iv.warnings
        return iv.width_percent()

    prior = make_problem("t12-s02@prior", track="twin", seed=run_seed(0, 0), budget=1)
    sc = make_problem("t12-s02@surface-current", track="twin", seed=run_seed(0, 0),
                         budget=1)
    w = width(sc.objective)
    other = _perturbed(prior.measured, MASKED, np.random.default_rng(1))
    for data in (prior.measured, other):
        assert np.allclose(width(Objective(data, sc.space, signals=SC.signals)), w,
                           rtol=1e-9, atol=0.0)
    assert not np.allclose(width(prior.objective), w, rtol=1e-4)


# --- the v2 best-known table --------------------------------------------------------------
@pytest.fixture(scope="module")
def table(tmp_path_factory) -> Path:
    """A real v2 table of one entry: ``ema-bench targets --suite emafdi-v2`` on tier 4,
    surface-current, instance ``small``, reference track, seed 0 (the polish and the
    clean-data fit; about 10 CPU-s)."""
    out = tmp_path_factory.mktemp("targets") / "t.json"
    assert main(["targets", "--suite", "emafdi-v2", "--tiers", "4", "--conditions",
                 "surface-current", "--per-tier", "1", "--seeds", "1", "--tracks",
                 "reference", "--workers", "1", "--quiet", "--out", str(out)]) == 0
    return out


@pytest.fixture
def use_table(monkeypatch):
    def use(path: Path) -> None:
        monkeypatch.setattr(v2, "targets_path", lambda: path)
        v2.shipped_targets.cache_clear()
    yield use
    v2.shipped_targets.cache_clear()


def test_targets_writes_a_v2_table_with_the_clean_data_fit(table, use_table):
    """The entry's f* is at most the fitness at the truth, the nominal's above; its x* has
    that fitness on the problem every run of the case solves; the clean-data fit's biases
    are its distances from the truth; Instance.best_known and Instance.judged read the table (the
    judged mask from the clean fit, on the reference track only)."""
    data = json.loads(table.read_text())
    assert data["suite"] == "emafdi-v2" and set(data["method"]) >= {"stages", "clean_stages"}
    key = target_key("small@surface-current", "reference", 0)
    e = data["entries"][key]
    assert e["f_star"] <= e["fitness_at_truth"] < e["f_nominal"]
    assert set(e["clean_x"]) == {"Na", "Fst", "BLK", "Gprop"} and e["cpu_s"] > 0
    truth = instance("small").truth
    p = make_problem("small@surface-current", track="reference", budget=1)
    bias = np.abs(np.array([e["clean_x"][n] for n in p.names]) - truth) / (p.upper - p.lower)
    assert np.allclose(bias, [e["clean_bias"][n] for n in p.names], rtol=1e-12)
    use_table(table)
    assert suites.instance("small@surface-current").best_known("reference", 0)["f_star"] == \
        e["f_star"]
    assert suites.instance("small@surface-current").best_known("reference", 1) is None
    assert suites.instance("small@surface-current").best_known("reference", 0, root_seed=3) \
        is None
    # the table's f* is that of the problem every run of the case solves
    x = np.array([e["x_star"][n] for n in p.names])
    q = make_problem("small@surface-current", track="reference", seed=run_seed(0, 0),
                        budget=1)
    assert q.objective.evaluate(x[None, :])[0][0] == e["f_star"]
    judged = suites.instance("small@surface-current").judged("reference")
    assert judged.tolist() == (bias <= MAX_TARGET_BIAS).tolist()
    assert suites.instance("small@surface-current").judged("twin") is None


def test_targets_show_summarises_the_v2_table(table, use_table, capsys):
    """``--show``: the exclusions (none here) and the cost per tier, read from the table."""
    use_table(table)
    capsys.readouterr()
    assert main(["targets", "--suite", "emafdi-v2", "--show", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    e = json.loads(table.read_text())["entries"]
    assert got["suite"] == "emafdi-v2" and got["entries"] == 1 and got["excluded"] == {}
    assert got["cost_by_tier"] == {"4": {"entries": 1, "cpu_s_median": e[next(iter(e))]["cpu_s"],
                                         "cpu_s_total": e[next(iter(e))]["cpu_s"]}}


def test_a_missing_or_mislabelled_table_is_tolerated_or_refused(tmp_path, use_table, table,
                                                                 capsys):
    use_table(tmp_path / "absent.json")   # absent: no fitness targets, every parameter judged
    assert suites.instance("t7-s00@prior").best_known("twin", 0) is None
    assert suites.instance("t7-s00@prior").judged("reference") is None
    assert main(["targets", "--suite", "emafdi-v2", "--show"]) != 0   # --show wants it
    assert "absent.json: no best-known table of suite emafdi-v2" in capsys.readouterr().err
    bad = tmp_path / "v1label.json"
    bad.write_text(table.read_text().replace('"emafdi-v2"', '"emafdi-v1"'))
    use_table(bad)
    with pytest.raises(SuiteError, match="not emafdi-v2"):
        suites.instance("t7-s00@prior").best_known("twin", 0)


def test_a_biased_parameter_loses_its_parameter_targets_on_the_reference_track(
        table, tmp_path, use_table, capsys):
    """The judged mask comes from the table, never the record: with a table whose clean fit
    puts Na 0.5 % of range off the truth, a run whose point misses Na by 2 % of range and
    hits the rest is a success on the reference track (and validate re-derives it so);
    with the true table it is not.  On the twin track every parameter is judged."""
    from ema_bench.leaderboard.derive import derive
    from ema_bench.leaderboard.tasks import Task, run_task
    from ema_bench.leaderboard.validate import check_record
    from ema_bench.registry import finish, register_solver

    case = "small@surface-current"
    truth = instance("small").truth
    p = make_problem("small@surface-current", track="reference", budget=1)
    off = truth + np.r_[-0.02, 0, 0, 0] * (p.upper - p.lower)

    @register_solver("at-off-na", description="test: one point 2 % off on Na", library="numpy")
    def _off(problem, budget, seed):
        problem.evaluate(off)
        return finish(problem, "at-off-na", "budget", 0.0)

    data = json.loads(table.read_text())
    e = data["entries"][target_key(case, "reference", 0)]
    e["clean_x"]["Na"] = float(truth[0] - 0.005 * (p.upper - p.lower)[0])
    doctored = tmp_path / "biased.json"
    doctored.write_text(json.dumps(data))
    use_table(doctored)
    assert main(["targets", "--suite", "emafdi-v2", "--show", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["excluded"] == {
        target_key(case, "reference", 0): ["Na"]}
    for path, success in ((table, False), (doctored, True)):
        use_table(path)
        rec = run_task(Task("at-off-na", case, "reference", 0, 1))
        assert rec["success"] is success and derive(rec).success is success
        assert rec["targets"]["parameters"]["0.03"] == 1
        assert check_record(rec) == []
    twin = run_task(Task("at-off-na", case, "twin", 0, 1))
    assert twin["success"] is False


def test_targets_subset_options_and_suites_do_not_mix(tmp_path):
    import argparse

    from ema_bench.cli.targets import _keys
    from ema_bench.suites.best_known import all_keys, compute_targets

    def keys(**kw):
        base = dict(suite="emafdi-v1", cases=None, tiers=None, conditions=None,
                    per_tier=None, seeds=None, tracks=None)
        return _keys(argparse.Namespace(**{**base, **kw}))

    # v1: the default is every key (the CI instances first); --cases picks instances
    assert keys() is None and len(all_keys()) == 460
    assert keys(cases=["paper"], seeds=1, tracks=["twin"]) == [
        "small|twin|0", "full|twin|0", "random|twin|0"]   # the sanity case has no f*
    assert keys(suite="emafdi-v2", tiers=["12"], conditions=["surface-current"], per_tier=1,
                seeds=2, tracks=["twin"]) == ["t12-s00@surface-current|twin|0",
                                              "t12-s00@surface-current|twin|1"]
    assert len(keys(suite="emafdi-v2")) == 1260

    with pytest.raises(SuiteError, match="in one table"):
        compute_targets(tmp_path / "x.json", keys=["small|twin|0", "t7-s00@prior|twin|0"])
    for argv in (["--suite", "emafdi-v2", "--cases", "small"], ["--tiers", "7"],
                 ["--suite", "emafdi-v2", "--tiers", "4", "--conditions", "no-prior"],
                 ["--suite", "emafdi-v2", "--tracks", "bench"], ["--cases", "s99"]):
        assert main(["targets", *argv, "--out", str(tmp_path / "y.json")]) != 0, argv
    assert not (tmp_path / "y.json").exists()


# --- a tiny v2 board through --check, export and validate ----------------------------------
@pytest.fixture(scope="module")
def board(tmp_path_factory) -> tuple[Path, list[str]]:
    """2 solvers x 1 instance per tier x 2 conditions x 1 seed, twin track, 40 evaluations
    per dimension (12 runs, a few seconds)."""
    out = tmp_path_factory.mktemp("v2board")
    argv = ["leaderboard", "--suite", "emafdi-v2", "--tiers", "4,7,12", "--conditions",
            "no-prior,surface-current", "--per-tier", "1", "--solvers", "random,nelder-mead",
            "--tracks", "twin", "--seeds", "1", "--budget-per-dim", "40", "--executor",
            "serial", "--no-plots", "--quiet"]
    assert main(argv + ["--out", str(out)]) == 0
    return out, argv


def test_check_reruns_a_v2_board_against_itself_and_refuses_another_suite(board, capsys,
                                                                           tmp_path):
    """``leaderboard --suite emafdi-v2 --check BOARD``: the same runs (deterministic) are no
    regression, the budget per case is the tier's; a baseline of another suite version is
    refused."""
    from ema_bench.leaderboard.check import compare, load_baseline

    out, argv = board
    capsys.readouterr()
    # tiers 4 and 7 rerun (tier 12 costs most): compared with their 8 committed runs
    argv = [a if a != "4,7,12" else "4,7" for a in argv]
    assert main(argv + ["--check", str(out), "--out", str(tmp_path / "now")]) == 0
    said = capsys.readouterr().out
    assert "no regression" in said and "40 x tier" in said and "runs at this budget: 8" in said
    recs = [json.loads(x) for x in (out / "runs.jsonl").read_text().splitlines()]
    # a smaller per-dimension budget: every committed run re-scored at its own tier's
    committed, used = load_baseline(out, lambda c: 20 * suites.instance(c).dim, 1)
    assert used == {"same_budget": 0, "re_scored": 12, "other_model_version": 0}
    assert sorted({r["budget"] for r in committed}) == [80, 140, 240]
    with pytest.raises(ValueError, match="suite version emafdi-v1"):
        compare(recs, [dict(r, suite="emafdi-v1") for r in recs])


def test_export_writes_one_ioh_function_per_condition_with_a_dimension_per_tier(board,
                                                                                tmp_path):
    ih = pytest.importorskip("iohinspector", reason="iohinspector not installed")
    out, _ = board
    recs = [json.loads(x) for x in (out / "runs.jsonl").read_text().splitlines()]
    assert main(["export", str(out / "runs.jsonl"), "--format", "ioh", "--out",
                 str(tmp_path / "ioh")]) == 0
    dm = ih.DataManager()
    dm.add_folder(str(tmp_path / "ioh"))
    ov = dm.overview
    assert len(ov) == len(recs) == 12
    assert set(ov["function_name"]) == {"no-prior@twin", "surface-current@twin"}
    got = {(r["algorithm_name"], r["function_name"], r["dimension"]): r
           for r in ov.iter_rows(named=True)}
    for rec in recs:
        inst = suites.instance(rec["case"])
        row = got[(rec["solver"], f"{inst.group[1]}@twin", inst.dim)]
        assert row["instance"] == 0 and row["evals"] == rec["evaluations"] == 40 * inst.dim
        assert row["best_y"] == min(y for _, y in rec["trace"])
    meta = json.loads(next((tmp_path / "ioh" / "random").glob("*surface-current*.json"))
                      .read_text())
    assert [s["dimension"] for s in meta["scenarios"]] == [4, 7, 12]
    assert [len(s["runs"][0]["best"]["x"]) for s in meta["scenarios"]] == [4, 7, 12]
    # precision needs f*: tier 4 has v1's, the others the shipped v2 table's (seed 0; a seed
    # beyond the table's has none, and is refused)
    assert main(["export", str(out / "runs.jsonl"), "--format", "ioh", "--value",
                 "precision", "--out", str(tmp_path / "p")]) == 0
    rec = next(r for r in recs if r["case"] == "t12-s00@surface-current")
    known = suites.instance(rec["case"]).best_known(rec["track"], 0)
    (run,) = [r for r in read_ioh(tmp_path / "p") if r["algorithm"] == rec["solver"]
              and r["function_name"] == "surface-current@twin" and r["dimension"] == 12]
    assert run["raw_y"] == pytest.approx(
        [max(0.0, (y - known["f_star"]) / (known["f_nominal"] - known["f_star"]))
         for _, y in rec["trace"]], rel=1e-12)
    later = tmp_path / "seed1.jsonl"
    later.write_text(json.dumps({**rec, "seed": 1, "key": rec["key"][:-1] + "1"}) + "\n")
    assert main(["export", str(later), "--format", "ioh", "--value", "precision", "--out",
                 str(tmp_path / "p1")]) != 0


def test_validate_with_replay_accepts_the_v2_board_and_refuses_a_doctored_record(board,
                                                                                 tmp_path,
                                                                                 capsys):
    """Every record re-derived and re-evaluated, the surface-current ones replayed (their
    problems rebuilt with the condition's weights: a replay on the full objective would
    not reproduce the trace); a record whose trace claims its final fitness one
    improvement early is refused."""
    out, _ = board
    keys = [k for r in map(json.loads, (out / "runs.jsonl").read_text().splitlines())
            if "surface-current" in (k := r["key"]) and "t12" not in k]
    assert main(["validate", str(out / "runs.jsonl"), "--partial",
                 *[a for k in keys for a in ("--replay-key", k)], "--replay", "all"]) == 0
    assert len(keys) == 4
    assert "replay: 4/4 records reproduced" in capsys.readouterr().out
    recs = [json.loads(x) for x in (out / "runs.jsonl").read_text().splitlines()]
    r = next(x for x in recs if x["case"] == "t7-s00@surface-current"
             and x["solver"] == "nelder-mead")
    bad = json.loads(json.dumps(r))
    # a hit moved earlier and the trace rewritten to match: re-derivation or replay sees it
    bad["trace"][1][1] = bad["trace"][-1][1]
    bad["trajectory"][1][1] = bad["trajectory"][-1][1]
    path = tmp_path / "bad.jsonl"
    path.write_text(json.dumps(bad) + "\n")
    assert main(["validate", str(path), "--partial", "--replay", "all"]) != 0
    said = capsys.readouterr().out
    assert "REFUSED" in said and "replay: 0/1 records reproduced" in said, said
    # a run made with every output weighed (no-prior: the same data and start rules) passed
    # off as surface-current: its fitness values are not the condition's
    from ema_bench.leaderboard.validate import check_record

    full = next(x for x in recs if x["case"] == "t7-s00@no-prior" and x["solver"] == "random")
    claim = dict(full, case="t7-s00@surface-current",
                 key=full["key"].replace("no-prior", "surface-current"))
    # refused: its targets are not the condition's (f*), nor, given them, its fitness values
    assert any("f_star" in p for p in check_record(claim))
    known = suites.instance("t7-s00@surface-current").best_known(full["track"], full["seed"])
    claim["targets"] = {**full["targets"], "f_star": known["f_star"],
                        "f_nominal": known["f_nominal"]}
    assert any("fitness" in p for p in check_record(claim))
