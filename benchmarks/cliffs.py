"""The cliffs near one case's optimum, found and attributed (issue 44: ``t12-s06``).

Lines through the case's shipped best fit ``x*`` (every parameter's axis, the line from
``x*`` to the truth, and ``--directions`` random unit directions of the unit box, the
atlas's seeds), each sampled in ``2 K + 1`` points over +-``--half-width`` of the box for
every half-width given, on the case's own model version (v3: 4).  Every line whose jump
(:func:`landscape_atlas.jumps`: its largest step between neighbours beyond the local
slope) is at least ``--threshold`` of ``f*`` is a cliff; each cliff is
zoomed 40x (:func:`jump_kinds.zoom`) and bisected to two points 1e-13 of the box apart
(:func:`jump_kinds.bisect`: a discontinuity keeps its size, a steep continuous stretch
vanishes); at the two points :func:`jump_kinds.first_flip` names the test whose fitness
moves and the first discrete state that differs (controller sample).  Then the monitor's
step is halved (25 us) and the same line measured again (its largest step, zoomed and
bisected, and the state that flips at that step): a jump that shrinks with the step is
numerical, one that keeps its size belongs to the problem.  With ``--outputs-along NAME``,
the monitor's and the reference model's outputs along that parameter's axis
(:func:`output_steps`): whether the model that makes the reference track's data jumps too.
Prints markdown.

    nice python benchmarks/cliffs.py --case v3-t12-s06@prior --half-widths 0.002,0.01 \\
        --outputs-along Gprop > benchmarks/results/cliffs_t12_s06.md
"""

from __future__ import annotations

import argparse
import time

import jump_kinds
import numpy as np
from landscape_atlas import _at, _directions, _f, jumps

from ema_bench.reference import simulate_reference
from ema_bench.seeding import run_seed
from ema_bench.suites import instance, v2, v3
from ema_bench.suites.problem import make_problem

#: The steps of the monitor (label, fraction of the standard step).
STEPS = (("50 us", "full"), ("25 us", "half"))


def _lines(inst, u_star: np.ndarray, u_truth: np.ndarray, tier: int, idx: int,
           directions: int) -> tuple[list[str], np.ndarray]:
    """Names and unit directions: each axis, x* to the truth, then the atlas's random ones."""
    dirs = _directions(tier, idx, inst.dim, directions)
    to_truth = (u_truth - u_star) / np.linalg.norm(u_truth - u_star)
    names = [*inst.names, "x* to the truth"] + [f"random direction {i}"
                                                 for i in range(directions)]
    return names, np.vstack([dirs[:inst.dim], to_truth, dirs[inst.dim:]])


def cliff(p, u_star: np.ndarray, d: np.ndarray, t: np.ndarray, F: np.ndarray,
          f_star: float, step: str, version: str) -> dict:
    """The line ``F`` (offsets ``t`` along ``d``) at ``step``: its largest step, zoomed 40x
    and bisected to 1e-13 (units of f*), where (offset, fraction of the box), and the test
    and first discrete state that differ across it (:func:`jump_kinds.first_flip`)."""
    _at(step, p, version)
    params = p.objective.params
    if step == "half":
        params = params.replace(dt_mon=params.dt_mon / 2)

    def f(tt):
        return _f(p, u_star[None, :] + np.asarray(tt)[:, None] * d[None, :])

    tt, FF = jump_kinds.zoom(f, t, F)
    a, b = jump_kinds.bisect(f, tt, FF)
    fa, fb = f(np.array([a, b]))
    X = p.objective.space.from_unit(np.clip(u_star[None] + np.array([a, b])[:, None]
                                            * d[None], 0.0, 1.0))
    test, state, tick = jump_kinds.first_flip(p.objective, X, params)
    _at("full", p, version)
    return {"step": float(jumps(F[None], f_star)[0]),
            "zoom": float(np.max(np.abs(np.diff(FF))) / f_star),
            "pair": float((fb - fa) / f_star), "at": 0.5 * (a + b),
            "flip": f"{state} ({test}, sample {tick})"}


def hunt(case: str, track: str, seed: int, halves: list[float], k: int, directions: int,
         threshold: float) -> tuple[list[dict], int]:
    """Every cliff of ``case`` (rows of :func:`cliff` at each of :data:`STEPS`), and how
    many lines were scanned."""
    inst = instance(case)
    e = inst.best_known(track, seed)
    p = make_problem(case, track=track, seed=run_seed(0, seed), budget=1)
    version = inst.model_version
    space = p.objective.space
    u_star = space.to_unit(np.array([[e["x_star"][n] for n in inst.names]]))[0]
    u_truth = space.to_unit(inst.truth[None, :])[0]
    name = case[len(v3.PREFIX):].split("@")[0]
    tier = next(tt for tt in v2.TIERS if name in v2.instance_names(tt))
    names, dirs = _lines(inst, u_star, u_truth, tier, v2.instance_names(tier).index(name),
                         directions)
    f_star = e["f_star"]
    rows = []
    for half in halves:
        t = np.linspace(-half, half, 2 * k + 1)
        _at("full", p, version)
        U = u_star[None, None, :] + t[None, :, None] * dirs[:, None, :]
        F = _f(p, U.reshape(-1, inst.dim)).reshape(len(dirs), t.size)
        for i, row in enumerate(F):
            if jumps(row[None], f_star)[0] < threshold:
                continue
            r = {"line": names[i], "half": half}
            for label, step in STEPS:
                Fs = row
                if step != "full":
                    _at(step, p, version)
                    Fs = _f(p, u_star[None, :] + t[:, None] * dirs[i][None, :])
                r[label] = cliff(p, u_star, dirs[i], t, Fs, f_star, step, version)
            rows.append(r)
    _at("full", p, version)
    return rows, len(dirs) * len(halves)


def output_steps(case: str, track: str, seed: int, name: str, half: float,
                 k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Along parameter ``name``'s axis through ``x*`` (``2 k + 1`` points over +-``half`` of
    the box): between neighbouring points, how far the outputs move, in the fitness's units
    (every test's weighted mean square of the change, over ``f*``: the fitness one point
    would have against the other's noise-free outputs), for the monitor and for the reference
    model (1 us, three-phase drive: the model behind the reference track's data, noise-free).
    A discontinuity of the model shows as an isolated large value; ``(t, monitor,
    reference)``, the offsets of each pair's left point."""
    inst = instance(case)
    e = inst.best_known(track, seed)
    p = make_problem(case, track=track, seed=run_seed(0, seed), budget=1)
    ob, space = p.objective, p.objective.space
    u = space.to_unit(np.array([[e["x_star"][n] for n in inst.names]]))[0]
    t = np.linspace(-half, half, 2 * k + 1)
    U = np.repeat(u[None], t.size, axis=0)
    U[:, inst.names.index(name)] += t
    X = space.from_unit(U)
    E = space.effects_for(X, ob.effects)
    mon = ob.outputs(X)[0]
    ref = [simulate_reference(X[j, :4], E[j], tests=ob.tests, params=ob.params, noise=False,
                              adc=False).data for j in range(t.size)]

    def moved(Y: dict) -> np.ndarray:
        return sum(np.einsum("nsk,k->n" if ob.weights[s].ndim == 1 else "nsk,sk->n",
                             np.diff(Y[s], axis=0) ** 2, ob.weights[s]) / Y[s].shape[1]
                   for s in Y) / e["f_star"]

    return (t[:-1], moved({s: mon[s] for s in mon}),
            moved({s: np.array([r[s] for r in ref]) for s in ref[0]}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default="v3-t12-s06@prior")
    ap.add_argument("--track", default="twin")
    ap.add_argument("--seed", type=int, default=0, help="noise seed (its best-known x*)")
    ap.add_argument("--half-widths", default="0.002,0.01,0.05",
                    help="comma-separated, fractions of the unit box")
    ap.add_argument("--points", type=int, default=30, help="K: 2 K + 1 points a line")
    ap.add_argument("--directions", type=int, default=6)
    ap.add_argument("--threshold", type=float, default=0.01,
                    help="a step of at least this many f* is a cliff")
    ap.add_argument("--outputs-along", default="",
                    help="a parameter: how far the monitor's and the reference model's "
                         "outputs move between neighbouring points of its axis")
    a = ap.parse_args()
    t0, c0 = time.perf_counter(), time.process_time()
    halves = [float(h) for h in a.half_widths.split(",")]
    rows, n = hunt(a.case, a.track, a.seed, halves, a.points, a.directions, a.threshold)
    inst = instance(a.case)
    print(f"# Cliffs near the optimum of {a.case} ({a.track}, noise seed {a.seed}, model "
          f"version {inst.model_version})\n")
    print(f"{n} lines through x* (half-widths {a.half_widths}"
          f" of the unit box, {2 * a.points + 1} points); {len(rows)} with a step of at "
          f"least {a.threshold:g} f* (the atlas's jump: a step beyond the local slope). Per "
          "cliff and monitor step: the line's jump, its largest step "
          "zoomed 40x, bisected to 1e-13 (signed), the bisected point's offset from x* "
          "(fraction of the box along the line), and the test and first discrete state "
          "that differ across it. Units of f*.\n")
    print("| line | half-width | step | line's jump | zoomed 40x | bisected | offset | "
          "first state to differ |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        for label, _ in STEPS:
            c = r[label]
            print(f"| {r['line']} | {r['half']:g} | {label} | {c['step']:.2e} | "
                  f"{c['zoom']:.2e} | {c['pair']:+.2e} | {c['at']:+.5f} | {c['flip']} |")
    if a.outputs_along:
        half = halves[0]
        t, mon, ref = output_steps(a.case, a.track, a.seed, a.outputs_along, half, 2 * a.points)
        print(f"\n## Monitor and reference model along {a.outputs_along}\n")
        print(f"{t.size + 1} points over +-{half:g} of the box along {a.outputs_along} through "
              "x*; between neighbours, how far the outputs move in the fitness's units (every "
              "test's weighted mean square of the change, over f*), for the monitor and the "
              "noise-free reference model (1 us, three-phase drive): median, and every pair "
              "where either moves by 1e-2 f* or more.\n")
        print(f"median: monitor {np.median(mon):.1e}, reference {np.median(ref):.1e}\n")
        print("| offset | monitor | reference |")
        print("|---|---|---|")
        for tt, m, r in zip(t, mon, ref):
            if max(m, r) >= 1e-2:
                print(f"| {tt:+.5f} | {m:.2e} | {r:.2e} |")
    print(f"\n(wall {time.perf_counter() - t0:.0f} s, CPU {time.process_time() - c0:.0f} s)")


if __name__ == "__main__":
    main()
