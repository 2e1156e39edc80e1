"""Limits at every door of the command line: each count option has an upper bound, each float
option refuses non-finite values, in one line with exit code 2, before any work."""

from __future__ import annotations

import argparse

import pytest

from ema_bench.cli import build_parser, main


def _options() -> list[tuple[list[str], argparse.Action]]:
    """(command words, option) for every option of every command and sub-command."""
    out, seen = [], set()

    def walk(parser: argparse.ArgumentParser, words: list[str]) -> None:
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    if id(sub) not in seen:
                        seen.add(id(sub))
                        walk(sub, [*words, name])
            elif action.option_strings:
                out.append((words, action))

    walk(build_parser(), [])
    return out


OPTIONS = _options()
COUNTS = [(w, a) for w, a in OPTIONS if getattr(a.type, "__name__", "") == "count"]
FLOATS = [(w, a) for w, a in OPTIONS if getattr(a.type, "__name__", "") == "finite"]


def _id(item) -> str:
    words, action = item
    return " ".join([*words, action.option_strings[-1]])


def test_every_number_option_is_bounded():
    """A plain ``type=int`` or ``type=float`` option (a new one, say) has no bound: refused
    here.  The list also checks that the walk found the commands' options at all."""
    plain = [_id(o) for o in OPTIONS if o[1].type in (int, float)]
    assert plain == []
    names = {_id(o) for o in COUNTS}
    assert {"blind --cases", "campaign make --units", "leaderboard --seeds",
            "diagnose --bootstrap", "coverage --instances", "solve --budget",
            "campaign track --workers", "bench --batch"} <= names
    assert {"coverage --noise-scale", "coverage --level", "solve --level",
            "solve --heterogeneity", "campaign score --alpha"} <= {_id(o) for o in FLOATS}


def _refused(argv: list[str], capsys) -> str:
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1, captured.err     # one line, no usage block
    return captured.err


@pytest.mark.parametrize("item", COUNTS, ids=[_id(o) for o in COUNTS])
def test_count_above_its_bound_is_refused_in_one_line(item, capsys):
    words, action = item
    option = action.option_strings[-1]
    err = _refused([*words, option, str(action.type.upper + 1)], capsys)
    assert f"argument {option}" in err and f"must be from {action.type.lower} to " \
        f"{action.type.upper}, got {action.type.upper + 1}" in err
    # the bound itself is a valid value (not an off-by-one refusal)
    assert action.type(str(action.type.upper)) == action.type.upper
    err = _refused([*words, option, "1e3"], capsys)       # not a whole number
    assert "expected a whole number" in err


def test_a_huge_count_is_refused_before_any_work(capsys):
    """The issue's examples (3 GB in seconds before): far past the bound, and as digits."""
    for argv in (["blind", "--cases", "10000000000"], ["campaign", "make", "fleet-v1",
                 "--units", "9" * 5000], ["diagnose", "x.csv", "--bootstrap", "10**9"],
                 ["leaderboard", "--seeds", "-1"]):
        _refused(argv, capsys)


@pytest.mark.parametrize("item", FLOATS, ids=[_id(o) for o in FLOATS])
@pytest.mark.parametrize("value", ["inf", "-inf", "nan", "1e999"])
def test_non_finite_float_is_refused_in_one_line(item, value, capsys):
    words, action = item
    option = action.option_strings[-1]
    err = _refused([*words, f"{option}={value}"], capsys)
    assert f"argument {option}: must be a finite number" in err


@pytest.mark.parametrize("argv", [
    ["solve", "--faults", "Na=inf"],
    ["solve", "--faults", "Na=0.95", "--effect", "delay=nan"],
])
def test_non_finite_assignment_is_refused_in_one_line(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is not a finite number" in err
