"""A newcomer's probes of the command line (issue 13): no traceback, no silent acceptance, every
output checked before the work, progress where work is long.

Each test is a probe that failed before the fix; the comment says what the old code did.
"""

from __future__ import annotations

import argparse
import os
import tracemalloc

import numpy as np
import pytest
from inprocess import run_cli

from ema_bench import make_problem
from ema_bench.cli import build_parser, main
from ema_bench.faults import FaultError, check_faults, get_case
from ema_bench.objective import ProblemError
from ema_bench.problem import MAX_BUDGET
from ema_bench.traces import load_traces


def _fail(capsys, argv: list[str]) -> str:
    """Run the CLI, expect exit code 2 with one error line; return that line."""
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err, err
    assert err.startswith(f"ema-bench {argv[0]}: error: "), err
    return err


@pytest.fixture
def a_file(tmp_path):
    f = tmp_path / "a_file"
    f.write_text("not a folder")
    return f


@pytest.fixture
def no_work(monkeypatch):
    """Make any simulation or fit fail loudly: the checks must come before the work."""
    def boom(*a, **k):
        raise AssertionError("work started before the output was checked")

    import ema_bench.cli.simulate as sim
    import ema_bench.diagnosis.workflow as wf
    import ema_bench.instances as inst

    monkeypatch.setattr(sim, "_simulate", boom)
    monkeypatch.setattr(inst, "make_problem", boom)
    monkeypatch.setattr(wf, "diagnose", boom)


# --- 4. write errors: one line, exit 2, before any computation ----------------------------
# (before: simulate computed the reference traces, then raised NotADirectoryError/
# IsADirectoryError from Traces.save; diagnose wrote its report after a minute's work)

@pytest.mark.parametrize("argv, needle", [
    (["simulate", "--out", "{f}/x.csv"], "--out"),
    (["simulate", "--case", "all", "--out", "{f}"], "exists and is not a folder"),
    (["simulate", "--out", "{d}"], "is a folder"),
    (["simulate", "--out", "{d}/traces.txt"], ".csv or .npz"),
    (["simulate", "--plot", "{f}/p.png"], "--plot"),
    (["simulate", "--plot", "{d}/p.bmpx"], ".png"),
    (["solve", "--plot", "{f}/p.png", "--budget", "10"], "--plot"),
])
def test_unwritable_outputs_fail_before_the_work(capsys, tmp_path, a_file, no_work, argv,
                                                 needle):
    argv = [a.format(f=a_file, d=tmp_path) for a in argv]
    assert needle in _fail(capsys, argv)


def test_diagnose_checks_its_report_folder_first(capsys, tmp_path, a_file, no_work):
    traces = tmp_path / "t.csv"
    traces.write_text("whatever")
    assert "--report" in _fail(capsys, ["diagnose", str(traces), "--report", str(a_file)])


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes through read-only permissions")
def test_read_only_folder(capsys, tmp_path, no_work):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        assert "cannot write" in _fail(capsys, ["simulate", "--out", str(ro / "x.csv")])
    finally:
        ro.chmod(0o700)


def test_a_late_write_error_is_one_line(capsys, tmp_path, monkeypatch):
    """A disk that fills after the checks: one line naming the file, exit 2 (before: an
    OSError traceback)."""
    import errno

    from ema_bench.traces import Traces

    def full(self, path):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(Traces, "save", full)
    out = tmp_path / "x.csv"
    err = _fail(capsys, ["simulate", "--model", "monitor", "--no-noise", "--out", str(out)])
    assert "No space left on device" in err and str(out) in err


# --- 5. huge budgets ---------------------------------------------------------------------
# (before: MemoryError preallocating a 10**12-row evaluation log)

def test_budget_beyond_the_maximum_is_refused(capsys):
    with pytest.raises(ProblemError, match="maximum"):
        make_problem("small", track="twin", budget=MAX_BUDGET + 1)
    assert f"--budget: must be from 1 to {MAX_BUDGET}" in \
        _fail(capsys, ["solve", "--budget", str(10**12)])
    for bad in (0, -1, True, 2.5):
        with pytest.raises(ProblemError, match="positive integer"):
            make_problem("small", track="twin", budget=bad)


def test_the_evaluation_log_grows_with_use():
    tracemalloc.start()
    p = make_problem("small", track="twin", budget=MAX_BUDGET)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert peak < 50e6  # bytes; a preallocated log would take 48 GB
    # crossing the first chunk keeps every evaluation, in order
    X = p.from_unit(np.random.default_rng(0).random((5000, p.dim)))
    f = np.concatenate([p.evaluate(X[:3000]), p.evaluate(X[3000:4500]), p.evaluate(X[4500:])])
    h = p.history()
    assert p.evaluations == 5000 and h["x"].shape == (5000, p.dim)
    np.testing.assert_array_equal(h["x"], X)
    np.testing.assert_array_equal(h["fitness"], f)
    assert p.best[1] == f.min()


def test_a_full_budget_is_still_exact():
    p = make_problem("small", track="twin", budget=4097)  # one past the first chunk
    X = np.tile(p.nominal, (4097, 1))
    p.evaluate(X)
    assert p.remaining == 0 and p.history()["fitness"].size == 4097


# --- 8. no silent acceptance in simulate -------------------------------------------------

@pytest.mark.parametrize("argv, needle", [
    (["--faults", "Na=0.9,Na=0.95"], "Na is given twice"),       # before: 0.95, silently
    (["--faults", ""], "empty"),                                 # before: nominal, silently
    (["--faults", ","], "empty"),
    (["--faults", "=0.9"], "NAME=VALUE"),
    (["--effect", "delay=1e-4", "--effect", "delay=2e-4"], "delay is given twice"),
    (["--effect", ""], "empty"),
    (["--effect", "bogus=1"], "unknown effect"),
    (["--faults", "Na=5"], "--faults: fault Na=5"),
])
def test_simulate_refuses_what_it_would_drop(capsys, no_work, argv, needle):
    assert needle in _fail(capsys, ["simulate", *argv])


@pytest.mark.parametrize("noise", [[], ["--no-noise"]])
def test_every_effect_used_is_recorded_in_the_file(capsys, tmp_path, noise):
    """Before: ``--model monitor --effect ...`` wrote no effect into the file's meta."""
    out = tmp_path / "m.csv"
    assert main(["simulate", "--model", "monitor", "--case", "small", "--effect",
                 "delay=6e-4", *noise, "--out", str(out)]) == 0
    meta = load_traces(out).meta
    assert meta["effects"] == {"delay": 6e-4}
    assert meta["faults"]["Na"] == 0.95


# --- 10. messages for the command line ---------------------------------------------------

def test_a_single_vector_error_names_no_row():
    bad = get_case("nominal").x.copy()
    bad[0] = 5.0
    with pytest.raises(FaultError) as exc:
        check_faults(bad)
    assert "Na=5" in str(exc.value) and "row" not in str(exc.value)
    with pytest.raises(FaultError, match="Na=5 - in row 1"):  # a batch says which row
        check_faults(np.array([get_case("nominal").x, bad]), batch=True)


def _helps(parser=None, prefix: str = "ema-bench") -> dict[str, str]:
    """Every command's and nested sub-command's help ('ema-bench campaign track' too)."""
    parser = build_parser() if parser is None else parser
    out = {prefix: parser.format_help()}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, p in action.choices.items():
                out.update(_helps(p, f"{prefix} {name}"))
    return out


@pytest.mark.parametrize("command", list(_helps()))
def test_help_shows_no_rest_markup(command):
    text = _helps()[command]
    assert "ema-bench campaign track" in _helps()   # nested sub-commands are walked
    # "%%" is argparse's escape in an option's help only; in a description it prints as is
    for markup in ("``", ":func:", ":class:", ":meth:", ":mod:", ":data:", "%%"):
        assert markup not in text, f"{command} --help shows {markup!r}"
    assert not any(line.rstrip().endswith("::") for line in text.splitlines())


def test_params_cites_nothing_outside_the_repository(capsys):
    for argv in (["params"], ["params", "--json"]):
        assert main(argv) == 0
        out = capsys.readouterr().out
        assert "DESIGN" not in out and "../" not in out and "shared/" not in out


# --- 9. progress of diagnose -------------------------------------------------------------
# (before: 15-70 s of silence)

@pytest.fixture(scope="module")
def monitor_traces_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("diag") / "m.csv"
    assert main(["simulate", "--model", "monitor", "--case", "small", "--tests",
                 "step,sine,sine2", "--out", str(path)]) == 0
    return path


# slow: two diagnoses that fit candidate effects (about 12 CPU-s each); the fast loop runs
# diagnose on the monitor's own data (test_diagnosis.py)
@pytest.mark.slow
@pytest.mark.parametrize("quiet", [False, True])
def test_diagnose_reports_its_stages_unless_quiet(monitor_traces_file, quiet):
    res = run_cli("diagnose", monitor_traces_file, "--budget", "100", "--bootstrap", "10",
                  *(["--quiet"] if quiet else []))
    assert res.returncode == 0, res.stderr
    assert "verdict:" in res.stdout
    lines = [ln for ln in res.stderr.splitlines() if "diagnose:" in ln]
    if quiet:
        assert lines == []
    else:  # not a terminal: one line per stage
        assert any("base fit done (100 evaluations)" in ln for ln in lines), res.stderr
        assert any("residuals assessed" in ln for ln in lines)


@pytest.mark.parametrize("track", ["twin", "reference"])
def test_the_data_makers_record_stays_out_of_the_problem(track):
    """simulate records faults and effects in the file; a problem's measured traces must not
    (a solver could read the truth there)."""
    p = make_problem("small", track=track, seed=1, budget=1, effects={"delay": 6e-4})
    assert set(p.measured.meta) <= {"model", "noise", "adc"}
