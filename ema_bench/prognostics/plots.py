"""Plots of a tracked campaign: one unit's faults and prediction cone, RUL against true RUL
with the alpha-lambda cone, the fleet's RUL errors at the cut per tracker, and the
alpha-lambda diagnostic curve over lambda per tracker (matplotlib, Agg)."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence

import numpy as np

from ..faults import FAULT_INDEX, FAULT_UNITS
from ..plots import plt, save_figure


def _truth_path(truth: Mapping) -> tuple[np.ndarray, np.ndarray]:
    """Flights and true faults (k, 4) of a unit: its inspections, then its hidden future."""
    pts = {int(f): v for f, v in truth["faults"].items()}
    pts.update({int(f): v for f, v in (truth.get("faults_after") or {}).items()})
    flights = np.array(sorted(pts))
    return flights, np.array([pts[f] for f in flights], dtype=float)


def _finish(fig: plt.Figure, ax: plt.Axes, path: str | os.PathLike, title: str,
            legend: str | None = "best", grid: str = "both") -> None:
    """The end of a one-axes plot: a grid (on ``grid``'s axes), the legend (at ``legend``;
    None: no legend), the title, and the figure saved to ``path`` and closed."""
    ax.grid(alpha=0.3, axis=grid)
    if legend is not None:
        ax.legend(fontsize=8, loc=legend)
    ax.set_title(title, fontsize=10)
    save_figure(fig, path)


def plot_unit(rows: Sequence[Mapping], truth: Mapping, thresholds: Mapping[str, float],
              path: str | os.PathLike, title: str = "") -> None:
    """A unit's failing faults over flights: the truth (dashed past the last inspection), the
    tracker's estimates with their 95 % intervals, the threshold, and the prediction cone of
    the last inspection (from its estimate to the threshold at the predicted end of life,
    median and 95 % RUL interval).

    ``rows``: the unit's steps of ``track.jsonl`` in flight order; ``truth``: its record of
    ``truth.json``.  Saves a PNG to ``path``."""
    names = list(thresholds)
    fig, axes = plt.subplots(1, len(names), figsize=(4.6 * len(names), 3.6), squeeze=False)
    flights, true = _truth_path(truth)
    last = int(truth["last_flight"])
    fl = np.array([r["flight"] for r in rows], dtype=float)
    final = rows[-1] if rows else None
    for ax, name in zip(axes[0], names):
        j = FAULT_INDEX[name]
        seen = flights <= last
        ax.plot(flights[seen], true[seen, j], "k-", lw=1.2, label="truth")
        ax.plot(flights[flights >= last], true[flights >= last, j], "k--", lw=1.0,
                label="truth (hidden)")
        if rows:
            est = np.array([r["estimate"][name] for r in rows])
            lo = np.array([r["low"][name] for r in rows])
            hi = np.array([r["high"][name] for r in rows])
            ax.errorbar(fl, est, yerr=[est - lo, hi - est], fmt="o", ms=3, lw=0.8,
                        color="C0", label="estimate, 95 %")
        thr = thresholds[name]
        ax.axhline(thr, color="C3", lw=1.0, label="threshold")
        if final is not None and final.get("failing_fault") == name and \
                math.isfinite(final["rul"]):
            f0, x0 = final["flight"], final["estimate"][name]
            for rul, style in ((final["rul"], "-"), (final["rul_low"], ":"),
                               (final["rul_high"], ":")):
                if math.isfinite(rul):
                    ax.plot([f0, f0 + rul], [x0, thr], style, color="C1", lw=1.2)
            ax.plot([], [], "-", color="C1", label="predicted EOL (median, 95 %)")
        if truth.get("eol") is not None:
            ax.axvline(truth["eol"], color="0.5", lw=0.8, ls="-.", label="true EOL")
        ax.set_xlabel("flight")
        ax.set_ylabel(f"{name} [{FAULT_UNITS[name]}]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(title or f"unit {truth['unit']}", fontsize=10)
    save_figure(fig, path)


def plot_rul(units: Mapping[str, Sequence[Mapping]], truth: Mapping[str, Mapping],
             path: str | os.PathLike, alpha: float = 0.2, title: str = "") -> None:
    """Predicted against true RUL over each failing unit's life (x: true RUL, counting down),
    with 95 % RUL intervals and the alpha cone ``(1 +- alpha)`` true RUL.  ``units``: unit ->
    its steps of ``track.jsonl``.  Saves a PNG to ``path``."""
    fig, ax = plt.subplots(figsize=(6.2, 5.0))
    top = 1.0
    for k, (unit, rows) in enumerate(sorted(units.items())):
        eol = truth[unit].get("eol")
        if eol is None or not rows:
            continue
        t = np.array([eol - r["flight"] for r in rows], dtype=float)
        p = np.array([r["rul"] for r in rows], dtype=float)
        lo = np.array([r["rul_low"] for r in rows], dtype=float)
        hi = np.array([r["rul_high"] for r in rows], dtype=float)
        top = max(top, float(t.max()))
        c = f"C{k % 10}"
        ax.plot(t, np.minimum(p, 3 * t.max()), "-o", ms=2.5, lw=0.8, color=c)
        ax.fill_between(t, lo, np.minimum(hi, 3 * t.max()), color=c, alpha=0.08, lw=0)
    x = np.array([0.0, top])
    ax.plot(x, x, "k-", lw=1.0, label="perfect")
    ax.fill_between(x, (1 - alpha) * x, (1 + alpha) * x, color="k", alpha=0.12,
                    label=f"alpha = {alpha:g} cone")
    ax.set_xlim(top * 1.02, 0)     # time runs left to right: RUL counts down
    ax.set_ylim(0, 2.0 * top)
    ax.set_xlabel("true RUL [flights]")
    ax.set_ylabel("predicted RUL [flights] (median, 95 % band)")
    _finish(fig, ax, path, title or "RUL predictions over life", legend="upper left")


def plot_errors(errors: Mapping[str, Sequence[float]], path: str | os.PathLike,
                title: str = "") -> None:
    """The fleet's RUL errors (predicted - true, flights; late > 0) per tracker, as box plots
    with every unit's point.  Saves a PNG to ``path``."""
    names = list(errors)
    fig, ax = plt.subplots(figsize=(1.6 + 1.4 * len(names), 4.2))
    data = [np.asarray(errors[n], dtype=float) for n in names]
    data = [d[np.isfinite(d)] for d in data]
    ax.boxplot(data, showfliers=False)
    ax.set_xticks(range(1, len(names) + 1), names)
    rng = np.random.default_rng(0)   # jitter only
    for i, d in enumerate(data, start=1):
        ax.plot(i + rng.uniform(-0.12, 0.12, d.size), d, "o", ms=3, alpha=0.6)
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_ylabel("RUL error at the cut [flights] (late > 0)")
    _finish(fig, ax, path, title or "RUL error over the fleet", legend=None, grid="y")


#: Trackers drawn dashed in :func:`plot_alpha_lambda`: the no-sensing references.
REFERENCES = ("rul-age", "life-table")


def plot_alpha_lambda(curves: Mapping[str, Mapping[str, Mapping]], path: str | os.PathLike,
                      alpha: float = 0.2, title: str = "") -> None:
    """The alpha-lambda diagnostic: per tracker, the share of failing units whose prediction at
    lambda of their life lies within ``+-alpha``, over lambda; the no-sensing references
    (:data:`REFERENCES`) dashed beside the trackers.  ``curves``: tracker -> lambda (str) ->
    ``{"share", "units"}`` (``score_tracking(...)["diagnostics"]["alpha_lambda"]``).  Saves a
    PNG to ``path``."""
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for k, (name, curve) in enumerate(curves.items()):
        lam = np.array([float(x) for x in curve])
        share = np.array([c["share"] for c in curve.values()], dtype=float)
        ref = name in REFERENCES
        ax.plot(lam, share, "--" if ref else "-o", ms=4, color=f"C{k % 10}", lw=1.2,
                label=name + (" (no sensing)" if ref else ""))
    ax.set_xlabel("lambda (share of life from the first inspection)")
    ax.set_ylabel(f"share within +-{alpha:.0%} of the true RUL")
    ax.set_ylim(-0.02, 1.02)
    _finish(fig, ax, path, title or "alpha-lambda over lambda (diagnostic)")


def plot_reliability(points: Mapping[str, Mapping[str, float]], path: str | os.PathLike,
                     title: str = "") -> None:
    """Reliability diagram: per tracker (and the oracle), the observed coverage of its
    central RUL intervals at the cut against their nominal level (50, 80, 95 %; a tracker that
    gives only its 95 % interval is one point), the diagonal for perfect calibration.
    ``points``: name -> level key -> observed share (``score_tracking(...)["reliability"]``).
    Saves a PNG to ``path``."""
    fig, ax = plt.subplots(figsize=(5.0, 4.6))
    ax.plot([0, 1], [0, 1], color="0.6", lw=1, ls=":", label="calibrated")
    for k, (name, pts) in enumerate(points.items()):
        nominal = np.array([float(x) for x in pts])
        observed = np.array(list(pts.values()), dtype=float)
        ax.plot(nominal, observed, "-s" if name == "oracle" else "-o", ms=5,
                color="k" if name == "oracle" else f"C{k % 10}", lw=1.2, label=name)
    ax.set_xlabel("nominal level of the central RUL interval")
    ax.set_ylabel("observed share holding the true RUL")
    ax.set_xlim(0.4, 1.0)
    ax.set_ylim(0.0, 1.02)
    _finish(fig, ax, path, title or "reliability of the RUL intervals at the cut")
