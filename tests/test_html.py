"""The self-contained HTML leaderboard page: read back with ``html.parser`` as a browser would
see it (structure, escaping, embedded figures, no network), and its sorter run under Node where
Node is installed."""

from __future__ import annotations

import base64
import hashlib
import json
import math
import os
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import matplotlib
import numpy as np
import pytest

from ema_bench.leaderboard.html import Section, Table, write_html

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)

EVIL = "<script>alert(1)</script>"
VOID = {"meta", "img", "br", "hr", "input", "link"}


class Node:
    """An element: tag, attributes and children (elements and text)."""

    def __init__(self, tag: str, attrs: dict[str, str | None]) -> None:
        self.tag, self.attrs, self.children = tag, attrs, []

    def find_all(self, tag: str) -> list[Node]:
        found = []
        for child in self.children:
            if isinstance(child, Node):
                found += [child] * (child.tag == tag) + child.find_all(tag)
        return found

    def elements(self) -> list[Node]:
        """Every element below this one."""
        return [e for c in self.children if isinstance(c, Node) for e in [c, *c.elements()]]

    def text(self) -> str:
        return "".join(c if isinstance(c, str) else c.text() for c in self.children)


class Page(HTMLParser):
    """The element tree of a page, built the way a browser's parser reads the markup."""

    def __init__(self, source: str) -> None:
        super().__init__()
        self.root = Node("#document", {})
        self.stack = [self.root]
        self.feed(source)
        self.close()

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        node = Node(tag, dict(attrs))
        self.stack[-1].children.append(node)
        if tag not in VOID:
            self.stack.append(node)

    def handle_startendtag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.stack[-1].children.append(Node(tag, dict(attrs)))

    def handle_endtag(self, tag: str) -> None:
        assert tag in [n.tag for n in self.stack], f"</{tag}> closes nothing"
        while self.stack.pop().tag != tag:
            pass

    def handle_data(self, data: str) -> None:
        self.stack[-1].children.append(data)

    def all(self, tag: str) -> list[Node]:
        return self.root.find_all(tag)


def read(path: Path) -> Page:
    page = Page(path.read_text(encoding="utf-8"))
    assert page.stack == [page.root], "unclosed elements"
    return page


def cells(table: Node) -> list[list[Node]]:
    (body,) = table.find_all("tbody")
    return [tr.find_all("td") for tr in body.find_all("tr")]


def tiny_figure(path: Path) -> Path:
    fig, ax = plt.subplots(figsize=(1, 1), dpi=20)
    ax.plot([0, 1], [1, 0])
    fig.savefig(path)
    plt.close(fig)
    return path


ERT_ROWS = [["cmaes", 10.0], ["de", math.inf], ["ngopt", None], ["powell", 2.5],
            ["random", math.nan], ["paper-ga", ("1.2e3 [0.9e3, 1.6e3]", 1200.0)],
            ["lbfgsb", 3], ["nelder-mead", 1e300]]


def test_tables_have_their_captions_headers_and_rows(tmp_path: Path) -> None:
    sections = [Section("twin track", "Scores.\n\nSecond paragraph.", tables=[
                    Table("all cases", ["solver", "ERT"], ERT_ROWS, note="ERT in evaluations"),
                    Table("small", ["solver", "success", "acc Na %"],
                          [["de", "3/5", 99.12345], ["cmaes", "5/5", 98.0]])]),
                Section("measured track", tables=[Table("empty", ["solver"], [])])]
    page = read(write_html(tmp_path / "lb.html", "Leaderboard", "Intro.", sections,
                           footer="commit abc123"))
    tables = page.all("table")
    assert [t.find_all("caption")[0].text() for t in tables] == ["all cases", "small", "empty"]
    assert [[th.text() for th in t.find_all("th")] for t in tables] == [
        ["solver", "ERT"], ["solver", "success", "acc Na %"], ["solver"]]
    assert [len(cells(t)) for t in tables] == [8, 2, 0]
    assert all(len(row) == 2 for row in cells(tables[0]))
    assert [c.text() for c in cells(tables[1])[0]] == ["de", "3/5", "99.12"]   # 4 digits
    assert [h.text() for h in page.all("h2")] == ["twin track", "measured track"]
    paragraphs = [p.text() for p in page.all("p")]
    assert {"Intro.", "Scores.", "Second paragraph.", "ERT in evaluations"} <= set(paragraphs)
    assert page.all("footer")[0].text() == "commit abc123"
    metas = [m.attrs for m in page.all("meta")]
    assert {"name": "generator", "content": "ema-bench"} in metas
    assert {"charset": "utf-8"} in metas


def test_a_row_of_the_wrong_length_is_refused() -> None:
    with pytest.raises(ValueError, match="row 1 has 1 cells, expected 2"):
        Table("t", ["solver", "ERT"], [["de", 1.0], ["cmaes"]])


def test_markup_in_names_and_text_is_shown_as_text_never_run(tmp_path: Path) -> None:
    sections = [Section(EVIL, EVIL, tables=[Table(EVIL, [EVIL], [[EVIL], [(EVIL, 1.0)]],
                                                  note=EVIL)])]
    path = write_html(tmp_path / "lb.html", EVIL, EVIL, sections, footer=EVIL)
    page = read(path)
    (script,) = page.all("script")   # only the sorter
    assert "querySelectorAll" in script.text() and "alert" not in script.text()
    assert [c.text() for row in cells(page.all("table")[0]) for c in row] == [EVIL, EVIL]
    for tag in ("title", "h1", "h2", "caption", "th", "footer"):
        assert page.all(tag)[0].text() == EVIL
    assert path.read_text(encoding="utf-8").count("<script") == 1


@pytest.mark.parametrize("suffix, mime", [(".png", "image/png"), (".svg", "image/svg+xml")])
def test_an_embedded_figure_round_trips_byte_for_byte(tmp_path: Path, suffix: str,
                                                      mime: str) -> None:
    figure = tiny_figure(tmp_path / f"convergence{suffix}")
    page = read(write_html(tmp_path / "lb.html", "t", "", [Section("s", images=[figure])]))
    (img,) = page.all("img")
    assert img.attrs["alt"] == figure.name
    prefix = f"data:{mime};base64,"
    assert img.attrs["src"].startswith(prefix)
    assert base64.b64decode(img.attrs["src"][len(prefix):], validate=True) == figure.read_bytes()


def test_the_page_references_nothing_outside_itself(tmp_path: Path) -> None:
    figure = tiny_figure(tmp_path / "f.png")
    page = read(write_html(tmp_path / "lb.html", "t", "see https://example.org",
                           [Section("s", tables=[Table("c", ["a"], [[1]])], images=[figure])]))
    for node in page.root.elements():
        for name in ("src", "href"):
            value = (node.attrs.get(name) or "").strip().lower()
            assert not value.startswith(("http://", "https://", "//")), (node.tag, value)
    assert not page.all("link") and all("src" not in s.attrs for s in page.all("script"))
    (csp,) = [m for m in page.all("meta") if m.attrs.get("http-equiv") ==
              "Content-Security-Policy"]
    assert "default-src 'none'" in csp.attrs["content"]   # the browser blocks any fetch
    assert "img-src data:" in csp.attrs["content"]


def test_the_content_security_policy_lets_the_sorter_and_stylesheet_run(tmp_path: Path) -> None:
    # a stale hash would make browsers silently block sorting and styling
    page = read(write_html(tmp_path / "lb.html", "t", "", []))
    csp = next(m.attrs["content"] for m in page.all("meta")
               if m.attrs.get("http-equiv") == "Content-Security-Policy")
    for tag, directive in (("script", "script-src"), ("style", "style-src")):
        (node,) = page.all(tag)
        digest = base64.b64encode(hashlib.sha256(node.text().encode()).digest()).decode()
        assert f"{directive} 'sha256-{digest}'" in csp


def test_tuple_cells_show_their_text_and_sort_by_their_value(tmp_path: Path) -> None:
    rows = [[("1.2e3 [0.9e3, 1.6e3]", 1234.56789)], [("n/a", None)], [("wide", math.inf)]]
    page = read(write_html(tmp_path / "lb.html", "t", "", [Section("s", tables=[
        Table("c", ["ERT"], rows)])]))
    tds = [row[0] for row in cells(page.all("table")[0])]
    assert [td.text() for td in tds] == ["1.2e3 [0.9e3, 1.6e3]", "n/a", "wide"]
    assert float(tds[0].attrs["data-value"]) == 1234.56789   # full precision, not the display
    assert [td.attrs["data-value"] for td in tds[1:]] == ["-", "inf"]


def test_numbers_are_formatted_and_missing_values_shown_as_a_dash(tmp_path: Path) -> None:
    row = [math.nan, math.inf, -math.inf, None, 1234.5678, 0.000123456, 7, np.float64(2 / 3),
           np.int64(42), "0.5 text", True]
    page = read(write_html(tmp_path / "lb.html", "t", "", [Section("s", tables=[
        Table("c", [str(i) for i in range(len(row))], [row])])]))
    (tds,) = cells(page.all("table")[0])
    assert [td.text() for td in tds] == ["-", "inf", "-inf", "-", "1235", "0.0001235", "7",
                                         "0.6667", "42", "0.5 text", "True"]
    values = [td.attrs.get("data-value") for td in tds]
    assert values[:4] == [None, "inf", "-inf", None]
    assert float(values[4]) == 1234.5678 and float(values[7]) == 2 / 3
    assert values[6] == "7" and values[8] == "42"
    assert values[9] is None and values[10] is None   # text sorts by its text


def test_a_missing_image_is_named_and_nothing_is_written(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    missing = tmp_path / "no-such-figure.png"
    with pytest.raises(FileNotFoundError, match="section 'figures'.*no-such-figure.png") as err:
        write_html(out / "lb.html", "t", "", [Section("figures", images=[missing])])
    assert err.value.filename == str(missing)
    assert list(out.iterdir()) == []


def test_a_figure_that_is_neither_png_nor_svg_is_refused_before_writing(tmp_path: Path) -> None:
    # anything else would embed as a data: URI no browser shows (e.g. a PDF from savefig)
    figure = tmp_path / "convergence.pdf"
    figure.write_bytes(b"%PDF-1.4")
    with pytest.raises(ValueError, match="convergence.pdf"):
        write_html(tmp_path / "lb.html", "t", "", [Section("s", images=[figure])])
    assert list(tmp_path.iterdir()) == [figure]


def test_an_interrupted_write_keeps_the_old_page_and_leaves_no_temp_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = write_html(tmp_path / "lb.html", "old", "", [])
    old = path.read_bytes()

    def crash(src: object, dst: object) -> None:
        raise KeyboardInterrupt   # the worst case: not even an Exception

    monkeypatch.setattr(os, "replace", crash)
    with pytest.raises(KeyboardInterrupt):
        write_html(path, "new", "", [Section("s", tables=[Table("c", ["a"], [[1]] * 1000)])])
    assert list(tmp_path.iterdir()) == [path] and path.read_bytes() == old
    path.unlink()
    with pytest.raises(KeyboardInterrupt):
        write_html(path, "new", "", [])
    assert list(tmp_path.iterdir()) == []


# The sorter run under Node on a minimal stand-in for the browser DOM built from the parsed
# page: clicks on headers, and the order of the rows after each.
NODE_HARNESS = r"""
const vm = require("vm");
const {script, heads, rows, clicks} = JSON.parse(require("fs").readFileSync(0, "utf8"));
const body = {rows: rows.map((cs, id) => ({id, cells: cs.map(c => ({
  textContent: c.text, dataset: c.value === null ? {} : {value: c.value}}))})),
  appendChild(r) { this.rows.splice(this.rows.indexOf(r), 1); this.rows.push(r); }};
const ths = heads.map(h => { const button = {addEventListener(t, f) { this.click = f; }};
  return {attrs: {}, querySelector: () => button, button,
          dataset: h.better === null ? {} : {better: h.better},
          getAttribute(k) { return k in this.attrs ? this.attrs[k] : null; },
          setAttribute(k, v) { this.attrs[k] = String(v); },
          removeAttribute(k) { delete this.attrs[k]; }}; });
const table = {tHead: {rows: [{cells: ths}]}, tBodies: [body]};
vm.runInNewContext(script, {document: {querySelectorAll: () => [table]}});
console.log(JSON.stringify(clicks.map(col => { ths[col].button.click();
  return {order: body.rows.map(r => r.id), sort: ths.map(th => th.getAttribute("aria-sort"))};
})));
"""


@pytest.mark.skipif(shutil.which("node") is None, reason="needs Node.js to run the sorter")
def test_clicking_a_header_sorts_numbers_with_inf_above_and_missing_last(tmp_path: Path) -> None:
    page = read(write_html(tmp_path / "lb.html", "t", "", [Section("s", tables=[
        Table("c", ["solver", "ERT"], ERT_ROWS)])]))
    table = page.all("table")[0]
    job = {"script": page.all("script")[0].text(),
           "heads": [{"better": th.attrs.get("data-better")} for th in table.find_all("th")],
           "rows": [[{"text": td.text(), "value": td.attrs.get("data-value")} for td in row]
                    for row in cells(table)],
           "clicks": [1, 1, 0, 1]}
    run = subprocess.run(["node", "-e", NODE_HARNESS], input=json.dumps(job), text=True,
                         capture_output=True, timeout=60, check=True)
    names = [row[0] for row in ERT_ROWS]
    got = [([names[i] for i in step["order"]], step["sort"]) for step in json.loads(run.stdout)]
    ascending = ["powell", "lbfgsb", "cmaes", "paper-ga", "nelder-mead", "de", "ngopt", "random"]
    descending = ["de", "nelder-mead", "paper-ga", "cmaes", "lbfgsb", "powell", "ngopt", "random"]
    assert got == [(ascending, [None, "ascending"]),
                   (descending, [None, "descending"]),   # the same header again toggles
                   (sorted(names), ["ascending", None]),
                   (ascending, [None, "ascending"])]     # another header starts ascending


@pytest.mark.skipif(shutil.which("node") is None, reason="needs Node.js to run the sorter")
def test_the_first_click_puts_the_better_end_first(tmp_path: Path) -> None:
    """An area (higher is better) sorts descending at the first click, an ERT ascending."""
    rows = [["a", 0.2, 30.0], ["b", 0.9, 10.0], ["c", 0.5, 20.0]]
    page = read(write_html(tmp_path / "lb.html", "t", "", [Section("s", tables=[
        Table("c", ["solver", "ECDF area", "ERT"], rows, higher_better=["ECDF area"])])]))
    table = page.all("table")[0]
    job = {"script": page.all("script")[0].text(),
           "heads": [{"better": th.attrs.get("data-better")} for th in table.find_all("th")],
           "rows": [[{"text": td.text(), "value": td.attrs.get("data-value")} for td in row]
                    for row in cells(table)],
           "clicks": [1, 1, 2]}
    run = subprocess.run(["node", "-e", NODE_HARNESS], input=json.dumps(job), text=True,
                         capture_output=True, timeout=60, check=True)
    got = [[rows[i][0] for i in step["order"]] for step in json.loads(run.stdout)]
    assert got == [["b", "c", "a"], ["a", "c", "b"], ["b", "c", "a"]]


def test_the_leaderboard_page_is_shareable(tmp_path: Path) -> None:
    """No local folder in the header, precisions floored at 0, areas sort best-first, every
    table in its own scroll container (the committed quick records)."""
    from ema_bench.leaderboard.page import shareable, write_page
    from ema_bench.leaderboard.run_store import read_records

    records = read_records(Path(__file__).resolve().parents[1] / "leaderboards" / "quick"
                           / "runs.jsonl")
    from ema_bench.leaderboard.anytime import anytime_scores
    from ema_bench.leaderboard.report import ranking_rows

    # cmaes's fits made to lie 1 % of the gap below the best-known f*: precision -0.01
    for r in records:
        t = r.get("targets") or {}
        if r["solver"] == "cmaes" and t.get("f_star") is not None:
            below = t["f_star"] - 0.01 * (t["f_nominal"] - t["f_star"])
            # the evidence, not the claims, is what the scores read (issue 29)
            r["best_at"] = [[b, below] for b, _ in r["best_at"]]
            r["trace"] = [[e, below] for e, _ in r["trace"]]
    raw = [v for t in ("reference", "twin") for r in ranking_rows(anytime_scores(records), t)
           for k, v in r.items() if k.startswith("median precision")]
    assert min(raw) == pytest.approx(-0.01)
    header = ("Produced by `ema-bench leaderboard --quick --out /home/me/secret/lb "
              "--check=/home/me/lbs --scheduler tcp://10.0.0.5:8786`")
    assert shareable(header) == ("Produced by `ema-bench leaderboard --quick --out OUT "
                                 "--check=DIR --scheduler ADDRESS`")
    page_path = write_page(records, tmp_path / "leaderboard.html", header, [])
    text = page_path.read_text()
    assert "/home/me" not in text and "10.0.0.5" not in text
    page = read(page_path)
    tables = page.all("table")
    assert len(page.all("div")) >= len(tables) == 6
    for table in tables:
        heads = table.find_all("th")
        names = [th.text() for th in heads]
        better = {th.text() for th in heads if th.attrs.get("data-better") == "high"}
        if "ECDF area [95 % CI]" in names:
            assert {"ECDF area [95 % CI]", "fitness area", "reached p0.01"} <= better
            assert not any(n.startswith("ERT") or "precision" in n for n in better)
            cols = [i for i, n in enumerate(names) if n.startswith("median precision")]
            values = [float(row[i].attrs["data-value"]) for row in cells(table) for i in cols
                      if row[i].attrs.get("data-value") not in (None, "-")]
            assert values and min(values) >= 0.0
