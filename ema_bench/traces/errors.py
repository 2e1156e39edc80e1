"""TracesError, and the helpers that build it for a file."""

from __future__ import annotations

from pathlib import Path


class TracesError(ValueError):
    """Invalid traces or traces file; the message names the file, test and column at fault.

    Attributes
    ----------
    unnamed_test : str or None
        Set when the file holds one test without a name: the message without its Python
        advice (``pass test=<name>``), for front ends that name tests their own way.
    """

    def __init__(self, message: str, *, unnamed_test: str | None = None) -> None:
        super().__init__(message)
        self.unnamed_test = unnamed_test


def _fail(path: Path, message: str) -> TracesError:
    return TracesError(f"{path}: {message}")


def _unnamed_test(path: Path, what: str) -> TracesError:
    """The error for a file holding one test without a name (see TracesError.unnamed_test)."""
    return TracesError(f"{path}: {what}; pass test=<name> to name its single test",
                       unnamed_test=f"{path}: {what}")


def _describe(exc: BaseException) -> str:
    """An exception as text, its type when it has no message (MemoryError())."""
    return str(exc) or type(exc).__name__
