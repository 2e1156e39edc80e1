"""``leaderboard.html``: the leaderboard as one self-contained page (a CI artifact, and the
page GitHub Pages publishes): the ranking, sanity and per-instance tables of each track,
sortable (the first click puts the better end first), and the plots embedded.  An emafdi-v2
or -v3 board shows instead, per track, the saturation check, the claims by instance (which
hold, which are fragile, why a tier cannot separate its best and fifth solvers, and their
table), the global-vs-local answer and table, the ERT scaling table and one ranking per tier
and condition.

The page is made to be shared: the command line in its header names no local folder (the
values of ``--out``, ``--check`` and ``--scheduler`` read ``OUT``, ``DIR`` and ``ADDRESS``),
and fixed-budget precisions are shown floored at 0 (a fit below the best-known ``f*`` fits the
noise a little better than the best fit found; it has reached every target)."""

from __future__ import annotations

import re
from pathlib import Path

from ..suites import board_suite, case_order
from . import by_instance, scaling
from .anytime import anytime_scores, sanity_scores
from .html import Section, Table, write_html
from .report import (
    _track_note,
    global_local_rows,
    group_heading,
    group_targets,
    instance_rows,
    ranking_rows,
    sanity_rows,
    scaling_rows,
)

#: options whose value is a local path or address, and what the page shows instead
_LOCAL = {"--out": "OUT", "--check": "DIR", "--scheduler": "ADDRESS"}
_LOCAL_RE = re.compile(r"(?P<opt>" + "|".join(map(re.escape, _LOCAL)) +
                       r")(?P<sep>[ =])(?P<val>(?!-)(?:'[^']*'|[^\s`]+))")
PRECISION_NOTE = ("Precision (f - f*) / (f_nominal - f*) is shown floored at 0: below 0 a fit "
                  "beats the best-known f* (it fits the noise a little better than the best "
                  "fit found) and has reached every fitness target.")


def shareable(header: str) -> str:
    """``header`` with the values of path-like options (``--out DIR``) replaced by their
    generic names (``OUT``, ``DIR``, ``ADDRESS``): a published page must not show the folders
    of the machine that made it."""
    return _LOCAL_RE.sub(lambda m: f"{m['opt']}{m['sep']}{_LOCAL[m['opt']]}", header)


def higher_better(columns: list[str]) -> list[str]:
    """The columns where a larger value is better: areas, hit rates, the sanity count and
    the per-instance areas (named by instance)."""
    instances = set(case_order())
    return [c for c in columns
            if "area" in c or "reached" in c or c.startswith("stayed")
            or c in instances]


def _floored(rows: list[dict[str, object]]) -> list[dict[str, object]]:
    return [{k: (max(0.0, v) if k.startswith("median precision") and isinstance(v, float)
                 and v == v else v) for k, v in r.items()} for r in rows]


def _table(caption: str, rows: list[dict[str, object]], note: str = "") -> Table:
    cols = list(rows[0]) if rows else ["(no runs)"]
    return Table(caption, cols, [list(r.values()) for r in rows], note=note,
                 higher_better=higher_better(cols))


def write_page(records: list[dict], path: Path, header: str, images: list[Path]) -> Path:
    """Write the page of ``records`` to ``path`` (atomically); returns ``path``."""
    suite = board_suite(records)
    if suite.grouped:
        return write_html(path, f"ema-bench leaderboard ({suite.id})", shareable(header),
                          [*v2_sections(records), Section("Plots", images=images)],
                          footer=f"suite {suite.id}, model version {suite.model_version}")
    scores = anytime_scores(records, per_case=True)
    sanity = sanity_scores(records)
    sections = [Section(
        f"{track} track", _track_note(track),
        tables=[_table("Ranking by ECDF area (every instance but the sanity case)",
                       _floored(ranking_rows(scores, track)),
                       "Click a header to sort (the first click puts the better end "
                       "first). Intervals: 95 % bootstrap over runs. " + PRECISION_NOTE),
                _table("Sanity: the healthy actuator (not ranked)", sanity_rows(sanity, track)),
                _table("ECDF area per instance", instance_rows(scores, track))])
        for track in dict.fromkeys(r["track"] for r in records)]
    return write_html(path, f"ema-bench leaderboard ({suite.id})", shareable(header),
                      [*sections, Section("Plots", images=images)],
                      footer=f"suite {suite.id}, model version {suite.model_version}")


def v2_sections(records: list[dict]) -> list[Section]:
    """emafdi-v2, per track: the saturation check and the global-vs-local answer (text), the
    global-vs-local and ERT scaling tables, then one ranking per tier and condition (the
    tables of ``leaderboard_<track>.md``, :func:`.report.v2_markdown`)."""
    grouped = scaling.group_scores(records)
    gl = scaling.global_vs_local(records)
    prior = scaling.global_vs_local(records, "prior")
    points = scaling.scaling_points(grouped)
    cs = by_instance.claims(records)
    sections = []
    for track in dict.fromkeys(r["track"] for r in records):
        text = "\n\n".join([_track_note(track), *scaling.saturation_lines(records, grouped,
                                                                         track),
                             by_instance.fragile_line(cs, track),
                             *by_instance.separation_lines(cs, records, track),
                             scaling.answer(gl, track)])
        tables = [_table("Claims by instance", by_instance.claim_rows(cs, track),
                         by_instance.CLAIMS_NOTE),
                  _table("Global vs local search without a prior (paired per instance and "
                         "seed)", global_local_rows(gl, prior, track),
                         "Groups: the scope each solver declares where it is registered "
                         "(ema-bench solvers). Intervals: 95 % bootstrap over (instance, "
                         "seed) pairs."),
                  _table("ERT to the 1 % parameter target per tier", scaling_rows(points,
                                                                                 track))]
        for (tr, tier, cond), recs in scaling.groups(records).items():
            if tr == track:
                tables.append(_table(
                    f"Ranking by ECDF area: {group_heading(tier, cond, recs)}",
                    _floored(ranking_rows(grouped, track, scaling.group_label(tier, cond))),
                    group_targets(tier, recs) + " Intervals: 95 % bootstrap over runs. "
                    + PRECISION_NOTE))
        sections.append(Section(f"{track} track", text, tables=tables))
    return sections
