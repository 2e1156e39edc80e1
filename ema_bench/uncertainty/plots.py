"""Pictures of a fit's uncertainty: profile curves, the confidence region in the paper's
Figure 5 plane, and the coverage of many intervals against the truth ("caterpillar").

Every function saves a PNG (matplotlib, the non-interactive backend of
:mod:`ema_bench.plots`) and closes its figure.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.patches import Rectangle
from matplotlib.ticker import MaxNLocator
from scipy.stats import chi2

from ..faults import FAULT_NAMES, LOWER, UPPER
from ..objective import Objective
from ..plots import plt, save_figure
from .methods import Intervals

#: Half-width of the zoom window of :func:`plot_region`, in interval half-widths.
ZOOM = 2.5
#: Points on the drawn Laplace parabolas and ellipses.
_CURVE_POINTS = 200


def _label(iv: Intervals, name: str) -> str:
    """Axis label ``name [unit]``."""
    return f"{name} [{iv.units.get(name, '')}]"


def _index(iv: Intervals, name: str) -> int:
    if name not in iv.names:
        raise ValueError(f"unknown parameter {name!r}; the intervals have {list(iv.names)}")
    return iv.names.index(name)


def plot_profiles(iv: Intervals, path: str | os.PathLike,
                  truth: np.ndarray | None = None) -> None:
    """Profile-likelihood curves of a profile fit, one panel per parameter.

    Each panel shows the chi-square-scale profile drop ``q`` (dimensionless, 0 at the
    estimate) against the parameter value (physical units), the threshold
    ``chi2.ppf(level, 1)``, the estimate, the final interval ``[low, high]`` (shaded; the
    calibration factor and any model-form allowance can make it wider than the threshold
    crossing), and the Laplace parabola ``q = ((v - estimate) / se)^2`` with
    ``se = sqrt(cov[j, j])`` (dashed): where the profile leaves the parabola the valley is
    curved or bounded.

    Parameters
    ----------
    iv : Intervals
        Intervals computed with ``method="profile"`` (they carry ``profiles``).
    path : str or PathLike
        Where the PNG goes.
    truth : array (dim,), optional
        True parameter values (physical units, ``iv.names`` order), drawn in red.

    Raises
    ------
    ValueError
        ``iv`` has no profiles (only the ``profile`` method computes them), or ``truth`` is
        shorter than the parameters.
    """
    items = [(j, p) for j, p in enumerate(iv.profiles) if p is not None]
    if not items:
        raise ValueError(f"no profiles in these {iv.method!r} intervals: profiles come from "
                         "intervals(..., method='profile')")
    if truth is not None:
        truth = np.asarray(truth, dtype=float).ravel()
        if truth.size < len(iv.profiles):
            raise ValueError(f"truth has {truth.size} values, the profiles "
                             f"{len(iv.profiles)}")
    threshold = float(chi2.ppf(iv.level, 1))
    k = len(items)
    ncols = min(k, 4)
    nrows = math.ceil(k / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.6 * ncols, 3.2 * nrows + 0.3),
                             squeeze=False)
    for ax, (j, prof) in zip(axes.flat, items):
        name = iv.names[j]
        v = np.asarray(prof["value"], dtype=float)
        q = np.asarray(prof["q"], dtype=float)
        est, lo, hi = iv.estimate[j], iv.low[j], iv.high[j]
        # the x range holds every profile point, the interval and the truth, with a margin
        pts = [v, [lo, hi, est]] + ([[truth[j]]] if truth is not None else [])
        span = np.concatenate([np.asarray(p, dtype=float) for p in pts])
        a, b = float(span.min()), float(span.max())
        pad = 0.08 * (b - a) if b > a else 1e-6 * (iv.upper[j] - iv.lower[j])
        grid = np.linspace(a - pad, b + pad, _CURVE_POINTS)
        ax.axvspan(lo, hi, color="tab:blue", alpha=0.15, label=f"interval ({iv.method})")
        se = math.sqrt(max(float(iv.cov[j, j]), 0.0))
        if se > 0:
            ax.plot(grid, ((grid - est) / se) ** 2, "--", color="0.4", lw=1.0,
                    label="Laplace parabola")
        # a profile has a few points per side: a faint line, so it reads as points
        ax.plot(v, q, "o-", color="tab:blue", ms=4, lw=0.8, alpha=0.8, label="profile points")
        ax.axhline(threshold, color="k", ls=":", lw=1.0,
                   label=f"chi2_1({iv.level:g}) = {threshold:.2f}")
        ax.axvline(est, color="k", lw=1.0, label="estimate")
        if truth is not None:
            ax.axvline(truth[j], color="red", lw=1.2, label="truth")
        # the parabola grows without bound on a wide x range: keep the profile readable
        top = max(float(np.nanmax(q)) if q.size else 0.0, threshold)
        ax.set_ylim(0.0, 1.3 * top)
        ax.set_xlim(grid[0], grid[-1])
        ax.set_xlabel(_label(iv, name))
        ax.xaxis.set_major_locator(MaxNLocator(4))  # long tick labels of narrow ranges
        title = name
        if iv.factor[j] != 1.0:
            title += f" (half-widths x{iv.factor[j]:.2g})"
        if prof.get("better") is not None:
            # a profile refit beat the fit: it was not at the optimum, the curve is suspect
            title += f"\nlower fitness found: {prof['better']:.3g}"
        ax.set_title(title, fontsize=9)
        ax.grid(alpha=0.3)
    for ax in axes.flat[k:]:
        ax.set_visible(False)
    for row in axes:
        row[0].set_ylabel("profile drop q (chi-square scale)")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    # below the panels, where it hides no curve
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=7,
               frameon=False)
    fig.suptitle(f"Profile likelihood, level {iv.level:g} (fit fitness {iv.fitness:.3g})",
                 fontsize=10)
    save_figure(fig, path, rect=(0.0, 0.07 / nrows, 1.0, 1.0))


def _fitness_grid(objective: Objective, base: np.ndarray, ix: int, iy: int,
                  xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Fitness over the ``ys x xs`` grid of parameters ``iy``, ``ix`` (the others at
    ``base``), shape ``(len(ys), len(xs))``: one batched monitor call."""
    XX, YY = np.meshgrid(xs, ys)
    X = np.tile(base, (XX.size, 1))
    X[:, ix], X[:, iy] = XX.ravel(), YY.ravel()
    return objective.evaluate(objective.space.check(X))[0].reshape(XX.shape)


def _ellipse(centre: np.ndarray, cov: np.ndarray, c: float) -> np.ndarray:
    """Points (2, m) of ``{p : (p - centre)' cov^-1 (p - centre) = c}`` (a segment where
    ``cov`` is singular)."""
    w, V = np.linalg.eigh(cov)
    t = np.linspace(0.0, 2.0 * np.pi, _CURVE_POINTS)
    # round-off can make a near-singular block's small eigenvalue slightly negative
    return centre[:, None] + (V * np.sqrt(np.clip(w, 0.0, None) * c)) @ np.vstack(
        [np.cos(t), np.sin(t)])


def plot_region(objective: Objective, iv: Intervals, path: str | os.PathLike,
                pair: tuple[str, str] = ("Na", "Fst"), truth: np.ndarray | None = None,
                n: int = 31) -> None:
    """The confidence region of two parameters in their fitness plane (the paper's
    Figure 5 plane for the default pair).

    Left: log10 fitness over the whole plane of ``pair`` within its bounds (``n x n`` grid,
    the other parameters at the estimate), the estimate and a rectangle showing the zoom
    window.  Right: the zoom window, ``estimate +- 2.5`` interval half-widths (clipped to
    the bounds), coloured by the fitness rise above the estimate's (linear), with the
    Laplace joint confidence ellipse (``chi2.ppf(level, 2)``, from the pair's block of
    ``iv.cov``) and the rectangle of the two per-parameter intervals ``[low, high]``.
    As in Figure 5, ``pair[0]`` is on the vertical axis and ``pair[1]`` on the horizontal.

    Parameters
    ----------
    objective : Objective
        The objective the intervals are of (``problem.objective``); ``2 n^2`` evaluations,
        not counted against any budget.
    iv : Intervals
        Intervals of a fit of ``objective`` (any method).
    path : str or PathLike
        Where the PNG goes.
    pair : (str, str)
        Names of the (vertical, horizontal) parameters.
    truth : array (dim,), optional
        True parameter values (physical units, ``iv.names`` order), a red star.
    n : int
        Grid points per axis of each panel.

    Raises
    ------
    ValueError
        Unknown or repeated names in ``pair``, ``n < 2``, or ``objective`` searches other
        parameters than ``iv``.
    """
    if tuple(objective.space.names) != tuple(iv.names):
        raise ValueError(f"the objective searches {list(objective.space.names)}, the "
                         f"intervals are of {list(iv.names)}")
    iy, ix = _index(iv, pair[0]), _index(iv, pair[1])
    if ix == iy:
        raise ValueError(f"pair needs two different parameters, got {pair}")
    if int(n) < 2:
        raise ValueError(f"n must be at least 2, got {n}")
    n = int(n)
    est = iv.estimate
    idx = [ix, iy]
    lower, upper = iv.lower[idx], iv.upper[idx]
    centre = est[idx]
    # a degenerate (zero-width) interval still gets a window one millionth of the range wide
    half = np.maximum((iv.high[idx] - iv.low[idx]) / 2.0, 1e-6 * (upper - lower))
    z_lo = np.maximum(centre - ZOOM * half, lower)
    z_hi = np.minimum(centre + ZOOM * half, upper)

    whole = _fitness_grid(objective, est, ix, iy, np.linspace(lower[0], upper[0], n),
                          np.linspace(lower[1], upper[1], n))
    zx, zy = np.linspace(z_lo[0], z_hi[0], n), np.linspace(z_lo[1], z_hi[1], n)
    zoom = _fitness_grid(objective, est, ix, iy, zx, zy)

    t = None if truth is None else np.asarray(truth, dtype=float).ravel()[idx]
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.6))
    im = left.pcolormesh(np.linspace(lower[0], upper[0], n), np.linspace(lower[1], upper[1], n),
                         np.log10(np.maximum(whole, np.finfo(float).tiny)), shading="auto",
                         cmap="viridis")
    fig.colorbar(im, ax=left, label="log10 fitness")
    left.plot(centre[0], centre[1], "wo", ms=5, mec="k", zorder=4, label="estimate")
    left.add_patch(Rectangle((z_lo[0], z_lo[1]), z_hi[0] - z_lo[0], z_hi[1] - z_lo[1],
                             fill=False, ec="w", lw=1.2, label="zoom window"))
    if t is not None:
        left.plot(t[0], t[1], "r*", ms=11, label="truth")
    left.set_xlim(lower[0], upper[0])
    left.set_ylim(lower[1], upper[1])
    left.set_title(f"whole plane ({n}x{n}, others at the estimate)", fontsize=9)

    im = right.pcolormesh(zx, zy, zoom - iv.fitness, shading="auto", cmap="viridis")
    fig.colorbar(im, ax=right, label="fitness above the estimate's")
    c2 = float(chi2.ppf(iv.level, 2))
    e = _ellipse(centre, iv.cov[np.ix_(idx, idx)], c2)
    right.plot(e[0], e[1], "w-", lw=1.5, label=f"Laplace joint region (chi2_2 = {c2:.2f})")
    right.add_patch(Rectangle((iv.low[ix], iv.low[iy]), iv.high[ix] - iv.low[ix],
                              iv.high[iy] - iv.low[iy], fill=False, ec="orange", ls="--",
                              lw=1.3, label="per-parameter intervals"))
    right.plot(centre[0], centre[1], "wo", ms=5, mec="k", zorder=4, label="estimate")
    if t is not None:
        inside = bool(np.all((z_lo <= t) & (t <= z_hi)))
        right.plot(t[0], t[1], "r*", ms=12,
                   label="truth" if inside else "truth (outside the window)")
    # the limits are the window: a truth far away must not stretch the zoom
    right.set_xlim(z_lo[0], z_hi[0])
    right.set_ylim(z_lo[1], z_hi[1])
    right.set_title(f"zoom: estimate +- {ZOOM:g} interval half-widths", fontsize=9)
    for ax in (left, right):
        ax.set_xlabel(_label(iv, pair[1]))
        ax.set_ylabel(_label(iv, pair[0]))
        ax.legend(fontsize=7, loc="lower right")
    fig.suptitle(f"{pair[0]}/{pair[1]} confidence region: {iv.method} intervals, level "
                 f"{iv.level:g}", fontsize=10)
    save_figure(fig, path)


def plot_coverage(records: Sequence[Mapping], path: str | os.PathLike
                  ) -> dict[str, tuple[int, int]]:
    """Caterpillar plot of coverage records, one panel per fault.

    Instances are sorted by interval width; each is a bar from ``low - truth`` to
    ``high - truth`` and a dot at ``estimate - truth``, in % of the fault's range (so the
    bar crosses the zero line when the interval contains the truth); intervals that miss
    the truth are red.  Panel titles give the coverage ``k/n`` and the median width (% of
    range); the figure title the run's track, method, level and instance count.

    Parameters
    ----------
    records : sequence of dict
        Records of :func:`~ema_bench.uncertainty.coverage.run_instance` (``truth``,
        ``estimate``, ``low``, ``high``: fault -> physical value; ``settings``), all of one
        run's settings.
    path : str or PathLike
        Where the PNG goes.

    Returns
    -------
    dict
        Fault -> ``(k, n)``: intervals containing the truth, instances (as drawn).

    Raises
    ------
    ValueError
        No records, or records of different tracks, methods or levels.
    """
    if not records:
        raise ValueError("no coverage records to plot")
    keys = ("track", "method", "level")
    s = records[0]["settings"]
    mixed = [k for k in keys if any(r["settings"][k] != s[k] for r in records)]
    if mixed:
        raise ValueError(f"records of different {mixed} in one coverage plot")
    ranges = dict(zip(FAULT_NAMES, UPPER - LOWER))
    fig, axes = plt.subplots(1, len(FAULT_NAMES), figsize=(3.8 * len(FAULT_NAMES), 3.8),
                             squeeze=False)
    counts: dict[str, tuple[int, int]] = {}
    for ax, name in zip(axes[0], FAULT_NAMES):
        t = np.array([r["truth"][name] for r in records], dtype=float)
        lo = np.array([r["low"][name] for r in records], dtype=float)
        hi = np.array([r["high"][name] for r in records], dtype=float)
        u = np.array([r["estimate"][name] for r in records], dtype=float)
        scale = 100.0 / ranges[name]
        width = (hi - lo) * scale
        order = np.argsort(width, kind="stable")
        # the same test as coverage.summarise: an end equal to the truth covers it
        hit = (lo <= t) & (t <= hi)
        k, m = int(hit.sum()), len(records)
        counts[name] = (k, m)
        rank = np.arange(m)
        colour = np.where(hit[order], "tab:blue", "red")
        ax.vlines(rank, ((lo - t) * scale)[order], ((hi - t) * scale)[order], colors=colour,
                  lw=1.5)
        ax.plot(rank, ((u - t) * scale)[order], "k.", ms=3)
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set_title(f"{name}: coverage {k}/{m} = {k / m:.0%}, median width "
                     f"{np.median(width):.2g}%", fontsize=9)
        ax.set_xlabel("instance (sorted by interval width)")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("interval and estimate - truth [% of range]")
    fig.suptitle(f"Coverage: {s['track']} track, {s['method']} intervals, level "
                 f"{s['level']:g}, n = {len(records)} (red: misses the truth)", fontsize=10)
    save_figure(fig, path)
    return counts
