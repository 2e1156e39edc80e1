"""Progress of long work: a bar in a terminal, one log line per finished item otherwise.

CI logs and redirected output get no bar (it would be a wall of carriage returns) but still see
the work advance: one ``logging`` line per finished item on the ``ema_bench`` logger, which the
command line routes to stderr (``--quiet`` silences both).
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

log = logging.getLogger("ema_bench")


@dataclass
class Progress:
    """Count finished items of ``total``; see :func:`progress`."""

    total: int | None
    desc: str
    unit: str
    bar: object | None = None
    quiet: bool = False
    done: int = 0
    t0: float = field(default_factory=time.perf_counter)

    def update(self, label: str = "", n: int = 1) -> None:
        """``n`` more items finished; ``label`` names the last one (shown, logged)."""
        self.done += n
        if self.bar is not None:
            self.bar.update(n)
            if label:
                self.bar.set_postfix_str(label, refresh=False)
        elif not self.quiet:
            of = "" if self.total is None else f"/{self.total}"
            log.info("%s: %d%s %s%s (%.0f s)", self.desc, self.done, of, self.unit,
                     f" {label}" if label else "", time.perf_counter() - self.t0)

    def note(self, message: str) -> None:
        """A stage of the work (a log line, or the bar's description in a terminal)."""
        if self.bar is not None:
            self.bar.set_description_str(f"{self.desc}: {message}", refresh=True)
        elif not self.quiet:
            log.info("%s: %s", self.desc, message)


@contextmanager
def progress(total: int | None, desc: str, unit: str = "item", quiet: bool = False,
             tty: bool | None = None, leave: bool = True) -> Iterator[Progress]:
    """A :class:`Progress` over ``total`` items (None: unknown): a tqdm bar on stderr when
    it is a terminal (``tty`` overrides the check; ``leave``: the bar stays when done), log
    lines otherwise, nothing when ``quiet``."""
    tty = sys.stderr.isatty() if tty is None else tty
    bar = None
    if tty and not quiet:
        from tqdm import tqdm

        bar = tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, dynamic_ncols=True,
                   leave=leave)
    p = Progress(total, desc, unit, bar=bar, quiet=quiet)
    try:
        yield p
    finally:
        if bar is not None:
            bar.close()


def configure_logging(quiet: bool = False) -> None:
    """Route the ``ema_bench`` logger to stderr (once): INFO, or WARNING with ``quiet``."""
    log.setLevel(logging.WARNING if quiet else logging.INFO)
    if not any(isinstance(h, _Stderr) for h in log.handlers):
        h = _Stderr()
        h.setFormatter(logging.Formatter("%(asctime)s %(message)s", "%H:%M:%S"))
        log.addHandler(h)
        log.propagate = False


class _Stderr(logging.StreamHandler):
    """Writes to whatever ``sys.stderr`` is now (tests and redirections replace it)."""

    def emit(self, record: logging.LogRecord) -> None:
        # not setStream: it flushes the old stream, which may be closed by now (a test's)
        self.stream = sys.stderr
        super().emit(record)
