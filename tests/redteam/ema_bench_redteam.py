"""Red-team solvers, installed as a plugin (an entry point of ``ema_bench.solvers``) only by
the tests that put this folder on ``sys.path``: replay runs solvers in worker processes, which
find them the way they find any submitted plugin."""

from __future__ import annotations

import gc

import numpy as np

from ema_bench import make_problem, register_solver
from ema_bench.faults import FAULT_NAMES, random_faults
from ema_bench.problem import Problem
from ema_bench.prognostics.tracking import TrackStep, register_tracker
from ema_bench.registry import SolveResult
from ema_bench.seeding import stream


@register_solver("rt-truth-peeker", description="reads the truth from memory", library="numpy")
def truth_peeker(problem, budget, seed):
    """Walks the garbage collector to the truthful problem behind its view."""
    for obj in gc.get_objects():
        if isinstance(obj, Problem) and obj.measured is problem.measured and obj.has_truth:
            truth = obj.score(obj.nominal).truth
            problem.evaluate(np.array([truth[n] for n in FAULT_NAMES]))
            break
    else:
        problem.evaluate(problem.start)
    x, f = problem.best
    return SolveResult("rt-truth-peeker", x, f, problem.evaluations, "done", 0.0, {})


@register_solver("rt-private-objective", description="searches a private copy of the objective",
                 library="numpy")
def private_objective(problem, budget, seed):
    """Builds an uncounted copy of the objective from the public API and searches it; the
    record shows one evaluation, the best of the private search."""
    copy = make_problem(measured=problem.measured, budget=10**6)
    rng = np.random.default_rng(seed)
    X = problem.start + 0.05 * (problem.upper - problem.lower) * rng.uniform(-1, 1, (6, 4))
    X = np.clip(X, problem.lower, problem.upper)
    f = copy.evaluate(X)
    problem.evaluate(X[int(np.argmin(f))])
    x, fx = problem.best
    return SolveResult("rt-private-objective", x, fx, problem.evaluations, "done", 0.0, {})


@register_solver("rt-seed-walker", description="rebuilds its run node from its seed",
                 library="numpy")
def seed_walker(problem, budget, seed):
    """Takes its seed for a spawned child of the run node (seed scheme 1: the node's entropy
    and spawn key, plus one index), rebuilds the node and draws the ``seeded`` instance's
    truth from its ``instance`` stream, as ``make_problem`` did."""
    node = np.random.SeedSequence(seed.entropy, spawn_key=seed.spawn_key[:-1])
    problem.evaluate(random_faults(stream(node, "instance"), 1.0))
    x, f = problem.best
    return SolveResult("rt-seed-walker", x, f, problem.evaluations, "done", 0.0, {})


#: The runs this process made before: a module global, the memory a plugin keeps.
_EARLIER_RUNS: list[np.ndarray] = []


@register_solver("rt-remembers", description="carries what it found from run to run",
                 library="numpy")
def remembers(problem, budget, seed):
    """Evaluates the best vector of each earlier run in its process, then the start: its
    first run makes one evaluation, its second two.  Replayed in one process in file order
    (replay before issue 48), every record reproduces; in a fresh process per record, only
    the first."""
    for x in _EARLIER_RUNS[:budget - 1]:
        problem.evaluate(x)
    problem.evaluate(problem.start)
    x, f = problem.best
    _EARLIER_RUNS.append(x)
    return SolveResult("rt-remembers", x, f, problem.evaluations, "done", 0.0, {})


@register_tracker("rt-campaign-peeker", description="looks for the campaign from its process")
def campaign_peeker(campaign_info, seed):
    """Looks through its process for what a tracker must not reach: the campaign object, its
    folder (a path holding a manifest.json), the callers' frames; reports what it found
    (and its parent process)."""
    import os
    import sys

    found = {"parent": os.getppid(), "objects": set(), "folders": set(), "frames": set()}
    for obj in gc.get_objects():
        if type(obj).__name__ in ("Campaign", "UnitSource", "InspectionRecord"):
            found["objects"].add(type(obj).__name__)
        values = (obj.values() if isinstance(obj, dict) else obj
                  if isinstance(obj, list | tuple) else ())
        for v in list(values):
            if isinstance(v, str | os.PathLike) and os.sep in str(v) and len(str(v)) < 500:
                if os.path.isfile(os.path.join(str(v), "manifest.json")):
                    found["folders"].add(str(v))
    frame = sys._getframe(1)
    while frame is not None:
        found["frames"] |= {k for k, v in frame.f_locals.items()
                            if type(v).__name__ in ("Campaign", "UnitSource")}
        frame = frame.f_back
    report = {k: sorted(v) if isinstance(v, set) else v for k, v in found.items()}

    def step(insp):
        x = {n: float(v) for n, v in zip(FAULT_NAMES, (1.0, 0.1689, 0.0, 1e5))}
        return TrackStep(flight=insp.flight, estimate=x, low=x, high=x, rul=1.0, rul_low=0.0,
                         rul_high=2.0, failing_fault=None, replace=False, evaluations=0,
                         extra={"found": report, "settings": campaign_info,
                                "seed": str(seed.entropy)})
    return step
