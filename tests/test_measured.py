"""Problems built from measured trace files (CSV written by the CLI, NPZ, MATLAB .mat)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.io
from inprocess import run_cli

from ema_bench.faults import CASES, LOWER, NOMINAL, UPPER
from ema_bench.problem import ProblemError
from ema_bench.reference import simulate_reference
from ema_bench.seeding import run_seed, stream
from ema_bench.suites.problem import make_problem
from ema_bench.traces import SIGNALS, UNITS, Traces, TracesError, load_traces

X = LOWER + np.random.default_rng(0).random((4, 4)) * (UPPER - LOWER)


@pytest.fixture(scope="module")
def cli_csv(tmp_path_factory):
    """Traces of the small case, seed 1, written by the real command line."""
    path = tmp_path_factory.mktemp("measured") / "small_seed1.csv"
    done = run_cli("simulate", "--case", "small", "--seed", "1", "--out", path)
    assert done.returncode == 0, done.stderr
    assert path.is_file()
    return path


@pytest.fixture(scope="module")
def cli_traces(cli_csv):
    return load_traces(cli_csv)


def problem_from(path, **kw):
    """What a user with a file does."""
    return make_problem(measured=load_traces(path, **kw), budget=10)


def csv_parts(path):
    """(comment lines, header fields, rows as lists of strings) of a traces CSV."""
    lines = path.read_text().splitlines()
    comments = [ln for ln in lines if ln.startswith("#")]
    body = [ln for ln in lines if ln and not ln.startswith("#")]
    return comments, body[0].split(","), [ln.split(",") for ln in body[1:]]


def write_csv(path, comments, header, rows):
    path.write_text("\n".join([*comments, ",".join(header), *(",".join(r) for r in rows)])
                    + "\n")
    return path


# ---- round trip ----------------------------------------------------------------------------------


def test_cli_csv_round_trips_to_the_reference_traces(cli_traces):
    # `simulate --seed 1`: the noise stream of run node (0, 1)
    expected = simulate_reference(CASES["small"].x, seed=stream(run_seed(0, 1), "noise"))
    assert cli_traces.tests == ("step", "sine")
    assert cli_traces.allclose(expected, rtol=0.0, atol=1e-12)


def test_measured_problem_evaluates_but_cannot_be_scored(cli_traces):
    p = make_problem(measured=cli_traces, budget=6)
    assert p.track == "measured" and not p.has_truth
    f = p.evaluate(X)
    assert f.shape == (4,) and np.all(np.isfinite(f)) and p.evaluations == 4
    assert p.evaluate(CASES["small"].x) < p.evaluate(NOMINAL)  # the data are the small case
    r = make_problem(measured=cli_traces, budget=1).residuals(X[0])
    np.testing.assert_allclose(np.sum(r**2), f[0], rtol=1e-10)
    with pytest.raises(ProblemError, match="unknown"):
        p.score(CASES["small"].x)
    with pytest.raises(ProblemError, match="unknown"):
        p.fitness_at_truth()


def test_saved_and_reloaded_problem_traces_give_the_same_fitness(tmp_path):
    original = make_problem("random", seed=0, budget=4)
    original.measured.save(tmp_path / "random.csv")
    reloaded = problem_from(tmp_path / "random.csv")
    np.testing.assert_array_equal(reloaded.evaluate(X), original.evaluate(X))


def test_measured_must_be_traces():
    with pytest.raises(ProblemError, match="Traces"):
        make_problem(measured={"step": np.zeros((300, 4))})


# ---- traces the protocol does not know -----------------------------------------------------------


def test_unknown_test_name_or_wrong_length_raise_problem_error(cli_traces):
    data = dict(cli_traces.data)
    with pytest.raises(ProblemError, match="chirp"):
        make_problem(measured=Traces({**data, "chirp": data["sine"]}))
    with pytest.raises(ProblemError, match=r"'step' has 299 samples.*expects 300"):
        make_problem(measured=Traces({**data, "step": data["step"][:-1]}))
    with pytest.raises(ProblemError, match="500 Hz"):
        make_problem(measured=Traces(data, dt=2e-3))
    # a subset of the standard tests is a valid (smaller) problem
    only_step = make_problem(measured=Traces({"step": data["step"]}), budget=1)
    assert only_step.n_residuals == 300 * 4 and np.isfinite(only_step.evaluate(NOMINAL))


def test_other_sample_rate_is_refused_when_the_problem_is_built(cli_traces):
    half_rate = Traces({t: v[::2] for t, v in cli_traces.data.items()}, dt=2e-3)
    with pytest.raises(ProblemError, match="1000 Hz|sample rate|dt"):
        p = make_problem(measured=half_rate, budget=1)
        p.evaluate(NOMINAL)


def test_truncated_file_loads_but_makes_no_problem(cli_csv, tmp_path):
    comments, header, rows = csv_parts(cli_csv)
    rows = [r for r in rows if r[0] == "sine"] + [r for r in rows if r[0] == "step"][:200]
    path = write_csv(tmp_path / "short_step.csv", comments, header, rows)
    assert load_traces(path).n_samples("step") == 200
    with pytest.raises(ProblemError, match="'step' has 200 samples"):
        problem_from(path)


# ---- every load error class, met where a user meets it: building the problem from a file ---------


def _drop_column(header, rows, name):
    j = next(i for i, h in enumerate(header) if h.startswith(name))
    return ([h for i, h in enumerate(header) if i != j],
            [[v for i, v in enumerate(r) if i != j] for r in rows])


def _swap_times(header, rows):
    rows = [list(r) for r in rows]
    rows[100][1], rows[101][1] = rows[101][1], rows[100][1]
    return header, rows


def _nan_gap(header, rows):
    rows = [list(r) for r in rows]
    k = next(i for i, r in enumerate(rows) if r[0] == "sine") + 500
    rows[k][4] = ""
    return header, rows


def _slow_clock(header, rows):
    return header, [[r[0], repr(2 * float(r[1])), *r[2:]] for r in rows]


def _few_rows(header, rows):
    return header, [r for r in rows if r[0] == "step"][:5] + [r for r in rows
                                                              if r[0] == "sine"][:5]


def _bad_unit(header, rows):
    return [h.replace("omega_m [rad/s]", "omega_m [V]") for h in header], rows


@pytest.mark.parametrize(("edit", "message"), [
    (lambda h, r: _drop_column(h, r, "i_eq"), r"missing signal column\(s\) i_eq"),
    (_bad_unit, r"unit 'V' not accepted for omega_m"),
    (_swap_times, r"test 'step': non-monotonic \(decreasing\) time at sample index 101"),
    (_nan_gap, r"test 'sine', signal 'omega_m': NaN gap"),
    (_slow_clock, r"sample rate too low"),
    (_few_rows, r"too short, 5 sample"),
], ids=["missing-signal", "unit", "non-monotonic", "nan-gap", "sample-rate", "too-short"])
def test_bad_files_fail_with_a_clear_error(cli_csv, tmp_path, edit, message):
    comments, header, rows = csv_parts(cli_csv)
    header, rows = edit(header, rows)
    path = write_csv(tmp_path / "bad.csv", comments, header, rows)
    with pytest.raises(TracesError, match=message) as err:
        problem_from(path)
    assert str(path) in str(err.value)


def test_plain_measured_csv_with_other_units_and_rate(cli_csv, cli_traces, tmp_path):
    """A 'plain' file: no comments, ms and degrees, sampled at 2 kHz -> the same problem."""
    header = ["test", "time [ms]", "theta_u [deg]", "theta_m [rad]", "omega_m [rpm]", "i_eq [mA]"]
    factors = np.array([180.0 / math.pi, 1.0, 60.0 / (2.0 * math.pi), 1e3])
    rows = []
    for t in cli_traces.tests:
        for k, v in enumerate(cli_traces.data[t] * factors):
            for half in (0, 1):
                rows.append([t, repr((2 * k + half + 0.5) * 0.5), *map(repr, v.tolist())])
    path = write_csv(tmp_path / "plain.csv", [], header, rows)
    p = problem_from(path)
    reference = make_problem(measured=cli_traces, budget=4)
    assert p.measured.allclose(cli_traces, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(p.evaluate(X), reference.evaluate(X), rtol=1e-9)


# ---- NPZ and MATLAB files ------------------------------------------------------------------------


def test_npz_file_makes_a_working_problem(cli_traces, tmp_path):
    cli_traces.save(tmp_path / "small.npz")
    p = problem_from(tmp_path / "small.npz")
    reference = make_problem(measured=cli_traces, budget=4)
    np.testing.assert_array_equal(p.evaluate(X), reference.evaluate(X))


def test_mat_file_makes_a_working_problem(cli_traces, tmp_path):
    variables = {"units": np.array(["time=s", *(f"{s}={UNITS[s]}" for s in SIGNALS)])}
    for t in cli_traces.tests:
        variables[f"time_{t}"] = cli_traces.time(t)
        for s in SIGNALS:
            variables[f"{t}_{s}"] = cli_traces.signal(t, s)
    scipy.io.savemat(tmp_path / "small.mat", variables)
    p = problem_from(tmp_path / "small.mat")
    assert p.measured.tests == ("step", "sine")
    reference = make_problem(measured=cli_traces, budget=4)
    np.testing.assert_array_equal(p.evaluate(X), reference.evaluate(X))
    # a plain one-test .mat (time + signal variables) needs its test name
    plain = {"units": variables["units"], "time": cli_traces.time("sine")}
    plain.update({s: cli_traces.signal("sine", s) for s in SIGNALS})
    scipy.io.savemat(tmp_path / "sine.mat", plain)
    with pytest.raises(TracesError, match="test="):
        problem_from(tmp_path / "sine.mat")
    sine_only = problem_from(tmp_path / "sine.mat", test="sine")
    assert sine_only.measured.tests == ("sine",) and np.isfinite(sine_only.evaluate(NOMINAL))
