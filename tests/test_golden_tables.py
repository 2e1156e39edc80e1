"""Every committed leaderboard table is what the code makes of the committed records.

Each folder of ``leaderboards/`` with tables is rebuilt here from its ``runs.jsonl`` (the
tables only: ``leaderboard_<track>.md`` / ``.csv`` and ``paper_tables.md``, with the header
line they were published under) and compared byte for byte.  A change of the scoring, the
re-derivation or the formatting that moves a published figure fails here until the tables
are regenerated (``ema-bench leaderboard ... --report-only``, commands in
``leaderboards/README.md``).  Cost: the main board (emafdi-v2) about 1 CPU-s at its partial
362 runs, about 5 CPU-s expected at 2400 (measured on 2172 records: 3.6 CPU-s; the v1 board's
5280 runs took 7).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from ema_bench.leaderboard.report import (
    load_paper_results,
    write_leaderboards,
    write_paper_tables,
)
from ema_bench.leaderboard.run_store import is_error, read_records
from ema_bench.leaderboard.scores import score_records

BOARDS = Path(__file__).resolve().parents[1] / "leaderboards"
FOLDERS = [p.parent for p in sorted(BOARDS.glob("**/leaderboard_*.md"))
           if (p.parent / "runs.jsonl").exists()]


def _header(path: Path) -> str:
    """The header line a table was published under (its third line: the command)."""
    return path.read_text().splitlines()[2]


@pytest.mark.parametrize("folder", sorted(set(FOLDERS)), ids=lambda p: str(p.relative_to(BOARDS))
                         or "main")
def test_committed_tables_are_regenerated_byte_for_byte(folder, tmp_path):
    records = read_records(folder / "runs.jsonl")
    tables = sorted(folder.glob("leaderboard_*.md"))
    written = write_leaderboards(records, tmp_path, _header(tables[0]))
    names = {p.name for p in written}
    assert names == {p.name for p in folder.glob("leaderboard_*.*")}
    if (folder / "paper_tables.md").exists():
        finished = [r for r in records if not is_error(r)]
        written.append(write_paper_tables(finished, score_records(records), tmp_path,
                                          _header(folder / "paper_tables.md"),
                                          load_paper_results()))
    for path in written:
        assert path.read_bytes() == (folder / path.name).read_bytes(), path.name


def test_the_tables_hold_plain_numbers():
    for csv_path in BOARDS.glob("**/leaderboard_*.csv"):
        text = csv_path.read_text()
        assert "np.float64" not in text and "np." not in text, csv_path
