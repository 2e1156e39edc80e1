"""The suite's best-known optima ``f*``: one long multi-solver polishing run per instance.

For each (instance, track, noise seed) of the suite (root seed 0, seeds
``0 .. TARGET_SEEDS - 1``; the sanity case ``nominal`` has no fitness targets) three runs of
the zoo's own solvers, ``POLISH_BUDGET`` evaluations in all:

1. ``least-squares`` (trust-region reflective) warm-started at the truth,
2. ``powell`` warm-started at the best point of 1,
3. ``cmaes`` from the nominal vector (the global view: a better basin elsewhere shows here).

``f*`` is the lowest fitness any of them evaluated, ``x*`` its point, ``f_nominal`` the fitness
of the nominal vector (the start of every zoo solver; the top of the target ladder).  On the
twin track ``f*`` lies below the fitness of the truth (the noise moves the optimum); on the
reference track ``x*`` shows the model-form bias (``bias_range_error``: its largest distance
from the truth in fractions of range).

``ema-bench targets`` regenerates ``ema_bench/suite_targets.json`` on the sweep engine
(:func:`~ema_bench.sweep.loop.run_sweep`: entries are appended to ``<out>.partial.jsonl`` as
they finish, type-checked when read back; a rerun or a second process runs exactly the
instances missing).  A test checks that a short rerun does not
beat a shipped ``f*`` by more than :data:`MARGIN`.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np

from ..faults import NOMINAL
from ..instances import TRACKS
from ..jsonio import write_atomic
from ..registry import run_solver
from ..scoring import range_error
from ..seeding import run_seed
from ..sweep.executors import Job
from ..sweep.loop import run_sweep
from ..sweep.schema import opt, req
from ..sweep.store import Store
from . import DEFAULT, instance, suite_of
from .problem import make_problem
from .targets import (
    TARGET_ROOT_SEED,
    SuiteError,
    check_model_version,
    target_key,
)
from .v1 import SANITY_CASES, TARGET_SEEDS, instance_names
from .v2 import CLEAN_SEED

#: (solver, budget, start) of the polishing stages; start "truth", "previous" or "nominal"
STAGES: tuple[tuple[str, int, str], ...] = (
    ("least-squares", 600, "truth"),
    ("powell", 600, "previous"),
    ("cmaes", 1500, "nominal"),
)
POLISH_BUDGET = sum(b for _, b, _ in STAGES)
#: A rerun may beat a shipped f* by at most this fraction of its f*-to-nominal gap.
MARGIN = 1e-4


def _run_stages(make, stages, truth: np.ndarray, nominal: np.ndarray, seed):
    """Run the polishing ``stages`` on problems from ``make(budget, start)``, each solver
    seeded with ``seed``: the best point, its fitness, the fitness each stage reached and
    the first problem."""
    best_x, best_f, reached, first = truth, np.inf, {}, None
    for solver, budget, start in stages:
        x0 = {"truth": truth, "previous": best_x, "nominal": nominal}[start]
        problem = make(budget, x0)
        if first is None:
            first = problem
        run_solver(solver, problem, budget, seed=seed)
        x, f = problem.best
        reached[solver] = f
        if f < best_f:
            best_x, best_f = x, f
    return best_x, best_f, reached, first


def polish(case: str, track: str, seed: int,
           root_seed: int = TARGET_ROOT_SEED) -> dict[str, object]:
    """The best-known entry of one instance: ``f_star``, ``x_star``, ``f_nominal``,
    ``fitness_at_truth``, ``bias_range_error`` and the fitness each stage reached.

    ``case`` is a case of a suite with the prior (``small``, ``t7-s03@prior``: the polish
    runs on the instance's search space and objective (tests, outputs), from the truth of
    every searched parameter; the entry also holds ``bias_range_errors``, per parameter).
    In a suite whose reference track judges the parameters its clean-data fit keeps
    (:attr:`~ema_bench.suites.base.Suite.clean_fits`), the reference-track entry of seed
    :data:`~ema_bench.suites.v2.CLEAN_SEED` also holds the clean-data fit ``clean_x``
    (:func:`clean_fit`).  ``root_seed``: the seed tree the runs (and so the instance's
    noise) come from; a board at another root seed ranks on a table of its own
    (``ema-bench targets --root-seed R``)."""
    node = run_seed(root_seed, seed)
    inst = instance(case)
    truth = inst.truth
    nominal = np.r_[NOMINAL, np.zeros(truth.size - NOMINAL.size)]   # effects off

    def make(budget: int, x0: np.ndarray):
        return make_problem(case, track=track, seed=node, budget=budget, start=x0)

    best_x, best_f, stages, first = _run_stages(make, STAGES, truth, nominal, node)
    f_nominal = float(first.objective.evaluate(nominal[None, :])[0][0])
    entry = {"key": target_key(case, track, seed), "f_star": float(best_f),
             "x_star": dict(zip(first.names, map(float, best_x))), "f_nominal": f_nominal,
             "fitness_at_truth": first.fitness_at_truth(),
             "bias_range_error": float(np.max(range_error(best_x[:NOMINAL.size],
                                                          truth[:NOMINAL.size]))),
             "stages": stages}
    if root_seed != TARGET_ROOT_SEED:
        entry["root_seed"] = int(root_seed)
    errs = np.abs(best_x - truth) / (first.upper - first.lower)
    entry["bias_range_errors"] = dict(zip(first.names, map(float, errs)))
    if inst.suite.clean_fits and track == "reference" and seed == CLEAN_SEED:
        entry.update(clean_fit(case))
    return entry


#: The clean-data fit: the polish's local stages (the model-form bias is a local property
#: of the truth's neighbourhood; cmaes's global view adds nothing there).
CLEAN_STAGES = tuple(s for s in STAGES if s[2] != "nominal")


def clean_fit(case: str) -> dict[str, object]:
    """The monitor's best fit to *noise-free* reference traces of a v2 case (its instance's
    faults and effects, its condition's tests and outputs), from the truth by
    :data:`CLEAN_STAGES`: ``clean_x`` (name -> value) and ``clean_bias`` (name -> distance
    from the truth in fractions of range).  No solver gets closer to the truth on the
    reference track than this on average: a parameter whose clean bias exceeds
    :data:`~ema_bench.suites.v2.MAX_TARGET_BIAS` carries no parameter target there.  (v1's
    tabulation, :func:`ema_bench.monitor_bias.clean_bias`, spends 12,000 CMA-ES evaluations
    on the faults only.)"""
    from ..effects import effects_vector
    from ..objective import KNOWN_TESTS
    from ..protocol import STANDARD_TESTS
    from ..reference import simulate_reference

    inst = instance(case)
    specs = STANDARD_TESTS if inst.tests is None else tuple(KNOWN_TESTS[n] for n in inst.tests)
    clean = simulate_reference(inst.truth[:NOMINAL.size], effects_vector(dict(inst.effects)),
                               tests=specs, noise=False, adc=False)
    truth = inst.truth

    def make(budget: int, x0: np.ndarray):
        return make_problem(measured=clean, augment=inst.augment, signals=inst.signals,
                            budget=budget, start=x0, params=inst.params)

    # the solvers' streams: the seed-0 entry's node (the clean data have no noise to seed)
    x, _, _, first = _run_stages(make, CLEAN_STAGES, truth, truth,
                                 run_seed(TARGET_ROOT_SEED, CLEAN_SEED))
    errs = np.abs(x - truth) / (first.upper - first.lower)
    return {"clean_x": dict(zip(first.names, map(float, x))),
            "clean_bias": dict(zip(first.names, map(float, errs)))}


#: The fields of a best-known entry, by JSON type.
ENTRY_SCHEMA = {"key": req("str"), "f_star": req("number"),
                "x_star": req("dict", values="number"), "f_nominal": req("number"),
                "fitness_at_truth": req("number"),
                "bias_range_error": req("number"), "stages": req("dict"),
                "root_seed": opt("int")}   # absent: TARGET_ROOT_SEED


#: Optional fields of an entry in a suite with clean-data fits: the per-parameter biases, the
#: clean-data fit (seed-0 reference entries), and what the entry cost (CPU seconds in its
#: worker, wall).
CLEAN_FIELDS = ("bias_range_errors", "clean_x", "clean_bias")
COST_FIELDS = ("cpu_s", "wall_s")


def _polish_key(job: Job) -> dict[str, object]:
    case, track, seed = job.key.split("|")
    t0, c0 = time.perf_counter(), time.process_time()
    entry = polish(case, track, int(seed), job.data)
    return {**entry, "cpu_s": time.process_time() - c0, "wall_s": time.perf_counter() - t0}


def _key(record: dict) -> str:
    return record["key"]


def all_keys() -> list[str]:
    """Every (instance, track, seed) the suite ships an ``f*`` for: the CI baseline's
    instances (``quick``) first, seed by seed, so a partial run covers the quick check."""
    quick = [c for c in instance_names("quick") if c not in SANITY_CASES]
    rest = [c for c in instance_names() if c not in quick and c not in SANITY_CASES]
    return [target_key(c, t, k) for group in (quick, rest)
            for k in range(TARGET_SEEDS) for c in group for t in TRACKS]


def compute_targets(out: Path, workers: int | None = None, quiet: bool = False,
                    keys: list[str] | None = None,
                    root_seed: int = TARGET_ROOT_SEED) -> dict:
    """Polish every instance (resuming from ``<out>.partial.jsonl``) and write ``out``: the
    table of the suite of ``keys`` (default: v1's, :func:`all_keys`; v2's:
    :func:`~ema_bench.suites.v2.target_keys`) at ``root_seed`` (the table records it:
    ``method.root_seed``); SuiteError for keys of two suites, or a partial file of another
    root seed."""
    out = Path(out)
    partial = out.with_name(out.name + ".partial.jsonl")
    keys = all_keys() if keys is None else keys
    suites = {suite_of(k.split("|")[0]).id: suite_of(k.split("|")[0]) for k in keys}
    if len(suites) > 1:
        raise SuiteError(f"keys of suites {sorted(suites)} in one table: compute each apart")
    suite = next(iter(suites.values()), DEFAULT)
    check_model_version(suite.id, suite.model_version)
    workers = workers or os.cpu_count() or 1
    with Store(partial, identity=_key, schema=ENTRY_SCHEMA) as store:
        other = {int(r.get("root_seed", TARGET_ROOT_SEED)) for r in store.records} - {root_seed}
        if other:
            raise SuiteError(f"{partial} holds entries of root seed {sorted(other)[0]}, not "
                             f"{root_seed}: write this table to another --out")
        run_sweep([Job(k, k, int(root_seed)) for k in keys], _polish_key,
                  [store], executor="serial" if workers == 1 else "processes",
                  workers=workers, label="best-known optima", unit="instance", quiet=quiet)
        done = {r["key"]: r for r in store.records}
    fields = ("f_star", "f_nominal", "x_star", "fitness_at_truth", "bias_range_error")
    method = {"stages": [list(s) for s in STAGES], "root_seed": int(root_seed),
              "command": "ema-bench targets"}
    if suite.clean_fits:
        fields += CLEAN_FIELDS + COST_FIELDS
        method["clean_stages"] = [list(s) for s in CLEAN_STAGES]
    data = {"suite": suite.id, "model_version": suite.model_version, "method": method,
            "entries": {k: {f: done[k][f] for f in fields if f in done[k]}
                        for k in keys if k in done}}
    # two runs on one file both write: each through its own temporary file
    write_atomic(out, json.dumps(data, indent=0, sort_keys=True) + "\n")
    return data
