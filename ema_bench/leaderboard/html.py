"""One self-contained HTML page of leaderboard tables and figures (a CI artifact opened offline).

Everything the page needs is inside the file: the stylesheet, a small sorter script, and the
figures as base64 ``data:`` URIs, so it opens from a downloaded artifact with no network. All
text is escaped (a solver may be named ``<script>``), and a Content-Security-Policy lets only
the page's own script and stylesheet run and loads images from ``data:`` URIs only, so even a
missed escape could neither run code nor reach the network.

Tables sort by clicking a header; the first click puts the better end first (a column marked
higher-is-better sorts descending, others ascending), the next reverses.  Each table sits in
its own horizontal scroll container, so a wide table never makes the page scroll sideways.
A cell sorts by its ``data-value`` attribute where it has one
(numbers, and ``(display_text, sort_value)`` cells such as ``("1.2e3 [0.9e3, 1.6e3]", 1200.0)``)
and by its text otherwise: numbers numerically (``inf`` above every number), then text, with
missing values (``-``) last in either direction.
"""

from __future__ import annotations

import base64
import errno
import hashlib
import html
import math
import mimetypes
import numbers
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ..jsonio import write_atomic

MISSING = "-"

_CSS = """\
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 80em; padding: 0 1em;
       color: #222; line-height: 1.4; }
table { border-collapse: collapse; margin: 1em 0; font-size: 0.9em; }
caption { text-align: left; font-weight: bold; padding: 0.3em 0; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
thead th { background: #f0f0f0; }
th button { all: inherit; border: 0; padding: 0; cursor: pointer; }
th[aria-sort=ascending] button::after { content: " \\25B2"; }
th[aria-sort=descending] button::after { content: " \\25BC"; }
tbody tr:nth-child(even) { background: #fafafa; }
p.note, footer { color: #666; font-size: 0.85em; }
p, footer { overflow-wrap: anywhere; }
div.scroll { overflow-x: auto; max-width: 100%; }
img { max-width: 100%; height: auto; display: block; margin: 1em 0; }
"""

# Sort keys: [rank, value] with rank 0 = number, 1 = text, 2 = missing; ranks never mix values,
# which keeps the order transitive in columns mixing numbers and text.
_JS = """\
"use strict";
(function () {
  const NUM = /^[-+]?(\\d+\\.?\\d*|\\.\\d+)(e[-+]?\\d+)?$/i;
  function key(cell) {
    const s = (cell.dataset.value !== undefined ? cell.dataset.value : cell.textContent).trim();
    const low = s.toLowerCase();
    if (s === "" || s === "-" || low === "nan") return [2, 0];
    if (low === "inf" || low === "+inf" || low === "infinity") return [0, Infinity];
    if (low === "-inf" || low === "-infinity") return [0, -Infinity];
    if (NUM.test(s)) return [0, parseFloat(s)];
    return [1, s];
  }
  function compare(a, b, dir) {
    if (a[0] !== b[0]) return a[0] === 2 || b[0] === 2 ? a[0] - b[0] : dir * (a[0] - b[0]);
    if (a[0] === 2) return 0;
    if (a[0] === 1) return dir * a[1].localeCompare(b[1], undefined, {numeric: true});
    return dir * (a[1] < b[1] ? -1 : a[1] > b[1] ? 1 : 0);
  }
  document.querySelectorAll("table.sortable").forEach(function (table) {
    const heads = table.tHead.rows[0].cells;
    Array.prototype.forEach.call(heads, function (th, col) {
      th.querySelector("button").addEventListener("click", function () {
        const now = th.getAttribute("aria-sort");
        const dir = now ? (now === "ascending" ? -1 : 1) : (th.dataset.better === "high" ? -1 : 1);
        Array.prototype.forEach.call(heads, function (h) { h.removeAttribute("aria-sort"); });
        th.setAttribute("aria-sort", dir === 1 ? "ascending" : "descending");
        const body = table.tBodies[0];
        const rows = Array.from(body.rows, function (r) { return [key(r.cells[col]), r]; });
        rows.sort(function (a, b) { return compare(a[0], b[0], dir); });  // stable: ties keep order
        rows.forEach(function (r) { body.appendChild(r[1]); });
      });
    });
  });
})();
"""


def _csp_hash(source: str) -> str:
    """CSP source expression allowing exactly this inline script or stylesheet."""
    return "'sha256-" + base64.b64encode(hashlib.sha256(source.encode()).digest()).decode() + "'"


# meta CSP also applies to file:// pages; form-action/base-uri close the non-fetch escapes
CSP = (f"default-src 'none'; img-src data:; style-src {_csp_hash(_CSS)}; "
       f"script-src {_csp_hash(_JS)}; base-uri 'none'; form-action 'none'")


@dataclass(frozen=True)
class Table:
    """One sortable table.

    Parameters
    ----------
    caption : str
        Shown above the table.
    columns : Sequence[str]
        Header cells.
    rows : Sequence[Sequence[object]]
        One sequence of cells per row, as many as ``columns``.  A cell is ``str`` (shown as
        is), ``int``, ``float`` (``digits`` significant digits; nan -> ``-``, inf -> ``inf``),
        ``None`` (``-``), or a tuple ``(display_text, sort_value)`` shown as ``display_text``
        and sorted by ``sort_value`` (a number, or ``None``/nan for missing).
    note : str
        Small print under the table.
    digits : int
        Significant digits of float cells.
    higher_better : Sequence[str]
        Columns where a larger value is better: their first click sorts descending.
    """

    caption: str
    columns: Sequence[str]
    rows: Sequence[Sequence[object]]
    note: str = ""
    digits: int = 4
    higher_better: Sequence[str] = ()

    def __post_init__(self) -> None:
        # a short row would silently shift every later cell under the wrong header
        for i, row in enumerate(self.rows):
            if len(row) != len(self.columns):
                raise ValueError(f"table {self.caption!r}: row {i} has {len(row)} cells, "
                                 f"expected {len(self.columns)} ({', '.join(self.columns)})")


@dataclass(frozen=True)
class Section:
    """One headed part of the page.

    Parameters
    ----------
    heading : str
        Section heading.
    text : str
        Plain text (escaped, not HTML); a blank line starts a new paragraph.
    tables : Sequence[Table]
        Tables shown after the text.
    images : Sequence[Path]
        PNG or SVG files embedded as base64 ``data:`` URIs, alt text the file name.
    """

    heading: str
    text: str = ""
    tables: Sequence[Table] = ()
    images: Sequence[Path] = ()


def format_cell(value: object, digits: int = 4) -> tuple[str, str | None]:
    """Display text and sort value (``data-value``, ``None`` for none) of one cell.

    Parameters
    ----------
    value : object
        A table cell, as described in :class:`Table`.
    digits : int
        Significant digits of floats.

    Returns
    -------
    tuple[str, str | None]
        Unescaped display text and sort value.
    """
    if isinstance(value, tuple):
        if len(value) != 2:
            raise ValueError(f"a tuple cell is (display_text, sort_value), got {value!r}")
        display, sort_value = value
        text = display if isinstance(display, str) else format_cell(display, digits)[0]
        if sort_value is None:
            return text, MISSING
        if isinstance(sort_value, numbers.Real) and not isinstance(sort_value, bool):
            return text, _number_key(sort_value)
        return text, str(sort_value)
    if value is None:
        return MISSING, None
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return str(value), None
    if isinstance(value, numbers.Integral):   # numpy integers too
        return str(int(value)), str(int(value))
    v = float(value)
    if math.isnan(v):
        return MISSING, None
    if math.isinf(v):
        return ("inf" if v > 0 else "-inf"), _number_key(v)
    return f"{v:.{digits}g}", _number_key(v)


def _number_key(value: numbers.Real) -> str:
    """Full-precision sort value of a number, as the sorter script parses it."""
    if isinstance(value, numbers.Integral):
        return str(int(value))
    v = float(value)
    if math.isnan(v):
        return MISSING
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return repr(v)   # shortest round-tripping form: ties only where the floats are equal


def _paragraphs(text: str, cls: str = "") -> list[str]:
    attr = f' class="{cls}"' if cls else ""
    return [f"<p{attr}>{html.escape(p.strip())}</p>"
            for p in re.split(r"\n[ \t]*\n", text) if p.strip()]


def _table(table: Table) -> list[str]:
    label = html.escape(table.caption, quote=True)
    out = [f'<div class="scroll" role="region" tabindex="0" aria-label="{label}">',
           '<table class="sortable">', f"<caption>{html.escape(table.caption)}</caption>",
           "<thead><tr>"]
    high = set(table.higher_better)
    better = ' data-better="high"'
    out += [f'<th scope="col"{better if c in high else ""}>'
            f'<button type="button">{html.escape(str(c))}</button></th>'
            for c in table.columns]
    out += ["</tr></thead>", "<tbody>"]
    for row in table.rows:
        cells = []
        for value in row:
            text, key = format_cell(value, table.digits)
            attrs = ' class="num"' if key is not None else ""
            if key is not None:
                attrs += f' data-value="{html.escape(key)}"'
            cells.append(f"<td{attrs}>{html.escape(text)}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    out += ["</tbody>", "</table>", "</div>"]
    return out + _paragraphs(table.note, "note")


def _image_uris(sections: Sequence[Section]) -> dict[Path, str]:
    """``data:`` URI of every image, read before anything is written."""
    uris: dict[Path, str] = {}
    for section in sections:
        for image in section.images:
            image = Path(image)
            if not image.is_file():
                raise FileNotFoundError(
                    errno.ENOENT, f"image of section {section.heading!r} not found", str(image))
            mime = mimetypes.guess_type(image.name)[0]
            if mime not in ("image/png", "image/svg+xml"):
                raise ValueError(f"image {image} is {mime or 'of unknown type'}: "
                                 "only PNG and SVG are embedded")
            uris[image] = f"data:{mime};base64," + base64.b64encode(image.read_bytes()).decode()
    return uris


def render_html(title: str, intro: str, sections: Sequence[Section], footer: str = "") -> str:
    """The page :func:`write_html` writes, as a string (see there)."""
    uris = _image_uris(sections)
    out = ["<!DOCTYPE html>", '<html lang="en">', "<head>", '<meta charset="utf-8">',
           f'<meta http-equiv="Content-Security-Policy" content="{html.escape(CSP)}">',
           '<meta name="viewport" content="width=device-width, initial-scale=1">',
           '<meta name="generator" content="ema-bench">',
           f"<title>{html.escape(title)}</title>", f"<style>{_CSS}</style>", "</head>",
           "<body>", f"<h1>{html.escape(title)}</h1>", *_paragraphs(intro)]
    for section in sections:
        out += ["<section>", f"<h2>{html.escape(section.heading)}</h2>",
                *_paragraphs(section.text)]
        for table in section.tables:
            out += _table(table)
        out += [f'<img src="{uris[Path(p)]}" alt="{html.escape(Path(p).name)}">'
                for p in section.images]
        out.append("</section>")
    if footer:
        out.append(f"<footer>{html.escape(footer)}</footer>")
    out += [f"<script>{_JS}</script>", "</body>", "</html>", ""]
    return "\n".join(out)


def write_html(path: Path, title: str, intro: str, sections: Sequence[Section],
               footer: str = "") -> Path:
    """Write one self-contained HTML5 page of tables and figures.

    The page is written atomically (a temporary file in the same folder, then renamed over
    ``path``), so a crash leaves either the old page or the new one, never half a page.

    Parameters
    ----------
    path : Path
        The page to write; its folder must exist.
    title : str
        Page title and top heading.
    intro : str
        Plain text under the title; a blank line starts a new paragraph.
    sections : Sequence[Section]
        The page's sections, in order.
    footer : str
        A last line of small print (e.g. the commit and date), none if empty.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    FileNotFoundError
        An image file, or the folder of ``path``, does not exist (nothing is written).
    ValueError
        An image is neither PNG nor SVG (nothing is written).
    """
    path = Path(path)
    page = render_html(title, intro, sections, footer)
    if not path.parent.is_dir():
        raise FileNotFoundError(errno.ENOENT, "folder of the HTML page not found", str(path.parent))
    write_atomic(path, page)
    os.chmod(path, 0o644)   # readable by all, whatever the umask: a page is there to be shared
    return path
