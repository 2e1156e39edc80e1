"""Run records as IOHprofiler data, for IOHanalyzer and iohinspector.

The format is the one the current IOHexperimenter writes with its default ``Analyzer`` logger
(``ioh::logger::analyzer::v2`` in ``include/ioh/logger/analyzer.hpp`` of
github.com/IOHprofiler/IOHexperimenter, version 0.3.23), and that iohinspector
(``src/iohinspector/data.py``: ``Dataset.from_dict``, ``Scenario.load``) and IOHanalyzer
(``R/readFiles.R``: ``read_index_file__json``, ``read_dat``) read.  Per algorithm folder,
one meta-data file per function and one data file per dimension::

    OUT/<solver>/IOHprofiler_f<fid>_<function>.json
    OUT/<solver>/data_f<fid>_<function>/IOHprofiler_f<fid>_DIM4.dat

The meta file: ``version``, ``suite``, ``function_id`` (int), ``function_name``,
``maximization`` (bool), ``algorithm`` ``{name, info}``, optional ``run_attributes`` (names
of per-run numbers), ``attributes`` (the data columns), ``scenarios``: per dimension
``{dimension, path (of the .dat, relative to the meta file), runs: [{instance, evals (of the
run), best: {evals, y, x}, <run attributes>}]}``.  The data file: each run starts with the
header line ``evaluations raw_y`` and has one line ``evaluation value`` per improvement; its
runs are in the order of ``runs``.  IOHanalyzer splits runs at header lines, iohinspector at
``evaluations == 1``: every run must start at evaluation 1 (ema-bench traces do).

The mapping: one IOH *function* per (case, track), named ``case@track``, with id the 1-based
position of its first appearance (or as given); dimension 4 (the fault vector, ``x`` in
``FAULT_NAMES`` order); minimisation; algorithm = solver, its info the library the solver
wraps (with its version when the record has it; else the suite); suite = the record's suite,
else ``ema-bench``.  The *instance* is the run seed itself (IOH tools store instances as
16-bit integers: iohinspector's ``instance`` column is ``UInt16``, so seeds must be below
65536); the root seed is not folded in, so one export holds runs of one root seed (an export
mixing root seeds is refused: the same seed of two root seeds is two instances).  Seed, root
seed and budget, and where the suite knows them the instance's ``f_star`` and ``f_nominal``,
are run attributes; ``fitness_targets`` lists each run's fitness targets in the written
values, and the meta file's ``targets`` the target precisions and parameter targets.

Suite ``emafdi-v2`` (case keys ``instance@condition``, docs/suite-v2.md): one IOH function per
(condition, track), named ``condition@track``, whose *dimensions* are the tiers (one data file
per tier: IOH's scaling view, ERT against dimension); ``x`` holds the faults then the tier's
effects (the record's ``fitted_effects``); the instance numbers the tier's instance and the
seed, ``1000 x`` the instance's position in its tier plus the seed (seeds below 1000).

Values (``experiment_attributes`` ``value``): ``raw`` (default) writes the best-so-far fitness;
``precision`` writes ``(f - f*) / (f_nominal - f*)``, the precision the suite's fitness targets
are defined on (1e-1 .. 1e-4), so IOH's fixed targets equal the board's; a run without a
known ``f*`` (a seed beyond the shipped ten; a root seed other than 0 without a user table,
``ema-bench targets --root-seed R`` and ``--targets``) cannot be written so and is refused.
Precision is floored at 0: a fit below the best-known ``f*`` (it fits the noise a little
better than the best fit found) has reached every target, and a negative value would make a
log-scaled analysis (iohinspector's ``transform_fval``) NaN; the raw export keeps the exact
value.  The sanity instances (``nominal``, outside every ranking) are left out unless asked
for, and then marked by the experiment attribute ``sanity`` (iohinspector: a column of its
overview).

``raw_y`` is the best-so-far value at each recorded evaluation: at an improvement it is the
evaluated value itself; the last line of a run, at its last evaluation, repeats the best-so-far
value where IOH would write that evaluation's own (records do not keep it).  A trace thinned
by the record writer has fewer improvement lines; none is invented.  Values are written in
Python's shortest round-trip form (``6.19e-05``), not IOH's default ``{:.10f}``, which would
round a normalised fitness of 1e-11 to zero.  Runs that failed with an error (and runs without
an evaluation, which IOH does not record) are skipped.
"""

from __future__ import annotations

import json
import logging
import math
import re
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from ..faults import FAULT_NAMES
from ..suites import DEFAULT, SUITES, find
from ..suites.targets import FITNESS_PRECISIONS, PARAMETER_TARGETS
from ..suites.v1 import SANITY_CASES
from .derive import best_known_of
from .run_store import is_error

log = logging.getLogger("ema_bench")

#: The IOHexperimenter version whose format this writes (IOHanalyzer reads a meta file of
#: version >= 0.3.3 as this JSON format).
IOH_FORMAT_VERSION = "0.3.23"
DEFAULT_SUITE = "ema-bench"
DIMENSION = len(FAULT_NAMES)
ATTRIBUTES = ("evaluations", "raw_y")
RUN_ATTRIBUTES = ("seed", "root_seed", "budget")
#: per-run numbers written where the suite knows them (floats)
OPTIMUM_ATTRIBUTES = ("f_star", "f_nominal")
#: what the data files' ``raw_y`` holds
VALUES = ("raw", "precision")

_UNSAFE = re.compile(r"[^A-Za-z0-9._@+-]")


def function_name(record: Mapping[str, Any]) -> str:
    """The IOH function of a run record: ``case@track`` (v1), ``condition@track`` (suite
    emafdi-v2: one function per condition, one dimension per tier)."""
    case = str(record["case"])
    inst = find(case)
    return f"{case if inst is None else inst.ioh_function}@{record['track']}"


def dimension_of(record: Mapping[str, Any]) -> int:
    """The IOH dimension of a run: its instance's searched parameters (4: the faults)."""
    inst = find(str(record["case"]))
    return DIMENSION if inst is None else inst.dim


def instance_of(record: Mapping[str, Any]) -> int:
    """The IOH instance of a run (0 .. 65535; the root seed is a run attribute): its seed,
    or (suite emafdi-v2, whose function spans a tier's instances) ``1000 x`` the instance's
    position in its tier plus the seed
    (:meth:`~ema_bench.suites.base.Instance.ioh_instance`)."""
    seed, root = int(record["seed"]), int(record.get("root_seed") or 0)
    if seed < 0 or root < 0:
        raise ValueError(f"run {_label(record)}: negative seed or root seed")
    inst = find(str(record["case"]))
    try:
        return (DEFAULT if inst is None else inst.suite).ioh_instance(inst, seed)
    except ValueError as exc:
        raise ValueError(f"run {_label(record)}: {exc}") from None


def optimum(record: Mapping[str, Any]) -> tuple[float, float] | None:
    """``(f*, f_nominal)`` of a run's instance: the suite's shipped one, as the board's
    re-derivation uses, else None (root seed other than 0, seed beyond the shipped ones, the
    sanity case, a custom case).  Never the record's own claim: a record that states a lower
    ``f_star`` would export better precisions than it reached."""
    known = best_known_of(record)
    return None if known is None else (float(known["f_star"]), float(known["f_nominal"]))


def precision(f: float, f_star: float, f_nominal: float) -> float:
    """``max(0, (f - f*) / (f_nominal - f*))``: the suite's precision of a fitness, floored
    at 0 (below ``f*``: every target reached)."""
    return max(0.0, (f - f_star) / (f_nominal - f_star))


def split_runs(records: Iterable[dict]) -> tuple[list[dict], list[dict]]:
    """``(runs to export, runs skipped)``: skipped are runs that failed with an error and
    runs without an evaluation.  ValueError for a record that is not a solver run (no
    ``solver``, ``case``, ``track`` or ``seed``, e.g. a blind-suite case)."""
    kept, skipped = [], []
    for r in records:
        missing = [f for f in ("solver", "case", "track", "seed") if f not in r]
        if missing:
            raise ValueError(f"record {_label(r)} is not a solver run: no "
                             f"{', '.join(map(repr, missing))}")
        (skipped if is_error(r) or not r.get("trace") else kept).append(r)
    return kept, skipped


def export_ioh(records: Iterable[dict], out: Path,
               function_ids: Mapping[str, int] | None = None, value: str = "raw",
               include_sanity: bool = False) -> list[Path]:
    """Write run records as IOHprofiler data under ``out`` (see the module docstring).

    Parameters
    ----------
    records
        Run records (one ``runs.jsonl`` line each); error records and runs without an
        evaluation are skipped, with a warning saying how many.
    out
        Output folder; one sub-folder per solver.  Files of the same names are replaced.
    function_ids
        ``case@track`` -> IOH function id; default: :func:`suite_function_ids` (the same
        id for the same instance and track in every export), then ids after those for
        anything else, in order of first appearance.
    value
        ``raw`` (the best-so-far fitness) or ``precision`` (``(f - f*) / (f_nominal - f*)``:
        IOH's fixed targets are then the board's fitness targets).
    include_sanity
        Export the sanity instances (``nominal``) too, marked by the experiment attribute
        ``sanity``; by default they are left out, as from every ranking.

    Returns
    -------
    list of Path
        The files written: per solver and function, the meta file then the data file.

    Raises
    ------
    ValueError
        A record lacks a field or has a malformed trace, a function has no id (or two share
        one), two solver or function names map to the same file name, the runs are of
        several root seeds, or (``value="precision"``) a run has no known ``f*``.
    """
    if value not in VALUES:
        raise ValueError(f"value must be one of {', '.join(VALUES)}, got {value!r}")
    runs, skipped = split_runs(records)
    if not include_sanity:
        sanity = [r for r in runs if r["case"] in SANITY_CASES]
        if sanity:
            log.info("IOH export: left out %d runs of the sanity instances (%s)", len(sanity),
                     ", ".join(SANITY_CASES))
        runs = [r for r in runs if r["case"] not in SANITY_CASES]
    roots = sorted({int(r.get("root_seed") or 0) for r in runs})
    if len(roots) > 1:
        raise ValueError(f"runs of several root seeds ({', '.join(map(str, roots))}) would "
                         "share IOH instance ids; export each root seed separately")
    if value == "precision":
        lacking = [_label(r) for r in runs if optimum(r) is None]
        if lacking:
            raise ValueError(f"{len(lacking)} runs have no known f* for a precision export "
                             f"(e.g. {', '.join(lacking[:3])}): the suite ships f* for root "
                             "seed 0 and its first seeds only; compute a table of their root "
                             "seed ('ema-bench targets --root-seed R --out T.json') and pass "
                             "--targets T.json, or export raw values")
    if skipped:
        log.warning("IOH export: skipped %d runs (%d failed with an error, the others made no "
                    "evaluation)", len(skipped), sum(map(is_error, skipped)))
    names = list(dict.fromkeys(function_name(r) for r in runs))
    ids = _function_ids(names, function_ids)
    groups: dict[tuple[str, str], list[dict]] = {}
    for r in runs:
        groups.setdefault((str(r["solver"]), function_name(r)), []).append(r)
    for r in runs:
        instance_of(r)   # every bad seed is refused before a file is written
    _check_unique_files([s for s, _ in groups], "solver")
    _check_unique_files(names, "function")
    # every file is made before the first is written: a bad record leaves no partial export
    files: list[tuple[Path, str]] = []
    for (solver, name), group in groups.items():
        group.sort(key=lambda r: (dimension_of(r), instance_of(r), int(r.get("budget") or 0)))
        files += _function_files(Path(out) / safe_name(solver), solver, name, ids[name], group,
                                 value)
    for path, text in files:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return [path for path, _ in files]


def safe_name(name: str) -> str:
    """``name`` for a file name: characters other than letters, digits and ``._@+-`` become
    ``_``."""
    safe = _UNSAFE.sub("_", name)
    return "_" if safe in ("", ".", "..") else safe


def suite_function_ids() -> dict[str, int]:
    """``case@track`` -> function id for the suite's instances: 1, 2, ... in the suite's
    order, tracks alternating (``nominal@reference`` 1, ``nominal@twin`` 2, ...); then
    emafdi-v2's ``condition@track`` in its order (``prior@reference`` 49, ...)."""
    from ..instances import TRACKS

    names = [f"{f}@{t}" for s in SUITES.values() for f in s.ioh_functions() for t in TRACKS]
    return {n: i for i, n in enumerate(names, 1)}


def function_id(name: str) -> int:
    """The IOH function id of ``case@track`` (or ``condition@track``) in an export without
    given ids: its :func:`suite_function_ids` id, or the first id after the suite's for a
    custom instance (what the ioh adapter logs, so its data and an export pool)."""
    return _function_ids([name], None)[name]


def _function_ids(names: list[str], given: Mapping[str, int] | None) -> dict[str, int]:
    if given is None:
        fixed = suite_function_ids()
        extra = [n for n in names if n not in fixed]
        fixed.update({n: i for i, n in enumerate(extra, len(fixed) + 1)})
        return {n: fixed[n] for n in names}
    missing = [n for n in names if n not in given]
    if missing:
        raise ValueError(f"no function id given for {', '.join(missing)}")
    ids = {n: int(given[n]) for n in names}
    if any(i < 0 for i in ids.values()) or len(set(ids.values())) < len(ids):
        raise ValueError(f"function ids must be distinct and >= 0, got {ids}")
    return ids


def _check_unique_files(names: Iterable[str], what: str) -> None:
    seen: dict[str, str] = {}
    for n in dict.fromkeys(names):
        other = seen.setdefault(safe_name(n), n)
        if other != n:
            raise ValueError(f"{what} names {other!r} and {n!r} map to the same file name")


def _function_files(folder: Path, solver: str, name: str, fid: int, group: list[dict],
                    value: str = "raw") -> list[tuple[Path, str]]:
    """``(path, text)`` of the meta file and the data files (one per dimension) of one
    solver on one function."""
    stem = f"f{fid}_{safe_name(name)}"
    # per-run numbers every run of the file has (IOH's run attributes: one list per file)
    attrs = [a for a in RUN_ATTRIBUTES if all(r.get(a) is not None for r in group)]
    optima = [optimum(r) for r in group]
    known = all(o is not None for o in optima)
    lines: dict[int, list[str]] = {}
    scenarios: dict[int, list[dict]] = {}
    for r, opt in zip(group, optima):
        trace = _trace(r)
        if value == "precision":
            f_star, f_nom = opt
            trace = [(e, precision(y, f_star, f_nom)) for e, y in trace]
        dim = dimension_of(r)
        out = lines.setdefault(dim, [])
        out.append(" ".join(ATTRIBUTES))
        out += [f"{e} {y!r}" for e, y in trace]
        best_y = min(y for _, y in trace)
        best_e = next(e for e, y in trace if y == best_y)
        run = {"instance": instance_of(r), "evals": _int(r, "evaluations"),
               "best": {"evals": best_e, "y": best_y, "x": _x(r)},
               **{a: _int(r, a) for a in attrs}}
        if known:
            run.update(zip(OPTIMUM_ATTRIBUTES, opt))
            run["fitness_targets"] = (list(FITNESS_PRECISIONS) if value == "precision" else
                                      [opt[0] + p * (opt[1] - opt[0])
                                       for p in FITNESS_PRECISIONS])
        scenarios.setdefault(dim, []).append(run)
    suites = {r.get("suite") or DEFAULT_SUITE for r in group}
    if len(suites) > 1:
        raise ValueError(f"{solver} on {name}: runs of several suites "
                         f"({', '.join(sorted(suites))}); export them separately")
    suite = suites.pop()
    dat = {d: f"data_{stem}/IOHprofiler_f{fid}_DIM{d}.dat" for d in scenarios}
    meta = {
        "version": IOH_FORMAT_VERSION, "suite": suite, "function_id": fid,
        "function_name": name, "maximization": False,
        "algorithm": {"name": solver, "info": _info(group[0]) or suite},
        "experiment_attributes": [
            {"value": value}, {"sanity": str(group[0]["case"] in SANITY_CASES)},
            {"root_seed": str(int(group[0].get("root_seed") or 0))}],
        "run_attributes": attrs + (list(OPTIMUM_ATTRIBUTES) if known else []),
        "attributes": list(ATTRIBUTES),
        "targets": {"fitness_precisions": list(FITNESS_PRECISIONS),
                    "parameter_targets": list(PARAMETER_TARGETS)},
        "scenarios": [{"dimension": d, "path": dat[d], "runs": runs}
                      for d, runs in scenarios.items()],
    }
    return [(folder / f"IOHprofiler_{stem}.json", json.dumps(meta, indent=1, allow_nan=False)
             + "\n")] + [(folder / dat[d], "\n".join(text) + "\n")
                         for d, text in lines.items()]


def _label(r: Mapping[str, Any]) -> str:
    return str(r.get("key") or "|".join(str(r.get(f)) for f in ("solver", "case", "track",
                                                                   "seed")))


def _int(r: Mapping[str, Any], field: str) -> int:
    try:
        return int(r[field])
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"run {_label(r)}: {field!r} missing or not an integer") from None


def _trace(r: Mapping[str, Any]) -> list[tuple[int, float]]:
    """The record's ``[evaluation, best-so-far]`` pairs, checked: evaluations increase from 1,
    values are finite."""
    try:
        trace = [(int(e), float(y)) for e, y in r["trace"]]
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"run {_label(r)}: 'trace' is not a list of [evaluation, value] "
                         "pairs") from None
    evals = [e for e, _ in trace]
    if not evals or evals[0] != 1 or any(b <= a for a, b in zip(evals, evals[1:])):
        raise ValueError(f"run {_label(r)}: trace evaluations must increase from 1, got "
                         f"{evals[:5]}{' ...' if len(evals) > 5 else ''}")
    if not all(math.isfinite(y) for _, y in trace):
        raise ValueError(f"run {_label(r)}: trace has a non-finite value")
    return trace


def _x(r: Mapping[str, Any]) -> list[float]:
    """The run's final vector: the faults (``x``), then its instance's fitted effects
    (``fitted_effects``) in the instance's order."""
    inst = find(str(r["case"]))
    try:
        x = [float(r["x"][n]) for n in FAULT_NAMES]
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"run {_label(r)}: 'x' lacks one of {', '.join(FAULT_NAMES)}") from None
    effects = () if inst is None else inst.augment
    try:
        return x + [float(r["fitted_effects"][n]) for n in effects]
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"run {_label(r)}: 'fitted_effects' lacks one of "
                         f"{', '.join(effects)}") from None


def _info(r: Mapping[str, Any]) -> str:
    """The library the solver wraps, with its version when the record has it."""
    lib = str(r.get("info") or "")
    version = (r.get("library") or {}).get(lib) if lib else None
    return f"{lib} {version}" if version else lib


def read_ioh(folder: Path) -> list[dict[str, Any]]:
    """The runs of the IOHprofiler data under ``folder`` (every ``IOHprofiler_*.json`` meta
    file below it and the data files it names), read from the format alone.

    Returns
    -------
    list of dict
        Per run: ``algorithm``, ``algorithm_info``, ``suite``, ``function_id``,
        ``function_name``, ``maximization``, ``dimension``, ``instance``, ``run_evals`` (the
        run's evaluations), ``evals`` and ``raw_y`` (the data lines), ``best_y``,
        ``best_evals``, ``best_x`` and the run attributes (``attributes``).

    Raises
    ------
    ValueError
        A data file's runs do not match its meta file's, or a line does not parse.
    """
    out = []
    for meta_path in sorted(Path(folder).rglob("IOHprofiler_*.json")):
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
        for scen in meta["scenarios"]:
            dat = meta_path.parent / scen["path"]
            blocks = _dat_runs(dat)
            if len(blocks) != len(scen["runs"]):
                raise ValueError(f"{dat}: {len(blocks)} runs, {meta_path} lists "
                                 f"{len(scen['runs'])}")
            for run, (header, rows) in zip(scen["runs"], blocks):
                cols = {h: [row[i] for row in rows] for i, h in enumerate(header)}
                out.append({
                    "algorithm": meta["algorithm"]["name"],
                    "algorithm_info": meta["algorithm"]["info"],
                    "suite": meta["suite"], "function_id": meta["function_id"],
                    "function_name": meta["function_name"],
                    "maximization": meta["maximization"], "dimension": scen["dimension"],
                    "instance": run["instance"], "run_evals": run["evals"],
                    "evals": [int(v) for v in cols["evaluations"]], "raw_y": cols["raw_y"],
                    "best_y": run["best"]["y"], "best_evals": run["best"]["evals"],
                    "best_x": run["best"]["x"],
                    "attributes": {a: run[a] for a in meta.get("run_attributes", [])},
                })
    return out


def _dat_runs(path: Path) -> list[tuple[list[str], list[list[float]]]]:
    """``(header, rows)`` per run of a .dat file: a line that does not start with a number
    is a header and starts a run."""
    runs: list[tuple[list[str], list[list[float]]]] = []
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        fields = line.split()
        if not fields:
            continue
        try:
            float(fields[0])
        except ValueError:
            runs.append((fields, []))
            continue
        if not runs:
            raise ValueError(f"{path}:{n}: data before the first header line")
        try:
            runs[-1][1].append([float(v) for v in fields])
        except ValueError:
            raise ValueError(f"{path}:{n}: not a number in {line!r}") from None
    return runs


def optima(folder: Path | str) -> list[dict[str, Any]]:
    """``{function_id, instance, f_star, f_nominal}`` of each instance in the IOHprofiler
    data under ``folder`` that has them: run attributes, which iohinspector (0.0.8) does not
    read; join these rows to its frame on ``function_id`` and ``instance`` (one export holds
    one root seed, so the pair names one instance's ``f*``)."""
    rows: dict[tuple[int, int], dict[str, Any]] = {}
    for r in read_ioh(Path(folder)):
        a = r["attributes"]
        if "f_star" in a:
            rows.setdefault((r["function_id"], r["instance"]), {
                "function_id": r["function_id"], "instance": r["instance"],
                "f_star": a["f_star"], "f_nominal": a["f_nominal"]})
    return list(rows.values())
