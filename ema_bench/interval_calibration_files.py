"""Which calibration file is active, and where a new one may be written.

The package ships two calibration tables (the fault intervals' ``uncertainty/calibration.json``
and the effect intervals' ``diagnosis/interval_calibration.json``).  Shipped data is read-only
(the design notes' integrity rules): ``--calibrate`` writes a user file where the user puts
it, a user file is used only when asked for (an environment variable, which the commands'
``--calibration`` option sets, so worker processes inherit it), and every command that uses
one names it.
Replacing a shipped table is ``python -m ema_bench.interval_calibration_files FILE``, run in a
checkout;
it refuses an installed package.
"""

from __future__ import annotations

import json
import math
import os
import sys
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from .jsonio import write_atomic

PACKAGE = Path(__file__).resolve().parent


@dataclass(frozen=True)
class Table:
    """One calibration table: its shipped file and the variable that names a user file."""

    name: str     # the file name, shipped and as --calibrate writes it
    shipped: Path
    env: str      # environment variable holding the path of a user file
    what: str     # what its size counts, for the command output


TABLES: dict[str, Table] = {
    "calibration.json": Table("calibration.json", PACKAGE / "uncertainty" / "calibration.json",
                              "EMA_BENCH_CALIBRATION", "instances"),
    "interval_calibration.json": Table(
        "interval_calibration.json", PACKAGE / "diagnosis" / "interval_calibration.json",
        "EMA_BENCH_INTERVAL_CALIBRATION", "effect cases"),
}


def active(table: Table) -> tuple[Path, bool]:
    """The file ``table`` is read from now and whether it is the user's: the path in the
    environment variable ``table.env`` when set (ValueError, one line, when it is not a file),
    else the shipped file."""
    user = os.environ.get(table.env)
    if not user:
        return table.shipped, False
    path = Path(user)
    if not path.is_file():
        raise ValueError(f"{table.env}={user}: no such calibration file (make one with "
                         f"--calibrate --out DIR; it is DIR/{table.name})")
    return path, True


def describe(table: Table, size: int) -> str:
    """``shipped, 400 instances`` or ``user file PATH, 1 instance``: the active file of
    ``table`` holding ``size`` calibration units, as command output names it."""
    path, user = active(table)
    unit = table.what if size != 1 else table.what.rstrip("s")
    return f"{'user file ' + str(path) if user else 'shipped'}, {size} {unit}"


@contextmanager
def using(table: Table, path: str | os.PathLike[str] | None) -> Iterator[None]:
    """Within the block, read ``table`` from the user file ``path`` (nothing changes when
    None): the environment variable is set, so processes started inside inherit it."""
    if path is None:
        yield
        return
    old = os.environ.get(table.env)
    os.environ[table.env] = str(Path(path).resolve())
    try:
        active(table)     # a missing file fails here, in one line, before any work
        yield
    finally:
        if old is None:
            os.environ.pop(table.env, None)
        else:
            os.environ[table.env] = old


def inside_package(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` lies inside the package folder (which may be the installed one)."""
    return Path(path).resolve().is_relative_to(PACKAGE)


def checkout_root(package: Path = PACKAGE) -> Path | None:
    """The source checkout ``package`` lives in (a git work tree with the project's
    ``pyproject.toml``), or None for an installed copy."""
    root = package.parent
    pyproject = root / "pyproject.toml"
    if (root / ".git").exists() and pyproject.is_file() and \
            'name = "ema-bench"' in pyproject.read_text(errors="replace"):
        return root
    return None


def check_scores(values: Iterable[object], where: str) -> None:
    """Calibration scores are finite, non-negative numbers (an error over a half-width);
    ValueError (one line) naming the first that is not: a NaN score gave ``[nan, nan]``
    intervals, a negative one inverted intervals."""
    if not isinstance(values, list | tuple):
        raise ValueError(f"{where}: calibration scores must be a list, got "
                         f"{type(values).__name__}")
    for v in values:
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
                or v < 0:
            raise ValueError(f"{where}: calibration score {v!r} is not a finite, non-negative "
                             "number")


def check_table(name: str, data: object, where: str) -> None:
    """Every score of the table ``name`` (a key of :data:`TABLES`) holding ``data``, by
    :func:`check_scores`: per key and fault (``calibration.json``), or per effect case
    (``interval_calibration.json``).  Its readers and :func:`ship` call it."""
    scores = data.get("scores") if isinstance(data, dict) else None
    if name == "interval_calibration.json":
        if not isinstance(scores, list) or not all(isinstance(r, dict) for r in scores):
            raise ValueError(f"{where}: 'scores' is not a list of scored cases")
        check_scores([r.get("score") for r in scores], f"{where}: scores")
        return
    if not isinstance(scores, dict):
        raise ValueError(f"{where}: 'scores' is not an object")
    for key, per in scores.items():
        if not isinstance(per, dict):
            raise ValueError(f"{where}: scores[{key!r}] is not an object of per-fault scores")
        for fault, values in per.items():
            check_scores(values, f"{where}: scores[{key!r}][{fault!r}]")


def ship(source: str | os.PathLike[str], package: Path = PACKAGE) -> Path:
    """Replace the shipped table named like ``source`` (a file ``--calibrate`` wrote) with it.

    Raises ValueError (one line) when ``source`` is not a known table or not JSON, or when
    ``package`` is not in a checkout: an installed package is never written."""
    source = Path(source)
    table = TABLES.get(source.name)
    if table is None:
        raise ValueError(f"{source}: not a calibration table (one of {', '.join(TABLES)})")
    root = checkout_root(package)
    if root is None:
        raise ValueError(f"{package} is an installed package, not a checkout: shipped data "
                         "is read-only; regenerate it in a git checkout of ema-bench")
    try:
        text = source.read_text()
        data = json.loads(text)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{source}: not a readable calibration table ({exc})") from None
    if not isinstance(data, dict) or not data.get("scores"):
        raise ValueError(f"{source}: holds no calibration scores")
    check_table(table.name, data, str(source))   # the values too
    target = package / table.shipped.relative_to(PACKAGE)
    write_atomic(target, text)
    return target


def main(argv: list[str] | None = None) -> int:
    """``python -m ema_bench.interval_calibration_files FILE...``: ship each FILE (in a
    checkout)."""
    args = sys.argv[1:] if argv is None else argv
    if not args or args[0] in ("-h", "--help"):
        print(__doc__)
        return 0 if args else 2
    try:
        for a in args:
            print(f"{a} -> {ship(a)}")
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
