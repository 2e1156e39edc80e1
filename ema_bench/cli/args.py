"""Arguments shared by several commands: one definition, one parser, one check each."""

from __future__ import annotations

import argparse
import math
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

# already loaded with the package face, which every command imports
from ..problem import MAX_BUDGET as PROBLEM_MAX_BUDGET
from . import CLIError

if TYPE_CHECKING:
    from ..traces import Traces


#: The most worker processes any command starts (far above the cores of one machine).
MAX_WORKERS = 256
#: The largest evaluation budget of one fit or run: the problem's own limit.
MAX_BUDGET = PROBLEM_MAX_BUDGET
#: Seeds are non-negative and below 2**63 (numpy's SeedSequence takes them as entropy).
MAX_SEED = 2**63 - 1


def count(lower: int, upper: int):
    """An argparse ``type``: a whole number in ``[lower, upper]``.

    Every count option of every command has an upper bound, so a mistyped ``--cases 10**9``
    is refused at once rather than filling the memory or the disk."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text[:40]!r}"
                                              ) from None
        if not lower <= value <= upper:
            raise argparse.ArgumentTypeError(f"must be from {lower} to {upper}, got {value}")
        return value

    parse.__name__ = "count"
    parse.lower, parse.upper = lower, upper  # type: ignore[attr-defined]  (for --help, tests)
    return parse


#: ``--seed``, ``--root-seed`` and the like.
seed_number = count(0, MAX_SEED)
#: ``--workers``.
worker_count = count(1, MAX_WORKERS)


def finite(text: str) -> float:
    """An argparse ``type``: a finite float (``inf`` and ``nan`` are refused)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text[:40]!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text[:40]!r}")
    return value


def parse_assignments(text: str, option: str = "--faults") -> dict[str, float]:
    """Parse ``"Na=0.95,Fst=0.3378"`` into ``{"Na": 0.95, "Fst": 0.3378}``.

    Raises ValueError (the CLI's one-line error, naming ``option``) on a malformed item, a
    name given twice or an empty list: nothing is silently dropped or replaced."""
    out: dict[str, float] = {}
    for item in comma_list(text):
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise ValueError(f"{option}: expected NAME=VALUE, got {item!r}")
        if name in out:
            raise ValueError(f"{option}: {name} is given twice ({name}={out[name]:g} and "
                             f"{item!r}); give each name once")
        try:
            out[name] = finite(value)
        except argparse.ArgumentTypeError:
            raise ValueError(f"{option}: value of {name!r} is not a finite number: "
                             f"{value.strip()[:40]!r}") from None
    if not out:
        raise ValueError(f"{option}: empty; expected NAME=VALUE[,NAME=VALUE...]")
    return out


def add_seeds(p: argparse.ArgumentParser, what: str) -> None:
    """``--seed k`` and ``--root-seed R``: the run node (root seed, k) of the seed tree."""
    p.add_argument("--seed", type=seed_number, default=0,
                   help=f"run seed k: {what} come from the run node (root seed, k) "
                        "(default 0)")
    p.add_argument("--root-seed", type=seed_number, default=0,
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
    from ..faults import FaultError, check_faults

    try:
        return check_faults(parse_assignments(args.faults, "--faults"))
    except FaultError as exc:
        raise ValueError(f"--faults: {exc}") from None


def add_effects(p: argparse.ArgumentParser, where: str) -> None:
    """``--effect NAME=VALUE`` (repeatable)."""
    p.add_argument("--effect", action="append", default=[], metavar="NAME=VALUE",
                   help=f"switch on an effect in {where} (repeatable); see 'ema-bench params'")


def effects_of(args: argparse.Namespace) -> dict[str, float]:
    """``--effect`` options as ``name -> value``, validated (names, bounds)."""
    from ..effects import EffectError, effects_vector

    # one merge, so a name repeated across --effect options is refused too
    effects = parse_assignments(",".join(args.effect), "--effect") if args.effect else {}
    try:
        effects_vector(effects)
    except EffectError as exc:
        raise ValueError(f"--effect: {exc}") from None
    return effects


def add_json(p: argparse.ArgumentParser, what: str = "the result") -> None:
    p.add_argument("--json", action="store_true", help=f"print {what} as JSON")


def add_targets(p: argparse.ArgumentParser) -> None:
    """``--targets FILE``: a best-known table of another root seed (``ema-bench targets
    --root-seed R``), used where the shipped one has no entry (``cli.use_targets``, run by
    ``main`` before the command)."""
    p.add_argument("--targets", action="append", default=None, metavar="FILE.json",
                   help="best-known table of another root seed (ema-bench targets "
                        "--root-seed R --out FILE.json): its f* gives the runs of that root "
                        "seed fitness targets (repeatable)")


def add_legacy(p: argparse.ArgumentParser, verb: str) -> None:
    """``--legacy``: admit schema-1 records into a view labelled legacy (the judge,
    :mod:`ema_bench.leaderboard.judge`, refuses them for ranking otherwise)."""
    p.add_argument("--legacy", action="store_true",
                   help=f"{verb} schema-1 (legacy) records too, in a view labelled legacy "
                        "(refused without it: their hits cannot be proven)")


def add_quiet(p: argparse.ArgumentParser) -> None:
    """``--quiet``: no progress bar and no progress lines (errors are still printed)."""
    p.add_argument("--quiet", "-q", action="store_true",
                   help="no progress output (a bar in a terminal, one line per finished "
                        "task otherwise)")


def add_test_names(p: argparse.ArgumentParser, files: str) -> None:
    """``--test NAME[,NAME...]`` (repeatable): one test name per file of ``files``."""
    p.add_argument("--test", action="extend", type=option_list, default=None,
                   metavar="NAME[,NAME...]",
                   help=f"one test name per {files} file, in order (step, sine or sine2): the "
                        "name of the single test of a file without a 'test' column, or the "
                        "one test to take from a file with one")


def comma_list(text: str) -> list[str]:
    """``"a, b,,c"`` -> ``["a", "b", "c"]``: the items of a comma-separated option."""
    return [s.strip() for s in text.split(",") if s.strip()]


def option_list(text: str) -> list[str]:
    """:func:`comma_list` as an option's type: an empty list (``--tiers ""``, ``--solvers=``)
    is a usage error, never "the whole grid"."""
    items = comma_list(text)
    if not items:
        raise argparse.ArgumentTypeError(f"an empty list ({text!r}): name at least one item, "
                                         "or leave the option out")
    return items


def load_measured_files(paths: Sequence[str], tests: Sequence[str] | None) -> Traces:
    """:func:`~ema_bench.traces.load_measured` for a command line: a file holding an unnamed
    test is told to name it with ``--test``, not with the Python ``test=`` argument."""
    from ..traces import TracesError, load_measured

    try:
        return load_measured(paths, tests)
    except TracesError as exc:
        if exc.unnamed_test is None:
            raise
        how = "--test NAME" if len(paths) == 1 else "--test NAME,NAME,... (one per file)"
        raise CLIError(f"{exc.unnamed_test}; name its test with {how}") from None


#: What ``--plot`` files may be (matplotlib picks the format from the suffix).
PLOT_SUFFIXES = (".png", ".pdf", ".svg")


def check_output(path: str | os.PathLike[str] | None, option: str, *, folder: bool,
                 suffixes: tuple[str, ...] = ()) -> Path | None:
    """Check before any work that ``path`` can be written (``folder``: created and filled).

    A folder is created now (with its parents); a file is not created, but its folder is, and
    must accept a new file.  Raises :class:`~ema_bench.cli.CLIError` (one line naming
    ``option``, exit code 2) for an existing file where a folder is expected or the reverse,
    a read-only place, a parent that is a file, or a file suffix not in ``suffixes`` (when
    given).  ``None`` passes through.
    """

    if path is None:
        return None
    path = Path(path)
    what = "folder" if folder else "file"
    if folder and path.exists() and not path.is_dir():
        raise CLIError(f"{option} {path}: exists and is not a folder")
    if not folder and path.is_dir():
        raise CLIError(f"{option} {path}: is a folder; give a file name")
    if suffixes and path.suffix.lower() not in suffixes:
        raise CLIError(f"{option} {path}: the file name must end in "
                       f"{' or '.join(suffixes)}")
    place = path if folder else path.parent
    try:
        place.mkdir(parents=True, exist_ok=True)
        # a real write, not os.access: it also catches read-only mounts and full disks
        with tempfile.NamedTemporaryFile(dir=place, prefix=".ema-bench-write-check-"):
            pass
        if not folder and path.exists():   # an existing file must take a rewrite
            with open(path, "ab"):
                pass
    except (FileExistsError, NotADirectoryError):
        raise CLIError(f"{option} {path}: cannot create the {what}: a file stands in its "
                       "path") from None
    except OSError as exc:
        raise CLIError(f"{option} {path}: cannot write the {what}: "
                       f"{exc.strerror or exc}") from None
    return path

