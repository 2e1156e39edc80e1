"""The noise-allowed parameter targets of suite emafdi-v3: writes ``suite_tolerances_v3.json``.

For every objective of the suite (instance x condition's tests and outputs: ``no-prior``
shares ``prior``'s), the noise-whitened Gauss-Newton covariance of the fitness's best fit at
the truth (:func:`ema_bench.uncertainty.methods.intervals`, Laplace, datasheet noise, no
polish, no calibration, no model-form allowance: the scatter the sensor noise alone gives
the exact best fit), then per track :func:`ema_bench.suites.v3.noise_z`: the smallest ``z``
for which the best fit lies within ``max(1 % of range, z sigma)`` of the truth on every
judged parameter with probability >= 0.95 (Monte Carlo over the Gaussian; on the reference
track centred on the clean-data bias: ``clean_x`` of v3's own best-known table,
``suite_targets_v3.json``, model version 4 like the covariance's objective).  Prints the
per-instance table (old and new rule, the condition number of the noise-whitened Jacobian
at the truth) as markdown, and with
``--linearisation CASES`` checks the Gaussian by refits from the truth on redrawn noise.

    nice python benchmarks/v3_tolerances.py --out ema_bench/suite_tolerances_v3.json \
        > benchmarks/results/v3_tolerances.md
    nice python benchmarks/v3_tolerances.py --linearisation v3-t12-s06@prior,v3-small@prior \
        --draws 10 --no-write
"""

from __future__ import annotations

import argparse
import json
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from ema_bench.jsonio import write_atomic
from ema_bench.seeding import child, run_seed
from ema_bench.suites import instance, v2, v3
from ema_bench.suites.problem import make_problem
from ema_bench.uncertainty.local import Counter, refit
from ema_bench.uncertainty.methods import intervals

#: Root of the Monte Carlo draws (one child per table entry).
MC_SEED = 20261128
TRACKS = ("reference", "twin")


def tolerance_cases() -> list[str]:
    """One v3 case per objective: the cases whose :func:`v3.tolerance_case` is themselves."""
    return [c for c in v3.SUITE.case_order() if v3.tolerance_case(instance(c)) == c]


def _laplace(case: str):
    """The Laplace intervals at the truth of ``case`` (no polish, datasheet noise): ``.cov``
    is the best fit's covariance (physical units)."""
    p = make_problem(case, track="twin", seed=run_seed(0, 0), budget=1)
    return intervals(p.objective, instance(case).truth, method="laplace", polish=False,
                     calibrate=False, noise="known", model_form="none")


def condition_number(case: str, iv=None) -> float:
    """The condition number of the noise-whitened Jacobian at the truth of ``case`` (from
    its Laplace intervals ``iv`` where given)."""
    s = np.asarray((iv or _laplace(case)).identifiability["singular_values"])
    return float(s[0] / s[-1])


def _x(entry: dict, names) -> np.ndarray:
    return np.array([float(entry["x_star"][n]) for n in names])


def reference_bias(case: str) -> np.ndarray:
    """The clean-data bias of ``case`` on the reference track: ``clean_x`` of its seed-0
    reference entry in v3's best-known table, minus the truth."""
    inst = instance(case)
    entry = inst.best_known("reference", v2.CLEAN_SEED)
    if entry is None or "clean_x" not in entry:
        raise SystemExit(f"{case}: no clean-data fit in {v3.TARGETS_FILE}; compute it first "
                         "(ema-bench targets --suite emafdi-v3)")
    return np.array([float(entry["clean_x"][n]) for n in inst.names]) - inst.truth


def entry(case: str, cov: np.ndarray, track: str, index: int) -> dict:
    inst = instance(case)
    judged = inst.judged(track)
    judged = np.ones(inst.dim, bool) if judged is None else np.asarray(judged, bool)
    bias = reference_bias(case) if track == "reference" else np.zeros(inst.dim)
    ranges = inst.ranges
    z, p_old, p_new = v3.noise_z(cov[np.ix_(judged, judged)], bias[judged], ranges[judged],
                                 seed=child(MC_SEED, index))
    return {"names": list(inst.names), "sigma": [float(s) for s in np.sqrt(np.diag(cov))],
            "bias": [float(b) for b in bias], "judged": [bool(j) for j in judged],
            "z": z, "p_old": round(p_old, 4), "p_new": round(p_new, 4)}


def shipped_inside(case: str, track: str, e: dict) -> tuple[int, int, int]:
    """Of the shipped noisy best fits ``x*`` of ``case`` on ``track`` (every seed of the
    best-known table): how many lie inside every judged 1 % of range, how many inside every
    judged tolerance of the entry ``e``, out of how many."""
    inst = instance(case)
    judged = np.array(e["judged"])
    tol = v3.tolerance(inst.ranges, np.array(e["sigma"]), e["z"])
    old = new = n = 0
    for k in range(v2.TARGET_SEEDS):
        known = inst.best_known(track, k)
        if known is None:
            continue
        d = np.abs(_x(known, inst.names) - inst.truth)[judged]
        n += 1
        old += bool(np.all(d <= v3.FLOOR * inst.ranges[judged]))
        new += bool(np.all(d <= tol[judged]))
    return old, new, n


def linearisation(cases: list[str], draws: int, max_evals: int) -> None:
    """Refit each case's twin data from the truth on ``draws`` redrawn noise seeds (root seed
    1000, so none is a board's): the refits' standard deviation against ``sigma``, and how
    many lie inside every 1 % of range and every tolerance."""
    table = v3.shipped_tolerances()["entries"]
    print("\n## Linearisation check: refits from the truth on redrawn noise (twin, model "
          f"version {v3.V3_MODEL_VERSION})\n")
    print("| case | condition number at the truth | refits | evaluations each | std / sigma "
          "per parameter (median, max) | inside 1 % | inside the tolerance | predicted "
          "p_old, p_new |")
    print("|---|---|---|---|---|---|---|---|")
    for case in cases:
        inst = instance(case)
        e = table.get(v3.tolerance_key(case, "twin"))
        if e is None:
            raise SystemExit(f"{case}: no tolerance entry; compute the table first")
        sigma = np.array(e["sigma"])
        tol = v3.tolerance(inst.ranges, sigma, e["z"])
        est, evals = [], []
        for k in range(draws):
            p = make_problem(case, track="twin", seed=run_seed(1000, k), budget=1)
            counter = Counter(p.objective)
            u0 = p.objective.space.to_unit(inst.truth[None, :])[0]
            u, _ = refit(counter, u0, max_evals=max_evals)
            est.append(p.objective.space.from_unit(u[None, :])[0])
            evals.append(counter.evaluations)
        d = np.array(est) - inst.truth
        ratio = d.std(axis=0, ddof=1) / sigma
        old = int(np.sum(np.all(np.abs(d) <= v3.FLOOR * inst.ranges, axis=1)))
        new = int(np.sum(np.all(np.abs(d) <= tol, axis=1)))
        print(f"| {case} | {condition_number(case):.0f} | {draws} | "
              f"{int(np.median(evals))} | {np.median(ratio):.2f}, "
              f"{ratio.max():.2f} ({inst.names[int(np.argmax(ratio))]}) | {old}/{draws} | "
              f"{new}/{draws} | {e['p_old']:.3f}, {e['p_new']:.3f} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="ema_bench/suite_tolerances_v3.json")
    ap.add_argument("--no-write", action="store_true", help="only the linearisation check")
    ap.add_argument("--linearisation", default="", help="comma-separated v3 cases")
    ap.add_argument("--draws", type=int, default=10)
    ap.add_argument("--max-evals", type=int, default=600)
    a = ap.parse_args()
    t0, c0 = time.perf_counter(), time.process_time()
    if not a.no_write:
        entries, conds = {}, {}
        cases = tolerance_cases()
        for i, case in enumerate(cases):
            iv = _laplace(case)
            conds[case] = condition_number(case, iv)
            for j, track in enumerate(TRACKS):
                entries[v3.tolerance_key(case, track)] = entry(case, iv.cov, track,
                                                               2 * i + j)
        data = {"suite": v3.SUITE_ID, "model_version": v3.V3_MODEL_VERSION,
                "method": {"coverage": v3.COVERAGE, "floor": v3.FLOOR,
                           "mc_draws": v3.MC_DRAWS, "mc_seed": MC_SEED,
                           "command": "python benchmarks/v3_tolerances.py"},
                "entries": entries}
        write_atomic(Path(a.out), json.dumps(data, indent=0, sort_keys=True) + "\n")
        v3.shipped_tolerances.cache_clear()
        report(entries, conds)
    if a.linearisation:
        linearisation(a.linearisation.split(","), a.draws, a.max_evals)
    print(f"\n(wall {time.perf_counter() - t0:.0f} s, CPU {time.process_time() - c0:.0f} s)")


def report(entries: dict, conds: dict) -> None:
    """Per tier, condition and track: the joint probabilities under the old and new rule,
    the shipped noisy best fits inside each and the condition numbers of the noise-whitened
    Jacobian at the truth (``conds``, per case); then every entry."""
    groups: dict = defaultdict(list)
    rows = []
    for key, e in entries.items():
        case, track = key.split("|")
        inst = instance(case)
        old, new, n = shipped_inside(case, track, e)
        groups[(inst.group[0], inst.group[1], track)].append((e, old, new, n, conds[case]))
        sig = np.array(e["sigma"]) / inst.ranges
        worst = int(np.argmax(np.where(e["judged"], sig, -1)))
        rows.append(f"| {case} | {track} | {e['p_old']:.3f} | {e['p_new']:.3f} | "
                    f"{e['z']:.2f} | {inst.names[worst]} {100 * sig[worst]:.2f} % | "
                    f"{old}/{n} | {new}/{n} | {conds[case]:.0f} |")
    print("## Per tier, objective and track\n")
    print("| tier | condition | track | cases | p_old min / median | p_new min | z max | "
          "shipped x* inside 1 % | inside the tolerance | condition number min / median / "
          "max |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for (d, cond, track), g in sorted(groups.items()):
        po = [e["p_old"] for e, *_ in g]
        n = sum(r[3] for r in g)
        cn = [r[4] for r in g]
        print(f"| {d} | {cond} | {track} | {len(g)} | {min(po):.3f} / {np.median(po):.3f} | "
              f"{min(r[0]['p_new'] for r in g):.3f} | {max(r[0]['z'] for r in g):.2f} | "
              f"{sum(r[1] for r in g)}/{n} | {sum(r[2] for r in g)}/{n} | "
              f"{min(cn):.0f} / {np.median(cn):.0f} / {max(cn):.0f} |")
    print("\n## Every entry\n")
    print("| case | track | p_old | p_new | z | widest sigma (% of range) | shipped x* "
          "inside 1 % | inside the tolerance | condition number |")
    print("|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows), flush=True)


if __name__ == "__main__":
    main()
