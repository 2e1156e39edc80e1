"""``ema-bench schema``: the JSON Schemas of the files a user submits or reads.

Each schema is made from the type table the package's own reader checks that file with
(``sweep.schema``: a run record's line of runs.jsonl, a tracking step, a blind case, a
coverage record, a best-known entry and table, the summaries of a board, a blind suite and a
coverage run), so a schema and the code cannot drift; docs/schemas/ holds them as published
(a test regenerates and compares).
A submitter checks a file without ema-bench, with any JSON Schema validator (draft
2020-12), e.g. ``check-jsonschema --schemafile run-record.schema.json`` on each line.

Examples::

    ema-bench schema                               # list them
    ema-bench schema run-record                    # print one
    ema-bench schema --out docs/schemas            # write every one as NAME.schema.json
"""

from __future__ import annotations

import argparse
import importlib
from dataclasses import dataclass
from pathlib import Path

from . import CLIError, print_json, print_result
from .args import add_json, check_output


@dataclass(frozen=True)
class SchemaFile:
    """One published schema: what it describes and the type tables it is made of
    (``module:NAME``, several: any of them, e.g. a step line or its error line)."""

    title: str
    description: str
    tables: tuple[str, ...]


#: name -> the file it describes (the registry the command and docs/schemas/ are made from)
SCHEMAS: dict[str, SchemaFile] = {
    "run-record": SchemaFile(
        "ema-bench run record",
        "One line of runs.jsonl (ema-bench leaderboard, solve --json, the adapters): the "
        "fields every reader relies on, by JSON type; 'ema-bench validate' checks the rest "
        "(its figures against their re-derivation).",
        ("ema_bench.leaderboard.run_store:RUN_SCHEMA",)),
    "track-step": SchemaFile(
        "ema-bench tracking step",
        "One line of a campaign tracking run's track.jsonl (ema-bench campaign track): an "
        "inspection's estimate, interval, RUL and decision, or a unit's error line.",
        ("ema_bench.prognostics.track_io:STEP_SCHEMA",
         "ema_bench.prognostics.track_io:ERROR_SCHEMA")),
    "blind-case": SchemaFile(
        "ema-bench blind-suite case",
        "One line of blind.jsonl (ema-bench blind): a diagnosed case and its verdict.",
        ("ema_bench.diagnosis.blind:CASE_SCHEMA",)),
    "coverage-record": SchemaFile(
        "ema-bench coverage record",
        "One line of OUT/TRACK_METHOD.jsonl (ema-bench coverage): an instance's fit and "
        "intervals.",
        ("ema_bench.uncertainty.coverage:RECORD_SCHEMA",)),
    "best-known-entry": SchemaFile(
        "ema-bench best-known entry",
        "One line of OUT.partial.jsonl (ema-bench targets) and one entry of a best-known "
        "table: an instance's f*, x*, f_nominal.",
        ("ema_bench.suites.best_known:ENTRY_SCHEMA",)),
    "best-known-table": SchemaFile(
        "ema-bench best-known table",
        "The JSON ema-bench targets writes (the shipped suite_targets.json, a table of "
        "another root seed that --targets reads); entries: best-known-entry's fields.",
        ("ema_bench.suites.targets:TABLE_SCHEMA",)),
    "blind-summary": SchemaFile(
        "ema-bench blind-suite summary",
        "OUT/summary.json of ema-bench blind: naming accuracy, false alarms, decoys, gap "
        "closed, parameter error and interval coverage, overall and per category.",
        ("ema_bench.diagnosis.blind_summary:SUMMARY_SCHEMA",)),
    "coverage-summary": SchemaFile(
        "ema-bench coverage summary",
        "OUT/TRACK_METHOD.json of ema-bench coverage: each fault's interval coverage and "
        "width, the settings, the calibration applied.",
        ("ema_bench.uncertainty.coverage:SUMMARY_SCHEMA",)),
    "leaderboard-summary": SchemaFile(
        "ema-bench leaderboard summary",
        "OUT/summary.json of ema-bench leaderboard: the command, the runs, which targets "
        "the board ranks on, failed runs, the anytime scores.",
        ("ema_bench.leaderboard.run:SUMMARY_SCHEMA",)),
}


def document(name: str) -> dict:
    """The JSON Schema of ``SCHEMAS[name]``, made from the readers' type tables."""
    from ..sweep.schema import json_schema_document

    spec = SCHEMAS[name]
    tables = []
    for ref in spec.tables:
        module, attr = ref.split(":")
        tables.append(getattr(importlib.import_module(module), attr))
    return {"$id": f"{name}.schema.json",
            **json_schema_document(spec.title, spec.description, *tables)}


def write_all(out: Path) -> list[Path]:
    """Every schema as ``out/NAME.schema.json``; the paths written."""
    from ..jsonio import dumps

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name in SCHEMAS:
        paths.append(out / f"{name}.schema.json")
        paths[-1].write_text(dumps(document(name), indent=2) + "\n")
    return paths


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("schema", help="JSON Schemas of the files a user submits or reads")
    p.add_argument("name", nargs="?", choices=SCHEMAS, metavar="NAME",
                   help=f"the schema to print: {', '.join(SCHEMAS)}")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="write every schema to DIR/NAME.schema.json")
    add_json(p, "the list")


def run(args: argparse.Namespace) -> int:
    if args.name and args.out:
        raise CLIError("give a NAME to print or --out DIR to write them all, not both")
    if args.name:
        print_json(document(args.name))
        return 0
    if args.out:
        paths = write_all(check_output(args.out, "--out", folder=True))
        return print_result(args, [str(p) for p in paths],
                            [f"{len(paths)} schemas -> {args.out}"])
    return print_result(args, {n: s.title for n, s in SCHEMAS.items()},
                        [f"{n:20s} {s.title}" for n, s in SCHEMAS.items()])
