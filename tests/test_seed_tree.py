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
    with pytest.raises(KeyError, match="unknown seed stream"):
        stream(node, "nosuch")


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


# slow: three diagnoses of a blind case (about 25 CPU-s); the fast loop checks the blind
# case's stream through simulate above and runs diagnose --json on the monitor's own data
@pytest.mark.slow
def test_diagnose_seed_is_the_diagnosis_stream_of_the_run(case_file, capsys):
    _, path = case_file
    assert main(["diagnose", str(path), "--root-seed", "4", "--seed", "2", "--budget", "100",
                 "--bootstrap", "10", "--json", "--quiet"]) == 0
    cli = json.loads(capsys.readouterr().out)
    api = diagnose(load_traces(path), Settings(budget=100, n_boot=10),
                   seed=stream(run_seed(4, 2), "diagnosis"))
    assert cli["faults"] == api.faults and cli["verdict"] == api.verdict
    other = diagnose(load_traces(path), Settings(budget=100, n_boot=10),
                     seed=stream(run_seed(4, 3), "diagnosis"))
    assert other.faults != api.faults   # the seed reaches the fits
