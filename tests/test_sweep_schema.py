"""One type check for every JSON-lines file the package reads: run records, blind cases,
tracking steps, coverage records and best-known entries.  A wrong type in any field a reader
relies on stops the reading with one line naming the file, the line and the field (before:
``"replace": "no"`` was read as true, wrong types gave tracebacks); the committed files pass.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from ema_bench.diagnosis.blind import CASE_SCHEMA
from ema_bench.leaderboard.run_store import RUN_SCHEMA
from ema_bench.leaderboard.run_store import read_records as read_runs
from ema_bench.prognostics.track_io import ERROR_SCHEMA, STEP_SCHEMA
from ema_bench.suites.best_known import ENTRY_SCHEMA
from ema_bench.sweep.schema import SchemaError
from ema_bench.sweep.store import Store, read_records
from ema_bench.uncertainty.coverage import RECORD_SCHEMA
from ema_bench.uncertainty.coverage import read_records as read_coverage

ROOT = Path(__file__).resolve().parents[1]
BOARDS = ROOT / "leaderboards"

#: A value of the wrong JSON type for each declared type (written out here, not derived
#: from the checker): a string for numbers, a number for strings, "no" for booleans, ...
WRONG = {"str": 1, "int": "1", "number": "1.0", "bool": "no", "list": {"a": 1}, "dict": [1],
         "str|null": 1, "int|null": 1.5, "number|null": "1", "list|null": "x",
         "str|int": 1.5, "dict|bool": "no"}


def first_line(path: Path) -> dict:
    return json.loads(path.read_text().splitlines()[0])


def committed(pattern: str) -> list[Path]:
    return sorted(BOARDS.glob(pattern))


def track_error_record() -> dict:
    return {"key": "u000/error", "unit": "u000", "index": 2, "flight": 20, "status": "error",
            "error": "RuntimeError: boom"}


#: (name, schema, a valid record, reader of a file)
CASES = [
    ("run", RUN_SCHEMA, lambda: first_line(BOARDS / "quick" / "runs.jsonl"), read_runs),
    ("blind", CASE_SCHEMA, lambda: first_line(BOARDS / "blind" / "blind.jsonl"),
     lambda p: read_records(p, schema=CASE_SCHEMA)),
    ("step", STEP_SCHEMA,
     # a run that gives quantiles and the unconditioned profile (issue 47), every field
     lambda: first_line(BOARDS / "campaign" / "reference" / "fleet-bayes-cut" / "track.jsonl"),
     lambda p: Store(p, schema=STEP_SCHEMA).records),
    ("track-error", ERROR_SCHEMA, track_error_record,
     lambda p: read_records(p, schema=ERROR_SCHEMA)),
    ("coverage", RECORD_SCHEMA, lambda: first_line(BOARDS / "coverage" / "twin_laplace.jsonl"),
     read_coverage),
    ("target", ENTRY_SCHEMA, lambda: {
        "key": "small|twin|0", "f_star": 1e-5, "x_star": {"Na": 1.0}, "f_nominal": 0.1,
        "fitness_at_truth": 2e-5, "bias_range_error": 0.01, "stages": {"powell": 1e-5}},
     lambda p: read_records(p, schema=ENTRY_SCHEMA)),
]
PARAMS = [(name, schema, make, read, field) for name, schema, make, read in CASES
          for field in schema]


@pytest.mark.parametrize("name,schema,make,read,field", PARAMS,
                         ids=[f"{p[0]}-{p[4]}" for p in PARAMS])
def test_a_wrong_type_in_any_field_is_refused_naming_file_line_and_field(
        tmp_path, name, schema, make, read, field):
    good = make()
    path = tmp_path / "records.jsonl"
    path.write_text(json.dumps(good) + "\n")
    assert len(read(path)) == 1                      # the valid record reads
    bad = {**good, field: WRONG[schema[field].types]}
    path.write_text(json.dumps(good) + "\n" + json.dumps(bad) + "\n")
    with pytest.raises(SchemaError) as info:
        read(path)
    msg = str(info.value)
    assert f"{path}, line 2: field {field!r}" in msg and "\n" not in msg
    # (a record without a solver is one of the keyed kind the run reader also reads)
    if schema[field].required and (name, field) != ("run", "solver"):
        path.write_text(json.dumps({k: v for k, v in good.items() if k != field}) + "\n")
        with pytest.raises(SchemaError, match=f"line 1: field '{field}' is missing"):
            read(path)


NESTED = [(name, schema, make, read, field) for name, schema, make, read in CASES
          for field, spec in schema.items() if spec.values]


@pytest.mark.parametrize("name,schema,make,read,field", NESTED,
                         ids=[f"{p[0]}-{p[4]}" for p in NESTED])
def test_a_wrong_type_inside_a_nested_field_is_refused_naming_it(tmp_path, name, schema, make,
                                                                   read, field):
    """``"estimate": {"Na": "abc"}`` gave a traceback later (a step), or was written into the
    targets table (an entry's ``x_star``): refused on reading, naming ``field.member``."""
    good = make()
    member = next(iter(good[field]))
    bad = {**good, field: {**good[field], member: "abc"}}
    path = tmp_path / "records.jsonl"
    path.write_text(json.dumps(good) + "\n" + json.dumps(bad) + "\n")
    with pytest.raises(SchemaError) as info:
        read(path)
    want = schema[field].values.replace("|", " or ")
    assert f"line 2: field '{field}.{member}' must be {want}" in str(info.value)
    assert "got 'abc'" in str(info.value)


def test_booleans_are_not_counts_and_counts_are_not_booleans(tmp_path):
    step = first_line(BOARDS / "campaign" / "twin" / "kalman" / "track.jsonl")
    path = tmp_path / "track.jsonl"
    for field, value in (("evaluations", True), ("index", False), ("replace", 0)):
        path.write_text(json.dumps({**step, field: value}) + "\n")
        with pytest.raises(SchemaError, match=f"field '{field}'"):
            read_records(path, schema=STEP_SCHEMA)


def test_a_line_that_is_not_an_object_is_refused(tmp_path):
    path = tmp_path / "runs.jsonl"
    path.write_text("[1, 2]\n")
    with pytest.raises(SchemaError, match="line 1: expected a JSON object, got list"):
        read_runs(path)


@pytest.mark.parametrize("pattern,reader", [
    ("**/runs.jsonl", read_runs),
    ("**/blind.jsonl", lambda p: read_records(p, schema=CASE_SCHEMA)),
    ("coverage/**/*.jsonl", read_coverage),
])
def test_the_committed_files_pass(pattern, reader):
    files = committed(pattern)
    assert files
    for path in files:
        assert reader(path)


def test_a_hand_edited_replace_no_is_refused_by_campaign_score(tmp_path):
    """The issue's example: ``"replace": "no"`` in a tracking run was read as true (RUL
    RMSE 52.9 -> 79.6); now ``campaign score`` says where, in one line, exit 2."""
    import shutil

    run = tmp_path / "rul-age"
    src = BOARDS / "campaign" / "reference" / "rul-age"
    shutil.copytree(src, run)
    manifest = json.loads((src / "manifest.json").read_text())
    manifest["campaign"] = str((src / manifest["campaign"]).resolve())
    (run / "manifest.json").write_text(json.dumps(manifest))
    lines = (run / "track.jsonl").read_text().splitlines()
    rec = json.loads(lines[4])
    lines[4] = json.dumps({**rec, "replace": "no"})
    (run / "track.jsonl").write_text("\n".join(lines) + "\n")
    res = subprocess.run([sys.executable, "-m", "ema_bench.cli", "campaign", "score",
                          str(run)], capture_output=True, text=True, timeout=120)
    assert res.returncode == 2, res.stderr
    err = res.stderr.strip().splitlines()
    assert len(err) == 1 and "track.jsonl, line 5: field 'replace' must be bool" in err[0]


def test_a_mistyped_member_of_a_truth_file_is_refused_in_one_line(tmp_path, capsys):
    """Nested fields of a campaign's truth are typed too: ``faults.0: "abc"`` gave a
    traceback in scoring; now ``campaign score`` names the unit and field, exit 2."""
    from ema_bench.cli import main
    from ema_bench.prognostics.campaign import read_truth

    src = BOARDS / "campaign" / "twin" / "campaign" / "truth.json"
    doc = json.loads(src.read_text())
    unit = next(iter(doc["units"]))
    doc["units"][unit]["faults"]["0"] = "abc"
    bad = tmp_path / "truth.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(SchemaError, match=rf"unit {unit}: field 'faults.0' must be list"):
        read_truth(bad)
    assert read_truth(src)["units"][unit]["faults"]["0"] != "abc"    # the committed one reads
    run = BOARDS / "campaign" / "twin" / "kalman"
    assert main(["campaign", "score", str(run), "--truth", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "field 'faults.0' must be list, got 'abc'" in err
