"""The weekly mutation gate (``.github/mutation_gate.py``, docs/mutation-testing.md): what
passes, what fails, the shards of ``.github/workflows/mutation.yml`` and the ratchet of the
known untriaged survivors (``.github/mutation_untriaged.json``).

Results files are written as ``mutmut results --all true`` prints them; the gate is run as
the workflow runs it, a subprocess with the exit code the job fails on.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from fnmatch import fnmatchcase
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parent.parent
GATE = ROOT / ".github" / "mutation_gate.py"
DOC = ROOT / "docs" / "mutation-testing.md"
UNTRIAGED = ROOT / ".github" / "mutation_untriaged.json"

P = "ema_bench.problem.xǁProblemǁevaluate__mutmut_"   # a method's name holds mutmut's ǁ
S = "ema_bench.scoring.x_range_error__mutmut_"


def _gate(tmp_path: Path, results: dict[str, str], doc: str, *args: str,
          ratchet: dict | None = None) -> tuple[int, list[str]]:
    r, d = tmp_path / "results.txt", tmp_path / "doc.md"
    r.write_text("".join(f"    {n}: {s}\n" for n, s in results.items()), encoding="utf-8")
    d.write_text(doc, encoding="utf-8")
    if ratchet is not None:
        (tmp_path / "u.json").write_text(json.dumps(ratchet), encoding="utf-8")
        args = (*args, "--untriaged", str(tmp_path / "u.json"))
    res = subprocess.run([sys.executable, str(GATE), str(r), str(d), *args],
                         capture_output=True, text=True, encoding="utf-8", timeout=60)
    return res.returncode, res.stdout.splitlines()


def test_every_survivor_must_be_listed_by_its_exact_name(tmp_path):
    results = {f"{P}1": "killed", f"{P}2": "timeout", f"{P}3": "caught by type check",
               f"{P}4": "survived", f"{P}5": "no tests", f"{S}6": "suspicious",
               f"{S}7": "not checked"}
    rc, out = _gate(tmp_path, results, f"- `{P}4`: equivalent.\n")
    assert rc == 1 and out == [f"untriaged mutant {P}5: no tests",
                               f"untriaged mutant {S}6: suspicious",
                               f"untriaged mutant {S}7: not checked"]
    # a name is listed only in backquotes and in full (``_5`` is not ``_55``'s prefix)
    rc, out = _gate(tmp_path, {**results, f"{P}55": "survived"},
                    f"`{P}4` `{P}5` `{S}6` `{S}7` {P}55 `{P}5`5")
    assert rc == 1 and out == [f"untriaged mutant {P}55: survived"]
    assert _gate(tmp_path, results, f"`{P}4` `{P}5` `{S}6` `{S}7`")[0] == 0


def test_a_gate_that_checked_nothing_fails(tmp_path):
    assert _gate(tmp_path, {}, "") == (1, ["no mutant in the results: nothing was checked"])
    rc, out = _gate(tmp_path, {f"{P}1": "killed"}, "", "--only", "ema_bench.check.*")
    assert rc == 1 and out == ["no mutant of ema_bench.check.* in the results: nothing was "
                               "checked"]


def test_a_shard_judges_only_its_own_mutants(tmp_path):
    results = {f"{P}1": "survived", f"{S}1": "killed", f"{S}2": "survived"}
    assert _gate(tmp_path, results, "", "--only", "ema_bench.scoring.*") == (
        1, [f"untriaged mutant {S}2: survived"])
    assert _gate(tmp_path, results, f"`{S}2`", "--only", "ema_bench.scoring.*")[0] == 0
    assert _gate(tmp_path, results, f"`{S}2`", "--only", "ema_bench.scoring.*",
                 "ema_bench.problem.*")[0] == 1


def test_the_ratchet_holds_known_survivors_and_fails_on_a_new_one_or_a_lower_score(tmp_path):
    ratchet = {"modules": {"ema_bench.problem": {"mutants": 4, "caught": 2,
                                                 "untriaged": [f"{P}3", f"{P}4"]}}}
    now = {f"{P}1": "killed", f"{P}2": "killed", f"{P}3": "survived", f"{P}4": "no tests",
           f"{S}1": "survived"}
    # the other module is not in the ratchet: its survivor needs listing as before
    assert _gate(tmp_path, now, "", ratchet=ratchet) == (
        1, [f"untriaged mutant {S}1: survived"])
    assert _gate(tmp_path, now, f"`{S}1`", ratchet=ratchet) == (0, [])
    # a new survivor of the ratcheted module fails, listed untriaged or not
    rc, out = _gate(tmp_path, {**now, f"{P}2": "survived"}, f"`{S}1`", ratchet=ratchet)
    assert rc == 1 and f"untriaged mutant {P}2: survived" in out
    # listing it as equivalent passes the name check, not the score: 1 of 4 < 2 of 4
    rc, out = _gate(tmp_path, {**now, f"{P}2": "survived"}, f"`{S}1` `{P}2`",
                    ratchet=ratchet)
    assert rc == 1 and out == ["score drop in ema_bench.problem: 1 of 4 mutants caught, the "
                               "ratchet holds 2 of 4"]
    # a new mutant listed equivalent lowers the share too (2 of 5 < 2 of 4)
    rc, out = _gate(tmp_path, {**now, f"{P}5": "survived"}, f"`{S}1` `{P}5`",
                    ratchet=ratchet)
    assert rc == 1 and out[-1].startswith("score drop in ema_bench.problem: 2 of 5")
    # a killed untriaged mutant passes, with a note to shrink the list
    rc, out = _gate(tmp_path, {**now, f"{P}3": "killed"}, f"`{S}1`", ratchet=ratchet)
    assert rc == 0 and out == [f"note: {P}3 no longer survives: remove it from the "
                               "untriaged list (--record rewrites it)"]


def test_record_writes_the_ratchet_that_the_same_results_pass(tmp_path):
    results = {f"{P}1": "killed", f"{P}2": "survived", f"{P}3": "no tests",
               f"{S}1": "killed", f"{S}2": "survived"}
    u = tmp_path / "u.json"
    u.write_text(json.dumps({"modules": {"other.module": {"mutants": 1, "caught": 0,
                                                          "untriaged": ["other.module.x"]},
                                         "ema_bench.scoring": {"mutants": 9, "caught": 0,
                                                               "untriaged": []}}}))
    r, d = tmp_path / "r.txt", tmp_path / "d.md"
    r.write_text("".join(f"    {n}: {s}\n" for n, s in results.items()), encoding="utf-8")
    d.write_text(f"`{S}2`", encoding="utf-8")
    subprocess.run([sys.executable, str(GATE), str(r), str(d), "--untriaged", str(u),
                    "--record"], check=True, timeout=60)
    assert json.loads(u.read_text(encoding="utf-8")) == {"modules": {
        "ema_bench.problem": {"mutants": 3, "caught": 1, "untriaged": [f"{P}2", f"{P}3"]},
        "other.module": {"mutants": 1, "caught": 0, "untriaged": ["other.module.x"]}}}
    ratchet = json.loads(u.read_text(encoding="utf-8"))
    assert _gate(tmp_path, results, f"`{S}2`", ratchet=ratchet) == (0, [])
    assert _gate(tmp_path, {**results, f"{S}1": "survived"}, f"`{S}2`",
                 ratchet=ratchet)[0] == 1


def _workflow() -> dict:
    return yaml.safe_load((ROOT / ".github" / "workflows" / "mutation.yml").read_text())


def _shards() -> list[dict]:
    return _workflow()["jobs"]["mutmut"]["strategy"]["matrix"]["include"]


def _only_mutate() -> list[str]:
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["mutmut"]
    return cfg["only_mutate"]


def test_every_mutated_module_is_in_exactly_one_shard_and_each_shard_gates_it():
    shards = _shards()
    modules = [p.removesuffix(".py").replace("/", ".") for p in _only_mutate()]
    for m in modules:
        mine = [s["shard"] for s in shards
                if any(fnmatchcase(f"{m}.x_f__mutmut_1", g) for g in s["mutants"].split())]
        assert len(mine) == 1, (m, mine)
    for s in shards:   # no glob of a module outside the scope (it would match nothing)
        for g in s["mutants"].split():
            assert any(fnmatchcase(f"{m}.x_f__mutmut_1", g) for m in modules), g
    steps = "\n".join(str(step.get("run", "")) for step in _workflow()["jobs"]["mutmut"]
                      ["steps"])
    assert "mutation_gate.py" in steps and "--only $MUTANTS" in steps
    assert _workflow()["jobs"]["mutmut"]["timeout-minutes"] <= 60


def test_the_judges_shard_is_strict_and_the_ratchet_names_only_untriaged_survivors():
    shards = {s["shard"]: s for s in _shards()}
    assert "--untriaged" not in shards["judge"].get("gate", "")
    ratchet = json.loads(UNTRIAGED.read_text(encoding="utf-8"))["modules"]
    doc = DOC.read_text(encoding="utf-8")
    ratcheted = [s for s in shards.values()
                 if "--untriaged .github/mutation_untriaged.json" in s.get("gate", "")
                 and "--record" not in s["gate"]]
    judge_globs = shards["judge"]["mutants"].split()
    for module, entry in ratchet.items():
        probe = f"{module}.x_f__mutmut_1"
        assert not any(fnmatchcase(probe, g) for g in judge_globs), module
        assert any(fnmatchcase(probe, g) for s in ratcheted for g in s["mutants"].split())
        assert 0 <= entry["caught"] <= entry["mutants"] - len(entry["untriaged"])
        for name in entry["untriaged"]:
            assert name.startswith(module + ".") and f"`{name}`" not in doc, name
        assert f"`{module}`" in doc   # the document names each ratcheted module


def test_every_shard_is_gated_strict_or_on_the_committed_ratchet():
    """No shard only records (``--record`` passes whatever survives): each is strict or
    gates on the committed ratchet, and the document says which."""
    gates = {s["shard"]: s.get("gate", "") for s in _shards()}
    assert gates == {"judge": "", "validate": "", "campaign-judge": "",
                     "solvers": "--untriaged .github/mutation_untriaged.json",
                     "model": "--untriaged .github/mutation_untriaged.json"}
    doc = DOC.read_text(encoding="utf-8")
    assert "### `problem.py` and `objective.py`: gated as a ratchet" in doc


def test_the_campaign_judge_is_its_own_shard_and_the_prognostics_scores_are_out():
    """The campaign's judge (replay of tracking runs, the tracker worker's inputs, the
    expected hits) is in its own strict shard; the other prognostics scores are not in the
    scope yet."""
    assert [m for m in _only_mutate() if m.startswith("ema_bench/prognostics/")] == [
        "ema_bench/prognostics/replay.py", "ema_bench/prognostics/track_worker.py",
        "ema_bench/prognostics/expected.py"]
    shards = {s["shard"]: s["mutants"].split() for s in _shards()}
    assert shards["campaign-judge"] == ["ema_bench.prognostics.replay.*",
                                        "ema_bench.prognostics.track_worker.*",
                                        "ema_bench.prognostics.expected.*"]
    doc = DOC.read_text(encoding="utf-8")
    assert "### The prognostics scores: out of the gated scope" in doc
