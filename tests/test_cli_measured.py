"""Measured data in several single-test files: ``load_measured`` and the ``--test`` option of
``ema-bench solve --measured`` and ``ema-bench diagnose`` (real command-line runs, in process)."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from ema_bench.cli import main
from ema_bench.faults import NOMINAL
from ema_bench.monitor import monitor_traces
from ema_bench.objective import KNOWN_TESTS
from ema_bench.traces import SIGNALS, UNITS, Traces, TracesError, load_measured

TESTS = ("step", "sine", "sine2")


@pytest.fixture(scope="module")
def source() -> Traces:
    return monitor_traces(NOMINAL, tests=tuple(KNOWN_TESTS[t] for t in TESTS))


def write_plain_csv(path, traces: Traces, test: str, ms_and_degrees: bool = False):
    """A plain measured CSV of one test: no 'test' column, no comment lines."""
    time_unit, angle_unit = ("ms", "deg") if ms_and_degrees else ("s", "rad")
    scale = np.array([180.0 / math.pi if ms_and_degrees else 1.0, 1.0, 1.0, 1.0])
    header = [f"time [{time_unit}]", f"theta_u [{angle_unit}]",
              *(f"{s} [{UNITS[s]}]" for s in SIGNALS[1:])]
    times = traces.time(test) * (1e3 if ms_and_degrees else 1.0)
    lines = [",".join(header)]
    lines += [",".join(map(repr, [t, *row])) for t, row in
              zip(times.tolist(), (traces.data[test] * scale).tolist())]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def files(source, tmp_path_factory) -> dict[str, str]:
    """test -> path of its plain CSV (sine in ms and degrees)."""
    folder = tmp_path_factory.mktemp("plain")
    return {t: str(write_plain_csv(folder / f"{t}.csv", source, t, ms_and_degrees=t == "sine"))
            for t in TESTS}


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def one_line_error(capsys, command: str, *argv: str) -> str:
    rc, out, err = run_cli(capsys, command, *argv)
    assert rc == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"ema-bench {command}: error: "), err
    return lines[0]


# ---- the library function ----------------------------------------------------------------------


def test_load_measured_names_and_merges_the_files(files, source):
    tr = load_measured([files[t] for t in TESTS], TESTS)
    assert tr.tests == TESTS
    assert tr.allclose(source, rtol=1e-12, atol=1e-12)
    assert tr.meta == {}  # plain files have no meta
    # one file, one name: a plain path and a plain string are accepted
    assert load_measured(files["sine"], "sine").tests == ("sine",)


def test_load_measured_takes_named_tests_and_keeps_agreed_meta(files, source, tmp_path):
    both = tmp_path / "both.csv"
    Traces({"step": source.data["step"], "sine": source.data["sine"]},
           meta={"model": "monitor", "run": 1}).save(both)
    # None takes the tests a file names; a plain file needs a name; a name picks one test
    assert load_measured([both, files["sine2"]], [None, "sine2"]).tests == TESTS
    with pytest.raises(TracesError, match="sine2.csv: no 'test' column"):
        load_measured([both, files["sine2"]])
    assert load_measured([both, files["sine2"]], ["sine", "sine2"]).tests == ("sine", "sine2")

    other = tmp_path / "other.npz"
    Traces({"sine2": source.data["sine2"]}, meta={"model": "monitor", "run": 2}).save(other)
    assert load_measured([both, other]).meta == {"model": "monitor"}  # "run" disagrees


@pytest.mark.parametrize(("names", "match"), [
    (["step", "sine"], r"3 file\(s\) but 2 test name\(s\) \(step, sine\); give one test name "
                       r"per file"),
    (["step", "sine", "step"], r"test 'step' is in both .*step\.csv and .*sine2\.csv; each "
                               r"test must come from one file"),
])
def test_load_measured_refuses_count_mismatch_and_duplicates(files, names, match):
    with pytest.raises(TracesError, match=match):
        load_measured([files[t] for t in TESTS], names)
    with pytest.raises(TracesError, match="no traces file given"):
        load_measured([])


def test_unnamed_test_error_speaks_python_and_keeps_a_plain_version(files):
    with pytest.raises(TracesError, match=r"no 'test' column; pass test=<name>") as info:
        load_measured([files["step"]])
    assert info.value.unnamed_test.endswith("step.csv: no 'test' column")


# ---- ema-bench solve --measured ... --test ... ---------------------------------------------------


def test_solve_several_measured_files(capsys, files):
    common = ("--solver", "random", "--budget", "20", "--json")
    rc, out, err = run_cli(capsys, "solve", "--measured", files["step"], files["sine"],
                           "--test", "step,sine", *common)
    assert rc == 0, err
    first = json.loads(out)
    assert first["measured"] == [files["step"], files["sine"]]
    assert first["track"] == "measured" and 0 < first["evaluations"] <= 20
    # the same with repeated options
    rc, out, err = run_cli(capsys, "solve", "--measured", files["step"], "--measured",
                           files["sine"], "--test", "step", "--test", "sine", *common)
    assert rc == 0, err
    assert json.loads(out)["fitness"] == first["fitness"]


@pytest.mark.parametrize(("argv", "message"), [
    (("--measured", "{step}", "{sine}"),
     r"step\.csv: no 'test' column; name its test with --test NAME,NAME,\.\.\. \(one per file\)$"),
    (("--measured", "{step}"), r"step\.csv: no 'test' column; name its test with --test NAME$"),
    (("--measured", "{step}", "{sine}", "--test", "step"),
     r"2 file\(s\) but 1 test name\(s\) \(step\); give one test name per file$"),
    (("--measured", "{step}", "{sine}", "--test", "step,step"), r"test 'step' is in both"),
    (("--case", "small", "--test", "step"), r"--test names the tests of --measured files"),
], ids=["unnamed", "unnamed-one-file", "count", "twice", "no-measured"])
def test_solve_measured_errors_speak_cli(capsys, files, argv, message):
    line = one_line_error(capsys, "solve", *(a.format(**files) for a in argv),
                          "--budget", "20")
    assert "test=<name>" not in line
    assert re.search(message, line), line


# ---- ema-bench diagnose A B C --test ... ---------------------------------------------------------


def test_diagnose_loads_several_named_files(capsys, files, source, monkeypatch):
    """The three files reach the diagnosis as one Traces (stopped there: a diagnosis takes a
    minute)."""
    seen = {}

    def stop(measured, settings, **kw):
        seen["measured"] = measured
        raise ValueError("diagnosis skipped by the test")

    monkeypatch.setattr("ema_bench.diagnosis.workflow.diagnose", stop)
    line = one_line_error(capsys, "diagnose", *(files[t] for t in TESTS),
                          "--test", "step,sine,sine2", "--quiet")
    assert line.endswith("diagnosis skipped by the test")
    assert seen["measured"].tests == TESTS
    assert seen["measured"].allclose(source, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(("names", "message"), [
    (None, r"step\.csv: no 'test' column; name its test with --test NAME,NAME,\.\.\. \(one per "
           r"file\)$"),
    ("step,sine", r"3 file\(s\) but 2 test name\(s\) \(step, sine\)"),
])
def test_diagnose_errors_speak_cli(capsys, files, names, message):
    argv = [files[t] for t in TESTS] + ([] if names is None else ["--test", names])
    line = one_line_error(capsys, "diagnose", *argv)
    assert "test=<name>" not in line
    assert re.search(message, line), line


@pytest.mark.parametrize("command", ["solve", "diagnose"])
def test_help_documents_test_names(capsys, command):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    text = capsys.readouterr().out
    assert "--test NAME[,NAME...]" in text and "one test name per" in text
    assert "--test step,sine" in text  # the example
