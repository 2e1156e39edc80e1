"""``leaderboard.html``: the leaderboard as one self-contained page (a CI artifact): the
ranking, sanity and per-instance tables of each track, sortable, and the plots embedded."""

from __future__ import annotations

from pathlib import Path

from ..suite import SUITE_ID
from ..trace_cache import MODEL_VERSION
from .anytime import anytime_scores, sanity_scores
from .html import Section, Table, write_html
from .report import _track_note, instance_rows, ranking_rows, sanity_rows


def _table(caption: str, rows: list[dict[str, object]], note: str = "") -> Table:
    cols = list(rows[0]) if rows else ["(no runs)"]
    return Table(caption, cols, [list(r.values()) for r in rows], note=note)


def write_page(records: list[dict], path: Path, header: str, images: list[Path]) -> Path:
    """Write the page of ``records`` to ``path`` (atomically); returns ``path``."""
    scores = anytime_scores(records, per_case=True)
    sanity = sanity_scores(records)
    sections = []
    for track in dict.fromkeys(r["track"] for r in records):
        sections.append(Section(
            f"{track} track", _track_note(track),
            tables=[_table("Ranking by ECDF area (every instance but the sanity case)",
                           ranking_rows(scores, track),
                           "Click a header to sort. Intervals: 95 % bootstrap over runs."),
                    _table("Sanity: the healthy actuator (not ranked)",
                           sanity_rows(sanity, track)),
                    _table("ECDF area per instance", instance_rows(scores, track))]))
    sections.append(Section("Plots", images=images))
    return write_html(path, f"ema-bench leaderboard ({SUITE_ID})", header, sections,
                      footer=f"suite {SUITE_ID}, model version {MODEL_VERSION}")
