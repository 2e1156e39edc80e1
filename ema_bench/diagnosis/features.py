"""Named statistics of the residuals (measured minus model), in units of sensor noise.

Per test and signal: bias, RMS, dependence on speed (slope, sign, fast vs slow RMS), on
surface position and on current, lag-1 autocorrelation (whiteness), the lag and height of the
cross-correlation with the command, and the order spectrum against rotor angle (orders 1, 2
and 12: eccentricity, its harmonic, cogging of the 12-slot motor).
"""

from __future__ import annotations

import numpy as np

from ..physics.sensors import SENSORS
from ..traces import SIGNALS

ORDERS = (1, 2, 12)
MAX_LAG = 25  # samples (ms) searched for the command cross-correlation
# samples a statistic of a subset (moving one way, fast, slow) needs: the step test's
# overshoot gives one or two samples of reverse speed, whose mean is one noise draw with no
# bootstrap envelope to match (a false alarm on data from the monitor itself)
MIN_SUPPORT = 10
# per-signal noise std of a recorded sample: white noise plus quantisation
NOISE_STD = np.array([np.hypot(s.noise_std, s.lsb / np.sqrt(12.0)) for s in SENSORS])


def one_sided(name: str) -> bool:
    """Magnitude statistics: only an excess over the envelope is anomalous."""
    return name.endswith(("rms", "order1", "order2", "order12"))


def whiten(residual: np.ndarray) -> np.ndarray:
    """Residual (n, 4) in units of each signal's sensor noise."""
    return residual / NOISE_STD


def _proj(r: np.ndarray, u: np.ndarray) -> float:
    """Projection of ``r`` on a regressor scaled to unit peak (mean of r * u)."""
    peak = np.abs(u).max()
    return float(np.mean(r * u) / peak) if peak > 0 else 0.0


def features_of_test(r: np.ndarray, y: np.ndarray, cmd: np.ndarray, prefix: str
                  ) -> dict[str, float]:
    """Features of one test.

    Parameters
    ----------
    r : (n, 4) whitened residuals.
    y : (n, 4) measured outputs (regressors: position, motor angle, speed, current).
    cmd : (n,) command at the output samples, rad.
    """
    out: dict[str, float] = {}
    w = y[:, 2]
    moving = np.abs(w) > 5.0
    fast = np.abs(w) > np.median(np.abs(w))
    phase = np.exp(-1j * np.outer(ORDERS, y[:, 1]))  # rotor-angle orders
    dc = cmd - cmd.mean()
    for k, sig in enumerate(SIGNALS):
        rk = r[:, k]
        p = f"{prefix}.{sig}."
        out[p + "bias"] = float(rk.mean())
        out[p + "rms"] = float(np.sqrt(np.mean(rk**2)))
        out[p + "speed_slope"] = _proj(rk, w)
        pos, neg = rk[w > 5.0], rk[w < -5.0]
        out[p + "speed_sign"] = float(pos.mean() - neg.mean()) \
            if min(pos.size, neg.size) >= MIN_SUPPORT else 0.0
        slow = rk[~fast]
        out[p + "fast_minus_slow_rms"] = float(np.sqrt(np.mean(rk[fast] ** 2)) -
                                               np.sqrt(np.mean(slow**2))) \
            if min(slow.size, int(fast.sum())) >= MIN_SUPPORT else 0.0
        out[p + "position"] = _proj(rk, y[:, 0] - y[:, 0].mean())
        out[p + "current"] = _proj(rk, y[:, 3] - y[:, 3].mean())
        rc = rk - rk.mean()
        den = float(rc @ rc)
        out[p + "acf1"] = float(rc[1:] @ rc[:-1] / den) if den > 0 else 0.0
        xc = np.array([np.mean(rc[max(0, L):rc.size + min(0, L)] *
                               dc[max(0, -L):dc.size - max(0, L)]) for L in
                       range(-MAX_LAG, MAX_LAG + 1)])
        # energy-weighted lag: continuous, unlike the argmax of a flat peak
        e2 = xc**2
        lags = np.arange(-MAX_LAG, MAX_LAG + 1)
        out[p + "xcorr_lag"] = float(lags @ e2 / e2.sum()) if e2.sum() > 0 else 0.0
        if moving.sum() >= MIN_SUPPORT:
            amp = np.abs(phase[:, moving] @ rk[moving]) / moving.sum()
        else:
            amp = np.zeros(len(ORDERS))
        for order, a in zip(ORDERS, amp):
            out[p + f"order{order}"] = float(a)
    return out


def residual_features(residuals: dict[str, np.ndarray], measured: dict[str, np.ndarray],
                      commands: dict[str, np.ndarray]) -> dict[str, float]:
    """All features of all tests: ``residuals[test]`` (n, 4) raw (measured - model)."""
    out: dict[str, float] = {}
    for test, res in residuals.items():
        out.update(features_of_test(whiten(res), measured[test], commands[test], test))
    return out
