"""The committed main board is the emafdi-v2 board ``leaderboards/README.md`` describes.

Its regeneration steps are what made it: the README's record-selection step, run on a sweep
file holding the committed records and runs outside the grid, writes the committed
``runs.jsonl`` back byte for byte; the README's ``--report-only`` command is the one every
committed table names in its header.  And no ``<!-- v2-board: ... -->`` placeholder (a
figure the full board fills) survives once the board is complete.  Cost: about 3 CPU-s, most
of it the zoo's imports (the selection registers every solver).
"""

from __future__ import annotations

import json
import re
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BOARD = ROOT / "leaderboards"
README = BOARD / "README.md"
MARKER = re.compile(r"<!-- v2-board: (.*?) -->", re.S)


def _section(text: str, title: str) -> str:
    return text.split(title, 1)[1].split("\n## ", 1)[0]


def _snippet() -> str:
    """The Python of step 1 of "Regenerating it" (the heredoc between ``<<'PY'`` and ``PY``)."""
    steps = _section(README.read_text(), "### Regenerating it")
    body = steps.split("<<'PY'\n", 1)[1].split("\n        PY\n", 1)[0]
    return textwrap.dedent(body)


def _commands(text: str, flag: str) -> list[str]:
    """The ``ema-bench leaderboard`` commands of indented code blocks holding ``flag``, with
    their continuation lines joined."""
    joined = re.sub(r"\\\n\s*", "", text)
    return [" ".join(line.split()) for line in joined.splitlines()
            if line.strip().startswith("ema-bench leaderboard") and flag in line]


def _complete() -> bool:
    return "PARTIAL" not in (BOARD / "leaderboard_reference.md").read_text().splitlines()[2]


def test_the_readme_selection_step_writes_the_committed_records_back(tmp_path, monkeypatch):
    committed = (BOARD / "runs.jsonl").read_bytes()
    lines = committed.decode().splitlines()
    outside = json.loads(lines[0])
    outside["case"] = "s19@prior"                     # a tier-4 instance past --per-tier 8
    outside["key"] = outside["key"].replace("|" + json.loads(lines[0])["case"] + "|",
                                            "|s19@prior|")
    sweep = tmp_path / "sweep.jsonl"
    # the sweep's file: a run outside the grid, then the board's runs in another order
    sweep.write_text(json.dumps(outside, sort_keys=True) + "\n"
                     + "\n".join(reversed(lines)) + "\n")
    out = tmp_path / "runs.jsonl"
    out.write_text("stale\n")                         # step 1 overwrites what was there
    monkeypatch.setattr(sys, "argv", ["-", str(sweep), str(out)])
    exec(compile(_snippet(), "leaderboards/README.md", "exec"), {"__name__": "__main__"})
    assert out.read_bytes() == committed


def test_the_readme_commands_are_the_committed_boards():
    """The documented sweep and ``--report-only`` commands are the grid every committed
    table of the main board was published under (their header names the command)."""
    steps = _section(README.read_text(), "## The emafdi-v2 board")
    (report,) = _commands(steps, "--report-only")
    sweeps = [c for c in _commands(steps, "--per-tier") if "--report-only" not in c]
    assert sweeps and all(c == report.replace(" --out leaderboards --report-only",
                                              " --out DIR") for c in sweeps)
    for table in [*BOARD.glob("leaderboard_*.md"), BOARD / "paper_tables.md"]:
        header = table.read_text().splitlines()[2]
        assert header.startswith(f"Produced by `{report}`: "), table.name


def test_no_v2_board_placeholder_is_left_on_a_complete_board():
    """While the committed board is partial its README says so in a marker; once complete,
    every marker (a figure of the full board: cost, validation, answers) must be filled."""
    docs = [ROOT / "README.md", README, *sorted((ROOT / "docs").glob("*.md"))]
    found = [f"{p.relative_to(ROOT)}: {m}" for p in docs for m in MARKER.findall(p.read_text())]
    if _complete():
        assert found == [], "fill these from the full board:\n" + "\n".join(found)
        assert "The committed v2 board is partial" not in README.read_text()
    else:
        assert any("PARTIAL board committed" in f for f in found), found


@pytest.mark.parametrize("name", ["leaderboard_reference.md", "paper_tables.md"])
def test_the_main_board_is_the_v2_suite(name):
    header = (BOARD / name).read_text().splitlines()[2]
    assert "suite emafdi-v2," in header and "--suite emafdi-v2" in header


def test_the_fit_overlay_shows_the_full_case_with_the_prior():
    """``fit_overlay.png`` shows the best fit of ``full`` on v1's problem (tier 4 with the
    prior): a step-only fit has a smaller fitness (one test weighed) and was shown before."""
    from ema_bench.leaderboard.run import overlay_run
    from ema_bench.leaderboard.run_store import read_records

    records = read_records(BOARD / "runs.jsonl")
    full = [r for r in records if r["case"] == "full@prior" and r["track"] == "reference"]
    best = min(r["fitness"] for r in full)
    # a fit of another condition with a smaller fitness (its objective weighs less)
    other = {**full[0], "case": "full@step-only", "fitness": best / 2}
    chosen = overlay_run([other, *records])
    assert chosen["case"] == "full@prior" and chosen["fitness"] == best
