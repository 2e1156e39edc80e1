"""``particle``: a particle filter over faults and degradation rates, weighted on the traces.

State
    Each particle is a fault vector (``Na, Fst, BLK, Gprop``, physical) plus one growth rate
    per failing fault: a damage rate (share of range per flight) for a fault that wears
    (``linear`` growth, :data:`~._common.GROWTH`: friction, backlash), a log-growth rate (per
    flight) for one that spreads (``exponential``: a coil short).
Transition (between inspections, ``dt`` flights)
    ``linear``: ``d += rate dt + N(0, q_d^2 dt)``, ``rate += N(0, q_r^2 dt)``;
    ``exponential``: ``d *= exp(g dt + N(0, q_y^2 dt))``, ``g += N(0, q_g^2 dt)``, once
    ``d`` exceeds :data:`ONSET` (below it the damage only diffuses, ``N(0, (1e-3)^2 dt)``);
    :data:`~._common.PROCESS_NOISE` for the ``q``.  ``Gprop`` random-walks,
    :data:`GAIN_DRIFT` of its range per sqrt(flight).  Faults are clipped into the box.
Proposal
    The sensors' likelihood is far narrower than the cloud the degradation noise spreads
    (a fitted friction is good to 0.1 % of its range, ten flights of wear scatter it by 1 %),
    so particles propagated blindly would almost all miss it.  Each inspection is therefore
    fitted first (:class:`~._common.Fitter`, warm-started at the last fit), and each
    particle is drawn from the product of its Gaussian transition and the fit's Laplace
    approximation of the likelihood (the linearised optimal proposal, Doucet, Godsill and
    Andrieu 2000): a backlash jump or a coil-short onset is followed as soon as the fit sees
    it.  Rates are carried over from the particle's ancestor.
Weights
    ``w = L^beta * transition / proposal``, with ``L`` the traces' Gaussian sensor-noise
    likelihood of every particle from one batched monitor call (the logged conditions'
    confounders switched on): ``-chi^2 / 2`` with ``chi^2`` the sum over every sample of
    ``(model - measured)^2 / sigma_s^2``, ``sigma_s`` per signal the larger of the sensors'
    datasheet noise (noise and 12-bit ADC) and the best particle's RMS residual (model-form
    error on the reference track).  ``beta`` (tempering) is the largest value <= 1 that keeps
    the effective sample size at least ``ess`` of the particles (1 unless the weights
    collapse).  The transition term is what teaches the rates: particles whose rate
    predicted the new faults well gain weight.  Then systematic resampling and roughening
    (Gaussian jitter of :data:`ROUGHEN` times the cloud's spread, rates included).
Initialisation
    The first inspection's fit (CMA-ES from nominal), particles drawn around it (three times
    its standard deviations) and weighted by ``L^beta / proposal``; rates from their priors
    (``linear``: uniform in ``[-5e-4, 7.5e-3]`` per flight; ``exponential``: uniform in
    ``[0, 0.05]``).
RUL distribution
    Every particle of the resampled cloud is run forward ``paths_per_particle`` times by the
    transition model, in half-interval steps up to 1,500 flights; a path fails with its first
    fault to cross its threshold; median and 2.5-97.5 % quantiles of the failure times (a
    coil short's onset is not predicted).
Estimates reported
    The weighted mean of the cloud and its weighted 2.5-97.5 % quantiles.
Replacement
    :func:`~._common.replace_now`; ``Gprop`` never counts.
Cost
    The fit (about 100 model runs when warm-started, 1,500 at a unit's first inspection)
    plus ``n_particles`` (200) in one batched call per inspection.
"""

from __future__ import annotations

import numpy as np

from ema_bench.faults import FAULT_INDEX, LOWER, N_FAULTS, UPPER
from ema_bench.prognostics.tracking import Inspection, TrackStep, register_tracker
from ema_bench.uncertainty.noise import known_sigma

from ._common import (
    RANGE,
    REPLACE_HORIZON,
    REPLACE_PROB,
    Fit,
    RulSummary,
    first_passage,
    from_damage,
    growth,
    make_step,
    process_noise,
    replace_now,
    rng_of,
    summarise,
    to_damage,
    unit_setup,
)

N_PARTICLES = 200
ESS = 0.3
ROUGHEN = 0.1
ONSET = 0.02
DIFFUSION_BELOW_ONSET = 1e-3
GAIN_DRIFT = 0.012
P_JUMP = 0.05
JUMP_SD = 0.05
#: Share of particles proposed from the jump component (defensive: more than P_JUMP, so a
#: jump the fit sees is followed by many particles; the weights correct for it).
Q_JUMP = 0.3
RATE_PRIOR = {"linear": (-5e-4, 7.5e-3), "exponential": (0.0, 0.05)}
PATHS_PER_PARTICLE = 10
INIT_SD = 3.0


class Cloud:
    """Particles: faults ``X`` (n, 4) physical and rates ``R`` (n, m), with log-weights."""

    def __init__(self, names: list[str], thresholds: dict[str, float]) -> None:
        self.names, self.thresholds = names, thresholds
        self.laws = [growth(n) for n in names]
        self.j = [FAULT_INDEX[n] for n in names]
        self.q_d, self.q_r = process_noise(names)
        self.X = np.empty((0, N_FAULTS))
        self.R = np.empty((0, len(names)))
        self.logw = np.empty(0)

    def damage(self, X: np.ndarray | None = None) -> np.ndarray:
        return to_damage(self.X if X is None else X, self.names, self.thresholds)

    def draw_rates(self, rng: np.random.Generator, n: int) -> np.ndarray:
        lo, hi = np.array([RATE_PRIOR[law] for law in self.laws]).T
        return rng.uniform(lo, hi, size=(n, len(self.names)))

    def grow(self, D: np.ndarray, R: np.ndarray, dt: float, rng: np.random.Generator | None
             ) -> tuple[np.ndarray, np.ndarray]:
        """Damage and rates ``dt`` flights on by the transition model (its mean when
        ``rng`` is None)."""
        D, R = D.copy(), R.copy()
        z = np.zeros((2, *D.shape)) if rng is None else rng.standard_normal((2, *D.shape))
        for k, law in enumerate(self.laws):
            if law == "linear":
                D[:, k] += R[:, k] * dt + self.q_d[k] * np.sqrt(dt) * z[0, :, k]
            else:
                on = D[:, k] > ONSET
                D[on, k] *= np.exp(R[on, k] * dt + self.q_d[k] * np.sqrt(dt) * z[0, on, k])
                D[~on, k] += DIFFUSION_BELOW_ONSET * np.sqrt(dt) * z[0, ~on, k]
            R[:, k] += self.q_r[k] * np.sqrt(dt) * z[1, :, k]
        return D, R

    def predict(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Transition mean (n, 4) physical and its variance (n, 4) in unit-box coordinates
        (damage units for the failing faults; diagonal)."""
        D0 = self.damage()
        D, _ = self.grow(D0, self.R, dt, None)
        X = self.X.copy()
        X[:, self.j] = from_damage(D, self.names, self.thresholds)
        var = np.zeros_like(X)
        for k, law in enumerate(self.laws):
            q = np.full(len(X), self.q_d[k] ** 2 * dt)
            if law == "exponential":   # multiplicative scatter, or diffusion below onset
                q = np.where(D0[:, k] > ONSET, D[:, k] ** 2 * q,
                             DIFFUSION_BELOW_ONSET ** 2 * dt)
            var[:, self.j[k]] = q + self.q_r[k] ** 2 * dt ** 3 / 3.0 * np.where(
                law == "exponential", np.maximum(D[:, k], 0.0) ** 2, 1.0)
        var[:, FAULT_INDEX["Gprop"]] = GAIN_DRIFT ** 2 * dt
        return np.clip(X, LOWER, UPPER), np.maximum(var, 1e-14)

    def resample(self, rng: np.random.Generator) -> None:
        """Systematic resampling, then roughening (jitter of ``ROUGHEN`` x the spread)."""
        n = self.X.shape[0]
        w = np.exp(self.logw - self.logw.max())
        c = np.cumsum(w / w.sum())
        idx = np.minimum(np.searchsorted(c, (rng.random() + np.arange(n)) / n), n - 1)
        Z = np.hstack([self.X[idx], self.R[idx]])
        sd = np.maximum(Z.std(axis=0), np.r_[1e-5 * RANGE, 1e-7 * np.ones(self.R.shape[1])])
        Z = Z + ROUGHEN * sd * rng.standard_normal(Z.shape)
        self.X = np.clip(Z[:, :N_FAULTS], LOWER, UPPER)
        self.R = Z[:, N_FAULTS:]
        self.logw = np.zeros(n)


def _gauss_logpdf(U: np.ndarray, M: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Log-density (n,) of rows ``U`` under N(M_i, P_i), batches (n, d) and (n, d, d)."""
    L = np.linalg.cholesky(P)
    z = np.linalg.solve(L, (U - M)[..., None])[..., 0]
    return -0.5 * np.sum(z ** 2, axis=1) - np.log(np.diagonal(L, axis1=1, axis2=2)).sum(1)


def _product(Um: np.ndarray, V: np.ndarray, uf: np.ndarray, Ci: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """Mean (n, 4) and covariance (n, 4, 4) of ``N(Um_i, diag V_i) x N(uf, Ci^-1)``."""
    P = np.linalg.inv(Ci[None] + np.eye(N_FAULTS)[None] / V[:, :, None])
    P = 0.5 * (P + np.swapaxes(P, 1, 2))
    return np.einsum("nij,nj->ni", P, (Ci @ uf)[None] + Um / V), P


def _mixture_logpdf(U: np.ndarray, parts: list[tuple[float, np.ndarray, np.ndarray]]
                    ) -> np.ndarray:
    """Log-density (n,) of rows ``U`` under a mixture of (weight, means, covariances)."""
    logs = [np.log(a) + _gauss_logpdf(U, m, P) for a, m, P in parts if a > 0]
    return np.logaddexp.reduce(np.stack(logs), axis=0)


def propose(rng: np.random.Generator, M: np.ndarray, V: np.ndarray | None, fit: Fit,
            jump: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Draw particles (n, 4) physical from the product of their transition and the fit, in
    the unit box; returns them, the proposal's and the transition's log-densities.

    The transition is the mixture ``(1 - P_JUMP) N(M_i, diag V_i) + P_JUMP N(M_i, diag(V_i
    + jump^2))`` (jumps of the failing faults: backlash chips, coil-short onsets); the
    proposal is the mixture of the products with the fit, the jump component drawn for
    :data:`Q_JUMP` of the particles.  ``V`` None (the first
    inspection): the fit alone, inflated :data:`INIT_SD` times, and no transition term."""
    n = M.shape[0]
    C = fit.cov / np.outer(RANGE, RANGE)                  # the fit, unit box
    uf = (fit.x - LOWER) / RANGE
    if V is None:
        P = np.broadcast_to(INIT_SD ** 2 * C, (n, N_FAULTS, N_FAULTS)).copy()
        parts = [(1.0, np.broadcast_to(uf, (n, N_FAULTS)), P)]
    else:
        Ci = np.linalg.inv(C)
        Um = (M - LOWER) / RANGE
        Vj = V + jump[None] ** 2
        parts = [(1.0 - Q_JUMP, *_product(Um, V, uf, Ci)), (Q_JUMP, *_product(Um, Vj, uf, Ci))]
    pick = rng.random(n) < parts[-1][0] if len(parts) > 1 else np.zeros(n, bool)
    mean = np.where(pick[:, None], parts[-1][1], parts[0][1])
    L = np.linalg.cholesky(np.where(pick[:, None, None], parts[-1][2], parts[0][2]))
    U = np.clip(mean + np.einsum("nij,nj->ni", L, rng.standard_normal((n, N_FAULTS))),
                0.0, 1.0)
    log_q = _mixture_logpdf(U, parts)
    if V is None:
        return LOWER + U * RANGE, log_q, np.zeros(n)
    diag = np.eye(N_FAULTS)[None]
    log_t = _mixture_logpdf(U, [(1.0 - P_JUMP, Um, diag * V[:, :, None]),
                                (P_JUMP, Um, diag * Vj[:, :, None])])
    return LOWER + U * RANGE, log_q, log_t


def temper(logw: np.ndarray, target: float) -> float:
    """The largest ``beta`` in (0, 1] whose weights ``beta logw`` keep the effective
    sample size at least ``target`` (bisection in log beta)."""
    if not np.isfinite(logw).any() or _ess(logw) >= target:
        return 1.0
    lo, hi = -40.0, 0.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if _ess(np.exp(mid) * logw) >= target:
            lo = mid
        else:
            hi = mid
    return float(np.exp(lo))


def _ess(logw: np.ndarray) -> float:
    w = np.exp(logw - np.max(logw))
    return float(w.sum() ** 2 / (w ** 2).sum())


def loglik(problem, X: np.ndarray) -> np.ndarray:
    """Gaussian log-likelihood (n,) of particles ``X`` on the problem's traces (one batched
    monitor call, counted by the problem); noise per signal the larger of the datasheet's
    and the best particle's RMS residual; ``-inf`` for a failed simulation."""
    obj = problem.objective
    _, outputs = problem.evaluate_outputs(X)
    res = obj.stack(outputs) - obj.data[None, :]
    idx = obj.signal_index
    ok = np.isfinite(res).all(axis=1)
    res[~ok] = 0.0
    ss = np.stack([np.sum(res[:, idx == s] ** 2, axis=1) for s in range(4)], axis=1)
    sigma = known_sigma()
    if ok.any():
        best = np.argmin(np.where(ok, (ss / sigma ** 2).sum(axis=1), np.inf))
        sigma = np.maximum(sigma, np.sqrt(ss[best] / np.bincount(idx, minlength=4)))
    return np.where(ok, -0.5 * (ss / sigma ** 2).sum(axis=1), -np.inf)


def _weighted_quantiles(v: np.ndarray, w: np.ndarray, qs: tuple[float, ...]) -> np.ndarray:
    order = np.argsort(v, axis=0)
    out = np.empty((len(qs), v.shape[1]))
    for k in range(v.shape[1]):
        c = np.cumsum(w[order[:, k]])
        c /= c[-1]
        for i, q in enumerate(qs):
            out[i, k] = v[order[min(np.searchsorted(c, q), len(c) - 1), k], k]
    return out


@register_tracker("particle", description="particle filter over faults and degradation rates, "
                  "weighted directly on the traces with the batched monitor (linearised "
                  "optimal proposal from a warm-started fit, systematic resampling, "
                  "roughening); RUL by propagating the particles to the thresholds")
def factory(campaign_info: dict, seed: np.random.SeedSequence, *,
            n_particles: int = N_PARTICLES, ess: float = ESS,
            paths_per_particle: int = PATHS_PER_PARTICLE, first_budget: int = 1500,
            global_budget: int = 1000, replace_prob: float = REPLACE_PROB,
            conditions: bool = True):
    u = unit_setup(campaign_info, seed, first_budget, global_budget, conditions)
    thresholds, every, names, d_thr, fitter, mc_seed = (u.thresholds, u.every, u.names, u.d_thr,
                                                        u.fitter, u.mc_seed)
    effects = u.effects
    cloud = Cloud(names, thresholds)
    jump = np.zeros(N_FAULTS)
    jump[cloud.j] = JUMP_SD
    last: dict[str, float | None] = {"flight": None}

    def step(insp: Inspection) -> TrackStep:
        rng = rng_of(mc_seed, insp.index)
        fit = fitter(insp)
        if last["flight"] is None:
            X, log_q, log_t = propose(rng, np.empty((n_particles, N_FAULTS)), None, fit,
                                      jump)
            cloud.R = cloud.draw_rates(rng, n_particles)
        else:
            M, V = cloud.predict(insp.flight - last["flight"])
            X, log_q, log_t = propose(rng, M, V, fit, jump)
        last["flight"] = insp.flight
        problem = insp.problem(budget=n_particles, effects=effects(insp))
        ll = loglik(problem, X)
        beta = temper(ll - ll.max() if np.isfinite(ll).any() else ll, ess * n_particles)
        cloud.X = X
        cloud.logw = np.where(np.isfinite(ll), beta * ll + log_t - log_q, -np.inf)
        if not np.isfinite(cloud.logw).any():
            raise RuntimeError("every particle's simulation failed")
        w = np.exp(cloud.logw - cloud.logw.max())
        w /= w.sum()
        x = w @ X
        low, high = _weighted_quantiles(X, w, (0.025, 0.975))
        cloud.resample(rng)
        summary = _rul(cloud, d_thr, rng, paths_per_particle, every)
        replace = replace_now(summary, low, high, names, thresholds, replace_prob)
        return make_step(insp, x, low, high, summary, replace,
                         fit.evaluations + problem.evaluations, fit=fit.how,
                         misfit=round(fit.misfit, 4), beta=round(beta, 6),
                         ess=round(float(1.0 / np.sum(w ** 2)), 1), p_fail=summary.p_fail,
                         rate={n: float(np.mean(cloud.R[:, k])) for k, n in enumerate(names)})

    return step


def _rul(cloud: Cloud, d_thr: np.ndarray, rng: np.random.Generator, per: int,
         every: float) -> RulSummary:
    """RUL of the (resampled) cloud: ``per`` transition paths per particle."""
    state = {"D": np.repeat(cloud.damage(), per, axis=0),
             "R": np.repeat(cloud.R, per, axis=0)}

    def advance(dt: float) -> np.ndarray:
        state["D"], state["R"] = cloud.grow(state["D"], state["R"], dt, rng)
        return state["D"]

    cross = first_passage(state["D"], advance, d_thr, every / 2)
    return summarise(cross, cloud.names, REPLACE_HORIZON * every)
