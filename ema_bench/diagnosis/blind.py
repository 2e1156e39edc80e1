"""Blind test of the workflow: hidden cases it must diagnose without seeing the answer.

Each case hides random faults and belongs to one category (:data:`CATEGORIES`, fixed shares
of the suite):

``single``
    one library effect at 1.5-4 times its detection threshold ``detect`` (log-uniform, capped
    at its bound, random sign for two-sided effects); the workflow must name it first.
``near_threshold``
    one library effect at 1-1.5 times ``detect``.
``two_effect``
    two different library effects, each at 1.5-3 times ``detect``; the pairs cycle through
    every pair of drawable effects.  The workflow should name both.
``null``
    the reference model with no effect: the workflow must say none.
``monitor_null``
    data made by the monitor model itself (the twin track): the workflow must say none.
``physical_decoy``
    a physical effect outside the library (:data:`~ema_bench.effects.DECOYS`) in the
    reference model, at 1-4 times ``detect``.
``acquisition_decoy``
    a fault of the acquisition chain applied to the measured traces
    (:mod:`~ema_bench.diagnosis.decoys`: a slow filter, mains hum, clipping, a time shift,
    drift, outliers on one channel).
``effect_acquisition``
    one library effect at 1.5-4 times ``detect`` and one fault of the acquisition chain the
    workflow's acquisition library holds (:data:`ACQUISITION_LIBRARY`, drawn as the decoys
    are); the workflow must name the effect, and name the acquisition fault or flag the
    verdict partial.
``three_effect``
    three different library effects, each at 2-3 times ``detect``, cycling through every
    triple; the workflow should name all three.
``effect_acquisition_sized``, ``near_threshold_acquisition``
    (fourth round) one library effect at 1.5-4 times ``detect`` beside an acquisition fault
    of the workflow's library sized at 1-4 (1-1.5) times its own detection threshold
    (:mod:`~ema_bench.diagnosis.sized`; a stuck channel and 1-2 sample time shifts among
    them), scored as ``effect_acquisition``.
``whole_chain_acquisition``, ``heavy_tailed``
    (issue 46, item 2) one library effect at 1.5-4 times ``detect`` beside a fault of one
    kind on several channels at once, sized at 1-4 times its threshold on each
    (:func:`~ema_bench.diagnosis.sized.draw_chain`: a shared shift or low-pass, a drift or
    hum per channel), or beside heavy-tailed noise on every channel (2-5 % of the samples
    hit by 10-40 noise sd); scored as ``effect_acquisition``, the fault named as the
    workflow's whole-chain suspect (``drift(all)``, ``heavy_tailed(all)``).

A decoy is handled when nothing is named confidently that is not there: the workflow reports
it unexplained or not at all, names a physical effect only flagged partial, or (an
acquisition decoy its acquisition library holds) names that fault on that channel.  The
coarse ``kind`` of a case is ``effect`` (single, near-threshold, two-, three-effect and
effect-plus-acquisition cases), ``null`` or ``decoy``.  Scores: naming accuracy (top-1) of
single effects, both-named rate of pairs, all-named rate of triples, effect named and
acquisition fault named (or flagged) beside it, confident misnames (a named physical effect
or acquisition fault that is not in the case, not flagged partial), false alarms on both
null kinds, decoys handled, held-out gap closed, parameter error and the coverage of the
named effects' intervals.

Records
-------
A case's record (:func:`run_case`) holds its identity (``key``, ``root_seed``, ``seed``,
``model_version``), the truth (the fields of :class:`BlindCase`: ``index``, ``category``,
``kind``, ``effects``, ``faults``, ``decoy``, ``decoy_params``), the answer (``verdict``,
``named``, ``partial``, ``gap_closed``, ``gap_before``, ``gap_after``, ``message``,
``evaluations``, ``wall_s``, ``cpu_s``) and its scores: ``correct`` (single and
near-threshold: the first named effect is the truth) or ``both_named`` and ``one_named``
(pairs), with ``named_partial`` and, per true effect found, ``estimates``, ``param_errors``
(relative), ``intervals`` and ``interval_covers`` (``name -> ...``); ``false_alarm`` (null kinds);
``decoy_ok`` (decoys); ``all_named`` (three effects); ``effect_named``,
``acquisition_named`` and ``acquisition_ok`` (effect plus acquisition fault);
``misnamed`` (every effect and decoy case: the confidently named suspects that are not
there).  ``named_acquisition`` lists the acquisition faults named, ``kind(channel)``.
"""

from __future__ import annotations

import functools
import itertools
import math
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..effects import DECOYS, EFFECT_INDEX, EFFECTS, LIBRARY, effects_vector
from ..faults import faults_to_dict, random_faults
from ..instances import twin_traces
from ..protocol import HOLDOUT_TESTS, STANDARD_TESTS
from ..reference import simulate_reference
from ..seeding import run_seed, stream
from ..sweep.executors import Job
from ..sweep.loop import run_sweep
from ..sweep.schema import opt, req
from ..sweep.store import Store, is_current
from ..trace_cache import MODEL_VERSION
from ..traces import Traces
from . import acquisition, decoys, sized
from .blind_categories import (
    ACQ_MULTIPLES,
    ACQUIRED,
    CATEGORIES,
    CHAIN_CATEGORIES,
    EFFECT_ACQUISITION,
    EXPECTED_TERMS,
    EXTRA_CATEGORIES,
    FOURTH_CATEGORIES,
    KINDS,
    LOOP_CATEGORIES,
    MAGNITUDES,
    OUTSIDE_CATEGORIES,
    OUTSIDE_PHYSICS,
)
from .blind_summary import summarise
from .results import Settings
from .workflow import diagnose

DRAWABLE = tuple(n for n in LIBRARY if math.isfinite(EFFECTS[EFFECT_INDEX[n]].detect))
#: Every unordered pair of different drawable effects (the two-effect cases cycle them).
PAIRS: tuple[tuple[str, str], ...] = tuple(itertools.combinations(DRAWABLE, 2))
#: Every unordered triple of different drawable effects (the three-effect cases cycle them).
TRIPLES: tuple[tuple[str, str, str], ...] = tuple(itertools.combinations(DRAWABLE, 3))
#: The acquisition decoys the suite's categories draw: the second round's six, so that a suite
#: drawn before keeps its cases (the stuck channel of the fourth round is not drawn here).
ACQUISITION = ("lowpass", "mains_hum", "clipping", "time_shift", "drift", "outliers")
#: The acquisition decoys the workflow's acquisition library holds (clipping it does not).
ACQUISITION_LIBRARY = tuple(n for n in ACQUISITION if n in acquisition.KINDS)
TESTS = STANDARD_TESTS + HOLDOUT_TESTS

Runner = Callable[["BlindCase", int, Settings], dict]
CASES_FILE = "blind.jsonl"
_FLAG = opt("bool")
#: The fields of a case's record a reader relies on, by JSON type (older formats' records
#: are read too, then refused by name on resume).
CASE_SCHEMA = {
    "key": req("str"), "root_seed": req("int"), "seed": req("int"), "index": req("int"),
    "model_version": opt("str|int"), "kind": req("str"), "category": opt("str"),
    "effects": opt("dict"), "faults": opt("dict"), "decoy": opt("str|null"),
    "decoy_params": opt("dict"), "verdict": req("str"), "named": opt("list"),
    "named_acquisition": opt("list"), "partial": opt("str|null"),
    "gap_closed": opt("number|null"), "evaluations": opt("int"), "wall_s": opt("number"),
    "cpu_s": opt("number"), "misnamed": opt("list"), "correct": _FLAG, "both_named": _FLAG,
    "one_named": _FLAG, "all_named": _FLAG, "named_partial": _FLAG, "false_alarm": _FLAG,
    "decoy_ok": _FLAG, "effect_named": _FLAG, "acquisition_named": _FLAG,
    "acquisition_ok": _FLAG, "interval_covers": opt("dict|bool"),
    "terms_named": opt("list"), "term_named": _FLAG, "right_term": _FLAG,
    "discoveries": opt("int"),
}


@dataclass(frozen=True)
class BlindCase:
    """One hidden case: its category, the truth and the faults.

    ``effects`` are the effects switched on in the reference model (``name -> value``, empty
    for null and acquisition-decoy cases); ``decoy`` names the decoy (a physical effect or an
    acquisition decoy) and ``decoy_params`` holds an acquisition decoy's keyword arguments.
    """

    index: int
    category: str
    kind: str                       # "effect" | "null" | "decoy"
    effects: dict[str, float]
    faults: dict[str, float]
    decoy: str | None = None
    decoy_params: dict[str, Any] = field(default_factory=dict)


def category_counts(n: int) -> dict[str, int]:
    """How many of ``n`` cases each category gets: its share, rounded by largest remainder
    (ties to the earlier category)."""
    exact = {c: w * n for c, w in CATEGORIES.items()}          # in hundredths of a case
    counts = {c: q // 100 for c, q in exact.items()}
    left = n - sum(counts.values())
    for c in sorted(CATEGORIES, key=lambda c: -(exact[c] % 100))[:left]:
        counts[c] += 1
    return counts


def _magnitude(rng: np.random.Generator, name: str, lo: float, hi: float) -> float:
    """A value of effect ``name`` log-uniform in ``[lo, hi]`` times its ``detect``, capped
    at its upper bound (an effect no size of which is detected, ``detect`` infinite: at its
    bound); negative half the time when the effect is two-sided and the
    negative value is within bounds."""
    spec = EFFECTS[EFFECT_INDEX[name]]
    top = min(hi * spec.detect, spec.upper)
    bottom = min(lo * spec.detect, top)
    # (capped at the bound again: exp(log(upper)) may round above it; no draw that was
    # within the bounds changes)
    value = min(float(math.exp(rng.uniform(math.log(bottom), math.log(top)))), spec.upper)
    if spec.lower < 0.0 and rng.random() < 0.5 and -value >= spec.lower:
        value = -value
    return value


def _perm(rng: np.random.Generator, items: Sequence) -> list:
    """``items`` in a random order of ``rng``."""
    return [items[i] for i in rng.permutation(len(items))]


def _orders(rng: np.random.Generator) -> dict[str, list[tuple[str, ...]]]:
    """The order each category cycles its effects (or decoys) in."""
    return {"single": [(n,) for n in _perm(rng, DRAWABLE)],
            "near_threshold": [(n,) for n in _perm(rng, DRAWABLE)],
            "two_effect": _perm(rng, PAIRS),
            "physical_decoy": [(n,) for n in DECOYS],
            "acquisition_decoy": [(n,) for n in _perm(rng, ACQUISITION)]}


def _extra_orders(rng: np.random.Generator) -> dict[str, list[tuple[str, ...]]]:
    """The order the third round's categories cycle their effects and faults in."""
    return {"effect_acquisition": [(n,) for n in _perm(rng, DRAWABLE)],
            "three_effect": _perm(rng, TRIPLES),
            "effect_acquisition_fault": [(n,) for n in _perm(rng, ACQUISITION_LIBRARY)]}


def _fourth_orders(rng: np.random.Generator) -> dict[str, list[tuple[str, ...]]]:
    """The order the fourth round's categories cycle their effects and fault kinds in."""
    return {"effect_acquisition_sized": [(n,) for n in _perm(rng, DRAWABLE)],
            "near_threshold_acquisition": [(n,) for n in _perm(rng, DRAWABLE)],
            "sized_kind": [(n,) for n in _perm(rng, tuple(sized.CHANNELS))]}


def _chain_orders(rng: np.random.Generator) -> dict[str, list[tuple[str, ...]]]:
    """The order the whole-chain categories cycle their effects and fault kinds in."""
    return {"whole_chain_acquisition": [(n,) for n in _perm(rng, DRAWABLE)],
            "heavy_tailed": [(n,) for n in _perm(rng, DRAWABLE)],
            "chain_kind": [(n,) for n in _perm(rng, tuple(sized.CHAIN_CHANNELS))]}


def _outside_orders(rng: np.random.Generator) -> dict[str, list[tuple[str, ...]]]:
    """The order the outside-library category cycles its physics in."""
    return {"outside_library": [(n,) for n in _perm(rng, OUTSIDE_PHYSICS)]}


def _loop_orders(rng: np.random.Generator) -> dict[str, list[tuple[str, ...]]]:
    """The current loop's and the sensor's outside-library categories: one physics each."""
    return {c: [(n,)] for c, n in LOOP_CATEGORIES.items()}


def draw_cases(n: int, seed: int, extra: int = 0, fourth: int = 0,
               chain: int = 0, outside: int = 0) -> list[BlindCase]:
    """``n`` hidden cases of the suite of root seed ``seed``, laid out in the fixed shares of
    :data:`CATEGORIES`, then ``extra`` cases of each of :data:`EXTRA_CATEGORIES` (indices
    ``n`` on, shuffled); each category cycles through its effects, pairs, triples or decoys
    so that every one appears.

    The layout (categories, effect order, magnitudes) comes from the root's ``plan`` stream
    (the extra cases' from its ``plan`` stream number 1, so ``extra`` leaves the first ``n``
    cases as they were); case ``i``'s faults from the ``instance`` stream of run ``i``
    (``run_seed(seed, i)``), an acquisition fault's channel and magnitude from its
    ``acquisition`` stream.  ``fourth`` cases of each of :data:`FOURTH_CATEGORIES` follow
    (indices ``n + 2 extra`` on; their layout from ``plan`` stream number 2), then
    ``chain`` cases of each of :data:`CHAIN_CATEGORIES` (``plan`` stream number 3), then
    ``outside`` cases of each of :data:`OUTSIDE_CATEGORIES` (``plan`` stream number 4) and
    as many of each of :data:`LOOP_CATEGORIES` (``plan`` stream number 5)."""
    if min(n, extra, fourth, chain, outside) < 0:
        raise ValueError(f"cases, extra, fourth-round, chain and outside cases must be >= 0, "
                         f"got {n}, {extra}, {fourth}, {chain} and {outside}")
    rng = np.random.default_rng(stream(seed, "plan"))
    layout = [c for c, k in category_counts(n).items() for _ in range(k)]
    rng.shuffle(layout)
    orders, taken = _orders(rng), Counter()
    cases = _draw(layout, 0, seed, rng, orders, taken)
    # the later rounds: each its own plan stream (number k), after the cases before it, so
    # adding one leaves every case drawn before as it was
    rounds = ((extra, EXTRA_CATEGORIES, _extra_orders), (fourth, FOURTH_CATEGORIES,
              _fourth_orders), (chain, CHAIN_CATEGORIES, _chain_orders),
              (outside, OUTSIDE_CATEGORIES, _outside_orders),
              (outside, tuple(LOOP_CATEGORIES), _loop_orders))
    first = n
    for k, (count, categories, order) in enumerate(rounds, start=1):
        if count:
            rng = np.random.default_rng(stream(seed, "plan", k))
            layout = [c for c in categories for _ in range(count)]
            rng.shuffle(layout)
            cases += _draw(layout, first, seed, rng, order(rng), Counter())
        first += len(categories) * count
    return cases


def _draw(layout: list[str], first: int, seed: int, rng: np.random.Generator,
          orders: dict[str, list[tuple[str, ...]]], taken: Counter) -> list[BlindCase]:
    """The cases of ``layout`` (their categories, in order), indices from ``first``."""
    cases = []
    for i, category in enumerate(layout, start=first):
        node = run_seed(seed, i)
        faults = faults_to_dict(random_faults(stream(node, "instance"), 1.0))
        names: tuple[str, ...] = ()
        if category in orders:
            names = orders[category][taken[category] % len(orders[category])]
            taken[category] += 1
        effects = ({name: _magnitude(rng, name, *MAGNITUDES[category]) for name in names}
                   if category in MAGNITUDES else {})
        decoy = names[0] if KINDS[category] == "decoy" else None
        if category == "effect_acquisition":
            cycle = orders["effect_acquisition_fault"]
            decoy = cycle[(taken[category] - 1) % len(cycle)][0]
        acq_rng = np.random.default_rng(stream(node, "acquisition"))
        if category in CHAIN_CATEGORIES:
            decoy = "heavy_tailed"
            if category == "whole_chain_acquisition":
                cycle = orders["chain_kind"]
                decoy = cycle[taken["chain"] % len(cycle)][0]
                taken["chain"] += 1
            params = sized.draw_chain(decoy, *ACQ_MULTIPLES.get(category, (1.0, 1.0)),
                                      acq_rng)
        elif category in FOURTH_CATEGORIES:
            cycle = orders["sized_kind"]
            decoy = cycle[(taken["sized"]) % len(cycle)][0]
            taken["sized"] += 1
            params = sized.draw(decoy, *ACQ_MULTIPLES[category], acq_rng)
        else:
            params = decoys.draw(decoy, acq_rng) if category in ACQUIRED else {}
        cases.append(BlindCase(i, category, KINDS[category], effects, faults, decoy, params))
    return cases


def case_record(case: BlindCase, seed: int) -> dict:
    """What identifies a case's record: its key, run (root seed, seed), model version and the
    hidden truth."""
    return {"key": f"case{case.index}", "root_seed": int(seed), "seed": case.index,
            "model_version": MODEL_VERSION, **asdict(case)}


def measured_traces(case: BlindCase, seed: int) -> Traces:
    """The measured traces of a hidden case (step, sine and the held-out sine2).

    The reference model with the case's effects and the sensor noise of the run's ``noise``
    stream (the traces of ``ema-bench simulate --root-seed R --seed i``); for
    ``monitor_null`` the monitor model through the same sensors (its ``model`` meta hidden);
    for ``acquisition_decoy`` and ``effect_acquisition`` the reference traces with the
    acquisition fault applied."""
    node = run_seed(seed, case.index)
    x = np.array(list(case.faults.values()))
    if case.category in ("monitor_null", "outside_monitor_null"):
        tr = twin_traces(x, effects_vector({}), stream(node, "noise"), TESTS)
        return tr.with_meta(model=None)
    tr = simulate_reference(x, case.effects, tests=TESTS, seed=stream(node, "noise"))
    if case.category in CHAIN_CATEGORIES:
        tr = sized.apply_chain(case.decoy, tr, case.decoy_params)
    elif case.category in ACQUIRED:
        tr = decoys.apply(case.decoy, tr, sized.decoy_params(case.decoy_params))
    return tr


def run_case(case: BlindCase, seed: int, settings: Settings) -> dict:
    """Make a hidden case's data, diagnose it blind, and score the answer.

    Case ``i`` of root ``seed`` is run ``i`` of the seed tree: its diagnosis is that of
    ``ema-bench diagnose --root-seed R --seed i`` on :func:`measured_traces`."""
    t0, c0 = time.perf_counter(), time.process_time()
    node = run_seed(seed, case.index)
    measured = measured_traces(case, seed)
    # the workflow sees the traces only
    d = diagnose(measured.with_meta(faults=None, effects=None), settings,
                 seed=stream(node, "diagnosis"))
    return {**case_record(case, seed), "verdict": d.verdict, "named": [e.name for e in d.effects],
            "named_acquisition": [a.name for a in getattr(d, "acquisition", [])],
            "terms_named": [t.name for t in getattr(d, "terms", [])],
            "partial": d.gap.get("partial"), "gap_closed": d.gap.get("closed", 0.0),
            "gap_before": d.gap["before"], "gap_after": d.gap["after"],
            "message": d.message, "evaluations": d.evaluations, **score(case, d),
            "wall_s": time.perf_counter() - t0,
            # this process's CPU time: comparable across loads of a shared machine
            "cpu_s": time.process_time() - c0}


def score(case: BlindCase, d: Any) -> dict:
    """The scores of diagnosis ``d`` (a :class:`~ema_bench.diagnosis.results.Diagnosis`)
    of ``case``: by kind, see the module's docstring."""
    if case.kind == "null":
        return {"false_alarm": d.verdict != "none",
                **({"discoveries": len(d.terms)} if case.category in OUTSIDE_CATEGORIES
                   else {})}
    if case.kind == "outside":
        return outside_score(case, d)
    fault = acquisition_truth(case)
    findings = list(d.effects) + list(getattr(d, "acquisition", []))
    # a verdict flagged partial claims no suspect as the whole answer
    flagged = bool(d.gap.get("partial")) or any(f.partial for f in findings)
    misnamed = [] if flagged else sorted(f.name for f in findings
                                         if f.name not in case.effects and f.name != fault)
    if case.kind == "decoy":
        return {"decoy_ok": not misnamed, "misnamed": misnamed}
    named = [e.name for e in d.effects]
    truth = list(case.effects)
    rec: dict[str, Any] = {"misnamed": misnamed}
    if case.category == "two_effect":
        found = [n for n in truth if n in named]
        rec.update(both_named=set(named) == set(truth), one_named=bool(found))
    elif case.category == "three_effect":
        found = [n for n in truth if n in named]
        rec.update(all_named=set(truth) <= set(named), n_named=len(found))
    elif case.category in EFFECT_ACQUISITION:
        found = [n for n in truth if n in named]
        acq_named = fault in [a.name for a in getattr(d, "acquisition", [])]
        rec.update(effect_named=bool(found), acquisition_named=acq_named,
                   acquisition_ok=acq_named or flagged)
    else:
        found = truth if named and named[0] == truth[0] else []
        rec["correct"] = bool(found)
    rec["named_partial"] = any(e.partial for e in d.effects if e.name in found)
    return {**rec, **_estimates(case.effects, d.effects, found)}


def outside_score(case: BlindCase, d: Any) -> dict:
    """An outside-library case's scores: whether a term was named, whether the right one
    (:data:`~ema_bench.diagnosis.blind_categories.EXPECTED_TERMS`: its equation and form;
    for physics no term has the form, that none was named) and the library effects named
    without a partial flag (``misnamed``)."""
    terms = [t.name for t in d.terms]
    want = EXPECTED_TERMS[next(iter(case.effects))]
    flagged = bool(d.gap.get("partial")) or any(e.partial for e in d.effects)
    return {"term_named": bool(terms), "discoveries": len(terms),
            "right_term": want in terms if want else not terms,
            "misnamed": [] if flagged else sorted(e.name for e in d.effects)}


def acquisition_truth(case: BlindCase) -> str | None:
    """The acquisition fault a case hides, as the workflow names it (``kind(channel)``), or
    ``None`` (also for a fault its library does not hold, e.g. clipping)."""
    if case.category not in ACQUIRED or case.decoy not in acquisition.KINDS:
        return None
    return f"{case.decoy}({case.decoy_params.get('signal')})"


def _estimates(truth: dict[str, float], findings: Sequence[Any], found: Sequence[str]) -> dict:
    """Estimate, relative error, 95 % interval and whether it covers the truth, per found
    true effect (``name -> ...`` dicts)."""
    est, err, ivs, covers = {}, {}, {}, {}
    for name in found:
        f = next(e for e in findings if e.name == name)
        if name not in f.params:
            continue
        est[name] = float(f.params[name])
        err[name] = abs(est[name] - truth[name]) / abs(truth[name])
        if len(f.interval) == 2:
            ivs[name] = [float(v) for v in f.interval]
            covers[name] = bool(ivs[name][0] <= truth[name] <= ivs[name][1])
    return {"estimates": est, "param_errors": err, "intervals": ivs, "interval_covers": covers}


# --- running a suite ------------------------------------------------------------------------

def _job(case: BlindCase) -> Job:
    """A case as a task of the sweep engine: its record's key and model version."""
    return Job(f"case{case.index}", (f"case{case.index}", MODEL_VERSION), case)


def _run_task(runner: Runner, seed: int, settings: Settings, job: Job) -> dict:
    return runner(job.data, seed, settings)


def run_blind(n: int, seed: int, out: str | Path | None = None,
              settings: Settings | None = None, quiet: bool = True, workers: int = 1,
              runner: Runner | None = None, extra: int = 0,
              only: Sequence[str] | None = None, fourth: int = 0,
              chain: int = 0, outside: int = 0) -> dict[str, object]:
    """Run (or resume, with ``out``) a blind suite of ``n`` cases (and ``extra`` of each
    third-round category, ``fourth`` of each fourth-round one, ``chain`` of each whole-chain
    one and ``outside`` of each outside-library one, :func:`draw_cases`) and summarise it;
    progress as :func:`~ema_bench.progress.progress` shows it unless ``quiet``.  ``only``: run and
    summarise the cases of these categories alone (the others are drawn, not run).

    The cases run on the sweep engine (:func:`~ema_bench.sweep.loop.run_sweep`): ``workers``
    > 1 runs them in that many spawned processes; each record is appended to
    ``out/blind.jsonl`` as its case finishes, a rerun (or a second process on the folder)
    runs exactly the cases missing, and the records come back in case order.  ``runner``
    replaces :func:`run_case` (a module-level function, for the processes)."""
    settings = settings or Settings()
    cases = draw_cases(n, seed, extra, fourth, chain, outside)
    if only is not None:
        unknown = sorted(set(only) - set(KINDS))
        if unknown:
            raise ValueError(f"unknown categories {unknown}; known: {list(KINDS)}")
        cases = [c for c in cases if c.category in only]
    tasks = [_job(c) for c in cases]
    run = functools.partial(_run_task, runner or run_case, seed, settings)
    sweep = dict(executor="serial" if workers <= 1 else "processes", workers=workers,
                 label="blind", unit="case", quiet=quiet, describe=_verdict)
    if out is None:
        got = run_sweep(tasks, run, **sweep).records
    else:
        with Store(Path(out) / CASES_FILE, schema=CASE_SCHEMA) as store:
            # cases of another model version are stale: run again, recorded beside the old
            drawn = {t.key: t.data for t in tasks}
            for rec in store.records:
                if is_current(rec) and rec["key"] in drawn:
                    _check_resumed(rec, drawn[rec["key"]], seed, store.path)
            run_sweep(tasks, run, [store], **sweep)
            got = [r for r in store.records if is_current(r)]
    by_key = {r["key"]: r for r in got}
    ordered = [by_key[t.key] for t in tasks]
    return {"seed": seed, "summary": summarise(ordered), "records": ordered}


def _verdict(outcome) -> str:
    return f"{outcome.task.key} {outcome.records[0]['verdict']}" if outcome.records \
        else outcome.task.key


def run_cases(cases: Sequence[BlindCase], seed: int, settings: Settings, workers: int = 1,
              runner: Runner = run_case, label: str = "blind", quiet: bool = True
              ) -> list[dict]:
    """The records of ``cases`` in completion order, run on the sweep engine (in this
    process, or in ``workers`` spawned processes, one numba thread each), stored nowhere;
    progress under ``label`` unless ``quiet``."""
    return run_sweep([_job(c) for c in cases], functools.partial(_run_task, runner, seed,
                                                                  settings),
                     executor="serial" if workers <= 1 else "processes",
                     workers=workers, label=label, unit="case", quiet=quiet).records


def _check_resumed(rec: dict, case: BlindCase, seed: int, path: Path) -> None:
    """A recorded case reused on resume must be the case drawn now, of the same root seed,
    in this format (categories and an ``effects`` truth)."""
    if "category" not in rec or "effects" not in rec:
        raise ValueError(f"{path}: case{case.index} there is a record of the old blind-suite "
                         "format (kinds effect/null/decoy, one effect and value); use another "
                         "--out, or move that file away to run the suite anew")
    drawn = {**asdict(case), "root_seed": seed}
    if any(rec.get(k) != v for k, v in drawn.items()):
        raise ValueError(f"{path}: case{case.index} there is not the case drawn for this "
                         "seed and number of cases; use another --out for another suite")
