"""Uncertainty plots: profiles, the confidence region and the coverage caterpillar write
readable PNGs from a real fit, and the coverage counts drawn are the true ones."""

from __future__ import annotations

import matplotlib.image as mpimg
import numpy as np
import pytest

from ema_bench.faults import FAULT_NAMES, LOWER, UPPER
from ema_bench.suites.problem import make_problem
from ema_bench.uncertainty import intervals
from ema_bench.uncertainty.plots import plot_coverage, plot_profiles, plot_region

#: The 'small' case truth (Na, Fst, BLK, Gprop).
TRUTH = np.array([0.95, 0.3378, 0.01, 1e5])


@pytest.fixture(scope="module")
def problem():
    return make_problem("small", track="twin", seed=0, budget=10)


@pytest.fixture(scope="module")
def profiled(problem):
    return intervals(problem.objective, TRUTH, method="profile", track="twin", max_evals=600)


def read_png(path, width_in: float, height_in: float) -> np.ndarray:
    """The image at ``path``, checked: non-empty, the figure's size at 110 dpi (savefig
    without ``bbox_inches`` keeps it), not one flat colour."""
    assert path.stat().st_size > 1000
    img = mpimg.imread(path)
    assert img.shape[:2] == (round(height_in * 110), round(width_in * 110))
    assert float(img[..., :3].std()) > 0.01
    return img


def test_profiles_png(profiled, tmp_path):
    assert len(profiled.profiles) == 4
    out = tmp_path / "profiles.png"
    plot_profiles(profiled, out, truth=TRUTH)
    read_png(out, 3.6 * 4, 3.2 + 0.3)


def test_profiles_need_the_profile_method(problem, profiled, tmp_path):
    iv = intervals(problem.objective, TRUTH, method="laplace", track="twin")
    with pytest.raises(ValueError, match="method='profile'"):
        plot_profiles(iv, tmp_path / "x.png")
    with pytest.raises(ValueError, match="truth"):
        plot_profiles(profiled, tmp_path / "x.png", truth=TRUTH[:2])
    assert not (tmp_path / "x.png").exists()


def test_region_png(problem, profiled, tmp_path):
    out = tmp_path / "region.png"
    plot_region(problem.objective, profiled, out, truth=TRUTH, n=9)
    read_png(out, 11, 4.6)
    other = tmp_path / "region_blk.png"
    plot_region(problem.objective, profiled, other, pair=("BLK", "Gprop"), n=5)
    read_png(other, 11, 4.6)


def test_region_rejects_bad_pairs(problem, profiled, tmp_path):
    with pytest.raises(ValueError, match="unknown parameter"):
        plot_region(problem.objective, profiled, tmp_path / "x.png", pair=("Na", "Kt"))
    with pytest.raises(ValueError, match="two different"):
        plot_region(problem.objective, profiled, tmp_path / "x.png", pair=("Na", "Na"))
    with pytest.raises(ValueError, match="n must"):
        plot_region(problem.objective, profiled, tmp_path / "x.png", n=1)


def synthetic_records(n: int, seed: int = 1) -> tuple[list[dict], dict[str, int]]:
    """Coverage records with a chosen miss pattern, and the misses per fault by
    construction (not by re-testing the intervals)."""
    rng = np.random.default_rng(seed)
    ranges = UPPER - LOWER
    settings = {"track": "twin", "method": "laplace", "level": 0.95, "solver": "de",
                "budget": 5000, "root_seed": 0, "noise_scale": 1.0, "model_form": "auto"}
    misses = dict.fromkeys(FAULT_NAMES, 0)
    records = []
    for i in range(n):
        truth = LOWER + rng.uniform(0.2, 0.8, 4) * ranges
        half = rng.uniform(0.005, 0.05, 4) * ranges
        miss = rng.random(4) < 0.3
        # a miss: the interval lies wholly above or below the truth; a hit straddles it,
        # one of them exactly at the truth (an end equal to the truth covers it)
        shift = np.where(miss, rng.choice([-1.0, 1.0], 4) * (half + 0.01 * ranges),
                         rng.uniform(-0.5, 0.5, 4) * half)
        est = truth + shift
        lo, hi = est - half, est + half
        if i == 0:   # low == truth exactly, bit for bit
            miss[0], est[0], lo[0], hi[0] = False, truth[0], truth[0], truth[0] + half[0]
        for name, m in zip(FAULT_NAMES, miss):
            misses[name] += int(m)
        records.append({
            "key": f"twin|laplace|0|{i}", "index": i, "settings": dict(settings),
            "truth": dict(zip(FAULT_NAMES, truth.tolist())),
            "estimate": dict(zip(FAULT_NAMES, est.tolist())),
            "low": dict(zip(FAULT_NAMES, lo.tolist())),
            "high": dict(zip(FAULT_NAMES, hi.tolist())),
        })
    return records, misses


def test_coverage_png_and_counts(tmp_path):
    records, misses = synthetic_records(12)
    assert 0 < sum(misses.values()) < 12 * 4   # both colours are drawn
    out = tmp_path / "coverage.png"
    counts = plot_coverage(records, out)
    read_png(out, 3.8 * 4, 3.8)
    assert counts == {name: (12 - misses[name], 12) for name in FAULT_NAMES}


def test_coverage_rejects_empty_and_mixed(tmp_path):
    with pytest.raises(ValueError, match="no coverage records"):
        plot_coverage([], tmp_path / "x.png")
    records, _ = synthetic_records(3)
    records[1]["settings"]["method"] = "profile"
    with pytest.raises(ValueError, match="method"):
        plot_coverage(records, tmp_path / "x.png")
