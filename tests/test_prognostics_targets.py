"""Issue 47's targets table (``docs/prognostics.md``, "Issue 47's targets: where they
stand"): every figure it quotes is the committed file's, recomputed here from the file, so the
table cannot drift from the board it reports."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
BOARD = ROOT / "leaderboards" / "campaign"


@pytest.fixture(scope="module")
def table() -> str:
    text = (ROOT / "docs" / "prognostics.md").read_text()
    start = text.index("## Issue 47's targets: where they stand")
    return text[start:text.index("\n## ", start + 1)]


def _row(table: str, target: str) -> str:
    (row,) = [x for x in table.splitlines() if x.startswith(f"| {target} |")]
    return row


def _results(path: Path) -> dict:
    doc = json.loads(path.read_text())
    rows = doc["results"] if isinstance(doc, dict) else doc
    return {(r["tracker"], r["track"]): r for r in rows}


def _ratio(h: dict, digits: int = 3) -> str:
    lo, hi = h["ratio_ci"]
    return f"{h['ratio']:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


@pytest.mark.parametrize("tracker", ["fleet-bayes-whole", "fleet-bayes-cut"])
def test_the_targets_table_quotes_the_committed_board(table, tracker):
    r = _results(BOARD / "scores.json")
    twin, ref = r[(tracker, "twin")], r[(tracker, "reference")]
    expect = {
        "expected ratio to the oracle >= 0.95 overall": [
            _ratio(twin["headline"]["expected"]), _ratio(ref["headline"]["expected"])],
        "realised ratio beside it": [_ratio(twin["headline"]["within"]),
                                     _ratio(ref["headline"]["within"])],
        "expected ratio >= 0.9 on every failure mode": [
            _ratio(twin["groups"][g]["headline"]["expected"]) for g in ("Fst", "BLK", "Na")],
        "CRPS within 1.2 x the oracle's": [_ratio(ref["headline"]["crps"])] + (
            [_ratio(twin["headline"]["crps"])] if tracker == "fleet-bayes-whole" else []),
        "95 % interval score within 1.2 x the oracle's": [_ratio(twin["headline"]["is95"]),
                                                         _ratio(ref["headline"]["is95"])],
    }
    for target, figures in expect.items():
        row = _row(table, target)
        for f in figures:
            assert f in row, (target, f)
    if tracker == "fleet-bayes-cut":     # its twin run was tracked before quantiles
        assert twin["headline"]["crps"]["value"] is None   # "twin not measurable"
    cov = twin["headline"]["coverage"]
    assert (f"{100 * cov['value']:.1f} % [{100 * cov['ci'][0]:.1f} %, {100 * cov['ci'][1]:.1f}"
            " %]") in _row(table, "95 % coverage 90-98 %")


def test_the_targets_table_quotes_the_committed_policy_and_sealed_tables(table):
    policy = {(p["tracker"], p["track"]): p for p in
              json.loads((BOARD / "policy.json").read_text())}
    row = _row(table, "policy cost within 1.2 x the oracle policy's")
    for key in (("fleet-bayes-whole", "twin"), ("fleet-bayes-whole", "reference"),
                ("fleet-bayes-cut", "twin"), ("fleet-bayes-cut", "reference"),
                ("fleet-bayes", "twin"), ("fleet-bayes", "reference")):
        h = policy[key]["ratio"]
        assert f"{h['value']:.2f} [{h['ci'][0]:.2f}, {h['ci'][1]:.2f}]" in row, key
    sealed = json.loads((BOARD / "sealed" / "scores.json").read_text())
    s = {r["tracker"]: r for r in sealed["results"]}["fleet-bayes-cut"]["headline"]
    assert f"sealed {_ratio(s['expected'], 2)}" in _row(
        table, "expected ratio to the oracle >= 0.95 overall")
    assert f"sealed {_ratio(s['crps'], 2)}" in _row(table, "CRPS within 1.2 x the oracle's")
    sp = {p["tracker"]: p for p in sealed["policy"]}["fleet-bayes-cut"]["ratio"]
    assert f"sealed {sp['value']:.2f} [{sp['ci'][0]:.2f}, {sp['ci'][1]:.2f}]" in row


def test_the_targets_table_quotes_the_measured_regeneration(table):
    """The board's regeneration time is the measured one (``benchmarks/board_regeneration.py``:
    the documented commands on a 12-unit sample, cold shared fit cache), and the per-tracker
    figures of the README's "Tracking time" are its own."""
    doc = json.loads((BOARD / "regeneration.json").read_text())
    row = _row(table, "board regenerated within 90 min on 2 cores")
    assert f"**{doc['board_wall_min_on_2_cores']:.1f} min**" in row
    assert f"{doc['board_total_cpu_min']:.1f} CPU-min" in row
    assert ("**yes**" in row) == (doc["board_wall_min_on_2_cores"] <= 90)
    readme = (BOARD / "README.md").read_text()
    for step, r in doc["steps"].items():
        name = step.removeprefix("track ")
        cpu = r["user_s"] + r["sys_s"]
        assert f"| {name} | {cpu:.0f} s | {doc['board_cpu_min'][step]:.1f} |" in readme, step


def test_the_regeneration_scaling_by_hand(monkeypatch):
    """``board_regeneration.scaled`` on a made measurement (100 twin and 50 reference sample
    inspections; the board's 4,796 + 685): per inspection to both campaigns, making per
    track, the tracking's CPU halved on two cores and the rest whole."""
    import sys
    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    sys.modules.pop("board_regeneration", None)
    from board_regeneration import scaled

    def cpu(s):
        return {"user_s": s - 1, "sys_s": 1}

    doc = scaled({"sample_inspections": 100, "reference_sample_inspections": 50,
                  "steps": {"make twin": cpu(10), "make reference": cpu(5), "track a": cpu(20),
                            "track b": cpu(10), "score": cpu(2), "policy": cpu(4)}})
    track = (20 + 10) / 100 * 5481                 # 1644.3 CPU-s, on two cores
    rest = 10 / 100 * 4796 + 5 / 50 * 685 + (2 + 4) / 100 * 5481
    assert doc["board_cpu_min"] == pytest.approx(
        {"track a": 18.27, "track b": 9.135, "make twin": 7.99, "make reference": 1.14,
         "score": 1.83, "policy": 3.65}, abs=0.006)
    assert doc["board_total_cpu_min"] == round((track + rest) / 60, 1) == 42.0
    assert doc["board_wall_min_on_2_cores"] == round((track / 2 + rest) / 60, 1) == 28.3
    assert doc["board_twin_tracking_cpu_min"] == 24.0   # 0.3 CPU-s x 4,796


def test_the_evidence_for_the_lead_quotes_the_gap_script():
    """The coil-short rows of "Evidence for the lead" are ``benchmarks/prognostics_gap.py``'s
    output on the committed lines (run as documented)."""
    import subprocess
    import sys

    text = (ROOT / "docs" / "prognostics.md").read_text()
    start = text.index("### Evidence for the lead")
    section = text[start:text.index("\n### ", start + 1)].splitlines()
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "prognostics_gap.py"),
         str(BOARD / "fleet-bayes-whole-offline.jsonl"), str(BOARD / "coil-short-ceiling.jsonl"),
         "--level", "fits", "--fault", "Na"], capture_output=True, text=True, check=True,
        cwd=ROOT).stdout.splitlines()
    labels = {"all": "coil shorts (44)", "early": "coil shorts, early cuts (15)",
              "mid": "coil shorts, mid cuts (16)", "late": "coil shorts, late cuts (13)"}
    for group, label in labels.items():
        (line,) = [x for x in out if x.startswith(f"Na {group} (")]
        tracker, rest = line.split(": tracker ")[1].split(", fits ")
        bound, diff = rest.split("; difference ")
        (row,) = [x for x in section if x.startswith(f"| {label} |")]
        for figure in (tracker, bound, diff.split(",  ")[0].split("], ")[0] + "]"):
            assert figure in row, (group, figure)


@pytest.mark.parametrize("tracker", ["fleet-bayes-onset"])
def test_the_targets_table_quotes_the_committed_offline_measurements(table, tracker):
    """``fleet-bayes-onset``'s figures are ``benchmarks/prognostics_offline.py``'s summary of
    its committed lines (the same bootstrap; ``fleet-bayes-whole`` is on the board, above)."""
    lines = [json.loads(x) for x in
             (BOARD / f"{tracker}-offline.jsonl").read_text().splitlines()]

    def ratio(sel):
        e, o = (np.array([x[k] for x in sel]) for k in ("tracker", "oracle"))
        idx = np.random.default_rng(0).integers(0, len(sel), (4000, len(sel)))
        b = e[idx].sum(1) / o[idx].sum(1)
        return (f"{e.sum() / o.sum():.3f} [{np.quantile(b, .025):.3f}, "
                f"{np.quantile(b, .975):.3f}]")

    row = _row(table, "expected ratio to the oracle >= 0.95 overall")
    assert f"`{tracker}` " in row and f"twin {ratio(lines)}" in row
    row = _row(table, "expected ratio >= 0.9 on every failure mode")
    for fault in ("Fst", "BLK", "Na"):
        sel = [x for x in lines if x["failing_fault"] == fault]
        assert ratio(sel)[:5] in row, (fault, ratio(sel))
    assert ratio([x for x in lines if x["failing_fault"] == "Na"]) in row


def test_the_paired_difference_script_reads_both_trackers_against_one_oracle(tmp_path):
    """``benchmarks/prognostics_paired.py`` (the +0.028 of the targets table) on a made
    ``campaign score --json``: tracker a hits what the oracle hits, b half of it on friction
    and all of it on backlash, so a/oracle = 1 and b/oracle = 0.5 on friction in every
    resample; the coil-short unit b did not score is left out of every line."""
    import subprocess
    import sys

    oracle = {"u0": 0.8, "u1": 0.6, "u2": 0.4, "u3": 1.0, "u4": 0.5, "u5": 0.9}
    fault = {"u0": "Fst", "u1": "Fst", "u2": "Fst", "u3": "BLK", "u4": "BLK", "u5": "Na"}

    def run(name, share):
        return {"tracker": name, "track": "twin",
                "per_unit": [{"unit": u, "failing_fault": fault[u],
                              "expected_hit": None if (name == "b" and u == "u5")
                              else share[fault[u]] * oracle[u]} for u in oracle],
                "oracle_per_unit": [{"unit": u, "expected_hit": h} for u, h in oracle.items()]}

    path = tmp_path / "full.json"
    path.write_text(json.dumps([run("a", {"Fst": 1.0, "BLK": 1.0, "Na": 1.0}),
                                run("b", {"Fst": 0.5, "BLK": 1.0, "Na": 1.0})]))
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "prognostics_paired.py"),
                          str(path), "a", "b"], capture_output=True, text=True, check=True,
                         cwd=ROOT).stdout.splitlines()
    total = sum(oracle[u] for u in oracle if u != "u5")             # 3.3
    b_all = (0.5 * (0.8 + 0.6 + 0.4) + 1.0 + 0.5) / total
    assert out[0].startswith(f"twin all (5 failing): a 1.000, b {b_all:.3f}, difference "
                             f"{1 - b_all:+.3f} [")
    assert out[1] == "twin Fst (3 failing): a 1.000, b 0.500, difference +0.500 [+0.500, +0.500]"
    assert out[2] == "twin BLK (2 failing): a 1.000, b 1.000, difference +0.000 [+0.000, +0.000]"
    assert len(out) == 3                      # Na: its one unit not scored by b
