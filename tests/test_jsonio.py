"""Strict JSON output (ema_bench.jsonio): what ``--json`` and summary files are written with."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ema_bench.jsonio import dumps, plain


def _strict(text: str):
    def refuse(name):
        raise ValueError(f"not JSON: {name}")
    return json.loads(text, parse_constant=refuse)


def test_non_finite_numbers_become_null_and_numpy_values_plain():
    doc = {"ert": float("inf"), "lo": -np.inf, "rmse": np.float64("nan"),
           "x": np.array([0.5, np.nan]), "n": np.int64(3), "ok": np.bool_(True),
           "pair": (1, np.float32(0.25)), 7: Path("a/b.json"), "nested": [{"v": np.inf}]}
    back = _strict(dumps(doc, indent=1))
    assert back == {"ert": None, "lo": None, "rmse": None, "x": [0.5, None], "n": 3,
                    "ok": True, "pair": [1, 0.25], "7": "a/b.json", "nested": [{"v": None}]}
    assert type(back["n"]) is int and type(back["ok"]) is bool
    assert plain(np.array([[np.inf, 2.0]], dtype=np.float32)) == [[None, 2.0]]


def test_finite_floats_are_written_exactly():
    xs = [0.1, 1 / 3, 2.0 ** -1074, 1.7976931348623157e308, -0.0]
    assert _strict(dumps(xs)) == xs


def test_unknown_objects_are_refused_unless_a_default_is_given():
    class Thing:
        def __str__(self):
            return "thing"
    with pytest.raises(TypeError, match="Thing is not JSON serialisable"):
        dumps({"a": Thing()})
    assert _strict(dumps({"a": Thing()}, default=str)) == {"a": "thing"}
