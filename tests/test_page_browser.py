"""The committed leaderboard page in a real browser (headless Chromium, Debian's package).

Chromium is driven over the DevTools protocol on a pipe (``--remote-debugging-pipe``: JSON
messages separated by NUL bytes on file descriptors 3 and 4), so no driver package is needed.
At 1280 x 900 CSS pixels the page must not scroll sideways, a click on a ranking header must
sort the table (the first click on the ECDF area puts the best first), and the page must
request nothing beyond itself and its ``data:`` images.  Skipped with the reason where no
Chromium is installed (``apt-get install chromium``; .ci/run installs it).
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import subprocess
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "leaderboards" / "leaderboard.html"
WIDTH, HEIGHT = 1280, 900
# Debian's chromium; GitHub's Ubuntu runners ship Google Chrome instead
CHROMIUM = next((p for p in map(shutil.which, ("chromium", "chromium-browser",
                                               "google-chrome")) if p), None)

pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="no Chromium installed (Debian: "
                                "apt-get install chromium)")


class DevTools:
    """A headless Chromium and a DevTools session on one page target, over a pipe."""

    def __init__(self, profile: Path) -> None:
        to_chrome_r, self._to_chrome = os.pipe()
        self._from_chrome, from_chrome_w = os.pipe()
        # the child's ends above 4, so that putting them on 3 and 4 cannot clobber each other
        ends = []
        for fd in (to_chrome_r, from_chrome_w):
            ends.append(fcntl.fcntl(fd, fcntl.F_DUPFD, 10))
            os.close(fd)
        to_chrome_r, from_chrome_w = ends
        # the child reads commands on fd 3 and writes replies on fd 4 (bash puts the
        # pipe ends there)
        self.proc = subprocess.Popen(
            ["bash", "-c", f'exec "$0" "$@" 3<&{to_chrome_r} 4>&{from_chrome_w}', CHROMIUM,
             "--headless=new", "--no-sandbox", "--disable-gpu", "--remote-debugging-pipe",
             f"--user-data-dir={profile}", "--no-first-run",
             f"--window-size={WIDTH},{HEIGHT}", "about:blank"],
            pass_fds=(to_chrome_r, from_chrome_w), stdout=subprocess.DEVNULL,
            stderr=open(profile.parent / "chromium.log", "w"))   # noqa: SIM115
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self.profile = profile
        self._buf = b""
        self._id = 0
        self.events: list[dict] = []
        self.session = ""

    def send(self, method: str, params: dict | None = None, session: bool = True,
             timeout: float = 60) -> dict:
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params or {}}
        if session and self.session:
            msg["sessionId"] = self.session
        os.write(self._to_chrome, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            reply = self._read(deadline)
            if reply.get("id") == self._id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self.events.append(reply)

    def wait_for(self, method: str, timeout: float = 60) -> dict:
        deadline = time.monotonic() + timeout
        for e in self.events:
            if e.get("method") == method:
                return e
        while True:
            e = self._read(deadline)
            self.events.append(e)
            if e.get("method") == method:
                return e

    def _read(self, deadline: float) -> dict:
        while b"\0" not in self._buf:
            if time.monotonic() > deadline:
                raise TimeoutError("no reply from Chromium")
            chunk = os.read(self._from_chrome, 1 << 16)
            if not chunk:
                log = (self.profile.parent / "chromium.log").read_text()[-1500:]
                raise RuntimeError(f"Chromium closed the pipe:\n{log}")
            self._buf += chunk
        msg, self._buf = self._buf.split(b"\0", 1)
        return json.loads(msg)

    def js(self, expression: str):
        res = self.send("Runtime.evaluate", {"expression": expression, "returnByValue": True})
        if "exceptionDetails" in res:
            raise RuntimeError(res["exceptionDetails"])
        return res["result"].get("value")

    def close(self) -> None:
        try:
            self.send("Browser.close", session=False, timeout=10)
        except (RuntimeError, TimeoutError, OSError):
            pass
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        os.close(self._to_chrome)
        os.close(self._from_chrome)


@pytest.fixture
def browser(tmp_path):
    dt = DevTools(tmp_path / "profile")
    try:
        target = dt.send("Target.createTarget", {"url": "about:blank"}, session=False)
        dt.session = dt.send("Target.attachToTarget", {"targetId": target["targetId"],
                                                       "flatten": True},
                             session=False)["sessionId"]
        for domain in ("Page", "Network", "Runtime"):
            dt.send(f"{domain}.enable")
        dt.send("Emulation.setDeviceMetricsOverride", {"width": WIDTH, "height": HEIGHT,
                                                       "deviceScaleFactor": 1,
                                                       "mobile": False})
        yield dt
    finally:
        dt.close()


def _widths(browser) -> tuple[int, int, list[bool]]:
    """The page's and the window's width, and per table container whether it scrolls."""
    page_w, view_w = browser.js("[document.documentElement.scrollWidth, window.innerWidth]")
    inner = browser.js("Array.from(document.querySelectorAll('div.scroll'), "
                       "d => d.scrollWidth > d.clientWidth)")
    return page_w, view_w, inner


def test_the_committed_page_fits_sorts_and_stays_offline(browser, tmp_path):
    url = PAGE.as_uri()
    browser.send("Page.navigate", {"url": url})
    browser.wait_for("Page.loadEventFired")
    # no sideways scroll of the page at 1280 px (a wide table scrolls inside its own
    # container: below)
    page_w, view_w, inner = _widths(browser)
    assert view_w == WIDTH and page_w <= view_w, (page_w, view_w)
    assert inner
    # the first click on the ECDF area header of the first ranking puts the best first
    order = browser.js("""(() => {
      const t = Array.from(document.querySelectorAll('table.sortable')).find(t =>
        Array.from(t.tHead.rows[0].cells).some(c => c.textContent.startsWith('ECDF area')));
      const heads = Array.from(t.tHead.rows[0].cells, c => c.textContent);
      const col = heads.findIndex(h => h.startsWith('ECDF area'));
      const solver = heads.indexOf('solver');
      const before = Array.from(t.tBodies[0].rows, r => r.cells[solver].textContent);
      t.tHead.rows[0].cells[col].querySelector('button').click();
      const rows = Array.from(t.tBodies[0].rows);
      return {index: Array.from(document.querySelectorAll('table.sortable')).indexOf(t),
              before, after: rows.map(r => r.cells[solver].textContent),
              values: rows.map(r => parseFloat(r.cells[col].dataset.value)),
              sort: t.tHead.rows[0].cells[col].getAttribute('aria-sort')};
    })()""")
    assert order["sort"] == "descending"
    assert order["values"] == sorted(order["values"], reverse=True)
    assert sorted(order["after"]) == sorted(order["before"])
    # the solver column of the same table (the second: rank, solver) sorts by name
    browser.js(f"document.querySelectorAll('table.sortable')[{order['index']}]"
               ".querySelector('th:nth-child(2) button').click()")
    solvers = browser.js(f"Array.from(document.querySelectorAll('table.sortable')"
                         f"[{order['index']}].tBodies[0].rows, r => r.cells[1].textContent)")
    assert solvers == sorted(solvers, key=str.casefold) or solvers == sorted(solvers)
    # nothing requested but the page itself and its inline data: images
    urls = [e["params"]["request"]["url"] for e in browser.events
            if e.get("method") == "Network.requestWillBeSent"]
    assert url in urls
    assert all(u == url or u.startswith("data:") for u in urls), urls
    assert not [e for e in browser.events if e.get("method") == "Runtime.exceptionThrown"]
    # the v1 board's per-instance table (24 columns) was wider than the page; the v2 board
    # has none, so the page writer is given one (40 instance columns), in the same browser
    from ema_bench.leaderboard.html import Section, Table, write_html

    cols = ["solver"] + [f"t12-s{i:02d}@no-prior" for i in range(40)]
    wide = write_html(tmp_path / "wide.html", "wide", "header", [Section(
        "reference track", "text", tables=[Table("ECDF area per instance", cols,
                                                 [["cmaes"] + [0.25] * 40])])])
    browser.events.clear()                       # wait for this page's load event
    browser.send("Page.navigate", {"url": wide.as_uri()})
    browser.wait_for("Page.loadEventFired")
    page_w, view_w, inner = _widths(browser)
    assert view_w == WIDTH and page_w <= view_w, (page_w, view_w)
    assert inner == [True]
