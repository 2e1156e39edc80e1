"""The campaign's judge in the test's process (``prognostics/replay.py``,
``prognostics/track_worker.py``): the comparison of a replayed track with its record (each
difference by its exact line, at the tolerance's edge), the refusals before any replay, the
sample and its seed, the report's lines, ``verified_runs``' refusal and the worker protocol
(a unit's job as pickled for its worker), found by mutation testing
(docs/mutation-testing.md).

The honest run is made once per process by ``track_campaign`` with its real worker processes
(6 units of 2 to 4 twin inspections; one unit fails at its second inspection, one at its
first), in a folder kept for the process: under mutmut every mutant's child, forked from the
process that ran the clean tests, reuses it.  ``replay_track`` then runs on the ``serial``
executor with each unit's job pickled and unpickled as the ``isolated`` executor sends it, so
a mutant costs a fraction of a second; the worker-process replays are
``tests/test_campaign_replay.py``'s.
"""

from __future__ import annotations

import atexit
import functools
import json
import math
import os
import pickle
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
import sweep_jobs

from ema_bench.prognostics import replay as rp
from ema_bench.prognostics.campaign import load_campaign
from ema_bench.prognostics.track_run import track_campaign, unit_inputs, unit_seed
from ema_bench.prognostics.track_worker import TrackerSpec, UnitInput, UnitSource
from ema_bench.prognostics.tracking import Inspection, TrackerError, TrackStep, register_tracker
from ema_bench.sweep import executors

COMMITTED = Path(__file__).resolve().parents[1] / "leaderboards" / "campaign" / "twin"
UNITS = ("u000", "u001", "u002", "u003", "u004", "u005")
DIED = ("WorkerDied: the worker process running this task died (killed, out of memory or "
        "os._exit)")
SCHEME_1 = ("seed scheme 1 (the tracker's seed spawned from its run node, which gives the "
            "node away) is accepted for the committed campaign runs only: track again with "
            "this version (seed_scheme 2)")


@register_tracker("drawn-age", description="test tracker: the age plus a draw of its seed, "
                  "with quantiles and a profile; fails on u003 and u005", scale=100.0)
def drawn_age(campaign_info, seed, *, scale):
    from ema_bench.faults import FAULT_NAMES, LOWER, NOMINAL, UPPER

    rng = np.random.default_rng(seed)

    def step(insp: Inspection) -> TrackStep:
        if (insp.unit, insp.index) in (("u003", 1), ("u005", 0)):
            raise ValueError(f"drawn-age stops at {insp.unit} inspection {insp.index}")
        rul = insp.flight + scale * rng.random()
        return TrackStep(flight=insp.flight,
                         estimate={n: float(v) for n, v in zip(FAULT_NAMES, NOMINAL)},
                         low={n: float(v) for n, v in zip(FAULT_NAMES, LOWER)},
                         high={n: float(v) for n, v in zip(FAULT_NAMES, UPPER)},
                         rul=rul, rul_low=0.0, rul_high=math.inf, failing_fault="Na",
                         replace=insp.flight >= 20, evaluations=insp.index,
                         extra={"draw": rul - insp.flight},
                         rul_quantiles={"0.5": rul}, profile_rul=2 * rul)
    return step


# the same tracker registered without a configuration (the factory's default scale)
@register_tracker("drawn-age-default", description="test tracker: drawn-age at scale 100")
def drawn_age_default(campaign_info, seed):
    return drawn_age(campaign_info, seed, scale=100.0)


@functools.cache
def _made() -> Path:
    """The campaign (sweep_jobs' 4 units, and u004, u005 on u000's and u001's first two
    inspections) and the honest run, made once per process in a folder of its own (removed
    when the process that made it exits, not a forked child)."""
    root = Path(tempfile.mkdtemp(prefix="ema-track-replay-"))
    owner = os.getpid()
    atexit.register(lambda: os.getpid() == owner and shutil.rmtree(root, ignore_errors=True))
    camp = sweep_jobs.campaign(root / "campaign")
    m = json.loads((camp / "manifest.json").read_text())
    for new, old in (("u004", 0), ("u005", 1)):
        m["units"].append({"unit": new, "inspections": m["units"][old]["inspections"][:2]})
    (camp / "manifest.json").write_text(json.dumps(m))
    track_campaign(camp, "drawn-age", root / "run", seed=5)
    return root


@functools.cache
def _committed() -> Path:
    """The committed twin ``life-table`` run (seed scheme 1, grandfathered) beside the committed
    campaign's manifest, each of whose inspection files is a stand-in (one of ``_made``'s
    traces: ``life-table`` reads no trace, and the committed campaign keeps none), made once
    per process."""
    root = Path(tempfile.mkdtemp(prefix="ema-track-replay-committed-"))
    owner = os.getpid()
    atexit.register(lambda: os.getpid() == owner and shutil.rmtree(root, ignore_errors=True))
    stand_in = _made() / "campaign" / "u000" / "i000.npz"
    shutil.copytree(COMMITTED / "life-table", root / "life-table")
    (root / "campaign").mkdir()
    shutil.copy(COMMITTED / "campaign" / "manifest.json", root / "campaign")
    for u in json.loads((root / "campaign" / "manifest.json").read_text())["units"]:
        (root / "campaign" / u["unit"]).mkdir()
        for insp in u["inspections"]:
            (root / "campaign" / insp["file"]).symlink_to(stand_in)
    return root


def lines(run: Path) -> list[dict]:
    return [json.loads(x) for x in (run / "track.jsonl").read_text().splitlines()]


def copy(tmp_path: Path, name: str = "run", edit=None, manifest=None) -> Path:
    """A copy of the honest run in ``tmp_path`` (beside a link to the campaign), its lines
    passed through ``edit`` (list -> list) and its manifest updated with ``manifest``."""
    if not (tmp_path / "campaign").exists():
        (tmp_path / "campaign").symlink_to(_made() / "campaign")
    out = Path(shutil.copytree(_made() / "run", tmp_path / name))
    if edit is not None:
        rows = edit(lines(out))
        (out / "track.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    if manifest is not None:
        m = json.loads((out / "manifest.json").read_text())
        m.update(manifest)
        (out / "manifest.json").write_text(json.dumps(m))
    return out


def line(rows: list[dict], key: str) -> dict:
    (r,) = [r for r in rows if r["key"] == key]
    return r


@pytest.fixture
def sent(monkeypatch):
    """replay's executor in this process: each unit's job pickled and unpickled as the
    ``isolated`` executor sends it to its worker, then run on the ``serial`` executor; the
    units named in the returned object's ``dead`` come back as a worker that died.  Each
    call is recorded (executor, workers, units)."""
    class Sent(list):
        dead: tuple = ()

    calls = Sent()

    def execute(jobs, runner, executor, workers, **kw):
        jobs = list(jobs)
        calls.append((executor, workers, [j.key for j in jobs]))
        for j in jobs:
            if j.key in calls.dead:
                yield executors._died(j)
            else:
                yield from executors.execute([pickle.loads(pickle.dumps(j))], runner, "serial", 1)
    monkeypatch.setattr(rp, "execute", execute)
    return calls


# --- the comparison, in the test's process ---------------------------------------------------

def test_an_honest_run_replays_in_this_process_as_its_workers_tracked_it(tmp_path, sent):
    run = copy(tmp_path)
    rows = lines(run)
    # what the run holds: u003 failed at its second inspection, u005 at its first
    assert line(rows, "u003/error")["error"] == "ValueError: drawn-age stops at u003 inspection 1"
    assert line(rows, "u005/error")["index"] == 0 and not any(
        r["unit"] == "u005" and "rul" in r for r in rows)
    r = rp.replay_track(run, units=list(UNITS), seed=3)
    assert r.findings == [] and r.ok
    assert (r.run, r.tracker, r.units, r.tracked, r.seed) == (str(run), "drawn-age",
                                                              list(UNITS), 6, None)
    assert sent == [("isolated", 1, list(UNITS))]
    assert r.summary() == (f"{run}: drawn-age, 6 of 6 units re-tracked (u000, u001, u002, "
                           "u003, u004, u005): every line agrees")
    assert r.record() == {"units": list(UNITS), "tracked": 6, "sample_seed": None,
                          "escape_chance": 0.0}
    # the units at once: as many as asked, at least one
    for workers, used in ((3, 3), (0, 1), (2.0, 2)):
        rp.replay_track(run, units=["u001"], workers=workers)
        assert sent[-1] == ("isolated", used, ["u001"]) and type(sent[-1][1]) is int


def test_a_sample_is_the_documented_draw_and_its_seed_is_reported(tmp_path, sent):
    run = copy(tmp_path)
    drawn = {}
    for k, seed in ((2, 123), (1, 7), (5, 2**62 + 11)):
        pick = np.random.default_rng(np.random.SeedSequence(seed)).choice(6, size=k,
                                                                          replace=False)
        want = drawn[k] = [UNITS[i] for i in sorted(pick)]
        r = rp.replay_track(run, k=k, seed=seed)
        assert (r.units, r.seed, r.ok) == (want, seed, True)
        assert sent[-1] == ("isolated", 1, want)
        chance = math.comb(6 - 1, k) / math.comb(6, k)
        assert r.record() == {"units": want, "tracked": 6, "sample_seed": seed,
                              "escape_chance": chance}
        assert r.summary() == (
            f"{run}: drawn-age, {k} of 6 units re-tracked ({', '.join(want)}; sample seed "
            f"{seed}): every line agrees; a single forged unit escapes a sample this size "
            f"with probability {chance:.2f}")
    assert rp.replay_track(run, seed=123).units == drawn[2]   # k = 2 by default
    # every unit when k covers them; a fresh 63-bit seed when none is given
    assert rp.replay_track(run, k=9, seed=1).units == list(UNITS)
    fresh = [rp.replay_track(run, k=1).seed for _ in range(2)]
    assert all(type(s) is int and 0 <= s < 2**63 for s in fresh) and fresh[0] != fresh[1]
    # named units replay those, with no sample seed (a given one is not a sample's)
    r = rp.replay_track(run, units=["u004", "u002"], seed=123)
    assert (r.units, r.seed) == (["u004", "u002"], None)
    assert r.record()["sample_seed"] is None and "sample seed" not in r.summary()


def test_each_edited_field_is_named_exactly_and_every_unit_is_compared(tmp_path, sent):
    honest = lines(_made() / "run")
    rul = line(honest, "u001/002")["rul"]
    na = line(honest, "u004/001")["estimate"]["Na"]

    def edit(rows):
        line(rows, "u001/002")["rul"] = rul * 0.9
        line(rows, "u001/003")["replace"] = False
        line(rows, "u004/001")["estimate"]["Na"] = na + 0.5
        line(rows, "u000/001").pop("extra")
        line(rows, "u000/002")["note"] = "hand-written"
        line(rows, "u003/error")["error"] = "ValueError: edited"
        return [r for r in rows if r["key"] != "u002/002"] + [
            {"key": "u000/error", "unit": "u000", "index": 3, "flight": 30, "status": "error",
             "error": "ValueError: hand-written"}]
    r = rp.replay_track(copy(tmp_path, edit=edit), units=list(UNITS))
    assert r.findings == [
        "u000 inspection 1.extra: not recorded",
        "u000 inspection 2.note: missing",
        "u000 failure: recorded {'key': 'u000/error', 'unit': 'u000', 'index': 3, "
        "'flight': 30, 'status': 'error', 'error': 'ValueError: hand-written'}, replayed None",
        f"u001 inspection 2.rul: recorded {rul * 0.9!r}, replayed {rul!r}",
        "u001 inspection 3.replace: recorded False, replayed True",
        "u002: 3 steps recorded, 4 replayed",
        "u003 failure.error: recorded 'ValueError: edited', replayed "
        "'ValueError: drawn-age stops at u003 inspection 1'",
        f"u004 inspection 1.estimate.Na: recorded {na + 0.5!r}, replayed {na!r}",
    ]
    assert not r.ok and r.summary().endswith("): 8 difference(s)")


def test_a_difference_is_named_by_the_recorded_inspection_index(tmp_path, sent):
    def edit(rows):
        r = line(rows, "u002/003")
        r["index"], r["key"] = 7, "u002/007"
        return rows
    r = rp.replay_track(copy(tmp_path, edit=edit), units=["u002"])
    assert r.findings == ["u002 inspection 7.index: recorded 7, replayed 3",
                          "u002 inspection 7.key: recorded 'u002/007', replayed 'u002/003'"]


def test_a_number_agrees_to_a_millionth_relative_and_later_fields_may_be_absent(tmp_path,
                                                                               sent):
    rul = line(lines(_made() / "run"), "u002/003")["rul"]

    def at(scale):
        def edit(rows):
            line(rows, "u002/003")["rul"] = rul * scale
            return rows
        return copy(tmp_path, f"x{scale}", edit=edit)
    assert rp.replay_track(at(1 + 0.5e-6), units=["u002"]).ok
    assert rp.replay_track(at(1 - 0.9e-6), units=["u002"]).ok
    assert rp.replay_track(at(1 + 2e-6), units=["u002"]).findings == [
        f"u002 inspection 3.rul: recorded {rul * (1 + 2e-6)!r}, replayed {rul!r}"]

    # a run tracked before its tracker gave quantiles and a profile is compared without them
    def older(rows):
        for r in rows:
            r.pop("rul_quantiles", None)
            r.pop("profile_rul", None)
        return rows
    assert rp.replay_track(copy(tmp_path, "older", edit=older), units=list(UNITS)).ok


def test_differences_of_values_by_hand():
    d = rp._differences
    nan, inf = math.nan, math.inf
    assert d({"a": nan, "b": inf, "c": 3}, {"a": nan, "b": inf, "c": 3.0}, "w") == []
    assert d(1.0, nan, "w") == ["w: recorded nan, replayed 1.0"]
    assert d(nan, 1.0, "w") == ["w: recorded 1.0, replayed nan"]
    assert d(1e300, inf, "w") == ["w: recorded inf, replayed 1e+300"]
    assert d(1e-10, 0, "w") == ["w: recorded 0, replayed 1e-10"]   # no absolute slack
    assert d(None, 0.0, "w") == ["w: recorded 0.0, replayed None"]
    assert d("a", "b", "w") == ["w: recorded 'b', replayed 'a'"]
    assert d({"x": 1}, 1, "w") == ["w: recorded 1, replayed {'x': 1}"]
    assert d(1, {"x": 1}, "w") == ["w: recorded {'x': 1}, replayed 1"]
    assert d(True, False, "w") == ["w: recorded False, replayed True"]
    assert d({"b": 1, "c": {"e": 2.0}}, {"a": 1, "b": 2, "c": {"e": 2.5, "f": 0}}, "w") == [
        "w.a: missing", "w.b: recorded 2, replayed 1", "w.c.f: missing",
        "w.c.e: recorded 2.5, replayed 2.0"]
    assert d({"z": 1, "y": 0}, {}, "w") == ["w.y: not recorded", "w.z: not recorded"]
    # relative to the larger of the two: 1e-6 of it passes, twice that does not
    assert d(1e6 + 1, 1e6, "w") == [] and d(1e6 + 2.5, 1e6, "w") != []
    assert d(-5.0, -5.0 * (1 + 1e-7), "w") == [] and d(-5.0, 5.0, "w") != []


# --- refusals before any replay ---------------------------------------------------------------

@pytest.mark.parametrize("scheme, finding", [
    (None, SCHEME_1), (1, SCHEME_1),
    ("2", "seed scheme '2', expected one of [1, 2]"),
    (True, "seed scheme True, expected one of [1, 2]"),
    (3, "seed scheme 3, expected one of [1, 2]"),
    (0, "seed scheme 0, expected one of [1, 2]"),
    (2.0, "seed scheme 2.0, expected one of [1, 2]"),
])
def test_a_run_of_another_seed_scheme_is_refused_without_a_replay(tmp_path, sent, scheme,
                                                                   finding):
    run = copy(tmp_path)
    m = json.loads((run / "manifest.json").read_text())
    if scheme is None:
        del m["seed_scheme"]   # a run before the schemes: scheme 1
    else:
        m["seed_scheme"] = scheme
    (run / "manifest.json").write_text(json.dumps(m))
    r = rp.replay_track(run, units=["u001", "u002"])
    assert (r.findings, r.units, r.tracked, sent) == ([finding], ["u001", "u002"], 6, [])


def test_another_tracker_config_is_refused_without_a_replay(tmp_path, sent):
    run = copy(tmp_path, manifest={"config": {"scale": 50.0}})
    r = rp.replay_track(run, k=1, seed=0)
    assert r.findings == ["the run's tracker config {'scale': 50.0} is not the registered "
                          "'drawn-age''s {'scale': 100.0}"] and sent == []
    r = rp.replay_track(copy(tmp_path, "none", manifest={"config": None}), units=["u000"])
    assert r.findings == ["the run's tracker config None is not the registered "
                          "'drawn-age''s {'scale': 100.0}"]


def test_a_run_without_a_config_is_judged_against_an_empty_one(tmp_path, sent):
    """A manifest without ``config`` (a tracker registered without one) is the empty
    configuration: the run replays; any configuration there is compared."""
    run = copy(tmp_path, manifest={"tracker": "drawn-age-default"})
    m = json.loads((run / "manifest.json").read_text())
    del m["config"]
    (run / "manifest.json").write_text(json.dumps(m))
    r = rp.replay_track(run, units=list(UNITS))
    assert (r.tracker, r.findings) == ("drawn-age-default", [])
    r = rp.replay_track(copy(tmp_path, "configured", manifest={
        "tracker": "drawn-age-default"}), units=["u000"])
    assert r.findings == ["the run's tracker config {'scale': 100.0} is not the registered "
                          "'drawn-age-default''s {}"]


def test_a_committed_scheme_1_run_is_replayed_under_scheme_1(sent, monkeypatch):
    """The committed twin ``life-table`` run (its manifest has no ``seed_scheme``: scheme 1,
    accepted as a committed run) is re-tracked with scheme-1 seeds and told its scheme, and
    gives its committed lines again; relabelled scheme 2 it would not be accepted."""
    import ema_bench_trackers.references  # noqa: F401  (registers life-table here)

    root = _committed()
    run = root / "life-table"
    assert "seed_scheme" not in json.loads((run / "manifest.json").read_text())
    jobs = []
    real = rp.execute

    def keep(js, *a, **kw):
        js = list(js)
        jobs.extend(pickle.loads(pickle.dumps(j)).data for j in js)
        return real(js, *a, **kw)
    monkeypatch.setattr(rp, "execute", keep)
    r = rp.replay_track(run, units=["u007"])
    assert r.ok and (r.tracker, r.tracked) == ("life-table", 200)
    order = [u["unit"] for u in json.loads(
        (COMMITTED / "campaign" / "manifest.json").read_text())["units"]]
    (inp,) = jobs
    want = unit_seed(0, order.index("u007"), 1)
    assert (inp.seed.entropy, inp.seed.spawn_key) == (want.entropy, want.spawn_key)
    assert inp.settings["seed_scheme"] == 1 and len(inp.inspections) == 10


def test_a_unit_the_run_did_not_track_is_refused_by_name(tmp_path, sent):
    run = copy(tmp_path)
    with pytest.raises(TrackerError) as e:
        rp.replay_track(run, units=["u001", "u009"])
    assert str(e.value) == f"{run}: no tracked unit 'u009'; tracked: u000, u001, u002, u003, " \
        "u004, ..."
    five = copy(tmp_path, "five", edit=lambda rows: [r for r in rows if r["unit"] != "u004"])
    with pytest.raises(TrackerError) as e:
        rp.replay_track(five, units=["u004"])
    assert str(e.value) == f"{five}: no tracked unit 'u004'; tracked: u000, u001, u002, u003, " \
        "u005"
    # a sample is drawn from the tracked units only
    r = rp.replay_track(five, k=9, seed=0)
    assert r.units == ["u000", "u001", "u002", "u003", "u005"] and r.tracked == 5 and r.ok
    assert sent == [("isolated", 1, r.units)]


def test_a_worker_that_died_is_a_finding_and_the_other_units_are_still_compared(tmp_path,
                                                                               sent):
    rul = line(lines(_made() / "run"), "u002/000")["rul"]

    def edit(rows):
        line(rows, "u002/000")["rul"] = rul + 1
        return rows
    sent.dead = ("u001",)
    r = rp.replay_track(copy(tmp_path, edit=edit), units=["u001", "u002"])
    assert r.findings == [f"u001: replay failed: {DIED}",
                          f"u002 inspection 0.rul: recorded {rul + 1!r}, replayed {rul!r}"]


# --- verified_runs: replay before judging, the first difference refused ------------------------

def test_verified_runs_replays_each_run_and_refuses_the_first_that_differs(tmp_path, sent):
    honest = copy(tmp_path)
    rul = line(lines(honest), "u000/003")["rul"]

    def edit(rows):
        line(rows, "u000/003")["rul"] = 0.0
        return rows
    bad = copy(tmp_path, "bad", edit=edit)
    (r,) = rp.verified_runs([honest], k=1)
    assert r.ok and len(r.units) == 1 and r.seed is not None
    (r,) = rp.verified_runs([honest])   # two units, one worker by default
    assert len(r.units) == 2 and sent[-1] == ("isolated", 1, r.units)
    assert len(rp.verified_runs([honest], k=3)[0].units) == 3
    checked = rp.verified_runs([honest, honest], units=["u000", "u004"], k=0, workers=2)
    assert [c.units for c in checked] == [["u000", "u004"]] * 2
    assert sent[-2:] == [("isolated", 2, ["u000", "u004"])] * 2
    assert rp.replayed_lines(checked, "costing") == [
        f"Replayed before costing: {honest}: drawn-age, 2 of 6 units re-tracked (u000, "
        "u004): every line agrees."] * 2
    del sent[:]
    for what, tail in ((None, "not costed"), ("scored or costed", "not scored or costed")):
        with pytest.raises(rp.ReplayError) as e:
            rp.verified_runs([honest, bad], units=["u000"],
                             **({} if what is None else {"what": what}))
        assert str(e.value) == (
            f"replay of {bad}: drawn-age, 1 of 6 units re-tracked (u000): 1 difference(s), "
            f"first u000 inspection 3.rul: recorded 0.0, replayed {rul!r}: the track file is "
            f"not what its tracker gives, {tail}")
    assert [c[2] for c in sent] == [["u000"]] * 4   # the honest run replayed first
    for k in (0, -1):
        with pytest.raises(rp.ReplayError) as e:
            rp.verified_runs([honest], k=k)
        assert str(e.value) == f"replay at least 1 unit per run, not {k}"


# --- the worker protocol (track_worker.py) ----------------------------------------------------

def test_a_unit_is_sent_as_its_inputs_alone_and_the_campaign_stays_behind(tmp_path):
    camp = load_campaign(_made() / "campaign")
    spec = TrackerSpec("drawn-age", __name__, "drawn_age", "d", {"scale": 100.0,
                                                                 "where": Path("x")})
    assert spec.manifest_config == {"scale": 100.0, "where": "x"}
    for scheme in (2, 1):
        seed = unit_seed(5, 3, scheme)
        src = UnitSource(spec, "u003", seed, functools.partial(unit_inputs, camp, "u003",
                                                               scheme))
        blob = pickle.dumps(src)
        got = pickle.loads(blob)
        settings, inspections = unit_inputs(camp, "u003", scheme)
        assert type(got) is UnitInput
        assert (got.tracker, got.settings, got.unit) == (spec, settings, "u003")
        assert got.settings.get("seed_scheme") == (1 if scheme == 1 else None)
        assert (got.seed.entropy, got.seed.spawn_key) == (seed.entropy, seed.spawn_key)
        assert [(i.unit, i.index, i.flight) for i in got.inspections] == [
            ("u003", k, f) for k, f in enumerate(sweep_jobs.FLIGHTS)]
        assert all(a.traces.data.keys() == b.traces.data.keys() and all(
            np.array_equal(a.traces.data[t], b.traces.data[t]) for t in a.traces.data)
            for a, b in zip(got.inspections, inspections, strict=True))
        # nothing that leads to the campaign: no Campaign, no folder, no campaign seed
        assert b"Campaign" not in blob and str(camp.root).encode() not in blob
        assert "seed" not in got.settings and not hasattr(got, "read")
