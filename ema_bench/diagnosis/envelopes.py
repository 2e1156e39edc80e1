"""What the fitted model plus sensor noise explains: bootstrap envelopes.

The fitted parameters are put into the detailed (reference) model, simulated once without
noise, and sensor noise is drawn ``n`` times; each replicate's residual against the fitted
monitor gives one sample of every feature and of every test's fitness.  The envelopes thus
hold both the sensor noise and the known form gap between the monitor and the detailed model,
which textbook whiteness tests would take for missing physics.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..physics.sensors import measure
from ..seeding import SeedLike, children
from .features import NOISE_STD, one_sided, residual_features, whiten

SPREAD_FLOOR = 1e-3  # features are in noise units: below this a spread is numerical zero


@dataclass(frozen=True)
class Envelope:
    """Bootstrap distribution of named statistics."""

    names: tuple[str, ...]
    samples: np.ndarray  # (n_boot, n_features)

    @property
    def median(self) -> np.ndarray:
        return np.median(self.samples, axis=0)

    @property
    def spread(self) -> np.ndarray:
        """Robust standard deviation (MAD), floored by half the sample std."""
        mad = 1.4826 * np.median(np.abs(self.samples - self.median), axis=0)
        return np.maximum(np.maximum(mad, 0.5 * self.samples.std(axis=0)), SPREAD_FLOOR)

    def z(self, values: dict[str, float]) -> np.ndarray:
        v = np.array([values[n] for n in self.names])
        return (v - self.median) / self.spread

    def outside(self, values: dict[str, float], z_max: float) -> list[tuple[str, float, float]]:
        """``(name, value, z)`` of the statistics beyond ``z_max`` robust deviations and
        beyond the whole bootstrap range, largest first."""
        z = self.z(values)
        lo, hi = self.samples.min(axis=0), self.samples.max(axis=0)
        out = []
        for i, n in enumerate(self.names):
            dev = z[i] if one_sided(n) else abs(z[i])
            if dev > z_max and not lo[i] <= values[n] <= hi[i]:
                out.append((n, values[n], float(z[i])))
        return sorted(out, key=lambda t: -abs(t[2]))


def fitness_of(model: dict[str, np.ndarray], data: dict[str, np.ndarray],
               weights: dict[str, np.ndarray]) -> dict[str, float]:
    """Per-test fitness: weighted mean squared error summed over signals (``weights[t]``
    per signal (4,), or per sample (n_samples, 4))."""
    return {t: float(np.sum(np.mean((model[t] - data[t]) ** 2 * weights[t], axis=0)))
            for t in model}


def refit_projector(jac: np.ndarray, tests: tuple[str, ...], shapes: dict[str, tuple]
                    ) -> Callable[[dict[str, np.ndarray]], dict[str, np.ndarray]]:
    """Linearised refit: remove from residuals what a small change of the fitted parameters
    would absorb (projection off the columns of the whitened Jacobian ``jac``).

    Real residuals come from a fit; bootstrap residuals must be treated alike, or the part of
    the model-form gap the fit absorbed would look like an anomaly."""
    q, _ = np.linalg.qr(jac)

    def project(res: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        v = np.concatenate([whiten(res[t]).ravel() for t in tests])
        v = v - q @ (q.T @ v)
        out, i = {}, 0
        for t in tests:
            n = int(np.prod(shapes[t]))
            out[t] = v[i:i + n].reshape(shapes[t]) * NOISE_STD
            i += n
        return out
    return project


def bootstrap(clean: dict[str, np.ndarray], model: dict[str, np.ndarray],
              commands: dict[str, np.ndarray], weights: dict[str, np.ndarray],
              feature_tests: tuple[str, ...], n: int, seed: SeedLike,
              project: Callable[[dict[str, np.ndarray]], dict[str, np.ndarray]] | None = None,
              mask: dict[str, np.ndarray] | None = None,
              record: Callable[[dict[str, np.ndarray]], dict[str, np.ndarray]] | None = None,
              ) -> tuple[Envelope, dict[str, np.ndarray]]:
    """Envelopes of the residual features and per-test fitness samples.

    Parameters
    ----------
    clean : test -> (n_samples, 4) clean outputs of the fitted detailed model.
    model : test -> (n_samples, 4) fitted monitor outputs.
    feature_tests : tests whose residual features are screened (the training tests).
    n : replicates.
    project : applied to each replicate's training residuals (see :func:`refit_projector`).
    mask : per test, (n_samples, 4) multipliers of the residuals before their statistics
        (the measured data's, so replicates and data are treated alike).
    record : applied to each replicate's noisy outputs (test -> (n_samples, 4)): the
        acquisition chain the fitted model carries, so that a low-pass smooths the
        replicates' noise as it did the data's.
    """
    rows, fits = [], {t: [] for t in clean}
    names: tuple[str, ...] = ()
    for b, kid in enumerate(children(seed, n)):
        rngs = {t: np.random.default_rng(k) for t, k in zip(clean, children(kid, len(clean)))}
        data = {t: measure(clean[t], rngs[t]) for t in clean}
        if record is not None:
            data = record(data)
        res = {t: (data[t] - model[t]) * (1.0 if mask is None else mask[t])
               for t in feature_tests}
        feats = residual_features(project(res) if project else res,
                                  {t: data[t] for t in feature_tests},
                                  {t: commands[t] for t in feature_tests})
        if b == 0:
            names = tuple(feats)
        rows.append([feats[k] for k in names])
        for t, f in fitness_of(model, data, weights).items():
            fits[t].append(f)
    return Envelope(names, np.array(rows)), {t: np.array(v) for t, v in fits.items()}
