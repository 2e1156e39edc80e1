"""Replay's own logic (``leaderboard/replay.py``) in the test's process: the comparison of a
record with its replayed log (each difference by its exact line, at the tolerance's edge),
the evaluation count, the sample, the worker's job, the findings of records it cannot
replay, and the results' order and BLAS note (found by mutation testing,
docs/mutation-testing.md).

The replayed logs are built here from the record's own points (what an exact replay gives);
the worker-process replays are tests/test_judge.py's and tests/test_replay_server.py's.
``replay`` itself runs once with the real worker job on the ``serial`` executor (in this
process), so its bookkeeping is reached without starting a fork server.
"""

from __future__ import annotations

import os

import evidence
import numpy as np
import pytest

from ema_bench.leaderboard import replay as rp
from ema_bench.leaderboard.tasks import Task
from ema_bench.manifest import blas_kernel
from ema_bench.problem import ProblemError
from ema_bench.sweep import executors

at = lambda p: evidence.level("small", "twin", 0, p)   # noqa: E731


def _record() -> dict:
    """Improvements at evaluations 1 and 7 of 100 (small, twin, seed 0)."""
    return evidence.record([(1, at(0.5), evidence.vector("small", 0.3)),
                            (7, at(0.1), evidence.vector("small", 0.2))])


def _history(rec: dict) -> tuple[dict, np.ndarray]:
    """The log and final vector of an exact replay: the record's points at their
    evaluations, worse ones in between."""
    n = rec["evaluations"]
    pts = {e: (f, v) for e, f, v in rec["trajectory"]}
    fit = np.array([pts[e][0] if e in pts else 1e9 for e in range(1, n + 1)])
    x = np.array([pts[e][1] if e in pts else [9.0] * 4
                  for e in range(1, n + 1)])
    last = max(pts)
    return {"fitness": fit, "best": np.minimum.accumulate(fit), "x": x}, x[last - 1]


def test_an_exact_replay_is_reproduced_and_each_difference_is_named():
    rec = _record()
    hist, x = _history(rec)
    f1, f7 = rec["trajectory"][0][1], rec["trajectory"][1][1]
    assert rp.compare(rec, hist, x) is None
    # the parameters past the four faults are not in the record's x
    assert rp.compare(rec, hist, np.concatenate([x, np.zeros(8)])) is None
    short = {k: v[:99] for k, v in hist.items()}
    assert rp.compare(rec, short, x) == "evaluations: recorded 100, replayed 99"
    # the fitness to REPLAY_RTOL, relative: half of it passes, twice of it is named
    for scale, found in ((1 + 0.5e-6, False), (1 + 2e-6, True)):
        h = {**hist, "best": hist["best"].copy()}
        h["best"][6:] *= scale
        msg = rp.compare(rec, h, x)
        assert (msg == f"trace at evaluation 7: recorded {f7!r}, replayed "
                       f"{float(h['best'][6])!r}") if found else msg is None
    # the replayed value named is the log's at that evaluation (the first, one before an
    # improvement, the last)
    for e, f, got in ((1, 2 * f1, f1), (6, 2 * f1, f1), (100, 2 * f7, f7)):
        assert rp.compare({**rec, "trace": [[e, f]]}, hist, x) == (
            f"trace at evaluation {e}: recorded {f!r}, replayed {got!r}")
    for e in (0, 101):   # outside the log
        bad = {**rec, "trace": [[e, f1]]}
        assert rp.compare(bad, hist, x) == (f"trace at evaluation {e}: recorded {f1!r}, "
                                            "replayed None")
    b = rec["best_at"][0][0]
    assert rp.compare({**rec, "best_at": [[b, 2 * f7]]}, hist, x) == (
        f"best_at {b}: recorded {2 * f7!r}, replayed {float(hist['best'][b - 1])!r}")
    assert rp.compare({**rec, "best_at": [[7, 2 * f7]]}, hist, x) == (
        f"best_at 7: recorded {2 * f7!r}, replayed {f7!r}")
    assert rp.compare({**rec, "best_at": [[1, f1], [6, f1], [7, f7], [100, f7]]}, hist,
                      x) is None
    assert rp.compare({k: v for k, v in rec.items() if k != "best_at"}, hist, x) is None
    assert rp.compare({**rec, "best_at": [[0, f7]]}, hist, x) == (
        f"best_at 0: recorded {f7!r}, replayed {float(hist['best'][-1])!r}")
    assert rp.compare({**rec, "best_at": [[101, f7]]}, hist, x) == (
        f"best_at 101: recorded {f7!r}, replayed {float(hist['best'][99])!r}")
    moved = x.copy()
    moved[1] *= 1 + 2e-6
    assert rp.compare(rec, hist, moved) == (
        f"x: recorded {[rec['x'][k] for k in ('Na', 'Fst', 'BLK', 'Gprop')]}, replayed "
        f"{[float(v) for v in moved[:4]]}")
    near = x.copy()
    near[1] *= 1 + 0.5e-6
    assert rp.compare(rec, hist, near) is None
    # no absolute slack: a fault at exactly 0 replayed at 1e-10 is not reproduced
    zero = {**rec, "x": {**rec["x"], "BLK": 0.0}}
    tiny = x.copy()
    tiny[2] = 1e-10
    assert rp.compare(zero, hist, tiny).startswith("x: recorded")
    zero["x"]["BLK"] = 1e-10
    assert rp.compare(zero, hist, tiny) is None
    h0 = {**hist, "x": hist["x"].copy()}
    h0["x"][99] = [9.0, 9.0, 1e-10, 9.0]
    for v, found in (([9.0, 9.0, 0.0, 9.0], True), ([9.0, 9.0, 1e-10, 9.0], False)):
        msg = rp.compare({**rec, "trajectory": [[100, f7, v]]}, h0, x)
        assert (msg == "trajectory vector at evaluation 100: not reproduced") is found
        assert found or msg is None
    tj = [list(p) for p in rec["trajectory"]]
    tj[0] = [1, tj[0][1], [tj[0][2][0] * (1 + 2e-6), *tj[0][2][1:]]]
    assert rp.compare({**rec, "trajectory": tj}, hist, x) == (
        "trajectory vector at evaluation 1: not reproduced")
    for e in (0, 101):
        tj = [[e, f1, rec["trajectory"][0][2]]]
        assert rp.compare({**rec, "trajectory": tj}, hist, x) == (
            f"trajectory vector at evaluation {e}: not reproduced")
    legacy = {k: v for k, v in rec.items() if k != "trajectory"}
    assert rp.compare(legacy, hist, x) is None
    assert rp.compare({**rec, "trajectory": None}, hist, x) is None


def test_a_run_that_evaluates_the_model_outside_its_budget_is_a_finding():
    rec = _record()
    hist, x = _history(rec)
    out = {"fitness": hist["fitness"].tolist(), "best": hist["best"].tolist(),
           "x_hist": hist["x"].tolist(), "x": x.tolist(), "evaluations": 100,
           "model_evaluations": 100}
    assert rp._finding(rec, out) is None
    assert rp._finding(rec, {**out, "model_evaluations": 101}) == (
        "the replayed run made 101 model evaluations, 100 of them counted: a solver that "
        "evaluates the model outside its budget")
    # a replay that differs is named by its difference first
    assert rp._finding(rec, {**out, "x": [0.0] * 4, "model_evaluations": 101}).startswith(
        "x: recorded")


def test_the_sample_leaves_out_error_records_keeps_file_order_and_selects_by_key():
    recs = [evidence.record([(1, at(0.5), evidence.vector("small", 0.3))], solver=s)
            for s in "abcd"]
    err = evidence.record([], solver="e", status="error")
    pool = [recs[0], err, *recs[1:]]
    assert rp.sample(pool, None, 7) == recs
    two = rp.sample(pool, 2, 7)
    assert len(two) == 2 and two == [r for r in recs if r in two]
    assert rp.sample(pool, 2, 7) == two and rp.sample(pool, 9, 7) == recs
    assert rp.sample(pool, None, 7, keys={recs[2]["key"], err["key"], "nothing"}) == [recs[2]]
    assert rp.sample([{"solver": "x"}, *recs], None, 0, keys={recs[0]["key"]}) == [recs[0]]


def test_the_workers_job_is_the_records_run_without_its_truth():
    rec = {**_record(), "root_seed": 3, "seed": 1, "budget": 50}
    job = rp._job(4, rec)
    solver, problem, budget, node, scheme = job.data
    assert (job.key, job.identity, solver, budget, scheme) == ("4", 4, "a", 50, 2)
    assert problem.budget == 50 and problem.evaluations == 0
    task = Task("a", "small", "twin", 1, 50, 3)
    assert node.entropy == task.node().entropy and node.spawn_key == task.node().spawn_key
    with pytest.raises(ProblemError, match="true faults of measured data are unknown"):
        problem.score(problem.nominal)   # no truth to score against
    # the root seed defaults to 0
    node0 = rp._job(0, {k: v for k, v in rec.items() if k != "root_seed"}).data[3]
    assert node0.spawn_key == Task("a", "small", "twin", 1, 50, 0).node().spawn_key
    assert node0.entropy == Task("a", "small", "twin", 1, 50, 0).node().entropy


def test_names_and_installed_solvers():
    assert rp._name({"key": "a\x1b[2Jb"}) == "a [2Jb" and rp._name({}) == "?"
    assert rp._name("k\nx") == "k x"
    assert rp._installed("random") and not rp._installed("no-such-solver")
    # an entry point of another group (the console script) is no solver
    assert not rp._installed("ema-bench")


def test_replay_reports_every_record_in_sample_order(monkeypatch):
    """Records it cannot replay are findings (an adapter's run, an instance it cannot
    build); the others run the real worker job (on the serial executor, in this process):
    an honest run is reproduced, a doctored one is named, with the BLAS note where the
    record was made under another kernel."""
    run = evidence.real_run("random", "s00", "twin", 0, 40)
    doctored = {**run, "key": "doctored", "trace": [[1, run["trace"][0][1] * 2],
                                                    *run["trace"][1:]]}
    other_blas = {**doctored, "key": "other-blas",
                  "manifest": {**run["manifest"], "blas": "NoSuchKernel"}}
    same_blas = {**doctored, "key": "same-blas",
                 "manifest": {**run["manifest"], "blas": blas_kernel()}}
    adapter = {**run, "key": "adapter", "solver": "scipy-adapter"}
    broken = {**run, "key": "broken", "case": "no-such-case"}
    used = []

    def serial(jobs, runner, executor, workers, preload=()):
        used.append((executor, workers, preload))
        return executors.execute(jobs, runner, "serial", workers)
    monkeypatch.setattr(rp, "execute", serial)
    out = rp.replay([adapter, run, broken, other_blas, same_blas], None, 0)
    assert [r.key for r in out] == ["adapter", run["key"], "broken", "other-blas",
                                    "same-blas"]
    assert used == [("isolated", min(3, os.cpu_count() or 1), rp.SERVER_PRELOAD)]
    assert out[0].finding == (
        "not replayable: solver 'scipy-adapter' is not an installed plugin (an adapter's "
        "run, e.g. SciPy through ema_bench.adapters, has no registered solver to re-run): "
        "install its package, or do not --replay it") and out[0].wall_s == 0.0
    assert out[1].finding is None and out[1].wall_s > 0
    assert out[2].finding.startswith("replay failed: ProblemError: unknown case "
                                     "'no-such-case'") and out[2].wall_s == 0.0
    first = f"trace at evaluation 1: recorded {run['trace'][0][1] * 2!r}"
    assert out[3].finding.startswith(first) and out[3].finding.endswith(
        f" (made under BLAS kernel NoSuchKernel, replayed under {blas_kernel()}: "
        "OPENBLAS_CORETYPE picks the kernel)")
    assert out[4].finding.startswith(first) and "BLAS" not in out[4].finding
    rp.replay([run], None, 0, workers=2)
    assert used[-1][1] == 2
    # one job: one worker; an unknown core count: one at a time
    rp.replay([run], None, 0)
    assert used[-1][1] == 1
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    rp.replay([run, run], None, 0)
    assert used[-1][1] == 1
    # a worker that fails is a finding, and a record without a kernel says so
    failed = rp.replay([{**run, "seed_scheme": 99, "manifest": {}}], None, 0)
    assert failed[0].finding.startswith("replay failed: ValueError: unknown seed scheme 99")
    assert failed[0].finding.endswith(f" (made under BLAS kernel unrecorded, replayed under "
                                      f"{blas_kernel()}: OPENBLAS_CORETYPE picks the kernel)")
    assert failed[0].wall_s >= 0


def test_replay_draws_its_sample_with_the_seed_and_keeps_to_the_keys():
    """Records it cannot replay cost nothing to sample: which of eight are replayed is the
    sample of :func:`~ema_bench.leaderboard.replay.sample` for that seed."""
    base = evidence.record([(1, at(0.5), evidence.vector("small", 0.3))])
    recs = [{**base, "key": f"k{i}", "solver": "scipy-adapter"} for i in range(8)]
    for seed in (1, 2):
        picked = [r.key for r in rp.replay(recs, 3, seed)]
        assert picked == [r["key"] for r in rp.sample(recs, 3, seed)] and len(picked) == 3
    assert [r.key for r in rp.replay(recs, None, 0, keys={"k5", "k2"})] == ["k2", "k5"]
