"""Coverage of the intervals, measured: fits with intervals on seeded instances whose truth
is known, and the fraction of intervals that contain it.

Instance ``i`` of a run is the seeded random case (:func:`~ema_bench.faults.random_faults`,
heterogeneity 1) of the run node ``run_seed(root_seed, i)``; its noise, its solver and its
bootstrap draw from that node's streams, so one (track, root seed, index, settings) is one
record, bit for bit.  The instances run on the sweep engine
(:func:`~ema_bench.sweep.loop.run_sweep`): records are appended to a JSON-lines file as they
finish (type-checked when read back, :data:`RECORD_SCHEMA`); a rerun, or a second process
on the same files, runs exactly the instances missing.
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..faults import FAULT_NAMES, LOWER, UPPER, faults_to_dict
from ..progress import log
from ..seeding import run_seed, stream
from ..sweep import store as sweep_store
from ..sweep.executors import Job
from ..sweep.loop import run_sweep
from ..sweep.schema import opt, req
from . import conformal as cal
from .local import UncertaintyError
from .methods import MISFIT_RATIO

#: The solver and budget of the fits (differential evolution at 5000 evaluations reaches the
#: twin optimum on every seeded instance tried; CMA-ES at 3000 missed one in 60).
SOLVER = "de"
BUDGET = 5000


@dataclass(frozen=True)
class Settings:
    """What a coverage run is: the records of two runs with equal settings are comparable."""

    track: str = "twin"
    method: str = "laplace"
    level: float = 0.95
    solver: str = SOLVER
    budget: int = BUDGET
    root_seed: int = 0
    noise_scale: float = 1.0
    model_form: str = "auto"

    def key(self, index: int) -> str:
        return f"{self.track}|{self.method}|{self.root_seed}|{index}"


_ENDS = req("dict", values="number|null")
_PAIRS = req("dict", values="list|null")   # per fault, an interval [low, high]
#: The fields of a coverage record a reader relies on, by JSON type.
RECORD_SCHEMA = {
    "key": req("str"), "index": req("int"), "settings": req("dict"),
    "truth": req("dict", values="number|null"), "estimate": req("dict", values="number|null"),
    "low": _ENDS, "high": _ENDS, "uncalibrated": _PAIRS,
    "noise_only": _PAIRS, "factor": req("list|null"), "calibration": req("str"),
    "model_form": req("str"), "noise_ratio": req("dict"), "fitness": req("number"),
    "interval_evaluations": req("int"), "non_identifiable": req("list"),
    "fit_fitness": opt("number"), "fit_evaluations": opt("int"), "error": opt("str"),
}


def _of(settings: Settings):
    """record -> the instance it completes for ``settings`` (``None``: another run's)."""
    same = asdict(settings)

    def task_of(record: dict) -> int | None:
        i = record["index"]
        return i if record["key"] == settings.key(i) and record["settings"] == same else None
    return task_of


def _problem(track: str, root_seed: int, index: int, budget: int):
    from ..suites.problem import make_problem

    return make_problem("seeded", track=track, seed=run_seed(root_seed, index), budget=budget)


@functools.lru_cache(maxsize=1024)
def _fit(track: str, root_seed: int, index: int, solver: str, budget: int):
    """The solver's result on an instance (cached: runs that differ only in how the
    intervals are made, such as a noise-scale study or another method, share their fits)."""
    from ..registry import run_solver

    problem = _problem(track, root_seed, index, budget)
    return run_solver(solver, problem, seed=run_seed(root_seed, index))


def run_instance(settings: Settings, index: int) -> dict[str, object]:
    """Fit instance ``index`` and compute its intervals; the record (JSON-ready)."""
    from .methods import intervals

    node = run_seed(settings.root_seed, index)
    res = _fit(settings.track, settings.root_seed, index, settings.solver, settings.budget)
    problem = _problem(settings.track, settings.root_seed, index, settings.budget)
    truth = np.array([problem.score(res.x).truth[n] for n in FAULT_NAMES])
    base = {"key": settings.key(index), "index": index, "settings": asdict(settings),
            "truth": faults_to_dict(truth), "fit_fitness": float(res.fitness),
            "fit_evaluations": int(res.evaluations)}
    try:
        iv = intervals(problem.objective, res.x, method=settings.method,
                       level=settings.level, track=settings.track,
                       model_form=settings.model_form, noise_scale=settings.noise_scale,
                       seed=stream(node, "intervals"))
    except UncertaintyError as exc:
        # no interval is a miss, logged and recorded; never the end of the run
        log.warning("coverage %s: no interval: %s", settings.key(index), exc)
        none = {n: [None, None] for n in FAULT_NAMES}
        return {**base, "error": str(exc), "estimate": faults_to_dict(res.x),
                "low": {n: None for n in FAULT_NAMES}, "high": {n: None for n in FAULT_NAMES},
                "uncalibrated": none, "noise_only": none, "factor": None,
                "calibration": "none", "model_form": settings.model_form, "noise_ratio": {},
                "fitness": float(res.fitness), "interval_evaluations": 0,
                "non_identifiable": []}
    u = iv.estimate
    raw_lo, raw_hi = iv.uncalibrated()
    return {
        **base, "estimate": faults_to_dict(u),
        "low": faults_to_dict(iv.low), "high": faults_to_dict(iv.high),
        "uncalibrated": {n: [float(a), float(b)] for n, a, b in zip(FAULT_NAMES, raw_lo,
                                                                     raw_hi)},
        "noise_only": {n: [float(a), float(b)] for n, a, b in zip(FAULT_NAMES, iv.noise_low,
                                                                   iv.noise_high)},
        "factor": iv.factor.tolist(), "calibration": iv.calibration,
        "model_form": iv.model_form, "noise_ratio": iv.noise_ratio,
        "fitness": iv.fitness, "interval_evaluations": iv.evaluations,
        "non_identifiable": iv.identifiability["non_identifiable"],
    }


def _ends(pair: Sequence[float | None]) -> tuple[float, float]:
    """An interval's ends; NaN for a record without one (which then covers nothing)."""
    return tuple(math.nan if v is None else float(v) for v in pair)  # type: ignore[return-value]


def _run_many(settings: tuple[Settings, ...], job: Job) -> list[dict[str, object]]:
    return [run_instance(st, job.data) for st in settings]


def read_records(path: Path) -> dict[str, dict]:
    """Records of a JSON-lines file by key, type-checked (a torn last line of an interrupted
    run is skipped)."""
    return {r["key"]: r for r in sweep_store.read_records(path, schema=RECORD_SCHEMA)}


def run(settings: Settings, n: int, path: Path | None = None, workers: int = 1,
        quiet: bool = False) -> list[dict]:
    """Records of instances ``0 .. n-1``, resuming from (and appending to) ``path``."""
    return run_methods([settings], n, [path], workers, quiet)[0]


def run_methods(settings: Sequence[Settings], n: int, paths: Sequence[Path | None],
                workers: int = 1, quiet: bool = False) -> list[list[dict]]:
    """:func:`run` for several settings over the same instances (typically one per interval
    method), each instance fitted once for all of them; one records file per settings
    (records in memory alone when a path is ``None``)."""
    tasks = [Job(f"#{i}", i, i) for i in range(n)]
    runner = functools.partial(_run_many, tuple(settings))
    place = {json.dumps(asdict(st), sort_keys=True): k for k, st in enumerate(settings)}
    what = "/".join(st.method for st in settings)
    def route(record: dict) -> int:
        return place[json.dumps(record["settings"], sort_keys=True)]

    sweep = dict(executor="serial" if workers <= 1 else "processes", workers=workers,
                 label=f"coverage {settings[0].track}/{what}", unit="instance", quiet=quiet,
                 route=route)
    if any(p is None for p in paths):
        by_key = [{} for _ in settings]
        for r in run_sweep(tasks, runner, **sweep).records:
            by_key[route(r)][r["key"]] = r
    else:
        stores = [sweep_store.Store(p, task_of=_of(st), schema=RECORD_SCHEMA)
                  for p, st in zip(paths, settings)]
        try:
            for st, store in zip(settings, stores):
                stale = [r["key"] for r in store.records
                         if r["key"] == st.key(r["index"]) and r["settings"] != asdict(st)]
                if stale:
                    raise ValueError(f"{store.path} holds records of other settings "
                                     f"({stale[0]}); use another file")
            run_sweep(tasks, runner, stores, **sweep)
            by_key = [{r["key"]: r for r in store.records} for store in stores]
        finally:
            for store in stores:
                store.close()
    return [[d[st.key(i)] for i in range(n)] for st, d in zip(settings, by_key)]


def wilson(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score interval of a binomial fraction ``k / n``."""
    if n == 0:
        return 0.0, 1.0
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return max(0.0, c - h), min(1.0, c + h)


def recalibrated(records: Sequence[Mapping], factors: Mapping[str, float]) -> list[dict]:
    """Copies of ``records`` whose ``low``/``high`` are the uncalibrated intervals with each
    half-width multiplied by ``factors[fault]`` (clipped to the fault's bounds): the intervals
    a calibration makes, applied after the fact."""
    out = []
    for r in records:
        low, high = {}, {}
        for n, lower, upper in zip(FAULT_NAMES, LOWER, UPPER):
            u = r["estimate"][n]
            a, b = _ends(r["uncalibrated"][n])
            low[n] = max(u - factors[n] * (u - a), lower) if math.isfinite(a) else None
            high[n] = min(u + factors[n] * (b - u), upper) if math.isfinite(b) else None
        out.append({**r, "low": low, "high": high, "factor": [factors[n] for n in FAULT_NAMES]})
    return out


#: ``OUT/TRACK_METHOD.json`` of ``ema-bench coverage``, by JSON type: checked before it is
#: written, and the published JSON Schema (``ema-bench schema coverage-summary``) is made from
#: it (``calibration_table``: which interval table calibrated the run).
SUMMARY_SCHEMA = {
    "coverage": req("dict", values="number|null"), "median_width": req("dict"),
    "coverage_interval": req("dict"), "coverage_noise_only": req("dict"),
    "coverage_uncalibrated": req("dict"), "instances": req("int"), "method": req("str"),
    "track": req("str"), "level": req("number"), "solver": req("str"), "budget": req("int"),
    "root_seed": req("int"), "noise_scale": req("number"), "model_form": req("str"),
    "calibration": req("str"), "interval_evaluations": req("dict"), "misfits": req("int"),
    "errors": req("int"), "calibration_factor": req("dict", values="number"),
    "calibration_table": opt("str"),
}


def summarise(records: Sequence[Mapping], factors: Mapping[str, float] | None = None
              ) -> dict[str, object]:
    """Coverage per fault, median width (% of range), cost; ``factors`` recalibrates the
    intervals first (:func:`recalibrated`; default: the intervals as recorded)."""
    if not records:
        raise ValueError("no coverage records to summarise")
    if factors is not None:
        records = recalibrated(records, factors)
    s = records[0]["settings"]
    ranges = dict(zip(FAULT_NAMES, UPPER - LOWER))
    cover, width, band = {}, {}, {}
    for name in FAULT_NAMES:
        inside, widths = 0, []
        for r in records:
            lo, hi = _ends((r["low"][name], r["high"][name]))
            inside += lo <= r["truth"][name] <= hi
            widths.append(100.0 * (hi - lo) / ranges[name])
        cover[name] = inside / len(records)
        band[name] = list(wilson(inside, len(records)))
        width[name] = float(np.nanmedian(widths)) if np.isfinite(widths).any() else math.nan

    def share(part: str) -> dict[str, float]:
        return {n: float(np.mean([_ends(r[part][n])[0] <= r["truth"][n] <= _ends(r[part][n])[1]
                                  for r in records])) for n in FAULT_NAMES}

    return {
        "coverage": cover, "median_width": width, "coverage_interval": band,
        # what the calibration and the model-form allowance add: the same intervals from the
        # noise alone, and with the allowance but before calibration
        "coverage_noise_only": share("noise_only"),
        "coverage_uncalibrated": share("uncalibrated"),
        "instances": len(records), "method": s["method"], "track": s["track"],
        "level": s["level"], "solver": s["solver"], "budget": s["budget"],
        "root_seed": s["root_seed"], "noise_scale": s["noise_scale"],
        "model_form": records[0]["model_form"], "calibration": records[0]["calibration"],
        "interval_evaluations": {
            "median": float(np.median([r["interval_evaluations"] for r in records])),
            "max": int(max(r["interval_evaluations"] for r in records))},
        "misfits": sum(max(r["noise_ratio"].values(), default=math.inf) > MISFIT_RATIO
                       for r in records),
        "errors": sum("error" in r for r in records),
    }


def calibration_scores(records: Sequence[Mapping]) -> dict[str, list[float]]:
    """Per fault, the nonconformity scores of the uncalibrated intervals of ``records``."""
    # a missing interval scores "never inside", kept finite for strict JSON
    return {n: [min(cal.score(r["truth"][n], r["estimate"][n], *_ends(r["uncalibrated"][n])),
                    1e9) for r in records] for n in FAULT_NAMES}


def write_calibration(runs: Mapping[str, Sequence[Mapping]], path: Path) -> dict:
    """Write the calibration table ``path`` (``--calibrate --out DIR``: DIR/calibration.json)
    from calibration runs (key ``kind|method|model_form`` -> records), keeping the entries of
    other keys already in that file.  Never the shipped table: ValueError for a path inside
    the package (:mod:`ema_bench.interval_calibration_files` ships a table, in a checkout)."""
    from ..interval_calibration_files import inside_package
    from ..jsonio import write_atomic

    if inside_package(path):
        raise ValueError(f"{path}: inside the package, whose data is read-only; write the "
                         "calibration elsewhere and ship it with 'python -m "
                         "ema_bench.interval_calibration_files' in a checkout")
    # read from disk, not the cached copy: another calibration run may have written since
    data = json.loads(Path(path).read_text()) if Path(path).exists() else {"scores": {}}
    data = {"faults": list(FAULT_NAMES), "root_seed": cal.CALIBRATION_ROOT_SEED,
            "scores": dict(data.get("scores", {})), "runs": dict(data.get("runs", {}))}
    for key, records in runs.items():
        data["scores"][key] = calibration_scores(records)
        data["runs"][key] = {"instances": len(records), **{k: records[0]["settings"][k] for k in
                                                          ("solver", "budget", "level",
                                                           "root_seed")}}
    write_atomic(Path(path), json.dumps(data, indent=0, sort_keys=True) + "\n")
    cal.read.cache_clear()
    return data
