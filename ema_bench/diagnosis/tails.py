"""Heavy-tailed noise on several channels: a suspect chosen by a test, and its robust loss.

Impulsive interference (a contactor, a bad ground) reaching the whole recording chain puts a
few per cent of every channel's samples tens of noise sd off, at any share and not only
isolated, which the one-channel ``outliers`` suspect (isolated, at most 2 %) does not fit;
a squared loss lets such samples pull the physics.

**The test** (the data choose the loss, not the user).  Per channel, on the training tests,
the residual (record minus model, in noise sd) less its 5-sample running median (which
follows the model's misfit, edges included, but not an isolated spike); a **tail sample**
stands more than :data:`~.acquisition.SPIKE_SD` (8) sd off.  Gaussian sensor noise puts
about 1e-15 of its samples there.  The noise is heavy-tailed when at least
:data:`TAIL_SHARE` of the training samples of each of at least :data:`TAIL_CHANNELS`
channels are tail samples; the suspect is ``heavy_tailed(those channels)``
(``heavy_tailed(all)`` on every channel).  Measured at the true faults (the monitor without
the effect standing for the base fit; ``benchmarks/heavy_tail_false_alarm.py``, 90 records
of 10 instances, each drawable effect at 4x its threshold): no record chooses it; the
positions never hold a tail sample, but a missing effect leaves up to 11 % of ``i_eq``'s
samples (cogging's ripple, a delay's current edges: misfit a running median does not
follow) and up to 0.77 % of ``omega_m``'s (a sensor offset), hence three channels.

**The loss.**  When chosen, the tail samples weigh zero in every fit, every assessment and
every screen (:func:`~.acquisition.weights`; recomputed, with the suspect, at each model):
a *skipped* (truncated quadratic) loss, the limit of a Student-t loss at small degrees of
freedom.  It gives a 30 sd spike no influence (Huber's would still pull with the cut's
k sd), and keeps the bootstrap envelopes, made of Gaussian noise, valid for the samples
kept.  Its value is the share of the group's training samples rejected, with a Poisson
interval ``(n +- 1.96 sqrt(n)) / N``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from scipy.ndimage import median_filter

from ..traces import SIGNALS
from .channel_faults import SPIKE_SD, Acquisition, Estimate, _channel, group_label

#: Share of a channel's training samples that must be tail samples.
TAIL_SHARE = 0.01
#: Channels that must hold that share (a strong effect's misfit reaches it on ``i_eq`` and
#: nearly on ``omega_m``, never on the positions).
TAIL_CHANNELS = 3


def _tail(raw: Mapping[str, np.ndarray], measured: Mapping[str, np.ndarray],
          w: Mapping[str, np.ndarray], train: tuple[str, ...],
          others: Sequence[Acquisition]) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Per test (every one), (n_samples, 4): the tail samples (booleans) and the whitened
    residual (0 where weighted 0)."""
    ch = _channel(raw, measured, others, w, list(range(len(SIGNALS))), train)
    hits, res = {}, {}
    for t in ch.pred:
        r = np.where(ch.w[t] > 0, ch.data[t] - ch.pred[t], 0.0)
        dev = r - median_filter(r, size=(1, 5), mode="nearest")
        hits[t] = ((np.abs(dev) > SPIKE_SD) & (ch.w[t] > 0)).T
        res[t] = r.T
    return hits, res


def tail_shares(raw: Mapping[str, np.ndarray], measured: Mapping[str, np.ndarray],
                w: Mapping[str, np.ndarray], train: tuple[str, ...],
                others: Sequence[Acquisition] = ()) -> dict[str, float]:
    """Per channel, the share of its (weighted) training samples that are tail samples."""
    hits, _ = _tail(raw, measured, w, train, others)
    n = sum(np.sum(w[t] > 0, axis=0) for t in train)
    k = sum(np.sum(hits[t], axis=0) for t in train)
    return {c: float(k[i] / max(n[i], 1)) for i, c in enumerate(SIGNALS)}


def estimate_tails(channels: Sequence[str], raw: Mapping[str, np.ndarray],
                   measured: Mapping[str, np.ndarray], w: Mapping[str, np.ndarray],
                   train: tuple[str, ...], others: Sequence[Acquisition] = ()) -> Estimate:
    """The suspect ``heavy_tailed(channels)`` at ``raw``: its tail samples on those channels
    in every test (their weights 0), the share of the training samples rejected, the
    sum of squares they held (its score) and the Poisson interval of the share."""
    hits, res = _tail(raw, measured, w, train, others)
    cols = [SIGNALS.index(c) for c in channels]
    keep = {}
    for t, h in hits.items():
        k = np.ones(h.shape)
        k[:, cols] = np.where(h[:, cols], 0.0, 1.0)
        keep[t] = k
    n = float(sum(np.sum(hits[t][:, cols]) for t in train))
    total = float(sum(np.sum(w[t][:, cols] > 0) for t in train))
    score = sum(float(np.sum(res[t][:, cols][hits[t][:, cols]] ** 2)) for t in train)
    half = 1.96 * math.sqrt(n)
    f = Acquisition("heavy_tailed", group_label(channels), n / max(total, 1.0),
                    {"keep": keep})
    return Estimate(f, float(score), [max(n - half, 0.0) / max(total, 1.0),
                                      (n + half) / max(total, 1.0)])


def detect(raw: Mapping[str, np.ndarray], measured: Mapping[str, np.ndarray],
           w: Mapping[str, np.ndarray], train: tuple[str, ...]) -> Estimate | None:
    """The heavy-tailed noise suspect when the test chooses it (``None``: Gaussian tails)."""
    shares = tail_shares(raw, measured, w, train)
    heavy = [c for c in SIGNALS if shares[c] >= TAIL_SHARE]
    if len(heavy) < TAIL_CHANNELS:
        return None
    return estimate_tails(heavy, raw, measured, w, train)
