"""The on-disk reference-trace cache returns exactly what the model makes, and rebuilds every
entry it cannot trust (corrupt, truncated, stale key, wrong shape) instead of reading it."""

import pytest

from ema_bench.faults import CASES
from ema_bench.protocol import STANDARD_TESTS
from ema_bench.reference import simulate_reference
from ema_bench.trace_cache import cache_key, cached_traces, expected_shapes

SHAPES = expected_shapes(STANDARD_TESTS)


def _make(calls):
    def make():
        calls.append(1)
        return simulate_reference(CASES["small"].x, seed=3)
    return make


def test_hit_returns_identical_traces_without_simulating(tmp_path):
    calls = []
    key = cache_key(case="small", seed=3)
    first = cached_traces(_make(calls), key, SHAPES, tmp_path)
    second = cached_traces(_make(calls), key, SHAPES, tmp_path)
    assert len(calls) == 1
    assert second.allclose(first)      # bit-identical (atol = rtol = 0)
    assert "cache_key" not in second.meta
    assert second.meta == first.meta == {"model": "reference", "noise": True, "adc": True}


def test_no_entry_holds_the_truth_and_legacy_entries_go(tmp_path, monkeypatch):
    """The cache folder is readable by any solver: an entry that kept the data maker's record
    would hand it the truth (the faults, found by matching the measured data)."""
    import numpy as np

    from ema_bench.suites.problem import make_problem
    from ema_bench.traces import load_traces

    legacy = tmp_path / "reference" / "old.npz"   # what earlier versions wrote
    legacy.parent.mkdir()
    legacy.write_bytes(b"faults")
    monkeypatch.setenv("EMA_BENCH_CACHE", str(tmp_path))
    p = make_problem({"Na": 0.97, "Fst": 0.31, "BLK": 0.02, "Gprop": 1.1e5}, seed=12345,
                     track="reference", budget=1)
    (entry,) = (tmp_path / "measured").glob("*.npz")
    stored = load_traces(entry)
    assert set(stored.meta) == {"model", "noise", "adc", "cache_key"}
    assert b"0.97" not in entry.read_bytes() and b"Gprop" not in entry.read_bytes()
    assert not legacy.parent.exists()
    assert all(np.array_equal(stored.data[t], p.measured.data[t]) for t in stored.tests)


def _entry(tmp_path):
    (path,) = (tmp_path / "measured").glob("*.npz")
    return path


@pytest.mark.parametrize("damage", ["garbage", "truncate", "empty"])
def test_corrupt_entry_is_rebuilt(tmp_path, damage):
    calls = []
    key = cache_key(case="small", seed=3)
    good = cached_traces(_make(calls), key, SHAPES, tmp_path)
    path = _entry(tmp_path)
    raw = path.read_bytes()
    path.write_bytes({"garbage": b"not a zip file" * 10, "truncate": raw[: len(raw) // 2],
                      "empty": b""}[damage])
    again = cached_traces(_make(calls), key, SHAPES, tmp_path)
    assert len(calls) == 2 and again.allclose(good)
    # and the rebuilt entry is good again
    cached_traces(_make(calls), key, SHAPES, tmp_path)
    assert len(calls) == 2


def test_entry_under_another_key_or_shape_is_not_trusted(tmp_path):
    calls = []
    key = cache_key(case="small", seed=3)
    cached_traces(_make(calls), key, SHAPES, tmp_path)
    path = _entry(tmp_path)
    # an entry whose stored key differs (a hash-prefix collision, a hand-copied file)
    other = cache_key(case="small", seed=4)
    target = tmp_path / "measured" / f"{other[:32]}.npz"
    path.rename(target)
    cached_traces(_make(calls), other, SHAPES, tmp_path)
    assert len(calls) == 2
    # an entry of the right key but the wrong length of test
    wrong = {k: (v[0] + 1, 4) for k, v in SHAPES.items()}
    cached_traces(_make(calls), key, wrong, tmp_path)
    assert len(calls) == 3


def test_key_changes_with_every_input():
    base = dict(x=(1.0, 0.0, 0.0, 100.0), e=(0.0,), entropy=0, spawn_key=(1,))
    keys = {cache_key(**base)}
    for k, v in [("x", (0.99, 0.0, 0.0, 100.0)), ("e", (1.0,)), ("entropy", 1),
                 ("spawn_key", (2,))]:
        keys.add(cache_key(**{**base, k: v}))
    assert len(keys) == 5


def test_off_switch(tmp_path, monkeypatch):
    monkeypatch.setenv("EMA_BENCH_CACHE", "off")
    calls = []
    cached_traces(_make(calls), cache_key(case="small"), SHAPES)
    cached_traces(_make(calls), cache_key(case="small"), SHAPES)
    assert len(calls) == 2
