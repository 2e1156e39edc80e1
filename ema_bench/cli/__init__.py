"""``ema-bench`` command line.

Each subcommand lives in its own module of this package and is listed in ``COMMANDS``; a module
provides ``register(subparsers)`` which adds its parser, and a handler ``run(args) -> int``
(the exit code) unless ``register`` sets ``func`` to another.  A command's description is its
module's docstring unless ``register`` gives one (reST markup shown plain; a docstring of
several lines as written).
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
from collections.abc import Iterable, Sequence

from ..version import __version__

# subcommand name -> module in this package (the registry the parser is built from)
COMMANDS: dict[str, str] = {
    "simulate": "simulate",
    "bench": "bench",
    "params": "params",
    "solve": "solve",
    "solvers": "solve",  # solve.register adds both commands, once
    "leaderboard": "leaderboard",
    "diagnose": "diagnose",
    "blind": "blind",
    "export": "export",
    "validate": "validate",
    "targets": "targets",
    "coverage": "coverage",
    "campaign": "campaign",
    "schema": "schema",
}


class OneLineParser(argparse.ArgumentParser):
    """A command's parser whose usage errors are one line (``ema-bench CMD: error: ...``) and
    exit code 2, like every other error of the command line; ``--help`` shows the usage."""

    def error(self, message: str):  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ema-bench",
        description="Model-based fault identification benchmark for aircraft electromechanical "
                    "actuators: simulate the actuator, fit the monitor model, compare solvers.",
        epilog="Run 'ema-bench COMMAND --help' for the options of a command.",
    )
    parser.add_argument("--version", action="version", version=f"ema-bench {__version__}")
    # each command's usage errors are one line, exit code 2 (its sub-commands inherit it)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True,
                                parser_class=OneLineParser)
    for module in dict.fromkeys(COMMANDS.values()):  # a module may add two commands
        importlib.import_module(f"{__name__}.{module}").register(sub)
    for name, p in sub.choices.items():  # by default, its module's docstring and run
        module = sys.modules[f"{__name__}.{COMMANDS[name]}"]
        p.set_defaults(func=p.get_default("func") or getattr(module, "run", None))
        doc = p.description or module.__doc__
        p.description, p.epilog = plain_text(doc), plain_text(p.epilog)
        if "\n" in doc:   # paragraphs and examples: shown as written
            p.formatter_class = argparse.RawDescriptionHelpFormatter
    return parser


_ROLE = re.compile(r":(?:func|class|meth|mod|data|attr|obj|exc):`~?([^`]+)`")


def plain_text(doc: str | None) -> str | None:
    """reST of a docstring as terminal text: ````x```` and roles lose their markup,
    ``Examples::`` its double colon."""
    if not doc:
        return doc
    doc = _ROLE.sub(r"\1", doc).replace("``", "'")
    return re.sub(r"::$", ":", doc, flags=re.MULTILINE)


class CLIError(Exception):
    """A user error: printed as one line, exit code 2."""


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        if exc.code == 2:   # a usage error, printed in one line: its exit code, as any other
            return 2
        raise               # --help, --version
    from ..progress import configure_logging

    configure_logging(quiet=getattr(args, "quiet", False))
    from ..sweep.loop import SweepError

    try:
        use_targets(args)
        return int(args.func(args) or 0)
    except (CLIError, ValueError, LookupError, OSError, MemoryError, SweepError) as exc:
        # OSError: a write that fails late (disk full, folder removed) is one line too
        print(f"ema-bench {args.command}: error: {_message(exc)}", file=sys.stderr)
        return 2


def use_targets(args: argparse.Namespace) -> None:
    """Make a command's ``--targets`` tables active for this process and its workers
    (:data:`ema_bench.suites.targets.TARGETS_ENV`), each checked first (ValueError, one line)."""
    import os
    from pathlib import Path

    from ..suites.targets import TARGETS_ENV, user_targets

    files = getattr(args, "targets", None)
    if not files:
        return
    known = [p for p in os.environ.get(TARGETS_ENV, "").split(os.pathsep) if p]
    os.environ[TARGETS_ENV] = os.pathsep.join(
        dict.fromkeys([str(Path(f).resolve()) for f in files] + known))
    user_targets()   # a missing or mislabelled file fails here, before any work


def _message(exc: BaseException) -> str:
    if isinstance(exc, MemoryError):
        return f"out of memory{f': {exc}' if str(exc) else ''}"
    if isinstance(exc, OSError) and exc.filename and exc.strerror:
        return f"{exc.filename}: {exc.strerror}"
    return str(exc)


def print_json(obj: object) -> None:
    """Machine-readable output on stdout: strict JSON, a non-finite number as ``null``
    (:mod:`ema_bench.jsonio`)."""
    from ..jsonio import dumps

    sys.stdout.write(dumps(obj, indent=2) + "\n")


def print_result(args: argparse.Namespace, obj: object, lines: Iterable[str]) -> int:
    """A command's result: ``obj`` as JSON (:func:`print_json`) with ``--json``, else the
    text ``lines``; returns the exit code, 0."""
    if args.json:
        print_json(obj)
    else:
        for line in lines:
            print(line)
    return 0
