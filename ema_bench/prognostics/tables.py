"""The campaign board's Markdown: its table (:func:`score_table`, one row per run and one for
each campaign's oracle) and where trackers lose, its figures by failure mode and by cut
position (:func:`group_tables`).

Each failing unit falls in one group of each kind: its failing fault (``Fst`` friction,
``BLK`` backlash, ``Na`` coil short) and its cut's share of life (``early`` below 0.65,
``mid`` 0.65-0.8, ``late`` from 0.8: thirds of the cut rule's 50-95 %).  Within a group the
figures are the headline's (:func:`~ema_bench.prognostics.scoring.headline`: value, bootstrap
interval, the oracle's on the same units and the paired ratio), computed from a scored run's
per-unit rows alone.
"""

from __future__ import annotations

from collections.abc import Callable

from ..escape import markdown
from .scoring import headline, headline_columns

#: The groups, in table order: name -> membership of a tracker's per-unit row.
GROUPS: dict[str, Callable[[dict], bool]] = {
    "Fst": lambda u: u["failing_fault"] == "Fst",
    "BLK": lambda u: u["failing_fault"] == "BLK",
    "Na": lambda u: u["failing_fault"] == "Na",
    "early": lambda u: u["life_fraction"] < 0.65,
    "mid": lambda u: 0.65 <= u["life_fraction"] < 0.8,
    "late": lambda u: u["life_fraction"] >= 0.8,
}
#: Figures of the group tables: key, header, cell format.
FIGURES = (("expected", "expected within +-20 %", "{:.0%}"),
           ("is95", "95 % interval score", "{:.0f}"),
           ("crps", "CRPS", "{:.1f}"))

#: The figures kept per group (the tables' and the hit rate realised).
KEPT = ("expected", "within", "mae", "is95", "crps")


def by_group(res: dict, n_boot: int = 2000) -> dict[str, dict]:
    """Per group of :data:`GROUPS`: ``units`` (count) and ``headline`` (figure of
    :data:`KEPT` -> value,
    ``ci`` and, when the run was scored with the oracle, ``oracle``, ``ratio``,
    ``ratio_ci``), from ``res`` (:func:`~ema_bench.prognostics.scoring.score_tracking`)."""
    failing = [u for u in res["per_unit"] if u["eol"] is not None]
    oracle = {u["unit"]: u for u in res.get("oracle_per_unit", [])}
    out = {}
    for name, member in GROUPS.items():
        rows = [u for u in failing if member(u)]
        if not rows:
            out[name] = {"units": 0, "headline": {}}
            continue
        cols = headline_columns(rows, res["rul_horizon"], res["alpha"])
        ocols = (headline_columns([oracle[u["unit"]] for u in rows], res["rul_horizon"],
                                  res["alpha"]) if oracle else None)
        h = headline(cols, ocols, n_boot)
        out[name] = {"units": len(rows), "headline": {k: h[k] for k in KEPT}}
    return out


def _fmt(v: float | None, fmt: str) -> str:
    if v is None or v != v:
        return "-"
    return "inf" if abs(v) == float("inf") else fmt.format(v)


def group_tables(results: list[dict]) -> list[str]:
    """Markdown: per figure of :data:`FIGURES` and track, a table with one row per run and
    one for the oracle, one column per group (value, and the ratio to the oracle in
    brackets).  ``results``: scored runs, each with its ``groups`` (:func:`by_group`)."""
    lines: list[str] = []
    tracks = list(dict.fromkeys(r["track"] for r in results))
    for key, header, fmt in FIGURES:
        for track in tracks:
            runs = [r for r in results if r["track"] == track]
            g0 = runs[0]["groups"]
            lines += ["", f"**{header} by failing fault and cut position, {track} track** "
                      "(value, `/ oracle` in brackets; units per group in the header)", "",
                      "| tracker | " + " | ".join(f"{g} ({g0[g]['units']})" for g in GROUPS)
                      + " |", "|---|" + "---|" * len(GROUPS)]
            for r in runs:
                cells = []
                for g in GROUPS:
                    h = r["groups"][g]["headline"].get(key, {})
                    cell = _fmt(h.get("value"), fmt)
                    if "ratio" in h and h["ratio"] == h["ratio"]:
                        cell += f" ({h['ratio']:.2f})"
                    cells.append(cell)
                lines.append(f"| {markdown(r['tracker'])} | " + " | ".join(cells) + " |")
            cells = [_fmt(g0[g]["headline"].get(key, {}).get("oracle"), fmt) for g in GROUPS]
            lines.append("| **oracle** | " + " | ".join(cells) + " |")
    return lines


# --- the board's table ------------------------------------------------------------------------

def _cell(h: dict, fmt: str) -> str:
    if h["value"] != h["value"]:   # not scored (no oracle, no quantiles given)
        return "-"
    lo, hi = h["ci"]
    return f"{_fmt(h['value'], fmt)} [{_fmt(lo, fmt)}, {_fmt(hi, fmt)}]"


def _ratio_cell(h: dict) -> str:
    return _cell({"value": h["ratio"], "ci": h["ratio_ci"]}, "{:.2f}") if "ratio" in h else "-"


#: Headline columns of the table: figure, header, format (the expected hit rate first: the
#: board's headline, free of the luck of the units' futures).
_HEAD = (("expected", "E within +-20 %", "{:.1%}"), ("within", "within +-20 %", "{:.0%}"),
         ("mae", "MAE", "{:.1f}"), ("rmse", "RMSE", "{:.1f}"),
         ("phm08", "PHM08/unit", "{:.3g}"), ("phm08_median", "PHM08 median", "{:.3g}"),
         ("coverage", "95 % cover", "{:.0%}"), ("width", "width", "{:.0f}"),
         ("is95", "IS 95 %", "{:.0f}"), ("crps", "CRPS", "{:.1f}"),
         ("cov50", "50 / 80 % cover", "{:.0%}"))
#: Ratio columns (to the oracle).
_RATIOS = (("expected", "E within / oracle"), ("within", "within / oracle"),
           ("mae", "MAE / oracle"), ("is95", "IS 95 % / oracle"), ("crps", "CRPS / oracle"))


def _head_cell(h: dict, k: str, fmt: str) -> str:
    """A headline cell; the 50 / 80 % coverages share one (without intervals)."""
    if k == "cov50":
        return f"{_fmt(h['cov50']['value'], fmt)} / {_fmt(h['cov80']['value'], fmt)}"
    return _cell(h[k], fmt)


def score_table(results: list[dict]) -> list[str]:
    """The Markdown table of scored runs: one row per run, then one per campaign for its
    oracle (when scored).  Tracker names come from plugins: escaped (``escape.markdown``)."""
    head = (["tracker", "track", "units", "failing"] + [h for _, h, _ in _HEAD]
            + [h for _, h in _RATIOS]
            + ["false / early repl.", "fail in service", "cost/unit", "PH / strict"])
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    oracles: dict[tuple, dict] = {}
    for r in results:
        h, d, g = r["headline"], r["decisions"], r["diagnostics"]
        scored = ("" if not r.get("tracked_only") else
                  f" (partial: {r['scored_units']} tracked)")
        cells = [markdown(r["tracker"]) + scored, markdown(r["track"]), str(r["units"]),
                 str(r["failing_units"])]
        cells += [_head_cell(h, k, fmt) for k, _, fmt in _HEAD]
        cells += [_ratio_cell(h[k]) for k, _ in _RATIOS]
        cells += [f"{d['false_replacements']} / {d['early_replacements']}",
                  str(d["failures_in_service"]), _fmt(d["maintenance_cost"], "{:.2f}"),
                  f"{_fmt(g['prognostic_horizon'], '{:.0f}')} / "
                  f"{_fmt(g['prognostic_horizon_strict'], '{:.0f}')}"]
        lines.append("| " + " | ".join(cells) + " |")
        if "oracle" in h["within"]:
            oracles.setdefault((r["campaign"], r["track"], r["scored_units"]), r)
    for (_, track, _), r in oracles.items():
        h = r["headline"]
        scored = ("" if not r.get("tracked_only") else
                  f" (on the {r['scored_units']} units of {markdown(r['tracker'])})")
        cells = ["**oracle**" + scored, track, str(r["units"]), str(r["failing_units"])]
        cells += [_head_cell({k: {"value": h[k]["oracle"], "ci": h[k]["oracle_ci"]}
                              for k in h}, k, fmt) for k, _, fmt in _HEAD]
        cells += ["1"] * len(_RATIOS) + ["-"] * 4
        lines.append("| " + " | ".join(cells) + " |")
    return lines
