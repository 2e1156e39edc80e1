"""The report of a v3 board has what issue 44 asks of it: the board's cost (CPU-h, wall on 2
cores), the claims by instance with their leave-one-solver-out line and FRAGILE, a sentence
per tier on best vs fifth, separate ECDFs of fitness and parameter targets, in the tables,
the page and ``summary.json``.  Made here from a slice of the committed v3 store (real
records, model version 4); the cost is checked against the records' own times."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from ema_bench.leaderboard.cost import board_cost, cost_line
from ema_bench.leaderboard.run import write_outputs

STORE = Path(__file__).resolve().parents[1] / "leaderboards" / "v3" / "runs.jsonl"
INSTANCES = ("v3-small", "v3-full", "v3-random", "v3-s00", "v3-s01", "v3-s02", "v3-s03",
             "v3-s04")


def test_the_cost_is_the_records_run_time_summed_per_tier():
    """Three runs of tier 4 and one of tier 7, one of them failed (its time counts too)."""
    recs = [{"case": "v3-small@prior", "wall_s": 3600.0, "solver_wall_s": 3000.0},
            {"case": "v3-s03@no-prior", "wall_s": 1800.0, "solver_wall_s": 1700.0},
            {"case": "v3-s03@no-prior", "wall_s": 900.0, "error": "boom"},
            {"case": "v3-t7-s02@prior", "wall_s": 7200.0, "solver_wall_s": 7000.0}]
    c = board_cost(recs)
    assert (c.runs, c.cores) == (4, 2)
    assert c.run_h == pytest.approx(3.75) and c.solver_h == pytest.approx(3.25)
    assert c.by_tier == {4: (3, pytest.approx(1.75)), 7: (1, pytest.approx(2.0))}
    assert c.wall_h == pytest.approx(1.875)
    assert cost_line(c) == (
        "Cost: the 4 runs took 3.75 h of run time in all (tier 4 1.75 (3 runs), tier 7 2.00 "
        "(1 runs); the solvers' own share 3.25 h): 3.75 CPU-h at most (a run is one "
        "single-threaded process), 1.88 h of wall time on 2 cores running 2 at a time.")


@pytest.fixture(scope="module")
def v3_slice() -> list[dict]:
    """Tier 4 with and without the prior, reference track, noise seed 0, from the committed
    v3 store, the paper cases and the first five seeded instances (8): every solver that
    has all 8 of both there (at least five)."""
    if not STORE.is_file():
        pytest.skip("no committed v3 store")
    recs = [json.loads(line) for line in STORE.read_text().splitlines() if line.strip()]
    recs = [r for r in recs if r["case"].rpartition("@")[2] in ("prior", "no-prior")
            and r["seed"] == 0 and r["track"] == "reference"
            and r["case"].rpartition("@")[0] in INSTANCES]
    per: dict[str, set] = {}
    for r in recs:
        per.setdefault(r["solver"], set()).add(r["case"])
    full = {s for s, cells in per.items() if len(cells) == 2 * len(INSTANCES)}
    if len(full) < 5:
        pytest.skip(f"the committed v3 store has {len(full)} complete solvers on tier 4")
    return [r for r in recs if r["solver"] in full]


@pytest.mark.slow
def test_the_report_of_a_v3_board_has_the_issues_answers(v3_slice, tmp_path):
    """About 13 CPU-s, most of it fixed: the imports, the plots and the process that reads
    the solvers' scopes (not the 7 x 16 runs)."""
    recs = v3_slice
    summary = write_outputs(recs, tmp_path, "ema-bench leaderboard --suite emafdi-v3 "
                            "--tiers 4 --out OUT --report-only", landscape_n=0)
    hours = math.fsum(r["wall_s"] for r in recs) / 3600
    doc = json.loads((tmp_path / "summary.json").read_text())
    assert doc["model_version"] == "4" and doc["suite"] == "emafdi-v3"
    assert doc["cost"]["run_h"] == pytest.approx(hours, rel=1e-12)
    assert doc["cost"]["wall_h"] == pytest.approx(hours / 2, rel=1e-12)
    md = (tmp_path / "leaderboard_reference.md").read_text()
    header = md.splitlines()[2]
    assert f"Cost: the {len(recs)} runs took {hours:.2f} h of run time" in header
    assert f"{hours / 2:.2f} h of wall time on 2 cores" in header
    # every claim, by instance, with its leave-one-out line; the verdict per claim
    claims = [c for c in doc["claims_by_instance"] if c["track"] == "reference"]
    assert [c["claim"] for c in claims][:3] == ["best vs 5th", "first vs second",
                                                "best vs 5th, parameter targets"]
    assert all(c["instances"] == len(INSTANCES) and c["without_diff"] is not None
               for c in claims[:3])
    assert claims[3]["claim"] in ("global vs local, no-prior", "local vs global, no-prior")
    for c in claims:
        lo = c["diff"][1]
        assert c["fragile"] == (not lo > 0 or not c["without_diff"][1] > 0)
    assert "## Claims by instance" in md and "By instance: " in md
    assert ("FRAGILE" in md) == any(c["fragile"] for c in claims)
    # best vs fifth: one sentence for tier 4, which says why where they are not separated
    (line,) = doc["best_vs_fifth"]["reference"]
    best5 = claims[0]
    assert line.startswith("Tier 4: best" if best5["diff"][1] > 0 else
                           "Tier 4 cannot separate its best")
    assert f"- {line}" in md
    page = (tmp_path / "leaderboard.html").read_text()
    assert "Claims by instance" in page and "Tier 4" in page and "Cost: the" in page
    # the fitness and the parameter targets apart, beside the pooled ECDF
    for kind in ("", "_fitness", "_parameters"):
        assert (tmp_path / f"ecdf_tiers_reference{kind}.png").stat().st_size > 0
    # v3's ladders: 21 fitness precisions and the noise-allowed parameter scale
    assert ("fitness within 21 precisions 1e-1 .. 1e-6" in md
            and "of its noise-allowed scale" in md)
    assert summary["cost"]["runs"] == len(recs)
