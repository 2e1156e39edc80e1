"""Arguments shared by several commands: one definition, one parser, one check each."""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

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


def add_quiet(p: argparse.ArgumentParser) -> None:
    """``--quiet``: no progress bar and no progress lines (errors are still printed)."""
    p.add_argument("--quiet", "-q", action="store_true",
                   help="no progress output (a bar in a terminal, one line per finished "
                        "task otherwise)")


def check_output(path: str | os.PathLike[str] | None, option: str, *, folder: bool
                 ) -> Path | None:
    """Check before any work that ``path`` can be written (``folder``: created and filled).

    A folder is created now (with its parents); a file is not created, but its folder is, and
    must accept a new file.  Raises :class:`~ema_bench.cli.CLIError` (one line naming
    ``option``, exit code 2) for an existing file where a folder is expected or the reverse,
    a read-only place, or a parent that is a file.  ``None`` passes through.
    """
    from . import CLIError

    if path is None:
        return None
    path = Path(path)
    what = "folder" if folder else "file"
    if folder and path.exists() and not path.is_dir():
        raise CLIError(f"{option} {path}: exists and is not a folder")
    if not folder and path.is_dir():
        raise CLIError(f"{option} {path}: is a folder; give a file name")
    place = path if folder else path.parent
    try:
        place.mkdir(parents=True, exist_ok=True)
        # a real write, not os.access: it also catches read-only mounts and full disks
        with tempfile.NamedTemporaryFile(dir=place, prefix=".ema-bench-write-check-"):
            pass
        if not folder and path.exists():
            with open(path, "ab"):
                pass
    except FileExistsError:
        raise CLIError(f"{option} {path}: cannot create the {what}: a file stands in its "
                       "path") from None
    except NotADirectoryError:
        raise CLIError(f"{option} {path}: cannot create the {what}: a file stands in its "
                       "path") from None
    except OSError as exc:
        raise CLIError(f"{option} {path}: cannot write the {what}: "
                       f"{exc.strerror or exc}") from None
    return path
