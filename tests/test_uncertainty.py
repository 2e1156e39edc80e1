"""Intervals and identifiability (ema_bench.uncertainty) against closed-form answers.

The linear-Gaussian toy is an objective with the interface the uncertainty code uses (a
search space, batched outputs, data, residual factors, signal index) whose outputs are
linear in the unit-box parameters, so the weighted least-squares estimate and its exact
covariance are known in closed form: ``A^-1 B A^-1`` with ``A = G' W G`` and
``B = G' W S W G``.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2, norm

from ema_bench.objective import ProblemError, SearchSpace
from ema_bench.physics.sensors import SENSORS
from ema_bench.uncertainty import intervals
from ema_bench.uncertainty.conformal import conformal_quantile, score
from ema_bench.uncertainty.identifiability import correlation
from ema_bench.uncertainty.local import UncertaintyError
from ema_bench.uncertainty.noise import known_sigma

Z95 = norm.ppf(0.975)


class LinearGaussian:
    """Outputs ``G u + c`` of the unit-box parameters ``u``; data at ``u_true`` plus
    Gaussian noise of the sensors' known level per signal; weights that are *not* the
    inverse noise variances (so the sandwich matters)."""

    def __init__(self, G: np.ndarray, u_true: np.ndarray, seed: int = 0,
                 sigma: np.ndarray | None = None, curvature: float = 0.0) -> None:
        rng = np.random.default_rng(seed)
        self.space = SearchSpace.of()
        self.G = G
        n = G.shape[0]
        # optional curvature in Na alone: the others still enter linearly, so Na's profile
        # has a closed form (test_profile_follows_a_curved_valley)
        self.curvature = curvature
        self.h = rng.normal(0.0, 1.0, n) * np.abs(G[:, 0]).mean()
        self.c = rng.normal(0.0, 1.0, n)
        self.signal_index = np.arange(n) % 4
        self.sigma = known_sigma() if sigma is None else sigma
        self.factors = np.sqrt(rng.uniform(0.5, 2.0, n) / self.sigma[self.signal_index] ** 2
                               / n)
        self.data = self.model(u_true[None, :])[0] + rng.normal(0.0, 1.0, n) * \
            self.sigma[self.signal_index]
        self.calls = 0

    def model(self, U: np.ndarray) -> np.ndarray:
        return U @ self.G.T + self.c + self.curvature * (U[:, :1] - 0.5) ** 2 * self.h

    def outputs(self, X: np.ndarray):
        self.calls += len(X)
        return {"y": self.model(self.space.to_unit(X))}, np.ones(len(X), bool)

    def stack(self, outputs):
        return outputs["y"].copy()

    def exact(self) -> tuple[np.ndarray, np.ndarray]:
        """Weighted least-squares estimate and its covariance, both in the unit box."""
        w = self.factors ** 2
        s2 = self.sigma[self.signal_index] ** 2
        A = self.G.T @ (w[:, None] * self.G)
        B = self.G.T @ ((w * w * s2)[:, None] * self.G)
        u = np.linalg.solve(A, self.G.T @ (w * (self.data - self.c)))
        Ainv = np.linalg.inv(A)
        return u, Ainv @ B @ Ainv


def _toy(seed: int = 0, n: int = 400, sigma: np.ndarray | None = None) -> LinearGaussian:
    rng = np.random.default_rng(100 + seed)
    G = rng.normal(0.0, 1.0, (n, 4)) * np.array([3.0, 1.0, 0.5, 2.0])
    return LinearGaussian(G, np.array([0.4, 0.55, 0.5, 0.6]), seed, sigma)


def _phys(toy: LinearGaussian, u: np.ndarray) -> np.ndarray:
    return toy.space.from_unit(u)


@pytest.mark.parametrize("seed", [0, 1])
def test_laplace_matches_the_exact_sandwich_interval(seed):
    toy = _toy(seed)
    u_hat, cov = toy.exact()
    x0 = _phys(toy, u_hat + 0.003)   # off the optimum: the polish must find it
    iv = intervals(toy, x0, noise="known", model_form="none", calibrate=False)
    ranges = toy.space.upper - toy.space.lower
    unit = toy.space.to_unit
    np.testing.assert_allclose(unit(iv.estimate), u_hat, rtol=0, atol=1e-7)
    np.testing.assert_allclose(iv.cov, cov * np.outer(ranges, ranges), rtol=1e-6)
    half = Z95 * np.sqrt(np.diag(cov))
    np.testing.assert_allclose(unit(iv.low), unit(iv.estimate) - half, rtol=0, atol=1e-9)
    np.testing.assert_allclose(unit(iv.high), unit(iv.estimate) + half, rtol=0, atol=1e-9)


def test_profile_matches_the_exact_interval_on_a_linear_model():
    toy = _toy(2)
    u_hat, cov = toy.exact()
    iv = intervals(toy, _phys(toy, u_hat), method="profile", noise="known",
                   model_form="none", calibrate=False)
    ranges = toy.space.upper - toy.space.lower
    unit = toy.space.to_unit
    half = Z95 * np.sqrt(np.diag(cov))
    # the secant on sqrt(q) is exact for a quadratic profile; the refits converge to 1e-10
    np.testing.assert_allclose(unit(iv.low), u_hat - half, rtol=0, atol=1e-3 * half.min())
    np.testing.assert_allclose(unit(iv.high), u_hat + half, rtol=0, atol=1e-3 * half.min())
    for j, p in enumerate(iv.profiles):
        # the profile itself is the parabola (v - v_hat)^2 / var on its grid
        v = np.array(p["value"])
        expected = ((v - iv.estimate[j]) / (np.sqrt(cov[j, j]) * ranges[j])) ** 2
        np.testing.assert_allclose(p["q"], expected, rtol=1e-3, atol=1e-6)
    assert iv.evaluations <= 3000


def test_profile_follows_a_curved_valley():
    """Na enters the outputs quadratically, the others linearly: Na's exact profile is a
    closed-form weighted least-squares problem per value of Na, and its 95 % interval is
    asymmetric; the profile method must find it, the Laplace one cannot."""
    from scipy.optimize import brentq, minimize_scalar

    rng = np.random.default_rng(12)
    G = rng.normal(0.0, 1.0, (300, 4)) * np.array([0.1, 1.0, 0.5, 2.0]) * 0.01
    toy = LinearGaussian(G, np.array([0.53, 0.5, 0.5, 0.5]), seed=12, curvature=20.0)
    w = toy.factors ** 2
    Go = G[:, 1:]

    def profile_f(t: float) -> float:   # min over the others, in closed form
        r = G[:, 0] * t + toy.curvature * (t - 0.5) ** 2 * toy.h + toy.c - toy.data
        uo = -np.linalg.solve(Go.T @ (w[:, None] * Go), Go.T @ (w * r))
        e = r + Go @ uo
        return float(e @ (w * e)), uo

    t_hat = minimize_scalar(lambda t: profile_f(t)[0], bounds=(0.0, 1.0), method="bounded",
                            options={"xatol": 1e-12}).x
    f_hat, uo_hat = profile_f(t_hat)
    # the sandwich at the optimum (the model's Jacobian there, exactly)
    J = np.column_stack([G[:, 0] + 2 * toy.curvature * (t_hat - 0.5) * toy.h, Go])
    s2 = toy.sigma[toy.signal_index] ** 2
    A = J.T @ (w[:, None] * J)
    Ainv = np.linalg.inv(A)
    V = Ainv @ (J.T @ ((w * w * s2)[:, None] * J)) @ Ainv
    thr = chi2.ppf(0.95, 1)

    def q(t):
        return (profile_f(t)[0] - f_hat) * Ainv[0, 0] / V[0, 0] - thr

    half = np.sqrt(thr * V[0, 0])
    lo = brentq(q, t_hat - 10 * half, t_hat)
    hi = brentq(q, t_hat, t_hat + 10 * half)
    assert (hi - t_hat) / (t_hat - lo) > 1.3 or (t_hat - lo) / (hi - t_hat) > 1.3
    x_hat = toy.space.from_unit(np.r_[t_hat, uo_hat])
    kw = dict(noise="known", model_form="none", calibrate=False, params=("Na",))
    iv = intervals(toy, x_hat, method="profile", **kw)
    unit = toy.space.to_unit
    # the search stops within 10 % of the threshold in q: about 5 % of the half-width
    assert unit(iv.low)[0] == pytest.approx(lo, abs=0.06 * (t_hat - lo))
    assert unit(iv.high)[0] == pytest.approx(hi, abs=0.06 * (hi - t_hat))
    lap = intervals(toy, x_hat, method="laplace", **kw)
    assert abs(unit(lap.high)[0] - hi) > 0.1 * (hi - t_hat) or \
        abs(unit(lap.low)[0] - lo) > 0.1 * (t_hat - lo)


def test_a_fit_off_the_optimum_is_flagged_by_its_profile():
    toy = _toy(13)
    u_hat, cov = toy.exact()
    off = u_hat + 3 * np.sqrt(np.diag(cov))
    iv = intervals(toy, _phys(toy, off), method="profile", polish=False, noise="known",
                   model_form="none", calibrate=False)
    assert any("lower fitness" in w for w in iv.warnings)
    polished = intervals(toy, _phys(toy, off), method="profile", noise="known",
                         model_form="none", calibrate=False)
    assert polished.warnings == []


def test_profile_stops_at_a_bound():
    """A parameter whose interval would cross its bound ends at the bound, not beyond."""
    toy = LinearGaussian(np.random.default_rng(3).normal(0, 1, (200, 4)) * 0.05,
                         np.array([0.999, 0.5, 0.5, 0.5]), seed=3)
    u_hat, cov = toy.exact()
    assert u_hat[0] + Z95 * np.sqrt(cov[0, 0]) > 1.0   # the exact interval crosses it
    iv = intervals(toy, _phys(toy, np.clip(u_hat, 0, 1)), method="profile", noise="known",
                   model_form="none", calibrate=False)
    assert iv.high[0] == pytest.approx(toy.space.upper[0])
    assert iv.low[0] < iv.estimate[0]


def test_the_evaluation_cap_holds_and_is_counted():
    toy = _toy(3)
    u_hat, cov = toy.exact()
    toy.calls = 0
    iv = intervals(toy, _phys(toy, u_hat + 0.01), method="profile", max_evals=120,
                   noise="known", model_form="none", calibrate=False)
    assert iv.evaluations == toy.calls <= 120
    # sides the cap cut short keep their Laplace ends: never narrower than a point
    assert (iv.low < iv.estimate).all() and (iv.estimate < iv.high).all()
    for cap in (500, 517, 733):   # the bootstrap stops at its cap, never one past it
        toy.calls = 0
        boot = intervals(toy, _phys(toy, u_hat), method="bootstrap", max_evals=cap,
                         noise="known", n_boot=1000)
        assert boot.evaluations == toy.calls <= cap
        assert boot.evaluations > cap - 20
    with pytest.raises(UncertaintyError, match="bootstrap refits"):
        intervals(toy, _phys(toy, u_hat), method="bootstrap", max_evals=100, noise="known")


def test_bootstrap_spread_matches_the_exact_standard_error():
    toy = _toy(4, n=200)
    u_hat, cov = toy.exact()
    iv = intervals(toy, _phys(toy, u_hat), method="bootstrap", noise="known",
                   model_form="none", calibrate=False, n_boot=200, max_evals=20000, seed=7)
    ranges = toy.space.upper - toy.space.lower
    sd = iv.replicates.std(axis=0, ddof=1) / ranges
    # 200 replicates: the sd is known to ~5 %; 20 % is a 4-sigma band
    np.testing.assert_allclose(sd, np.sqrt(np.diag(cov)), rtol=0.2)
    # the normal bootstrap interval: estimate +- z sd of the replicates (ddof 1), per fault
    half = Z95 * iv.replicates.std(axis=0, ddof=1)
    np.testing.assert_allclose(iv.low, iv.estimate - half, rtol=1e-9)
    np.testing.assert_allclose(iv.high, iv.estimate + half, rtol=1e-9)
    # same seed, same numbers
    again = intervals(toy, _phys(toy, u_hat), method="bootstrap", noise="known",
                      model_form="none", calibrate=False, n_boot=200, max_evals=20000,
                      seed=7)
    np.testing.assert_array_equal(again.low, iv.low)


def test_noise_scale_and_level_scale_the_half_width():
    toy = _toy(5)
    u_hat, _ = toy.exact()
    kw = dict(noise="known", model_form="none", calibrate=False)
    base = intervals(toy, _phys(toy, u_hat), **kw)
    half = base.high - base.estimate
    scaled = intervals(toy, _phys(toy, u_hat), noise_scale=0.5, **kw)
    np.testing.assert_allclose(scaled.high - scaled.estimate, 0.5 * half, rtol=1e-6)
    wide = intervals(toy, _phys(toy, u_hat), level=0.99, **kw)
    np.testing.assert_allclose(wide.high - wide.estimate,
                               half * norm.ppf(0.995) / Z95, rtol=1e-6)


def test_estimated_noise_follows_the_residuals():
    """With data twice as noisy as the sensors' datasheet, the estimated noise ratio is 2
    and the estimated-noise interval is twice the known-noise one."""
    toy = _toy(6, n=4000, sigma=2.0 * known_sigma())
    u_hat, _ = toy.exact()
    est = intervals(toy, _phys(toy, u_hat), model_form="none", calibrate=False)
    known = intervals(toy, _phys(toy, u_hat), noise="known", model_form="none",
                      calibrate=False)
    assert all(1.9 < r < 2.1 for r in est.noise_ratio.values())
    assert len(est.warnings) == 1 and "exceed the sensor noise" in est.warnings[0]
    assert all(f"{s} " in est.warnings[0] for s in est.noise_ratio)
    np.testing.assert_allclose((est.high - est.low) / (known.high - known.low), 2.0, rtol=0.06)


def test_known_noise_is_the_sensors_noise_and_quantisation():
    for s, spec in zip(known_sigma(), SENSORS):
        span = spec.hi - spec.lo
        assert s == pytest.approx(np.sqrt((1e-3 * span) ** 2 + (span / 4095) ** 2 / 12))


def test_identifiability_names_a_confounded_pair_and_an_unseen_fault():
    rng = np.random.default_rng(8)
    g = rng.normal(0, 1, 300)
    G = np.column_stack([g, g + 1e-3 * rng.normal(0, 1, 300), rng.normal(0, 1, 300),
                         np.zeros(300)])   # Na ~ Fst; Gprop unseen
    toy = LinearGaussian(G, np.array([0.5, 0.5, 0.5, 0.5]), seed=8)
    iv = intervals(toy, _phys(toy, np.full(4, 0.5)), noise="known", model_form="none",
                   calibrate=False, polish=False)
    ident = iv.identifiability
    assert [c["pair"] for c in ident["confounded"]] == [["Na", "Fst"]]
    assert ident["confounded"][0]["correlation"] < -0.99
    assert set(ident["non_identifiable"]) >= {"Gprop"}
    assert "BLK" not in ident["non_identifiable"]
    # the unseen fault spans the whole box; the weakest direction is Gprop alone
    assert iv.low[3] == toy.space.lower[3] and iv.high[3] == toy.space.upper[3]
    weakest = ident["weakest"][0]["direction"]
    assert abs(weakest["Gprop"]) == pytest.approx(1.0)


def test_correlation_of_a_known_covariance():
    cov = np.array([[4.0, 1.2], [1.2, 1.0]])
    np.testing.assert_allclose(correlation(cov), [[1.0, 0.6], [0.6, 1.0]])


@pytest.mark.parametrize("kwargs, match", [
    ({"method": "jackknife"}, "unknown interval method"),
    ({"level": 1.0}, "level"),
    ({"level": float("nan")}, "level"),
    ({"model_form": "guess"}, "model_form"),
    ({"noise": "loud"}, "noise"),
    ({"noise_scale": 0.0}, "noise_scale"),
    ({"params": ("Nb",)}, "unknown parameter"),
])
def test_bad_settings_are_clear_errors(kwargs, match):
    toy = _toy(0, n=50)
    with pytest.raises(UncertaintyError, match=match):
        intervals(toy, _phys(toy, np.full(4, 0.5)), **kwargs)


@pytest.mark.parametrize("x", [[0.9, 0.3, 0.01], [0.9, np.nan, 0.01, 1e5],
                               [1.2, 0.3, 0.01, 1e5]])
def test_bad_vectors_are_clear_errors(x):
    toy = _toy(0, n=50)
    with pytest.raises(ProblemError):
        intervals(toy, np.array(x))


def test_conformal_quantile_and_score():
    scores = np.arange(1, 20) / 10.0           # 19 scores: 0.1 .. 1.9
    # ceil(20 * 0.95) = 19th smallest
    assert conformal_quantile(scores, 0.95) == pytest.approx(1.9)
    assert conformal_quantile(scores, 0.5) == pytest.approx(1.0)
    assert score(truth=1.0, estimate=2.0, low=0.4, high=2.5) == pytest.approx(1.0 / 1.6)
    assert score(truth=3.0, estimate=2.0, low=0.4, high=2.5) == pytest.approx(2.0)
    assert score(truth=2.0, estimate=2.0, low=2.0, high=2.0) == 0.0
    assert score(truth=1.0, estimate=2.0, low=2.0, high=3.0) == float("inf")   # no width
    assert conformal_quantile([], 0.95) == 1.0
    assert conformal_quantile([0.7], 0.5) == 0.7
    assert conformal_quantile(np.array([3, 1, 2]), 0.5) == 2.0   # sorted, as floats


def test_calibration_kind_of_each_track():
    from ema_bench.uncertainty.conformal import calibration_kind

    assert calibration_kind("twin") == "twin"
    for track in ("reference", "measured", None):
        assert calibration_kind(track) == "reference"


def test_chi2_threshold_is_z_squared():
    assert np.sqrt(chi2.ppf(0.95, 1)) == pytest.approx(Z95)


def test_model_form_allowance_is_the_quantile_of_the_shipped_biases_in_quadrature():
    import json
    import math

    from ema_bench.uncertainty import model_form

    data = json.loads(model_form.PATH.read_text())
    biases = np.abs([row["range_error"] for row in data["instances"].values()])
    n = biases.shape[0]
    assert n >= 20
    expected = np.sort(biases, axis=0)[math.ceil(0.95 * (n - 1))]
    np.testing.assert_allclose(model_form.allowance(0.95), expected)
    toy = _toy(9)
    u_hat, cov = toy.exact()
    kw = dict(noise="known", calibrate=False, polish=False)
    none = intervals(toy, _phys(toy, u_hat), model_form="none", **kw)
    disc = intervals(toy, _phys(toy, u_hat), model_form="discrepancy", **kw)
    ranges = toy.space.upper - toy.space.lower
    np.testing.assert_allclose(disc.allowance, expected * ranges)
    np.testing.assert_allclose(disc.high - disc.estimate,
                               np.hypot(none.high - none.estimate, expected * ranges))
    # auto: none on the twin track, the allowance everywhere else
    assert intervals(toy, _phys(toy, u_hat), track="twin", **kw).model_form == "none"
    assert intervals(toy, _phys(toy, u_hat), track="reference", **kw).model_form == \
        "discrepancy"
    assert intervals(toy, _phys(toy, u_hat), track="measured", **kw).model_form == \
        "discrepancy"


def test_calibration_factors_come_from_the_shipped_scores():
    import json
    import math

    from ema_bench.uncertainty import conformal

    data = json.loads(conformal.PATH.read_text())
    scores = data["scores"]["twin|laplace|none"]
    factor = []
    for name in ("Na", "Fst", "BLK", "Gprop"):
        s = sorted(scores[name])
        factor.append(s[math.ceil((len(s) + 1) * 0.95) - 1])
    toy = _toy(10)
    u_hat, _ = toy.exact()
    kw = dict(track="twin", noise="known", polish=False)
    raw = intervals(toy, _phys(toy, u_hat), calibrate=False, **kw)
    cal = intervals(toy, _phys(toy, u_hat), **kw)
    assert cal.calibration == "twin" and raw.calibration == "none"
    np.testing.assert_allclose(cal.factor, factor)
    np.testing.assert_allclose(cal.high - cal.estimate, np.array(factor) *
                               (raw.high - raw.estimate))
    # a method without shipped scores is uncalibrated, and says so
    boot = intervals(toy, _phys(toy, u_hat), method="bootstrap", n_boot=20, **kw)
    assert boot.calibration == "none" and (boot.factor == 1.0).all()


def test_a_refit_never_passes_its_evaluation_cap():
    """Every cap from 1 to 40, including those that end exactly where a Jacobian batch
    (2 dim + 1 runs) would start."""
    from ema_bench.uncertainty.local import Counter, refit

    toy = _toy(11)
    for cap in range(1, 41):
        counter = Counter(toy)
        refit(counter, np.full(4, 0.05), max_evals=cap)   # far from the optimum
        assert counter.evaluations <= cap, cap


def test_the_step_test_alone_cannot_tell_na_from_fst():
    """The paper's Na/Fst valley, seen from the data side: fitted to the step test alone,
    Na and Fst are confounded; the step and the sine together separate every pair."""
    from ema_bench.suites.problem import make_problem

    truth = np.array([0.95, 0.3378, 0.01, 1e5])   # the 'small' case
    pairs = {}
    for tests in (("step",), ("step", "sine")):
        p = make_problem("small", track="twin", seed=0, budget=10, tests=tests)
        iv = intervals(p.objective, truth, track="twin", calibrate=False, polish=False)
        pairs[tests] = [c["pair"] for c in iv.identifiability["confounded"]]
        assert iv.evaluations == 1 + 9
    assert ["Na", "Fst"] in pairs[("step",)]
    assert pairs[("step", "sine")] == []
