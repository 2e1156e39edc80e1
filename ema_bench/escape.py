"""Safe text for the tables we write: the one helper of every Markdown and CSV writer.

Names in tables come from plugins and records (solver, tracker, case names): text we did not
write.  :func:`markdown` makes such text inert in a Markdown table cell (no HTML, no link, no
emphasis, no column break, no new line); :func:`csv_value` makes a CSV cell a plain value that
no spreadsheet reads as a formula (OWASP "CSV injection": a leading ``= + - @``, tab or
carriage return is quoted with ``'``) and writes numbers as plain decimal text (``0.25``,
``inf``, ``nan``: what ``float()`` reads back), never a NumPy repr.  Registration refuses the
worst names outright (:func:`check_name`); this is the second line.
"""

from __future__ import annotations

import math
import numbers
import re
import unicodedata

#: Characters with a meaning inside a Markdown (CommonMark) table cell: code, emphasis, a
#: column break, strike-through, a link target (`[x](y)` is no link once `(` is escaped).
_MARKDOWN_SPECIAL = re.compile(r"([\\`*_|~(])")
_HTML = {"&": "&amp;", "<": "&lt;", ">": "&gt;"}
#: A CSV cell starting with one of these is read as a formula by spreadsheets.
FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def _printable(text: str) -> str:
    """Control and format characters (new lines, tabs, bidi overrides) as spaces."""
    return "".join(" " if unicodedata.category(c) in ("Cc", "Cf", "Zl", "Zp") else c
                   for c in text)


def markdown(text: object) -> str:
    """``text`` as inert Markdown table-cell text (names stay readable: ``nelder-mead`` is
    unchanged, ``a|b`` becomes ``a\\|b``, ``<script>`` becomes ``&lt;script&gt;``)."""
    s = _printable(str(text))
    s = "".join(_HTML.get(c, c) for c in s)
    return _MARKDOWN_SPECIAL.sub(r"\\\1", s)


def terminal(text: object) -> str:
    """``text`` safe to print on a terminal line: control and format characters (escape
    sequences, new lines, bidi overrides) as spaces."""
    return _printable(str(text))


def code_span(text: object) -> str:
    """``text`` as one inert Markdown code span: fenced by one backtick more than its
    longest run of backticks (CommonMark), so a backtick inside cannot end it."""
    s = _printable(str(text))
    runs = re.findall(r"`+", s)
    fence = "`" * (max(map(len, runs), default=0) + 1)
    pad = " " if s.startswith("`") or s.endswith("`") else ""
    return f"{fence}{pad}{s}{pad}{fence}"


def csv_value(value: object) -> object:
    """A CSV cell: numbers as plain decimal text, text with no control character and no
    formula start; None stays empty."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        v = float(value)
        return "nan" if math.isnan(v) else ("inf" if v == math.inf else
                                            "-inf" if v == -math.inf else repr(v))
    s = _printable(str(value))
    return "'" + s if s.startswith(FORMULA_START) else s


def check_name(name: object, kind: str) -> str:
    """``name`` if it is a safe plugin name, else ValueError saying why (one line): a
    non-empty string without control characters, path separators or surrounding spaces, not
    starting with ``= + - @`` (a formula in a spreadsheet)."""
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"{kind} name must be a non-empty string, got {name!r}")
    if _printable(name) != name:
        raise ValueError(f"{kind} name {name!r} contains control characters")
    if "/" in name or "\\" in name or name in (".", ".."):
        raise ValueError(f"{kind} name {name!r} contains a path separator")
    if name.startswith(FORMULA_START[:4]):
        raise ValueError(f"{kind} name {name!r} starts with {name[0]!r} (a spreadsheet "
                         "formula)")
    if name != name.strip():
        raise ValueError(f"{kind} name {name!r} has leading or trailing spaces")
    return name
