"""The emafdi-v3 board is the one ``leaderboards/README.md`` describes, while it runs and once
it is complete.

Its documented sweep command is docs/suite-v3.md's and ``--report-only`` is that command's
report; every record in the committed store is one of that command's runs (its budget and
root seed, once each: a smoke run written into the folder by mistake, or a run appended
twice, fails); and once the store holds every planned run and the tables are written, no
``<!-- v3-board: ... -->`` placeholder survives and every table names the documented report
command in its header.  About 3 CPU-s (the zoo's imports and reading the store).
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
BOARD = ROOT / "leaderboards" / "v3"
README = ROOT / "leaderboards" / "README.md"
MARKER = re.compile(r"<!-- v3-board: (.*?) -->", re.S)


def _commands(text: str) -> list[str]:
    """The ``ema-bench leaderboard --suite emafdi-v3`` commands of indented code blocks,
    their continuation lines joined."""
    joined = re.sub(r"\\\n\s*", "", text)
    return [" ".join(line.split()) for line in joined.splitlines()
            if line.strip().startswith(("ema-bench leaderboard --suite emafdi-v3",
                                        "nice ema-bench leaderboard --suite emafdi-v3"))]


def _section(text: str, title: str) -> str:
    return text.split(title, 1)[1].split("\n## ", 1)[0]


@pytest.fixture(scope="module")
def plan() -> dict:
    """The README's sweep command and its runs: the plan ``benchmarks/board_cost.py`` holds,
    which ``tests/test_board_cost.py`` holds to docs/suite-v3.md's command (and the first
    test here the README's to the same)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        from board_cost import plan_tasks
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    sweep, = [c for c in _commands(_section(README.read_text(), "## The emafdi-v3 board"))
              if "--report-only" not in c]
    return {"sweep": sweep, "tasks": {t.key: t for t in plan_tasks()}}


def test_the_readme_commands_are_the_documented_plans(plan):
    readme = _section(README.read_text(), "## The emafdi-v3 board")
    report, = [c for c in _commands(readme) if "--report-only" in c]
    assert report == plan["sweep"] + " --report-only"
    docs = [c.removeprefix("nice ") for c in
            _commands((ROOT / "docs" / "suite-v3.md").read_text()) if "--solvers cmaes," in c]
    assert docs and all(c == plan["sweep"] for c in docs)
    assert len(plan["tasks"]) == 5936


def test_every_committed_record_is_a_run_of_the_plan_once(plan):
    lines = (BOARD / "runs.jsonl").read_text().splitlines()
    keys = []
    for ln in lines:
        r = json.loads(ln)
        t = plan["tasks"].get(r["key"])
        assert t is not None, f"{r['key']}: not a run of the documented sweep"
        assert (r["solver"], r["case"], r["track"], r["seed"], r["budget"],
                r.get("root_seed", 0), r["suite"]) == (t.solver, t.case, t.track, t.seed,
                                                       t.budget, t.root_seed, "emafdi-v3")
        keys.append(r["key"])
    assert len(set(keys)) == len(keys)


def test_a_complete_board_has_its_figures_and_its_tables_name_the_command(plan):
    n = len((BOARD / "runs.jsonl").read_text().splitlines())
    table = BOARD / "leaderboard_reference.md"
    complete = n == len(plan["tasks"]) and table.is_file() \
        and "PARTIAL" not in table.read_text().splitlines()[2]
    left = [(p.relative_to(ROOT), m.group(1)[:60])
            for p in [README, *(ROOT / "docs").glob("*.md")]
            for m in MARKER.finditer(p.read_text())]
    if not complete:
        # running: the placeholders are there to be filled, and no table is published
        assert left and not table.is_file()
        return
    assert not left, f"unfilled v3-board placeholders: {left}"
    for t in [*BOARD.glob("leaderboard_*.md"), BOARD / "paper_tables.md"]:
        header = t.read_text().splitlines()[2]
        assert header.startswith(f"Produced by `{plan['sweep']} --report-only`: "), t.name


def _claim_row(c: dict) -> str:
    """The README's row of one claim of ``summary.json``'s ``claims_by_instance``."""
    d, w = c["diff"], c.get("without_diff")
    side = lambda names: ", ".join(names)          # noqa: E731
    left = (f"without {c['without']}: {side(c['without_a'])} vs {side(c['without_b'])} "
            f"{d_fmt(w)}" if w else "-")
    return (f"| {c['track']} | {c['tier']} | {c['claim']} | {side(c['a'])} vs {side(c['b'])} "
            f"| {c['instances']} | {d_fmt(d)} | {left} | {c['verdict']} |")


def d_fmt(d: list[float]) -> str:
    return f"{d[0]:+.3f} [{d[1]:+.3f}, {d[2]:+.3f}]"


def test_a_complete_boards_answers_quote_its_claims_by_instance(plan):
    """Once complete, the README's v3 answers hold one row per claim of ``summary.json``
    (track, tier, claim, sides, instances, the interval over instances, the leave-one-out
    line, the verdict): an answer written from another store, or from a partial one, fails."""
    summary = BOARD / "summary.json"
    if not summary.is_file() or json.loads(summary.read_text())["runs"] != len(plan["tasks"]):
        pytest.skip("the v3 board is not complete: its answers are not written yet")
    readme = _section(README.read_text(), "## The emafdi-v3 board")
    claims = json.loads(summary.read_text())["claims_by_instance"]
    assert claims
    missing = [_claim_row(c) for c in claims if _claim_row(c) not in readme]
    assert not missing, "\n".join(missing)


def test_a_sample_of_the_committed_records_has_the_fitness_it_claims():
    """A record of the store edited to a better fitness than its vectors have is refused:
    a sample drawn from fresh entropy each run (its seed in the message) is re-evaluated
    (``check_record``, the same check as ``ema-bench validate``, about 25 ms a record; the
    whole store, 144 CPU-s, is README step 2's), and one of them edited is refused."""
    import secrets

    from ema_bench.leaderboard.validate import check_record

    lines = (BOARD / "runs.jsonl").read_text().splitlines()
    seed = secrets.randbits(32)
    picked = [json.loads(lines[i]) for i in
              np.random.default_rng(seed).choice(len(lines), 24, replace=False)]
    bad = {r["key"]: m for r in picked if (m := check_record(r))}
    assert not bad, f"sample seed {seed}: {bad}"
    r = picked[0]
    forged = {**r, "fitness": r["fitness"] * 0.5}
    assert check_record(forged), f"sample seed {seed}: a halved fitness passed"
