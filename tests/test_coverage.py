"""Coverage of the fault intervals, measured on real fits (ema_bench.uncertainty.coverage),
and the command lines that produce and print intervals (``ema-bench coverage``,
``ema-bench solve --intervals``), run as a user types them (test_cli_solve's ``cli``)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import binomtest
from test_cli_solve import cli

from ema_bench.faults import FAULT_NAMES
from ema_bench.uncertainty.coverage import Settings, read_records, run, summarise, wilson

ROOT = Path(__file__).resolve().parents[1]
COMMITTED = ROOT / "leaderboards" / "coverage"
N_SMALL = 20


def _rejects(summary: dict, committed: dict) -> list[str]:
    """Faults whose coverage over the small run is inconsistent with the committed fraction
    (two-sided exact binomial test at 1 %)."""
    n = summary["instances"]
    out = []
    for f in FAULT_NAMES:
        k = round(summary["coverage"][f] * n)
        p = min(max(committed["coverage"][f], 1e-3), 1 - 1e-3)
        if binomtest(k, n, p).pvalue < 0.01:
            out.append(f)
    return out


@pytest.fixture(scope="module")
def small_runs(tmp_path_factory):
    """20 twin instances with honest intervals, then the same fits with a noise level
    deliberately scaled by 0.4 (the fits are shared through the cache)."""
    d = tmp_path_factory.mktemp("coverage")
    s = Settings(track="twin", method="laplace")
    honest = run(s, N_SMALL, d / "honest.jsonl", quiet=True)
    wrong = run(replace(s, noise_scale=0.4), N_SMALL, d / "wrong.jsonl", quiet=True)
    return honest, wrong


# slow (20 twin fits with intervals, about 30 CPU-s): the fast loop runs the same run() on 3
# instances (test_an_instance_without_interval_...) and through the CLI (..._and_resume)
@pytest.mark.slow
def test_small_run_reproduces_the_committed_coverage(small_runs):
    committed = json.loads((COMMITTED / "twin_laplace.json").read_text())
    assert committed["instances"] >= 100 and committed["method"] == "laplace"
    honest, _ = small_runs
    summary = summarise(honest)
    assert summary["instances"] == N_SMALL
    assert _rejects(summary, committed) == []


@pytest.mark.slow
def test_a_mis_scaled_noise_level_fails_the_check(small_runs):
    committed = json.loads((COMMITTED / "twin_laplace.json").read_text())
    honest, wrong = small_runs
    bad = summarise(wrong)
    assert _rejects(bad, committed), bad["coverage"]
    # same fits, same estimates; only the half-widths shrank, by the noise scale
    for h, w in zip(honest, wrong):
        assert h["estimate"] == w["estimate"]
        for f in FAULT_NAMES:
            hw = h["noise_only"][f][1] - h["noise_only"][f][0]
            ww = w["noise_only"][f][1] - w["noise_only"][f][0]
            if 0 < h["noise_only"][f][0] and h["noise_only"][f][1] < 1e9:
                assert ww == pytest.approx(0.4 * hw, rel=0.02) or ww < 0.4 * hw


def test_committed_summaries_are_what_their_records_give():
    """The committed summaries are recomputed from the committed records, independently of
    the code that wrote them: inside-counts and median widths (% of the fault table's
    ranges, DESIGN section 3)."""
    bounds = {"Na": (0.8, 1.0), "Fst": (0.1689, 0.8445), "BLK": (0.0, 0.04),
              "Gprop": (5e4, 1.5e5)}
    paths = sorted(COMMITTED.glob("*.json"))
    assert paths
    for path in paths:
        summary = json.loads(path.read_text())
        records = [r for r in read_records(path.with_suffix(".jsonl")).values()
                   if r["index"] < summary["instances"]]
        assert len(records) == summary["instances"], path
        f = summary["calibration_factor"]
        for name, (lower, upper) in bounds.items():
            inside, widths = 0, []
            for r in records:
                u, t = r["estimate"][name], r["truth"][name]
                a, b = r["uncalibrated"][name]
                lo, hi = max(u - f[name] * (u - a), lower), min(u + f[name] * (b - u), upper)
                inside += lo <= t <= hi
                widths.append(100 * (hi - lo) / (upper - lower))
            assert summary["coverage"][name] == pytest.approx(inside / len(records)), path
            assert summary["median_width"][name] == pytest.approx(np.median(widths)), path


def test_wilson_interval_of_known_fractions():
    lo, hi = wilson(95, 100)
    assert lo == pytest.approx(0.8882, abs=1e-3) and hi == pytest.approx(0.9785, abs=1e-3)
    assert wilson(0, 10)[0] == 0.0 and wilson(10, 10)[1] == pytest.approx(1.0)


def test_coverage_cli_json_files_and_resume(tmp_path):
    out = tmp_path / "cov"
    r = cli("coverage", "--track", "twin", "--instances", "2", "--budget", "300",
            "--solver", "cmaes", "--out", str(out), "--json")
    assert r.returncode == 0, r.stderr
    summary = json.loads(r.stdout)
    assert {"coverage", "median_width", "instances", "method", "track"} <= set(summary)
    assert summary["instances"] == 2 and summary["method"] == "laplace"
    assert summary["track"] == "twin" and set(summary["coverage"]) == set(FAULT_NAMES)
    assert all(0.0 <= v <= 1.0 for v in summary["coverage"].values())
    for suffix in (".jsonl", ".json", ".png"):
        assert (out / f"twin_laplace{suffix}").stat().st_size > 0
    first = (out / "twin_laplace.jsonl").read_text().splitlines()
    # one more instance: the first two are read back, not recomputed
    r = cli("coverage", "--track", "twin", "--instances", "3", "--budget", "300",
            "--solver", "cmaes", "--out", str(out), "--json")
    assert r.returncode == 0, r.stderr
    lines = (out / "twin_laplace.jsonl").read_text().splitlines()
    assert lines[:2] == first and len(lines) == 3
    # other settings into the same file: refused, nothing lost
    r = cli("coverage", "--track", "twin", "--instances", "3", "--budget", "200",
            "--solver", "cmaes", "--out", str(out))
    assert r.returncode == 2 and "other settings" in r.stderr
    assert (out / "twin_laplace.jsonl").read_text().splitlines() == lines


@pytest.mark.parametrize("args, match", [
    (("--level", "1.5"), "--level"),
    (("--instances", "0"), "--instances"),
    (("--solver", "nope"), "nope"),
    (("--noise-scale", "-1"), "--noise-scale"),
])
def test_coverage_cli_bad_input(args, match):
    r = cli("coverage", *args)
    assert r.returncode == 2 and match in r.stderr


def test_solve_intervals_json_and_text(tmp_path):
    r = cli("solve", "--case", "small", "--track", "twin", "--solver", "least-squares",
            "--budget", "300", "--intervals", "laplace", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["interval_method"] == "laplace" and set(out["intervals"]) == set(FAULT_NAMES)
    for name, (lo, hi) in out["intervals"].items():
        assert lo <= out["interval_estimate"][name] <= hi
    assert out["calibration"] == "twin" and out["model_form"] == "none"
    png = tmp_path / "region.png"
    r = cli("solve", "--case", "small", "--track", "reference", "--solver", "least-squares",
            "--budget", "300", "--intervals", "profile", "--interval-plot", str(png))
    assert r.returncode == 0, r.stderr
    assert "profile intervals" in r.stdout and "truth in" in r.stdout
    assert png.stat().st_size > 0
    assert (tmp_path / "region_profiles.png").stat().st_size > 0


def test_solve_interval_plot_needs_intervals(tmp_path):
    r = cli("solve", "--case", "small", "--interval-plot", str(tmp_path / "a.png"))
    assert r.returncode == 2 and "--intervals" in r.stderr


def test_an_instance_without_interval_is_a_logged_miss_not_a_crash(tmp_path, monkeypatch):
    from ema_bench.uncertainty import methods as iv_module
    from ema_bench.uncertainty.local import UncertaintyError

    real = iv_module.intervals
    calls = []

    def flaky(objective, x, **kw):
        calls.append(1)
        if len(calls) == 2:
            raise UncertaintyError("the monitor model fails at the fit: no interval")
        return real(objective, x, **kw)

    monkeypatch.setattr(iv_module, "intervals", flaky)
    s = Settings(track="twin", solver="random", budget=20)
    records = run(s, 3, tmp_path / "r.jsonl", quiet=True)
    assert [("error" in r) for r in records] == [False, True, False]
    summary = summarise(records)
    assert summary["errors"] == 1
    for name in FAULT_NAMES:
        assert summary["coverage"][name] <= 2 / 3
    # the file holds all three, and reads back
    assert len(read_records(tmp_path / "r.jsonl")) == 3
