"""The published JSON Schemas (docs/schemas/, ``ema-bench schema``) are the readers' own type
tables, and an independent validator (``jsonschema``) agrees with the package's reader on the
committed files and on broken lines (issue 45)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ema_bench.cli.schema import SCHEMAS, document
from ema_bench.sweep.schema import SchemaError, check

jsonschema = pytest.importorskip("jsonschema", reason="jsonschema not installed ([test])")

REPO = Path(__file__).resolve().parents[1]
PUBLISHED = REPO / "docs" / "schemas"
LB = REPO / "leaderboards"


def _validator(name: str):
    schema = json.loads((PUBLISHED / f"{name}.schema.json").read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def _lines(path: Path, limit: int = 400) -> list[dict]:
    """The first ``limit`` lines (the main board's runs.jsonl is tens of MB)."""
    with path.open() as f:
        return [json.loads(ln) for ln, _ in zip(f, range(limit)) if ln.strip()]


def test_the_published_schemas_are_the_readers_tables(cli, tmp_path):
    # regenerate and compare: a reader's table changed without docs/schemas/ fails here
    assert sorted(p.name for p in PUBLISHED.glob("*.schema.json")) == sorted(
        f"{n}.schema.json" for n in SCHEMAS)
    for name in SCHEMAS:
        assert json.loads((PUBLISHED / f"{name}.schema.json").read_text()) == document(name), \
            f"docs/schemas/{name}.schema.json is stale: ema-bench schema --out docs/schemas"
    res = cli("schema", "--out", tmp_path, check=True)
    assert f"{len(SCHEMAS)} schemas" in res.stdout
    assert (tmp_path / "run-record.schema.json").read_text() == \
        (PUBLISHED / "run-record.schema.json").read_text()


@pytest.mark.parametrize(("name", "files"), [
    ("run-record", ["quick/runs.jsonl", "runs.jsonl", "paper-ga-10k/runs.jsonl"]),
    ("track-step", ["campaign/twin/kalman/track.jsonl", "campaign/reference/particle/track.jsonl"]),
    ("blind-case", ["blind/blind.jsonl", "blind_r4/blind.jsonl"]),
    ("coverage-record", ["coverage/calibration/twin_laplace.jsonl"]),
    ("leaderboard-summary", ["quick/summary.json", "summary.json"]),
    ("blind-summary", ["blind/summary.json", "blind_r3/summary.json", "blind_r4/summary.json"]),
    ("coverage-summary", [str(p.relative_to(LB)) for p in sorted((LB / "coverage").glob("*_*.json"))
                          if not p.name.startswith("example")]),
])
def test_the_committed_files_validate_without_ema_bench(name, files):
    v = _validator(name)
    for f in files:
        records = ([json.loads((LB / f).read_text())] if f.endswith(".json")
                   else _lines(LB / f))
        assert records, f
        for r in records:
            errors = [e.message for e in v.iter_errors(r)]
            assert errors == [], (f, errors[:3])


def test_the_shipped_best_known_tables_validate():
    table, entry = _validator("best-known-table"), _validator("best-known-entry")
    for f in ("suite_targets.json", "suite_targets_v2.json", "suite_targets_v3.json"):
        data = json.loads((REPO / "ema_bench" / f).read_text())
        assert list(table.iter_errors(data)) == []
        bad = [k for k, e in data["entries"].items()
               if list(entry.iter_errors({"key": k, "stages": {}, **e}))]
        assert bad == []   # entries in a table drop key and stages (the partial lines' own)


@pytest.mark.parametrize(("name", "table", "edit"), [
    ("run-record", "ema_bench.leaderboard.run_store:RUN_SCHEMA", {"seed": "3"}),
    ("run-record", "ema_bench.leaderboard.run_store:RUN_SCHEMA", {"success": 1}),
    ("run-record", "ema_bench.leaderboard.run_store:RUN_SCHEMA", {"budget": True}),
    ("run-record", "ema_bench.leaderboard.run_store:RUN_SCHEMA", {"solver": None}),
    ("track-step", "ema_bench.prognostics.track_io:STEP_SCHEMA", {"replace": "no"}),
    ("track-step", "ema_bench.prognostics.track_io:STEP_SCHEMA", {"rul": "12"}),
])
def test_validator_and_reader_refuse_the_same_broken_lines(name, table, edit):
    import importlib

    module, attr = table.split(":")
    fields = getattr(importlib.import_module(module), attr)
    src = (LB / ("quick/runs.jsonl" if name == "run-record"
                 else "campaign/twin/kalman/track.jsonl"))
    good = _lines(src, 1)[0]
    v = _validator(name)
    assert v.is_valid(good)
    check(good, fields, "good")
    bad = {**good, **edit}
    assert not v.is_valid(bad)
    with pytest.raises(SchemaError):
        check(bad, fields, "bad")
    missing = {k: x for k, x in good.items() if k != next(iter(fields))}
    assert not v.is_valid(missing)
    with pytest.raises(SchemaError, match="missing"):
        check(missing, fields, "missing")
