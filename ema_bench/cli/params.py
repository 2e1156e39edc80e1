"""``ema-bench params``: the physical parameter set, fault table and effects, with units."""

from __future__ import annotations

import argparse

from ..effects import EFFECTS
from ..faults import CASES, FAULTS
from ..params import EMAParams
from . import print_result
from .args import add_json


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("params", help="list physical parameters, faults, cases and effects")
    add_json(p, "the tables")


def run(args: argparse.Namespace) -> int:
    table = {
        "parameters": EMAParams.describe(),
        "faults": [vars(f) for f in FAULTS],
        "cases": {n: {"faults": dict(zip([f.name for f in FAULTS], c.faults)),
                      "description": c.description} for n, c in CASES.items()},
        "effects": [vars(e) for e in EFFECTS],
    }
    return print_result(args, table, [
        "Physical parameters",
        *(f"  {row['name']:<20} {row['value']:<12.6g} {row['unit']:<10} {row['source']}"
          for row in table["parameters"]),
        "\nFaults (name, unit, lower, upper, nominal)",
        *(f"  {f.name:<6} {f.unit:<4} {f.lower:<8g} {f.upper:<8g} {f.nominal:<8g} "
          f"{f.description}" for f in FAULTS),
        "\nCases",
        *(f"  {n:<8} {c.faults}  {c.description}" for n, c in CASES.items()),
        "\nEffects (off = 0)",
        *(f"  {e.name:<17} {e.unit:<10} [{e.lower:g}, {e.upper:g}]  {e.description}"
          for e in EFFECTS)])
