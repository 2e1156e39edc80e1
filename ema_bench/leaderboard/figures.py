"""Leaderboard plots: convergence, ECDF of (instance, target) pairs reached (emafdi-v2: per tier
and condition, and the ERT scaling plot), a fit's trace overlay, and the paper's Figure 5 (the
Na/Fst fitness landscape, raw and normalised)."""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path

import numpy as np

from ..faults import CASES, FAULT_NAMES, NOMINAL, check_faults
from ..plots import plot_traces, plt, save_figure
from ..suites.problem import make_problem
from ..suites.v1 import SANITY_CASES
from ..traces import Traces
from .anytime import ecdf_curve
from .scaling import group_of, groups


def _best_at(trace: list[list[float]], grid: np.ndarray) -> np.ndarray:
    """Best-so-far of a thinned trace evaluated on an evaluation grid (step function)."""
    ev = np.array([p[0] for p in trace])
    best = np.array([p[1] for p in trace])
    idx = np.searchsorted(ev, grid, side="right") - 1
    out = np.where(idx >= 0, best[np.clip(idx, 0, None)], np.nan)
    out[grid > ev[-1]] = best[-1]
    return out


def _styles(records: list[dict]) -> dict[str, dict[str, object]]:
    """One colour and line style per solver, the same in every panel (ten colours, then
    dashed)."""
    cmap = plt.get_cmap("tab10")
    solvers = sorted({r["solver"] for r in records})
    return {s: {"color": cmap(i % 10), "ls": ("-", "--", ":")[i // 10 % 3]}
            for i, s in enumerate(solvers)}


def convergence_plot(records: list[dict], track: str, path: Path) -> None:
    """Best fitness vs evaluations: median and quartiles over seeds, per solver and paper
    case (the seeded instances are in the ECDF and the tables; the sanity case, where every
    solver starts at the optimum and the bands pile into one grey block, in its table)."""
    cases = [c for c in dict.fromkeys(r["case"] for r in records if r["track"] == track)
             if c in CASES and c not in SANITY_CASES]
    fig, axes = plt.subplots(1, len(cases), figsize=(4.2 * len(cases), 3.8), squeeze=False)
    budget = max(r["budget"] for r in records)
    grid = np.unique(np.geomspace(1, budget, 120).astype(int))
    style = _styles(records)
    for ax, case in zip(axes[0], cases):
        groups = defaultdict(list)
        for r in records:
            if r["track"] == track and r["case"] == case and r["trace"]:
                groups[r["solver"]].append(_best_at(r["trace"], grid))
        for solver, curves in sorted(groups.items()):
            c = np.array(curves)
            med = np.nanmedian(c, axis=0)
            ax.plot(grid, med, lw=1.3, label=solver, **style[solver])
            ax.fill_between(grid, np.nanpercentile(c, 25, axis=0),
                            np.nanpercentile(c, 75, axis=0), color=style[solver]["color"],
                            alpha=0.15)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"{case} ({track})")
        ax.set_xlabel("evaluations")
        ax.grid(alpha=0.3, which="both")
    axes[0, 0].set_ylabel("best fitness (median, IQR)")
    axes[0, -1].legend(fontsize=7, loc="upper right")
    save_figure(fig, path)


def ecdf_plot(records: list[dict], path: Path) -> None:
    """ECDF of (run, target) pairs reached vs evaluations, per solver, one panel per track
    (the curve whose area ranks the solvers; the sanity case left out)."""
    tracks = list(dict.fromkeys(r["track"] for r in records))
    fig, axes = plt.subplots(1, len(tracks), figsize=(5.5 * len(tracks), 4), squeeze=False)
    budget = max(r["budget"] for r in records)
    grid = np.unique(np.geomspace(1, budget, 200).astype(int))
    style = _styles(records)
    for ax, track in zip(axes[0], tracks):
        _ecdf_panel(ax, [r for r in records if r["track"] == track], grid, style)
        ax.set_xlabel("evaluations")
        ax.set_title(f"ECDF over (instance, target) pairs ({track} track)")
    axes[0, 0].set_ylabel("fraction of targets reached")
    axes[0, -1].legend(fontsize=7, loc="upper left")
    save_figure(fig, path)


def _ecdf_panel(ax, records: list[dict], grid: np.ndarray, style: dict, per: float = 1.0,
                kinds: str = "fp") -> None:
    """One ECDF panel: per solver, the fraction of its (run, target) pairs of ``kinds``
    reached by each evaluation count of ``grid`` (:func:`.anytime.ecdf_curve`), drawn against
    ``grid / per`` on a log axis."""
    groups = defaultdict(list)
    for r in records:
        groups[r["solver"]].append(r)
    for solver, rs in sorted(groups.items()):
        ax.step(grid / per, ecdf_curve(rs, grid, kinds), where="post", label=solver, lw=1.3,
                **style[solver])
    ax.set_xscale("log")
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3, which="both")


#: The targets an ECDF figure counts: its file-name suffix and its title's words.
ECDF_KINDS = {"fp": ("", "targets"), "f": ("_fitness", "fitness targets"),
              "p": ("_parameters", "parameter targets")}


def ecdf_tiers_plot(records: list[dict], track: str, path: Path, kinds: str = "fp") -> None:
    """emafdi-v2 and -v3: the ECDF of (run, target) pairs reached per solver, one panel per
    tier (rows) and condition (columns) of ``track``, against evaluations / dimension
    (COCO's runtime distributions: panels of different tiers share an axis); ``kinds``: the
    targets counted (:data:`ECDF_KINDS`)."""
    g = {(t, c): rs for (tr, t, c), rs in groups(records).items() if tr == track}
    tiers = sorted({t for t, _ in g})
    conds = list(dict.fromkeys(c for _, c in g))
    fig, axes = plt.subplots(len(tiers), len(conds), figsize=(4.4 * len(conds),
                                                              3.2 * len(tiers)),
                             squeeze=False, sharey=True)
    style = _styles(records)
    for i, t in enumerate(tiers):
        for j, c in enumerate(conds):
            ax = axes[i, j]
            rs = g.get((t, c))
            if not rs:
                ax.set_axis_off()
                ax.set_title(f"tier {t}, {c}: not offered")
                continue
            budget = max(r["budget"] for r in rs)
            grid = np.unique(np.geomspace(1, budget, 200).astype(int))
            _ecdf_panel(ax, rs, grid, style, per=t, kinds=kinds)
            ax.set_title(f"tier {t}, {c} ({track}, {len(rs)} runs)", fontsize=9)
            if i == len(tiers) - 1:
                ax.set_xlabel("evaluations / dimension")
            if j == 0:
                ax.set_ylabel(f"fraction of {ECDF_KINDS[kinds][1]} reached")
    save_figure(fig, path, dpi=100, rect=(0, 0, 1, _shared_legend(fig, axes)))


def _shared_legend(fig, axes, ncol: int = 6) -> float:
    """One legend for every panel, above them (each label once); returns the figure
    fraction the panels may use (the legend's rows take a fixed height in inches, so a
    one-row figure's titles are not covered)."""
    handles, labels = [], []
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    ncol = min(ncol, max(1, len(labels)))
    fig.legend(handles, labels, fontsize=7, loc="upper center", ncol=ncol)
    rows = -(-len(labels) // ncol)
    return 1 - (0.1 + 0.17 * rows) / fig.get_figheight()


def ert_scaling_plot(records: list[dict], points, path: Path) -> None:
    """emafdi-v2, COCO's scaling plot: ERT to the 1 % parameter target divided by the
    dimension against the dimension, one panel per track (rows) and condition (columns),
    one line per solver (its colour and line style in every panel: 12 solvers and four
    conditions in one axes could not be told apart).  ``points``:
    :func:`.scaling.scaling_points` (the ERT of :mod:`.anytime`).  A point where not every
    run reached the target is labelled with the successes ``k/n``; a solver with none is
    drawn as a cross above the budget line (grey: the budget / dimension)."""
    tracks = list(dict.fromkeys(p.track for p in points)) or ["-"]
    conds = list(dict.fromkeys(p.condition for p in points)) or ["-"]
    fig, axes = plt.subplots(len(tracks), len(conds), figsize=(4.4 * len(conds),
                                                               3.6 * len(tracks)),
                             squeeze=False, sharey=True)
    style = _styles(records)
    per_dim = max((r["budget"] / group_of(r)[0] for r in records), default=1.0)
    # the crosses above every point (an ERT exceeds the budget when some runs miss)
    top = 1.6 * max([per_dim] + [p.ert[0] / p.dim for p in points if math.isfinite(p.ert[0])])
    dims = sorted({p.dim for p in points})
    for i, track in enumerate(tracks):
        for j, cond in enumerate(conds):
            ax = axes[i, j]
            lines = defaultdict(list)
            for p in points:
                if p.track == track and p.condition == cond:
                    lines[p.solver].append(p)
            offset = {k: 1 + 0.02 * (n - len(lines) / 2) for n, k in enumerate(sorted(lines))}
            for solver, pts in sorted(lines.items()):
                pts = sorted(pts, key=lambda p: p.dim)
                y = [p.ert[0] / p.dim if math.isfinite(p.ert[0]) else np.nan for p in pts]
                ax.plot([p.dim for p in pts], y, marker="o", ms=4, lw=1.2, label=solver,
                        **style[solver])
                for p, v in zip(pts, y):
                    if not math.isfinite(v):
                        # spread a little sideways: the crosses of every solver share a height
                        ax.plot([p.dim * offset[solver]], [top], marker="x",
                                color=style[solver]["color"], ms=5, ls="none")
                    elif p.hits < p.runs:
                        ax.annotate(f"{p.hits}/{p.runs}", (p.dim, v), fontsize=6,
                                    color=style[solver]["color"], textcoords="offset points",
                                    xytext=(3, 3))
            ax.axhline(per_dim, color="0.5", ls=":", lw=1)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xticks(dims, [str(d) for d in dims])
            ax.minorticks_off()
            if dims:
                ax.set_xlim(dims[0] / 1.3, dims[-1] * 1.3)
            ax.set_ylim(top=1.4 * top)
            ax.set_title(f"{cond} ({track} track)", fontsize=9)
            if i == len(tracks) - 1:
                ax.set_xlabel("dimension (tier)")
            if j == 0:
                ax.set_ylabel("ERT to p0.01 / dimension")
            ax.grid(alpha=0.3, which="both")
    fig.suptitle("k/n: runs that reached the 1 % parameter target, where not all did; "
                 "x: none did; dotted: the budget", fontsize=8, y=0.01, va="bottom")
    save_figure(fig, path, dpi=100, rect=(0, 0.03, 1, _shared_legend(fig, axes)))



def overlay_plot(record: dict, path: Path) -> None:
    """Measured traces vs the monitor at nominal (before) and at the fitted vector (after)."""
    from .tasks import Task

    task = Task(record["solver"], record["case"], record["track"], record["seed"],
                record["budget"], record["root_seed"])
    # a v2 case too (its searched effects: the healthy point has them at 0)
    problem = make_problem(task.case, track=task.track, seed=task.node(), budget=1)
    x = check_faults([record["x"][n] for n in FAULT_NAMES])
    if problem.dim > len(FAULT_NAMES):   # the effects: from the best point's full vector
        x = np.asarray(record["trajectory"][-1][2], dtype=float)
    healthy = np.r_[NOMINAL, np.zeros(problem.dim - len(FAULT_NAMES))]
    outs, _ = problem.simulate(np.vstack([healthy, x]))
    before = Traces({t: v[0] for t, v in outs.items()})
    after = Traces({t: v[1] for t, v in outs.items()})
    plot_traces([problem.measured, before, after],
                ["measured", "monitor at nominal (before)", f"monitor fitted by {task.solver}"],
                path, title=f"{task.case} case, {task.track} track, seed {task.seed}: fit "
                            f"fitness {record['fitness']:.3g}")


def landscape(n: int = 40, track: str = "reference", seed: int = 0,
              truth: dict[str, float] | None = None) -> dict[str, np.ndarray]:
    """The paper's Figure 5: fitness over an ``n x n`` grid of Na and Fst, the other faults
    at their true values; raw and normalised.  Returns the grid and both fitness arrays."""
    truth = truth or {"Na": 0.9, "Fst": 0.3378, "BLK": CASES["nominal"].x[2],
                      "Gprop": CASES["nominal"].x[3]}
    x_true = check_faults(truth)
    na = np.linspace(0.8, 1.0, n)
    fst = np.linspace(0.1689, 0.8445, n)
    NA, FST = np.meshgrid(na, fst, indexing="ij")
    X = np.tile(x_true, (n * n, 1))
    X[:, 0], X[:, 1] = NA.ravel(), FST.ravel()
    out = {"Na": na, "Fst": fst}
    for label, normalise in (("raw", False), ("normalised", True)):
        p = make_problem(x_true, track=track, seed=seed, budget=n * n, normalise=normalise)
        out[label] = np.asarray(p.evaluate(X)).reshape(n, n)
    out["truth"] = x_true
    return out


def landscape_plot(data: dict[str, np.ndarray], path: Path) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4))
    for ax, label in zip(axes, ("raw", "normalised")):
        f = data[label]
        im = ax.pcolormesh(data["Fst"], data["Na"], np.log10(f), shading="auto",
                           cmap="viridis")
        fig.colorbar(im, ax=ax, label="log10 fitness")
        # the valley: per Fst column, where Na is best
        ax.plot(data["Fst"], data["Na"][np.argmin(f, axis=0)], "w.", ms=3,
                label="best Na per Fst")
        ax.plot(data["truth"][1], data["truth"][0], "r*", ms=12, label="truth")
        ax.set_xlabel("Fst [N m]")
        ax.set_ylabel("Na [-]")
        ax.set_title(f"{label} fitness (paper Figure 5 grid, {f.shape[0]}x{f.shape[1]})")
        ax.legend(fontsize=7, loc="lower right")
    save_figure(fig, path)


def valley_rise(f: np.ndarray) -> float:
    """How well the minimum stands out of its valley: median over Fst columns of the best
    fitness in the column, divided by the global minimum (near 1: a long valley of near-equal
    minima, as the paper's raw fitness; large: one clear minimum)."""
    return float(np.median(f.min(axis=0)) / f.min())
