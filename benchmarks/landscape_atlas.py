"""Landscape atlas of suite emafdi-v3, per tier: writes docs/landscape-atlas.md and its plots.

A small sample (``--per-tier`` instances of each tier, twin track, noise seed 0, the prior's
objective), around each instance's best-known fit ``x*`` (the shipped twin entry), on the
suite's model version (:data:`AFTER`, version 4: its data, ``x*`` and fitness) and, for the
jumps, on version 3 too (:data:`BEFORE`: the same data and lines, the monitor before the
located commutation transfer), so that the atlas shows the jumps before and after the fix:

- **conditioning at the truth**: the condition number of the noise-whitened Jacobian
  (:func:`ema_bench.uncertainty.methods.intervals`' singular values);
- **jumps near the optimum**: the fitness along lines through ``x*`` (every parameter's axis
  and ``--directions`` random unit directions of the unit box), ``2 K + 1`` points over
  +-``--half-width`` of the box; the line's jump is its largest step between neighbours
  beyond the local slope (:func:`jumps`, in units of ``f*``);
- **the halved-step experiment**: the same lines with the monitor's step halved (25 us,
  ``simulate_monitor(dt=...)``): a jump that shrinks with the step is numerical (an event
  decided at step resolution), one that stays is a property of the problem;
- **distinct local minima**: local least-squares refits (:func:`ema_bench.uncertainty.local.
  refit`) from ``--starts`` uniform random points, end points within 2 % of the box merged;
- **zoom**: each instance's worst line's largest jump resampled 40x closer (:func:`refine`):
  a discontinuity keeps its size, a steep continuous stretch splits into small steps;
- **model version 3, before the fix**: the same lines with ``locate_commutation`` off
  (:func:`ema_bench.params.model_params`), which has the numerical kind of jump; its worst
  line zoomed, bisected and attributed (:func:`worst_flip`), and a census of every line on
  both versions (:func:`census`);
- **kinds of jump**: each kind of :mod:`jump_kinds` on its witness line, at 50 and 25 us on
  versions 3 and 4: the line's jump, its largest step zoomed 40x and bisected to 1e-13, and
  the first discrete state that differs across it (:func:`kinds`);
- **valley width**: per parameter, the smallest offset from ``x*`` (either side, fraction of
  range) at which the fitness rises above the finest fitness target of v2 (1e-4 of the
  f*-to-nominal gap) and of v3 (1e-6).

    nice python benchmarks/landscape_atlas.py --per-tier 3 --out docs/landscape-atlas.md

``--tiers 4`` runs one tier (to time it; its output is not the committed atlas).
"""

from __future__ import annotations

import argparse
import functools
import time
from pathlib import Path

import jump_kinds
import numpy as np

import ema_bench.objective as objective_module
from ema_bench.monitor import simulate_monitor
from ema_bench.params import DEFAULT_PARAMS, model_params
from ema_bench.plots import save_figure
from ema_bench.seeding import child, run_seed
from ema_bench.suites import instance, v2, v3
from ema_bench.suites.problem import make_problem
from ema_bench.uncertainty.local import Counter, refit
from ema_bench.uncertainty.methods import intervals

SEED = 20261128
TRACK = "twin"
#: The model version the atlas describes (the suite's) and the one before the fix.
AFTER, BEFORE = v3.V3_MODEL_VERSION, "3"


def _problem(case: str):
    return make_problem(case, track=TRACK, seed=run_seed(0, 0), budget=1)


def _f(p, U: np.ndarray) -> np.ndarray:
    """Fitness of unit-box points (one batched monitor call, not counted)."""
    space = p.objective.space
    return p.objective.evaluate(space.from_unit(np.clip(U, 0.0, 1.0)))[0]


@functools.cache
def _half_step():
    return functools.partial(simulate_monitor, dt=DEFAULT_PARAMS.dt_mon / 2)


def _at(step: str, p=None, version: str = AFTER):
    """The objective module's monitor at the standard or the halved step; with ``p``, its
    objective on model ``version`` (:func:`ema_bench.params.model_params`; default the
    suite's, :data:`AFTER`)."""
    objective_module.simulate_monitor = simulate_monitor if step == "full" else _half_step()
    if p is not None:
        p.objective.params = model_params(version)


def _directions(tier: int, idx: int, dim: int, directions: int) -> np.ndarray:
    """The lines of instance ``idx`` of ``tier``: each axis, then random unit directions."""
    rng = np.random.default_rng(child(SEED, 1000 * tier + idx))
    R = rng.standard_normal((directions, dim))
    return np.vstack([np.eye(dim), R / np.linalg.norm(R, axis=1)[:, None]])


def lines(p, u_star: np.ndarray, dirs: np.ndarray, half: float, k: int) -> np.ndarray:
    """Fitness on ``2 k + 1`` points of each direction through ``u_star`` (rows: lines)."""
    t = np.linspace(-half, half, 2 * k + 1)
    U = u_star[None, None, :] + t[None, :, None] * dirs[:, None, :]
    return _f(p, U.reshape(-1, u_star.size)).reshape(len(dirs), t.size)


def jumps(F: np.ndarray, f_star: float) -> np.ndarray:
    """Per line, the largest step between neighbours beyond the local slope (each difference
    minus the mean of its two neighbours: a smooth fitness leaves ``h^2 f''``, a jump of
    size ``J`` leaves about ``J``), in units of ``f*``."""
    d = np.diff(F, axis=1)
    return np.max(np.abs(d[:, 1:-1] - 0.5 * (d[:, :-2] + d[:, 2:])), axis=1) / f_star


def refine(p, u_star: np.ndarray, direction: np.ndarray, F: np.ndarray, half: float,
           f_star: float, zoom: int = 40) -> tuple[float, float]:
    """The largest jump of one line looked at ``zoom`` times closer: the line's worst interval
    (:func:`jumps`) resampled in ``zoom + 1`` points, at the standard and the halved step;
    the largest step between neighbours there, in units of ``f*``.  A discontinuity keeps its
    size under the zoom; a steep but continuous stretch splits into ``zoom`` small steps."""
    t = np.linspace(-half, half, F.size)
    d = np.diff(F)
    k = int(np.argmax(np.abs(d[1:-1] - 0.5 * (d[:-2] + d[2:])))) + 1
    tt = np.linspace(t[k], t[k + 1], zoom + 1)
    out = []
    for step in ("full", "half"):
        _at(step)   # the objective's model version as the caller set it
        f = _f(p, u_star[None, :] + tt[:, None] * direction[None, :])
        out.append(float(np.max(np.abs(np.diff(f))) / f_star))
    _at("full")
    return out[0], out[1]


def minima(p, u_star: np.ndarray, f_star: float, f_nom: float, starts: int, seed,
           max_evals: int) -> list[tuple[float, float, int]]:
    """Distinct end points of local refits from uniform starts: (precision of their
    fitness, unit-box distance from ``x*``, how many starts ended there)."""
    rng = np.random.default_rng(seed)
    ends = []
    for _ in range(starts):
        u, f = refit(Counter(p.objective), rng.random(u_star.size), max_evals=max_evals)
        ends.append((u, f))
    found: list[list] = []
    for u, f in sorted(ends, key=lambda e: e[1]):
        for g in found:
            if np.max(np.abs(g[0] - u)) < 0.02:
                g[2] += 1
                break
        else:
            found.append([u, f, 1])
    return [((f - f_star) / (f_nom - f_star), float(np.max(np.abs(u - u_star))), n)
            for u, f, n in found]


def valley(p, u_star: np.ndarray, f_star: float, gap: float,
           levels=(1e-4, 1e-6)) -> np.ndarray:
    """(levels, dim): per parameter the smallest offset (fraction of range, either side) at
    which the fitness exceeds ``f* + level x gap`` (nan: not within 0.3)."""
    d = np.geomspace(1e-5, 0.3, 40)
    n = u_star.size
    U = np.repeat(u_star[None, :], 2 * n * d.size, axis=0).reshape(2, n, d.size, n)
    for i in range(n):
        U[0, i, :, i] += d
        U[1, i, :, i] -= d
    F = _f(p, U.reshape(-1, n)).reshape(2, n, d.size)
    out = np.full((len(levels), n), np.nan)
    for j, lv in enumerate(levels):
        above = F - f_star > lv * gap
        for i in range(n):
            first = [d[np.argmax(above[s, i])] for s in range(2) if above[s, i].any()]
            out[j, i] = min(first) if first else np.nan
    return out


#: The atlas's line scans: key -> (monitor step, model version).
SCANS = {"full": ("full", AFTER), "half": ("half", AFTER),
         "before": ("full", BEFORE), "before_half": ("half", BEFORE)}


def atlas(per_tier: int, directions: int, half: float, k: int, starts: int,
          max_evals: int, tiers=v2.TIERS) -> dict:
    """Per tier, one row per case: every measurement of the module docstring."""
    out = {}
    for d in tiers:
        rows = []
        for idx, name in enumerate(v2.instance_names(d)[:per_tier]):
            case = v3.case_key(name, "prior")
            inst = instance(case)
            e = inst.best_known(TRACK, 0)
            p = _problem(case)
            space = p.objective.space
            x_star = np.array([e["x_star"][n] for n in inst.names])
            u_star = space.to_unit(x_star[None, :])[0]
            f_star, gap = e["f_star"], e["f_nominal"] - e["f_star"]
            iv = intervals(p.objective, inst.truth, method="laplace", polish=False,
                           calibrate=False, noise="known", model_form="none")
            s = np.array(iv.identifiability["singular_values"])
            dirs = _directions(d, idx, inst.dim, directions)
            F = {}
            for key, (step, version) in SCANS.items():
                _at(step, p, version)
                F[key] = lines(p, u_star, dirs, half, k)
            _at("full", p)
            worst = int(np.argmax(jumps(F["full"], f_star)))
            rows.append({
                "zoom": refine(p, u_star, dirs[worst], F["full"][worst], half, f_star),
                "case": case, "names": inst.names, "cond": float(s[0] / s[-1]),
                **{f"jump_{key}": jumps(F[key], f_star) for key in SCANS},
                "worst": worst_flip(p, u_star, dirs, F["full"], half, f_star, AFTER),
                "before_worst": worst_flip(p, u_star, dirs, F["before"], half, f_star, BEFORE),
                "census": {key: census(p, u_star, dirs, F[key], half, f_star, v, step)
                           for key, step, v in (("before", "full", BEFORE), ("full", "full", AFTER),
                                                ("half", "half", AFTER))},
                "F": F, "f_star": f_star,
                "minima": minima(p, u_star, f_star, e["f_nominal"], starts,
                                 child(SEED, 7 + 1000 * d + idx), max_evals),
                "valley": valley(p, u_star, f_star, gap), "gap_over_f": gap / f_star})
        out[d] = rows
    return out


def worst_flip(p, u_star: np.ndarray, dirs: np.ndarray, F: np.ndarray, half: float,
               f_star: float, version: str) -> tuple[int, float, float, str]:
    """The worst of the lines ``F`` (model ``version``, standard step) zoomed 40x: its index,
    the largest zoomed step and that step bisected to 1e-13 (units of f*: a discontinuity
    keeps its size, a steep continuous stretch vanishes), and the first discrete state that
    differs across the zoomed step (:func:`jump_kinds.first_flip`, ``"state (test, sample
    k)"``)."""
    i = int(np.argmax(jumps(F, f_star)))
    _at("full", p, version)

    def f(tt):
        return _f(p, u_star[None, :] + np.asarray(tt)[:, None] * dirs[i][None, :])

    tt, FF = jump_kinds.zoom(f, np.linspace(-half, half, F.shape[1]), F[i])
    j = int(np.argmax(np.abs(np.diff(FF))))
    X = p.objective.space.from_unit(np.clip(u_star[None] + tt[j:j + 2, None] * dirs[i][None],
                                            0.0, 1.0))
    test, state, tick = jump_kinds.first_flip(p.objective, X, model_params(version))
    a, b = jump_kinds.bisect(f, tt, FF)
    fa, fb = f(np.array([a, b]))
    _at("full", p)
    return (i, float(np.abs(FF[j + 1] - FF[j]) / f_star), float(abs(fb - fa) / f_star),
            f"{state} ({test}, sample {tick})")


#: A bisected step of at least this many f* is a discontinuity (rounding leaves 1e-13-1e-11
#: between two points 1e-13 apart; v3's finest fitness target is 2.6e-4 f* or more).
DISCONTINUITY = 1e-6


def census(p, u_star: np.ndarray, dirs: np.ndarray, F: np.ndarray, half: float,
           f_star: float, version: str, step: str = "full") -> dict[str, list[float]]:
    """Every line of ``F`` (model ``version`` at ``step``): its largest step zoomed 40x and
    bisected to 1e-13; the sizes (units of f*) of those at least :data:`DISCONTINUITY`, by
    the first discrete state that flips across them (:func:`jump_kinds.first_flip`)."""
    _at(step, p, version)
    params = model_params(version)
    if step == "half":
        params = params.replace(dt_mon=params.dt_mon / 2)
    t = np.linspace(-half, half, F.shape[1])
    found: dict[str, list[float]] = {}
    for d, row in zip(dirs, F):
        def f(tt, d=d):
            return _f(p, u_star[None, :] + np.asarray(tt)[:, None] * d[None, :])

        tt, FF = jump_kinds.zoom(f, t, row)
        a, b = jump_kinds.bisect(f, tt, FF)
        fa, fb = f(np.array([a, b]))
        size = float(abs(fb - fa) / f_star)
        if size >= DISCONTINUITY:
            X = p.objective.space.from_unit(np.clip(u_star[None] + np.array([a, b])[:, None]
                                                    * d[None], 0.0, 1.0))
            state = jump_kinds.first_flip(p.objective, X, params)[1]
            found.setdefault(state, []).append(size)
    _at("full", p)
    return found


#: Each kind's witness line is measured at these (step, model version) settings.
SETTINGS = (("full", BEFORE), ("half", BEFORE), ("full", AFTER), ("half", AFTER))


def kinds(directions: int, half: float, k: int) -> list[dict]:
    """Per kind of jump (:data:`jump_kinds.KINDS`): its witness line's jump and its largest
    step zoomed 40x and the jump between the two points 1e-13 apart that bisection of that
    step finds, at every :data:`SETTINGS` (units of f*); and the first state that differs
    between the ends of the zoomed step (standard step, version 3;
    :func:`jump_kinds.first_flip`)."""
    rows = []
    for kind in jump_kinds.KINDS:
        inst = instance(kind.case)
        e = inst.best_known(TRACK, 0)
        p = _problem(kind.case)
        space = p.objective.space
        u_star = space.to_unit(np.array([[e["x_star"][n] for n in inst.names]]))[0]
        name = kind.case[len(v3.PREFIX):].split("@")[0]
        tier = next(t for t in v2.TIERS if name in v2.instance_names(t))
        dirs = _directions(tier, v2.instance_names(tier).index(name), inst.dim, directions)
        d = jump_kinds.direction(kind, inst.names, dirs[inst.dim:])
        t = np.linspace(-half, half, 2 * k + 1)

        def f(tt, p=p, u_star=u_star, d=d):
            return _f(p, u_star[None, :] + np.asarray(tt)[:, None] * d[None, :])

        row = {"kind": kind, "f_star": e["f_star"]}
        for step, version in SETTINGS:
            _at(step, p, version)
            F = f(t)
            tt, FF = jump_kinds.zoom(f, t, F)
            row["line", step, version] = float(jumps(F[None], e["f_star"])[0])
            row["zoom", step, version] = float(np.max(np.abs(np.diff(FF))) / e["f_star"])
            a, b = jump_kinds.bisect(f, tt, FF)
            fa, fb = f(np.array([a, b]))
            row["pair", step, version] = float((fb - fa) / e["f_star"])
            if (step, version) == SETTINGS[0]:
                j = int(np.argmax(np.abs(np.diff(FF))))
                ends = tt[j:j + 2]
        _at("full", p, BEFORE)   # the kind as version 3 has it (the first setting)
        X = space.from_unit(np.clip(u_star[None] + ends[:, None] * d[None], 0.0, 1.0))
        row["flip"] = jump_kinds.first_flip(p.objective, X, model_params(BEFORE))
        _at("full", p)
        rows.append(row)
    return rows


def plots(data: dict, folder: Path) -> list[str]:
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    names = []
    fig, axes = plt.subplots(1, len(data), figsize=(4.4 * len(data), 3.4), squeeze=False)
    for ax, (d, rows) in zip(axes[0], data.items()):
        sets = {key: np.concatenate([r[f"jump_{key}"] for r in rows])
                for key in ("before", "full", "half")}
        every = np.concatenate(list(sets.values()))
        bins = np.geomspace(max(every.min(), 1e-12), every.max(), 30)
        for key, label in (("before", f"version {BEFORE}, 50 us"),
                           ("full", f"version {AFTER}, 50 us"),
                           ("half", f"version {AFTER}, 25 us")):
            ax.hist(sets[key], bins=bins, alpha=0.5, label=label)
        ax.set_xscale("log")
        ax.set_title(f"tier {d}: largest jump per line")
        ax.set_xlabel("jump / f*")
    axes[0, 0].set_ylabel("lines")
    axes[0, 0].legend(fontsize=8)
    save_figure(fig, folder / "jumps.png", dpi=100)
    names.append("jumps.png")
    fig, axes = plt.subplots(1, len(data), figsize=(4.4 * len(data), 3.4), squeeze=False)
    for ax, rows in zip(axes[0], data.values()):
        r = rows[0]
        i = int(np.argmax(r["jump_full"]))
        t = np.linspace(-1, 1, r["F"]["full"].shape[1])
        for key, ls, label in (("full", "-", f"version {AFTER}, 50 us"),
                               ("half", "--", f"version {AFTER}, 25 us"),
                               ("before", ":", f"version {BEFORE}, 50 us")):
            ax.plot(t, r["F"][key][i] / r["f_star"] - 1, ls, label=label)
        label = r["names"][i] if i < len(r["names"]) else f"random direction {i - len(r['names'])}"
        ax.set_title(f"{r['case']}: {label}", fontsize=9)
        ax.set_xlabel("offset / half-width")
    axes[0, 0].set_ylabel("f / f* - 1")
    axes[0, 0].legend(fontsize=8)
    save_figure(fig, folder / "worst_line.png", dpi=100)
    names.append("worst_line.png")
    return names


def _line_name(r: dict, i: int) -> str:
    return r["names"][i] if i < len(r["names"]) else f"random direction {i - len(r['names'])}"


def _before_cell(r: dict) -> str:
    i, zoomed, bisected, flip = r["before_worst"]
    return (f"{r['jump_before'].max():.2e}, {np.median(r['jump_before']):.2e}, {_line_name(r, i)}, "
            f"{zoomed:.2e}, {bisected:.1e}, {flip}")


def kinds_markdown(rows: list[dict]) -> list[str]:
    """The section on the kinds of jump: the measured table, then each kind's attribution."""
    def four(r, what):
        return " / ".join(f"{r[what, s, v]:.1e}" for s, v in SETTINGS)

    md = ["", "## Kinds of jump: attribution, and model version 4", "",
          "Each kind on its witness line (the atlas's line through x* named below): the line's "
          "jump and its largest step zoomed 40x, at 50 us / 25 us on model version 3 (v1's "
          "and v2's; before the fix) / 50 us / 25 us on version 4 (v3's; `locate_commutation`, "
          "`ema_bench.params.model_params('4')`), and the jump between the two points 1e-13 "
          "of the box apart that bisection of each zoomed step finds (a discontinuity keeps "
          "its size, a steep continuous stretch vanishes); then, on version 3 at 50 us, the "
          "test whose fitness moves across the zoomed step and the first discrete state "
          "that differs between its two ends (controller sample). Units of f*; "
          "`benchmarks/jump_kinds.py` holds the experiment and the attribution.", "",
          "| kind | physics or numerics | witness | line jump | zoomed 40x | bisected to 1e-13 "
          "| first state to differ |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        k = r["kind"]
        test, state, tick = r["flip"]
        md.append(f"| {k.name} | {'physics' if k.physics else 'numerics: removed in v4'} | "
                  f"{k.case}, {k.line} | {four(r, 'line')} | {four(r, 'zoom')} | "
                  f"{four(r, 'pair')} | {state} ({test}, sample "
                  f"{tick}) |")
    md.append("")
    for r in rows:
        k = r["kind"]
        md += [f"**{k.name}** ({'physics' if k.physics else 'numerics'}). {k.mechanism} "
               f"Evidence: {k.evidence}", ""]
    md += [f"**The quantiser.** {jump_kinds.QUANTISER}", ""]
    return md


def markdown(data: dict, kind_rows: list[dict], args, cost: str, images: list[str]) -> str:
    md = ["# Landscape atlas (suite emafdi-v3, per tier)", "",
          f"Generated by `python benchmarks/landscape_atlas.py --per-tier {args.per_tier} "
          f"--directions {args.directions} --half-width {args.half_width:g} --points "
          f"{args.points} --starts {args.starts} --max-evals {args.max_evals}"
          + (f" --tiers {args.tiers}" if args.tiers != ",".join(map(str, v2.TIERS)) else "")
          + f"` ({cost}); do "
          "not edit by hand. A small sample: the first "
          f"{args.per_tier} instances of each tier, twin track, noise seed 0, the prior's "
          f"objective, on model version {AFTER} (the suite's: its twin data, its fitness and "
          f"the shipped best fit x* of `ema_bench/suite_targets_v3.json`, twin, seed 0), "
          f"around x*; the jumps also on version {BEFORE} (the same data, lines and points, "
          "the monitor before the located commutation transfer): before and after the fix. "
          "The script's docstring defines every column.", ""]
    md += ["## Conditioning and jumps", "",
           "Jump: per line through x* (each parameter's axis, then random directions), the "
           "largest step between neighbouring points beyond the local slope (a difference "
           f"minus the mean of its two neighbours), over +-{args.half_width:g} of the unit "
           f"box in {2 * args.points + 1} "
           "points, in units of f*. Halved step: the same lines with the monitor at 25 us "
           "(the kernels unchanged, `simulate_monitor(dt=...)`). Condition number: of the "
           f"noise-whitened Jacobian at the truth (version {AFTER}). Every column but the "
           f"last is version {AFTER}'s; the last is version {BEFORE}'s, before the fix.", "",
           f"| case | condition number | largest jump (50 us) | median jump (50 us) | "
           "largest jump (25 us) | median (25 us) | axis of the largest | it zoomed 40x: "
           "largest step 50 us / 25 us | it bisected to 1e-13, first discrete state to "
           f"differ across it | before the fix, model version {BEFORE} (50 us): "
           "largest jump, median, its line, zoomed 40x, bisected to 1e-13, first discrete "
           "state to differ across it |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for rows in data.values():
        for r in rows:
            axis = _line_name(r, int(np.argmax(r["jump_full"])))
            md.append(f"| {r['case']} | {r['cond']:.0f} | {r['jump_full'].max():.2e} | "
                      f"{np.median(r['jump_full']):.2e} | {r['jump_half'].max():.2e} | "
                      f"{np.median(r['jump_half']):.2e} | {axis} | "
                      f"{r['zoom'][0]:.2e} / {r['zoom'][1]:.2e} | {r['worst'][2]:.1e}, "
                      f"{r['worst'][3]} | {_before_cell(r)} |")
    md += ["", "Per tier, the ratio (25 us / 50 us) of each line's jump: median and range "
           "(a ratio near 1: the jump stays, near 0.5 or below: it shrinks with the step), "
           f"on version {AFTER} and, before the fix, on version {BEFORE}.", "",
           f"| tier | lines | median ratio (v{AFTER}) | 10-90 % | axes whose jump halves or "
           f"better | median ratio (v{BEFORE}) | 10-90 % | axes whose jump halves or better |",
           "|---|---|---|---|---|---|---|---|"]
    for d, rows in data.items():
        cells = []
        for full, half in (("full", "half"), ("before", "before_half")):
            ratio = np.concatenate([r[f"jump_{half}"] / r[f"jump_{full}"] for r in rows])
            shrink = sorted({r["names"][i] for r in rows for i in range(len(r["names"]))
                             if r[f"jump_{half}"][i] <= 0.6 * r[f"jump_{full}"][i]})
            cells.append(f"{np.median(ratio):.2f} | {np.quantile(ratio, 0.1):.2f}-"
                         f"{np.quantile(ratio, 0.9):.2f} | {', '.join(shrink) or 'none'}")
        md.append(f"| {d} | {ratio.size} | " + " | ".join(cells) + " |")
    md += ["", "Discontinuities on every line: each line's largest step zoomed 40x and "
           f"bisected to 1e-13; those of {DISCONTINUITY:g} f* or more, counted by the first "
           "discrete state that flips across them (sector index: a commutation; PI "
           "integrating: the speed loop's anti-windup; none: no tracked state flips at a "
           f"controller sample), with the largest, on model version {BEFORE} (50 us, before "
           f"the fix) and on version {AFTER} (50 us, 25 us).", "",
           f"| case | lines | version {BEFORE} (before) | version {AFTER} | version {AFTER}, "
           "25 us |", "|---|---|---|---|---|"]
    for rows in data.values():
        for r in rows:
            cells = ["; ".join(f"{state} {len(v)} (<= {max(v):.1e})"
                               for state, v in sorted(r["census"][ver].items())) or "none"
                     for ver in ("before", "full", "half")]
            md.append(f"| {r['case']} | {r['jump_full'].size} | " + " | ".join(cells) + " |")
    md += kinds_markdown(kind_rows)
    md += ["", "## Distinct local minima (multi-start local refits)", "",
           f"{args.starts} uniform random starts per instance, trust-region least-squares "
           f"refits of at most {args.max_evals} evaluations, end points within 2 % of the "
           "box merged: each minimum's fitness precision (f - f*) / (f_nominal - f*), its "
           "largest distance from x* (fraction of range) and how many starts ended there.",
           "", "| case | distinct end points | best three (precision, distance, starts) |",
           "|---|---|---|"]
    for rows in data.values():
        for r in rows:
            best = "; ".join(f"{p:.1e}, {dd:.3f}, {n}" for p, dd, n in r["minima"][:3])
            md.append(f"| {r['case']} | {len(r['minima'])} | {best} |")
    md += ["", "## Valley width per parameter", "",
           "Per parameter, the smallest offset from x* (either side, % of range) at which the "
           "fitness exceeds v2's finest fitness target (f* + 1e-4 of the gap) / v3's "
           "(1e-6); '>30' where it stays below within 30 %.", ""]
    for d, rows in data.items():
        names = rows[0]["names"]
        md += [f"### Tier {d}", "", "| case | " + " | ".join(names) + " |",
               "|---|" + "---|" * len(names)]
        for r in rows:
            cells = [("/".join(">30" if np.isnan(v) else f"{100 * v:.2g}"
                               for v in r["valley"][:, i])) for i in range(len(names))]
            md.append(f"| {r['case']} | " + " | ".join(cells) + " |")
        md.append("")
    md += ["## Plots", ""] + [f"![{n}](landscape-atlas/{n})" for n in images] + [""]
    return "\n".join(md)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--per-tier", type=int, default=3)
    ap.add_argument("--directions", type=int, default=8)
    ap.add_argument("--half-width", type=float, default=2e-3)
    ap.add_argument("--points", type=int, default=40)
    ap.add_argument("--starts", type=int, default=6)
    ap.add_argument("--max-evals", type=int, default=300)
    ap.add_argument("--tiers", default=",".join(map(str, v2.TIERS)),
                    help="comma-separated tiers (one, to time it)")
    ap.add_argument("--out", default="docs/landscape-atlas.md")
    a = ap.parse_args()
    t0, c0 = time.perf_counter(), time.process_time()
    data = atlas(a.per_tier, a.directions, a.half_width, a.points, a.starts, a.max_evals,
                 tuple(int(t) for t in a.tiers.split(",")))
    kind_rows = kinds(a.directions, a.half_width, a.points)
    out = Path(a.out)
    images = plots(data, out.parent / "landscape-atlas")
    cost = f"{time.process_time() - c0:.0f} CPU-s, {time.perf_counter() - t0:.0f} s wall"
    out.write_text(markdown(data, kind_rows, a, cost, images))
    print(f"{out} ({cost})")


if __name__ == "__main__":
    main()
