"""Arguments shared by several commands: one definition, one parser, one check each."""

from __future__ import annotations

import argparse

import numpy as np


def parse_assignments(text: str) -> dict[str, float]:
    """Parse ``"Na=0.95,Fst=0.3378"`` into ``{"Na": 0.95, "Fst": 0.3378}``.

    Raises ValueError (the CLI's one-line error) on a malformed item."""
    out: dict[str, float] = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        name, sep, value = item.partition("=")
        if not sep:
            raise ValueError(f"expected NAME=VALUE, got {item!r}")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"value of {name.strip()!r} is not a number: {value!r}") from None
    return out


def add_seeds(p: argparse.ArgumentParser, what: str) -> None:
    """``--seed k`` and ``--root-seed R``: the run node (root seed, k) of the seed tree."""
    p.add_argument("--seed", type=int, default=0,
                   help=f"run seed k: {what} come from the run node (root seed, k) "
                        "(default 0)")
    p.add_argument("--root-seed", type=int, default=0,
                   help="root seed R (default 0); --root-seed R --seed k is row k of "
                        "'ema-bench leaderboard --root-seed R'")


def run_node(args: argparse.Namespace) -> np.random.SeedSequence:
    """The run node of ``--root-seed`` and ``--seed`` (ValueError when negative)."""
    from ..seeding import run_seed

    return run_seed(args.root_seed, args.seed)


def add_faults(group: argparse._ActionsContainer) -> None:
    """``--faults NAME=VALUE,...``: explicit true faults (missing ones nominal)."""
    group.add_argument("--faults", default=None, metavar="NAME=VALUE,...",
                       help="fault values, e.g. Na=0.95,Fst=0.3378,BLK=0.01,Gprop=1e5 "
                            "(units -, N m, rad, 1/s; missing ones are nominal)")


def faults_of(args: argparse.Namespace) -> np.ndarray:
    """The validated fault vector of ``--faults``."""
    from ..faults import check_faults

    return check_faults(parse_assignments(args.faults))


def add_effects(p: argparse.ArgumentParser, where: str) -> None:
    """``--effect NAME=VALUE`` (repeatable)."""
    p.add_argument("--effect", action="append", default=[], metavar="NAME=VALUE",
                   help=f"switch on an effect in {where} (repeatable); see 'ema-bench params'")


def effects_of(args: argparse.Namespace) -> dict[str, float]:
    """``--effect`` options as ``name -> value`` (validated where they are used)."""
    return {k: v for item in args.effect for k, v in parse_assignments(item).items()}


def add_json(p: argparse.ArgumentParser, what: str = "the result") -> None:
    p.add_argument("--json", action="store_true", help=f"print {what} as JSON")
