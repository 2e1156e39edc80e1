"""One seed tree (issue 11): the blind suite and the diagnosis draw from named streams of run
nodes, so a blind case replays from the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ema_bench.cli import main
from ema_bench.diagnosis.blind import draw_cases, measured_traces
from ema_bench.diagnosis.results import Settings
from ema_bench.diagnosis.workflow import diagnose
from ema_bench.faults import random_faults
from ema_bench.seeding import STREAMS, run_seed, stream
from ema_bench.traces import load_traces


def test_streams_are_distinct_children_with_indexed_families():
    node = run_seed(3, 7)
    assert len(set(STREAMS.values())) == len(STREAMS)
    # an indexed member is a grandchild: (..., stream index, i, j), by hand
    ss = stream(node, "fit", 2, 5)
    assert ss.entropy == 3 and ss.spawn_key == (7, STREAMS["fit"], 2, 5)
    assert stream(node, "fit", 2, 5).generate_state(4).tolist() == \
        ss.generate_state(4).tolist()
    draws = {np.random.default_rng(stream(node, n)).random() for n in STREAMS}
    assert len(draws) == len(STREAMS)
    with pytest.raises(KeyError) as exc:
        stream(node, "nosuch")
    assert exc.value.args[0] == f"unknown seed stream 'nosuch'; known: {list(STREAMS)}"
    assert stream(node, "noise").spawn_key == (7, 1)      # no index: the child itself


def test_a_blind_case_is_run_k_of_its_root_seed():
    """Case k of `blind --seed R` has the faults of the instance stream of run (R, k)."""
    cases = draw_cases(12, 4)
    for c in cases:
        expect = random_faults(stream(run_seed(4, c.index), "instance"), 1.0)
        np.testing.assert_array_equal(list(c.faults.values()), expect)
    # the layout comes from the root's plan stream: another root, another layout
    assert [c.kind for c in draw_cases(12, 4)] == [c.kind for c in cases]
    assert cases != draw_cases(12, 5)


@pytest.fixture(scope="module")
def case_file(tmp_path_factory):
    """Case 2 of `blind --seed 4`, made from the command line."""
    case = draw_cases(12, 4)[2]
    path = tmp_path_factory.mktemp("seedtree") / "case2.csv"
    faults = ",".join(f"{k}={v!r}" for k, v in case.faults.items())
    assert case.category == "single"   # a reference-model case, as simulate makes it
    effect = [a for k, v in case.effects.items() for a in ("--effect", f"{k}={v!r}")]
    assert main(["simulate", "--root-seed", "4", "--seed", "2", "--faults", faults, *effect,
                 "--tests", "step,sine,sine2", "--out", str(path)]) == 0
    return case, path


def test_blind_traces_replay_with_simulate(case_file):
    from ema_bench.protocol import HOLDOUT_TESTS, STANDARD_TESTS
    from ema_bench.reference import simulate_reference

    case, path = case_file
    # what run_case simulates for case 2 of root 4
    blind = simulate_reference(np.array(list(case.faults.values())), case.effects,
                               tests=STANDARD_TESTS + HOLDOUT_TESTS,
                               seed=stream(run_seed(4, 2), "noise"))
    assert load_traces(path).allclose(blind, rtol=1e-12, atol=0.0)
    assert load_traces(path).allclose(measured_traces(case, 4), rtol=1e-12, atol=0.0)


# slow: two diagnoses of a blind case (about 27 CPU-s); the fast loop checks the blind
# case's stream through simulate above and runs diagnose --json on the monitor's own data
@pytest.mark.slow
def test_diagnose_seed_is_the_diagnosis_stream_of_the_run(case_file, capsys, monkeypatch):
    """``diagnose --root-seed 4 --seed 2`` runs the workflow on the file with the run's
    diagnosis stream and prints what it returned; another run's stream gives other fits.
    The command's own call is recorded on its way (its data, settings and seed checked)
    rather than made a second time through the API with the same arguments."""
    from ema_bench.diagnosis import workflow

    _, path = case_file
    calls = []

    def through(measured, settings=None, seed=0, on_stage=None):
        # the seed's identity as it arrives (a spawn before the call would move its children)
        given = (seed.entropy, seed.spawn_key, seed.pool_size, seed.n_children_spawned)
        calls.append((measured, settings, given, diagnose(measured, settings, seed, on_stage)))
        return calls[-1][-1]

    monkeypatch.setattr(workflow, "diagnose", through)
    assert main(["diagnose", str(path), "--root-seed", "4", "--seed", "2", "--budget", "100",
                 "--bootstrap", "10", "--json", "--quiet"]) == 0
    cli = json.loads(capsys.readouterr().out)
    ((measured, settings, seed, api),) = calls
    assert load_traces(path).allclose(measured, rtol=0.0, atol=0.0)
    assert settings == Settings(budget=100, n_boot=10)
    want = stream(run_seed(4, 2), "diagnosis")
    assert seed == (want.entropy, want.spawn_key, want.pool_size, want.n_children_spawned)
    assert cli["faults"] == api.faults and cli["verdict"] == api.verdict
    other = diagnose(load_traces(path), Settings(budget=100, n_boot=10),
                     seed=stream(run_seed(4, 3), "diagnosis"))
    assert other.faults != api.faults   # the seed reaches the fits


def test_seeds_are_checked_and_recorded_as_given():
    from ema_bench.seeding import as_seed_sequence, child, children, seed_repr

    node = np.random.SeedSequence(11, spawn_key=(2,), pool_size=8)
    assert as_seed_sequence(node) is node
    assert as_seed_sequence(0).entropy == 0 and as_seed_sequence(np.int64(9)).entropy == 9
    assert as_seed_sequence(None).entropy != as_seed_sequence(None).entropy   # fresh entropy
    for bad in (-1, 2.5, True):
        with pytest.raises(ValueError) as exc:
            as_seed_sequence(bad)
        assert str(exc.value) == f"seed must be a non-negative integer, got {bad!r}"
    # a record of a seed: enough to recreate it, plain JSON
    assert seed_repr(node) == {"entropy": "11", "spawn_key": [2]}
    assert seed_repr(None) is None and seed_repr(7) == 7 and type(seed_repr(np.int64(7))) is int
    # a child keeps the parent's entropy and pool size, appends its index, and leaves the
    # parent unspawned; children(n) are a first spawn(n)
    c = child(node, 3)
    assert (c.entropy, c.spawn_key, c.pool_size) == (11, (2, 3), 8)
    assert node.n_children_spawned == 0
    fresh = np.random.SeedSequence(11, spawn_key=(2,), pool_size=8)
    assert [k.generate_state(2).tolist() for k in children(node, 3)] == \
        [k.generate_state(2).tolist() for k in fresh.spawn(3)]


def test_a_run_node_is_checked_and_built_from_its_root_and_seed():
    node = run_seed(0, 0)
    assert (node.entropy, node.spawn_key) == (0, (0,))
    assert (run_seed(5, 9).entropy, run_seed(5, 9).spawn_key) == (5, (9,))
    for args, name, bad in (((-1, 0), "root seed", -1), ((0, -2), "seed", -2),
                            ((1.5, 0), "root seed", 1.5), ((0, True), "seed", True),
                            ((False, 0), "root seed", False)):
        with pytest.raises(ValueError) as exc:
            run_seed(*args)
        assert str(exc.value) == f"{name} must be a non-negative integer, got {bad!r}"


def test_the_one_way_seed_follows_its_recipe_for_every_kind_of_node():
    """The recipe (SHA-256 of the JSON of a label, the name, the node's entropy, spawn key
    and pool size) computed here by hand: a node whose entropy is a list, another pool size,
    another name each give their own seed, with no spawn key."""
    import hashlib

    from ema_bench.seeding import one_way, solver_seed

    def by_hand(name, entropy, key, pool):
        text = json.dumps(["ema-bench one-way seed", name, entropy, key, pool])
        return int.from_bytes(hashlib.sha256(text.encode()).digest(), "big")

    node = np.random.SeedSequence([5, 6], spawn_key=(1, 2), pool_size=8)
    got = one_way(node, "tracker")
    assert got.entropy == by_hand("tracker", [5, 6], [1, 2], 8) and got.spawn_key == ()
    assert one_way(3, "solver").entropy == by_hand("solver", 3, [], 4)
    # entropy given as a numpy array: its entries, as plain ints
    arr = np.random.SeedSequence(np.array([5, 6]), spawn_key=(1, 2), pool_size=8)
    assert one_way(arr, "tracker").entropy == got.entropy
    assert solver_seed(node).entropy == one_way(node, "solver").entropy != got.entropy
    assert solver_seed(node, 2).entropy == solver_seed(node).entropy
    old = solver_seed(node, 1)
    assert (old.entropy, old.spawn_key, old.pool_size) == ([5, 6], (1, 2, STREAMS["solver"]), 8)
    for scheme in (0, 3):
        with pytest.raises(ValueError) as exc:
            solver_seed(node, scheme)
        assert str(exc.value) == f"unknown seed scheme {scheme!r}; known: [1, 2]"
