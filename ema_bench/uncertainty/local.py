"""Local (Laplace / Gauss-Newton) uncertainty of a weighted least-squares fit.

A fit ``x`` minimises ``f(x) = sum(w_i (y_i(x) - d_i)^2)`` with the objective's weights ``w``
(:attr:`~ema_bench.objective.Objective.factors` squared), which are not the inverse noise
variances: the fitness normalises each signal by its range.  The covariance of such an
estimator is the sandwich

    cov = A^-1 B A^-1,   A = J' W J,   B = J' W S W J,

with ``J`` the Jacobian of the outputs and ``S`` the noise covariance (diagonal: white sensor
noise, per signal).  With ``W = S^-1`` it is the familiar ``(J' S^-1 J)^-1``.

Everything here works in the unit box of the search space (:meth:`SearchSpace.to_unit`), where
the four faults are on one scale; covariances are returned there too and converted to physical
units by the callers.  Every model run goes through a :class:`Counter`, which counts
evaluations against a cap so that an interval's cost is measured and bounded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..objective import Objective, ProblemError

#: Finite-difference step of the Jacobian, in the unit box (central differences): 1 % of each
#: range.  Dry friction and backlash make the outputs slightly rough at small scales; with
#: 1e-3 the standard error of one twin instance's Gprop came out 3x too small (step 1e-2,
#: 1e-4 and 3e-5 agreed), while 1e-2 and 3e-3 gave the same coverage over 30 instances.
JAC_STEP = 1e-2


class UncertaintyError(ProblemError):
    """An interval that cannot be computed: a failed simulation at the fit, a budget too
    small, an unknown method."""


class OutOfEvaluations(UncertaintyError):
    """The interval's evaluation cap is spent."""


@dataclass
class Counter:
    """The objective, counted: model runs of batches in the unit box.

    ``max_evals`` caps the total (``None``: no cap); a batch that would exceed it raises
    :class:`OutOfEvaluations` before any run."""

    objective: Objective
    max_evals: int | None = None
    evaluations: int = 0
    #: data the residuals are taken against (default: the objective's measured data; a
    #: bootstrap replicate swaps in resampled data)
    data: np.ndarray | None = None

    @property
    def remaining(self) -> float:
        return np.inf if self.max_evals is None else self.max_evals - self.evaluations

    def outputs(self, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Stacked raw outputs (n, n_residuals) and fitness (n,) against ``data`` of unit-box
        points ``U`` (clipped into the box); a failed simulation is a NaN row and ``inf``."""
        U = np.clip(np.atleast_2d(np.asarray(U, dtype=float)), 0.0, 1.0)
        if U.shape[0] > self.remaining:
            raise OutOfEvaluations(f"{U.shape[0]} evaluation(s) asked with {self.remaining} "
                                   f"of {self.max_evals} left")
        space = self.objective.space
        outputs, ok = self.objective.outputs(space.check(space.from_unit(U)))
        self.evaluations += U.shape[0]
        Y = self.objective.stack(outputs)
        with np.errstate(over="ignore", invalid="ignore"):
            r = self.objective.factors * self.residual(Y)
            f = np.einsum("ij,ij->i", r, r)
        failed = ~ok | ~np.isfinite(f)
        Y[failed] = np.nan
        return Y, np.where(failed, np.inf, f)

    def residual(self, Y: np.ndarray) -> np.ndarray:
        """Raw residuals ``model - data`` of stacked outputs."""
        return Y - (self.objective.data if self.data is None else self.data)


def jacobian(counter: Counter, u: np.ndarray, free: np.ndarray | None = None,
             step: float = JAC_STEP) -> tuple[np.ndarray, np.ndarray]:
    """Outputs at ``u`` (n_residuals,) and their Jacobian (n_residuals, n_free) in the unit
    box, by central differences of ``step`` (one-sided, inwards, at a bound); the ``2 n + 1``
    points run as one batch.

    Raises
    ------
    UncertaintyError
        If a simulation fails at or next to ``u``.
    """
    u = np.asarray(u, dtype=float)
    cols = np.flatnonzero(np.ones(u.size, bool) if free is None else free)
    lo = np.maximum(u[cols] - step, 0.0)
    hi = np.minimum(u[cols] + step, 1.0)
    hi = np.where(hi - lo < step, np.minimum(lo + step, 1.0), hi)   # a bound: stay inside
    lo = np.where(hi - lo < step, hi - step, lo)
    U = np.tile(u, (2 * cols.size + 1, 1))
    for k, j in enumerate(cols):
        U[1 + 2 * k, j], U[2 + 2 * k, j] = lo[k], hi[k]
    Y, _ = counter.outputs(U)
    if not np.isfinite(Y).all():
        raise UncertaintyError("the monitor model fails at or next to the fitted vector: no "
                               "local covariance")
    J = (Y[2::2] - Y[1::2]).T / (hi - lo)
    return Y[0], J


def sandwich(objective: Objective, J: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray,
                                                                              np.ndarray]:
    """Covariance ``A^-1 B A^-1`` of the weighted least-squares estimate (unit box) and the
    information ``A = J' W J``, for per-signal noise ``sigma`` (4,).

    A singular ``A`` (a parameter the tests cannot see) gives infinite variance along its null
    directions rather than an error: the pseudo-inverse on the range, ``inf`` on the rest."""
    w = objective.factors ** 2
    s2 = sigma[objective.signal_index] ** 2
    A = J.T @ (w[:, None] * J)
    B = J.T @ ((w * w * s2)[:, None] * J)
    scale = np.sqrt(np.maximum(np.diag(A), 1e-300))
    An = A / np.outer(scale, scale)        # equilibrated: the faults' scales differ
    vals, vecs = np.linalg.eigh(An)
    keep = vals > 1e-12 * max(vals.max(), 1e-300)
    inv = (vecs[:, keep] / vals[keep]) @ vecs[:, keep].T / np.outer(scale, scale)
    cov = inv @ B @ inv
    if not keep.all():   # unidentifiable directions: unbounded variance
        null = vecs[:, ~keep] / scale[:, None]
        touched = np.abs(null).max(axis=1) > 1e-8 * np.abs(null).max()
        cov[touched, :] = cov[:, touched] = np.inf
    return cov, A


def refit(counter: Counter, u0: np.ndarray, free: np.ndarray | None = None,
          max_evals: int | None = None, step: float = JAC_STEP, ftol: float = 1e-10,
          xtol: float = 1e-8) -> tuple[np.ndarray, float]:
    """Local weighted least-squares refit from ``u0`` over the ``free`` coordinates (the
    others stay fixed): scipy's trust-region reflective method in the unit box with batched
    central-difference Jacobians.  Returns the best unit-box point seen and its fitness.

    Stops at convergence, at ``max_evals`` evaluations of this refit, or when the counter's
    cap is reached (then the best point so far is returned)."""
    from scipy.optimize import least_squares

    from ..threads import blas_single_thread

    u0 = np.clip(np.asarray(u0, dtype=float), 0.0, 1.0)
    free = np.ones(u0.size, bool) if free is None else np.asarray(free, bool)
    factors = counter.objective.factors
    limit = counter.evaluations + (np.inf if max_evals is None else max_evals)
    best = [u0.copy(), np.inf]
    cache: dict[bytes, np.ndarray] = {}

    def full(z: np.ndarray) -> np.ndarray:
        u = u0.copy()
        u[free] = z
        return u

    def fun(z: np.ndarray) -> np.ndarray:
        key = z.tobytes()
        if key not in cache:
            if counter.evaluations + 1 > limit:
                raise OutOfEvaluations("refit budget spent")
            Y, f = counter.outputs(full(z)[None, :])
            if not np.isfinite(f[0]):
                return np.full(factors.size, 1e6)   # a failed run: far worse than any fit
            r = factors * counter.residual(Y[0])
            cache.clear()
            cache[key] = r
            if f[0] < best[1]:
                best[0], best[1] = full(z), float(f[0])
        return cache[key]

    def jac(z: np.ndarray) -> np.ndarray:
        if counter.evaluations + 2 * z.size + 1 > limit:   # jacobian runs 2 n + 1 points
            raise OutOfEvaluations("refit budget spent")
        _, J = jacobian(counter, full(z), free, step)
        return factors[:, None] * J

    try:
        with blas_single_thread():   # an SVD per step between kernel calls (threads.py)
            least_squares(fun, u0[free], jac=jac, bounds=(0.0, 1.0), method="trf",
                          x_scale="jac", ftol=ftol, xtol=xtol, gtol=1e-12)
    except (OutOfEvaluations, UncertaintyError):
        pass
    if not np.isfinite(best[1]):
        raise UncertaintyError("the refit found no point the monitor model can simulate")
    return best[0], best[1]
