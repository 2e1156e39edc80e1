"""Where ``--check`` finds its baseline (``leaderboard/check.py``): the checkout's
``leaderboards/`` when there is one, else the quick baseline a wheel installs as data under
``<prefix>/share/ema-bench/leaderboards``; a folder without committed runs is refused in one
line naming the baseline this installation has (found by mutation testing,
docs/mutation-testing.md; tests/test_wheel.py runs the installed case end to end).

The installed case is built here with real ``importlib.metadata`` objects (a distribution in
a temporary folder whose RECORD lists the data file), and the module's ``__file__`` moved out
of the checkout, so both branches run in this process.
"""

from __future__ import annotations

import importlib.metadata
import json
from pathlib import Path

import pytest

from ema_bench.leaderboard import check
from ema_bench.leaderboard.judge import JudgeError
from ema_bench.trace_cache import MODEL_VERSION

QUICK = "share/ema-bench/leaderboards/quick/runs.jsonl"


def _installed(tmp_path: Path, entries: list[str], make: tuple[str, ...] = (QUICK,)):
    """A real distribution under ``tmp_path/prefix/lib/site`` whose RECORD lists ``entries``
    (paths relative to the prefix) and whose files ``make`` exist."""
    prefix = tmp_path / "prefix"
    info = prefix / "lib" / "site" / "ema_bench-0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: ema-bench\nVersion: 0\n")
    (info / "RECORD").write_text("".join(f"../../{e},,\n" for e in entries))
    for m in make:
        (prefix / m).parent.mkdir(parents=True, exist_ok=True)
        (prefix / m).write_text("{}\n")
    return importlib.metadata.PathDistribution(info), prefix


@pytest.fixture
def outside(tmp_path, monkeypatch):
    """``check.py`` as if installed outside a checkout (no ``leaderboards/`` beside it)."""
    monkeypatch.setattr(check, "__file__", str(tmp_path / "site" / "ema_bench" / "leaderboard"
                                               / "check.py"))

    def use(dist_files):
        monkeypatch.setattr(importlib.metadata, "files", dist_files)
    return use


def test_a_checkout_uses_its_own_leaderboards():
    root = Path(__file__).resolve().parent.parent
    assert (root / "leaderboards" / "quick" / "runs.jsonl").is_file()
    assert check.packaged_baseline() == root / "leaderboards"


def test_an_installation_uses_the_quick_baseline_its_wheel_installed(tmp_path, outside):
    # a quick baseline elsewhere (not under the data prefix) and another board come first
    elsewhere = "lib/site/leaderboards/quick/runs.jsonl"
    dist, prefix = _installed(tmp_path, ["share/ema-bench/leaderboards/full/runs.jsonl",
                                         elsewhere, QUICK], make=(elsewhere, QUICK))
    asked = []
    outside(lambda name: asked.append(name) or dist.files)
    found = check.packaged_baseline()
    assert asked == ["ema-bench"]
    assert found.resolve() == (prefix / "share" / "ema-bench" / "leaderboards").resolve()
    # a checkout's leaderboards/ without the quick baseline is not taken for one
    checkout = tmp_path / "site" / "leaderboards"
    (checkout / "full").mkdir(parents=True)
    (checkout / "runs.jsonl").write_text("{}\n")
    (checkout / "full" / "runs.jsonl").write_text("{}\n")
    assert check.packaged_baseline().resolve() == found.resolve()
    (checkout / "quick").mkdir()
    (checkout / "quick" / "runs.jsonl").write_text("{}\n")
    assert check.packaged_baseline() == checkout


def test_no_baseline_where_the_file_is_missing_or_nothing_is_installed(tmp_path, outside):
    dist, _ = _installed(tmp_path, [QUICK], make=())
    outside(lambda name: dist.files)
    assert check.packaged_baseline() is None       # listed, but not on disk
    outside(lambda name: None)                      # a distribution without RECORD
    assert check.packaged_baseline() is None

    def missing(name):
        raise importlib.metadata.PackageNotFoundError(name)
    outside(missing)
    assert check.packaged_baseline() is None


def test_require_baseline_takes_a_folder_with_runs_and_refuses_one_without(tmp_path,
                                                                           outside):
    top, nested, empty = tmp_path / "top", tmp_path / "nested", tmp_path / "empty"
    (nested / "quick").mkdir(parents=True)
    top.mkdir()
    empty.mkdir()
    (top / "runs.jsonl").write_text("{}\n")
    (nested / "quick" / "runs.jsonl").write_text("{}\n")
    assert check.require_baseline(str(top)) == top
    assert isinstance(check.require_baseline(str(nested)), Path)
    assert check.require_baseline(nested) == nested
    dist, prefix = _installed(tmp_path, [QUICK])
    outside(lambda name: dist.files)
    with pytest.raises(ValueError) as err:
        check.require_baseline(str(empty))
    packaged = check.packaged_baseline()
    assert str(err.value) == (
        f"--check {empty}: no committed runs there (runs.jsonl or */runs.jsonl); the baseline "
        f"installed with this package is {packaged} (--check with no folder uses it)")
    outside(lambda name: None)
    with pytest.raises(ValueError) as err:
        check.require_baseline(empty)
    assert str(err.value) == (
        f"--check {empty}: no committed runs there (runs.jsonl or */runs.jsonl); this "
        "installation has no baseline (install the wheel, or use a checkout)")


# --- per-case budgets, the suite of a check, the records a baseline judges -----------------

def _run(case: str, seed: int, budget: int, solver: str = "a", suite: str = "emafdi-v1"
         ) -> dict:
    """The identity fields ``baseline`` and ``compare``'s suite checks read (no evidence)."""
    return {"solver": solver, "case": case, "track": "twin", "seed": seed, "budget": budget,
            "root_seed": 0, "model_version": MODEL_VERSION, "suite": suite}


def test_a_per_case_budget_picks_and_re_scores_each_case_at_its_own_budget():
    per_case = {"small": 100, "nominal": 200}
    runs = [_run("small", 0, 100), _run("small", 0, 400), _run("nominal", 0, 150),
            _run("nominal", 0, 400), _run("nominal", 1, 200)]
    base, used = check.baseline(runs, per_case.__getitem__, 2)
    assert sorted((r["case"], r["seed"], r["budget"]) for r in base) == [
        ("nominal", 0, 200), ("nominal", 1, 200), ("small", 0, 100)]
    assert used == {"same_budget": 2, "re_scored": 1, "other_model_version": 0}
    assert check.budget_of(per_case.__getitem__, "nominal") == 200
    assert check.budget_of(300, "nominal") == 300


V2 = "t12-s00@prior"


def test_compare_checks_both_sides_against_the_suite_of_this_runs_cases():
    assert check.compare([], [_run("small", 0, 100)]) == []          # nothing run
    now, base = [_run(V2, 0, 100, suite="emafdi-v2")], [_run(V2, 1, 100, suite="emafdi-v2")]
    assert check.compare(now, base) == []                             # no run in common
    with pytest.raises(ValueError) as err:
        check.compare(now, [_run("small", 0, 100)])
    assert str(err.value).startswith("the baseline holds runs of suite version emafdi-v1; "
                                     "this is emafdi-v2:")
    with pytest.raises(ValueError) as err:
        check.compare([*now, _run("small", 0, 100)], base)
    assert str(err.value) == "this run mixes suites emafdi-v1, emafdi-v2: check each apart"


def test_load_baseline_judges_only_the_runs_it_compares_and_counts_other_versions(tmp_path):
    """A doctored committed record (its fitness doubled: the judge refuses it) beyond the
    check's seeds or outside its keys does not block the check; a record of another model
    version is counted, not judged."""
    quick = Path(__file__).resolve().parent.parent / "leaderboards" / "quick" / "runs.jsonl"
    s00 = [json.loads(ln) for ln in quick.read_text().splitlines() if '"case": "s00"' in ln]
    good = s00[0]
    seed1 = next(r for r in s00 if r["seed"] == 1 and r["solver"] == good["solver"]
                 and r["track"] == good["track"])
    other = next(r for r in s00 if r["seed"] == 0 and r["solver"] != good["solver"])
    doctor = lambda r: {**r, "fitness": 2 * r["fitness"]}   # noqa: E731
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "runs.jsonl").write_text("".join(
        json.dumps(r) + "\n" for r in (good, {**good, "model_version": "1"}, doctor(seed1))))
    base, used = check.load_baseline(tmp_path / "a", 400, 1)
    assert [r["solver"] for r in base] == [good["solver"]]
    assert used == {"same_budget": 1, "re_scored": 0, "other_model_version": 1}
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "runs.jsonl").write_text(
        json.dumps(good) + "\n" + json.dumps(doctor(other)) + "\n")
    key = check.run_id(good)
    base, used = check.load_baseline(tmp_path / "b", 400, 1, keys={key})
    assert [check.run_id(r) for r in base] == [key] and used["other_model_version"] == 0
    with pytest.raises(JudgeError, match=r"^--check baseline: \d+ finding.* in 2 records"):
        check.load_baseline(tmp_path / "b", 400, 1)
