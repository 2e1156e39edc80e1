"""Acquisition faults of one channel: the kinds, the fitted fault, how faults act on the
model's outputs, and each kind's fit on one channel (or on the channels of a group whose
parameter is shared); the names of whole-chain groups.

The suspects' front (names parsed, whole-chain groups dispatched to :mod:`.chain`, the
screen, the verdict's phrases) is :mod:`.acquisition`, which this module's users below it
(:mod:`.chain`, :mod:`.tails`) do not import, so the three make no circle.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.ndimage import median_filter
from scipy.optimize import minimize_scalar

from ..traces import OUTPUT_DT, SIGNALS
from .features import NOISE_STD

#: Noise sd a sample must stand off the median of its 5-sample neighbourhood to be a spike.
SPIKE_SD = 8.0
#: Largest share of a channel's samples the outlier model may drop (more is not "sparse").
MAX_SPIKE_SHARE = 0.02
#: Shifts tried, in samples (both signs: a channel may be time-stamped early too).
MAX_SHIFT = 8
#: Frequency range of the hum search (Hz): mains of 50/60 Hz harmonics up to 400 Hz, below
#: the 500 Hz Nyquist frequency of the 1 kHz record.
HUM_BAND = (40.0, 495.0)
HUM_STEP = 0.25        # Hz, the periodogram grid (a 1 s test resolves ~1 Hz)
CHI2_95 = 3.841        # chi-square quantile, 1 dof
#: Fewest samples a frozen span holds (shorter flat stretches are a pause, not a fault).
STUCK_MIN = 30
#: Noise sd the model's channel must move over a frozen span: a record that is flat where
#: the model is flat too (a settled step) says nothing about the sensor.
STUCK_MOVE = 20.0
#: Noise sd of the chi-square excess a flat span may hold (its spread about its level).
STUCK_FLAT = 5.0


@dataclass(frozen=True)
class AcquisitionKind:
    """One kind of acquisition fault: its parameter, bounds and thresholds.

    ``lower``, ``upper``, ``trivial`` and ``detect`` are in ``scale`` units: seconds or
    samples, or the channel's noise sd (per second for the drift) when ``per_sd``."""

    name: str
    param: str
    unit: str
    lower: float
    upper: float
    trivial: float      # |value| below this is negligible
    # |value| from which it is detected and screened first at the true physics in every
    # draw (benchmarks/acquisition_thresholds.py), at least twice ``trivial``; outliers:
    # the spikes a count needs for an interval excluding zero (their height:
    # :data:`~.sized.OUTLIER_DETECT_SD`)
    detect: float
    signature: str
    per_sd: bool = False
    additive: bool = False   # adds to the record (else a filter of it, or weights)

    def scaled(self, channel: str) -> tuple[float, float, float, float]:
        """``lower, upper, trivial, detect`` on ``channel``, in its unit."""
        s = float(NOISE_STD[SIGNALS.index(channel)]) if self.per_sd else 1.0
        return self.lower * s, self.upper * s, self.trivial * s, self.detect * s


KINDS: dict[str, AcquisitionKind] = {k.name: k for k in (
    AcquisitionKind("lowpass", "tau", "s", 0.0, 20e-3, 3e-4, 6e-4,
                    "one channel's edges smeared over several samples, lagging its peers"),
    AcquisitionKind("time_shift", "samples", "samples (1 ms)", -MAX_SHIFT, MAX_SHIFT, 0.5, 1,
                    "one channel's residual is the derivative of the signal times a lag; "
                    "the others fit"),
    AcquisitionKind("drift", "rate", "unit/s", -200.0, 200.0, 1.0, 2.0,
                    "one channel's residual grows linearly from each test's start",
                    per_sd=True, additive=True),
    AcquisitionKind("mains_hum", "amplitude", "unit", 0.0, 50.0, 0.5, 2.0,
                    "a pure tone in one channel's residual, its phase set by each test",
                    per_sd=True, additive=True),
    AcquisitionKind("outliers", "spikes", "samples", 0.0, math.inf, 0.5, 4.0,
                    "isolated spikes of tens of noise sd on one channel"),
    AcquisitionKind("stuck", "share", "share of samples", 0.0, 1.0, 0.01, 0.03,
                    "one channel flat (dead, or frozen at one value) while the model, "
                    "and the other channels, move"),
    AcquisitionKind("heavy_tailed", "share", "share of samples", 0.0, 1.0, 0.002, 0.01,
                    "spikes at any share on several channels: the noise's tails, not "
                    "the physics"),
)}
#: Order in which fitted faults act on the model's outputs: filters, then what adds, then
#: weights (outliers), then what replaces the values (a stuck channel's level).
ORDER = ("time_shift", "lowpass", "drift", "mains_hum", "outliers", "stuck", "heavy_tailed")
#: The kinds that filter the channel (act before the additive ones).
FILTERS = ("time_shift", "lowpass")


@dataclass(frozen=True)
class Acquisition:
    """A fitted acquisition fault on one channel.

    ``value`` is the parameter in the channel's unit (:data:`KINDS`); ``detail`` holds what
    else it needs: the hum's ``freq`` (Hz) and per-test ``coef`` (sine, cosine), the
    outliers' per-test ``spikes`` (sample indices)."""

    kind: str
    channel: str
    value: float
    detail: dict[str, Any] = field(default_factory=dict, compare=False)

    @property
    def name(self) -> str:
        return f"{self.kind}({self.channel})"

    @property
    def column(self) -> int:
        return SIGNALS.index(self.channel)

    @property
    def channels(self) -> tuple[str, ...]:
        """The channels it acts on (one, or a whole-chain group's)."""
        return SIGNALS if self.channel == "all" else tuple(self.channel.split(","))

    def parts(self) -> tuple[Acquisition, ...]:
        """The one-channel faults it amounts to (itself, or a group's members)."""
        return tuple(self.detail.get("parts", (self,)))



# --- whole-chain groups: their names ----------------------------------------------------------

#: The kinds a whole-chain group may have: whether its parameter is shared by the channels.
GROUPED: dict[str, bool] = {"lowpass": True, "time_shift": True, "drift": False,
                            "mains_hum": False, "heavy_tailed": True}


def group_label(channels: Sequence[str]) -> str:
    """``all``, or the channels in :data:`SIGNALS` order joined by commas."""
    chosen = [c for c in SIGNALS if c in channels]
    return "all" if len(chosen) == len(SIGNALS) else ",".join(chosen)


def is_group(label: str) -> bool:
    """Whether ``label`` names a whole-chain group (``all`` or 2-3 channels, in order)."""
    parts = label.split(",")
    return label == "all" or (1 < len(parts) < len(SIGNALS) and set(parts) <= set(SIGNALS)
                              and group_label(parts) == label)


# --- the model's outputs through the faults -------------------------------------------------

def _lowpass(y: np.ndarray, tau: float) -> np.ndarray:
    """First-order low-pass along the last axis, at rest at the first sample (the
    :func:`~ema_bench.diagnosis.decoys.lowpass` recursion)."""
    if tau <= 0.0:
        return y
    a = 1.0 - math.exp(-OUTPUT_DT / tau)
    zi = (1.0 - a) * y[..., :1]
    # scipy.signal imported here, not with the module: it pulls in scipy.stats, half a
    # second of every CLI start-up (the parser imports the diagnosis)
    from scipy.signal import lfilter

    return lfilter([a], [1.0, -(1.0 - a)], y, axis=-1, zi=zi)[0]


def _shift(y: np.ndarray, s: int) -> np.ndarray:
    """``y`` ``s`` samples late along the last axis (early if negative), the edge value
    repeated (the :func:`~ema_bench.diagnosis.decoys.time_shift` convention)."""
    n = y.shape[-1]
    idx = np.clip(np.arange(n) - int(s), 0, n - 1)
    return y[..., idx]


def _times(n: int) -> np.ndarray:
    return (np.arange(n) + 0.5) * OUTPUT_DT


def _tone(freq: float, n: int) -> np.ndarray:
    """(2, n): sine and cosine of ``freq`` at the window centres, window-averaged."""
    w = 2 * math.pi * freq * _times(n)
    return np.sinc(freq * OUTPUT_DT) * np.vstack([np.sin(w), np.cos(w)])


def _added(f: Acquisition, test: str, n: int) -> np.ndarray:
    """What an additive fault adds to its channel in ``test`` (n,)."""
    if f.kind == "drift":
        return f.value * _times(n)
    coef = f.detail["coef"].get(test)
    return np.zeros(n) if coef is None else np.asarray(coef) @ _tone(f.detail["freq"], n)


def carry(outputs: Mapping[str, np.ndarray], faults: Sequence[Acquisition]
          ) -> dict[str, np.ndarray]:
    """The record the model predicts: ``outputs`` (test -> (n_samples, 4) or (k, n_samples,
    4)) with each fault applied to its channel, in :data:`ORDER` (outliers change weights
    only, :func:`weights`)."""
    faults = [p for f in faults for p in f.parts() if p.kind not in ("outliers", "heavy_tailed")]
    if not faults:
        return dict(outputs)
    out = {}
    for test, y in outputs.items():
        y = np.array(y, dtype=float, copy=True)
        for f in sorted(faults, key=lambda f: ORDER.index(f.kind)):
            col = y[..., f.column]
            if f.kind == "time_shift":
                col = _shift(col, int(f.value))
            elif f.kind == "lowpass":
                col = _lowpass(col, f.value)
            elif KINDS[f.kind].additive:
                col = col + _added(f, test, col.shape[-1])
            elif f.kind == "stuck" and test in f.detail["onset"]:
                col = np.array(col, copy=True)
                col[..., f.detail["onset"][test]:] = f.detail["level"][test]
            y[..., f.column] = col
        out[test] = y
    return out


def weights(faults: Sequence[Acquisition], shapes: Mapping[str, tuple[int, ...]]
            ) -> dict[str, np.ndarray]:
    """Per test, (n_samples, 4) sample weights: 0 at the outlier model's spikes and over a
    stuck channel's frozen span, 1 else; 0 where heavy-tailed noise rejects a sample."""
    out = {t: np.ones(s) for t, s in shapes.items()}
    for f in (p for g in faults for p in g.parts()):
        if f.kind == "heavy_tailed":
            for t, keep in f.detail["keep"].items():
                if t in out:
                    out[t] = out[t] * keep
        elif f.kind == "outliers":
            for t, idx in f.detail["spikes"].items():
                if t in out:
                    out[t][np.asarray(idx, dtype=int), f.column] = 0.0
        elif f.kind == "stuck":
            for t, k in f.detail["onset"].items():
                if t in out:
                    out[t][int(k):, f.column] = 0.0
    return out


# --- fitting one fault at a model's residuals -----------------------------------------------

@dataclass
class _Channel:
    """One channel of the data and of the model's prediction without the fault, whitened,
    with its sample weights; ``pre`` is that prediction before the additive faults (where a
    filter acts)."""

    data: dict[str, np.ndarray]
    pred: dict[str, np.ndarray]
    pre: dict[str, np.ndarray]
    w: dict[str, np.ndarray]
    train: tuple[str, ...]

    def sse(self, pred: Mapping[str, np.ndarray], tests: Sequence[str] | None = None) -> float:
        return float(sum(np.sum(self.w[t] * (self.data[t] - pred[t]) ** 2)
                         for t in (tests or self.train)))

    def n(self) -> float:
        return float(sum(np.sum(self.w[t] > 0) for t in self.train))


def _channel(raw: Mapping[str, np.ndarray], measured: Mapping[str, np.ndarray],
             others: Sequence[Acquisition], w: Mapping[str, np.ndarray],
             col: int | list[int], train: tuple[str, ...]) -> _Channel:
    """One channel (``col``: arrays (n,)) or several (a list: (k, n), whitened each, for a
    whole-chain parameter shared between them)."""
    sd = NOISE_STD[col]
    filters = [f for f in others if f.kind in FILTERS]
    pre = carry(raw, filters)
    pred = carry(raw, others)
    ow = weights(others, {t: v.shape for t, v in raw.items()})
    return _Channel({t: (measured[t][:, col] / sd).T for t in raw},
                    {t: (pred[t][:, col] / sd).T for t in raw},
                    {t: (pre[t][:, col] / sd).T for t in raw},
                    {t: (w[t][:, col] * ow[t][:, col]).T for t in raw}, train)


def _with_filter(ch: _Channel, fn: Callable[[np.ndarray], np.ndarray]) -> dict[str, np.ndarray]:
    """The prediction with a filter applied where filters act (before the additive faults)."""
    return {t: ch.pred[t] - ch.pre[t] + fn(ch.pre[t]) for t in ch.pred}


def _fit_lowpass(ch: _Channel) -> tuple[float, dict, float, list[float]]:
    def sse(tau: float) -> float:
        return ch.sse(_with_filter(ch, lambda y: _lowpass(y, tau)))

    lo, hi = KINDS["lowpass"].lower, KINDS["lowpass"].upper
    grid = np.r_[0.0, np.geomspace(2e-4, hi, 24)]
    vals = np.array([sse(t) for t in grid])
    i = int(np.argmin(vals))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    tau = float(grid[i])
    if b > a:
        r = minimize_scalar(sse, bounds=(a, b), method="bounded", options={"xatol": 1e-6})
        if r.fun < vals[i]:
            tau = float(r.x)
    best = sse(tau)
    s2 = max(best / max(ch.n(), 1.0), 1.0)
    fine = np.unique(np.r_[np.linspace(lo, min(hi, 3 * tau + 1e-3), 61),
                           np.linspace(0.8 * tau, min(1.2 * tau, hi), 81), tau])
    ok = fine[np.array([sse(t) for t in fine]) <= best + CHI2_95 * s2]
    return tau, {}, vals[0] - best, [float(ok.min()), float(ok.max())]


def _fit_time_shift(ch: _Channel) -> tuple[float, dict, float, list[float]]:
    shifts = np.arange(-MAX_SHIFT, MAX_SHIFT + 1)
    vals = np.array([ch.sse(_with_filter(ch, lambda y, s=s: _shift(y, s))) for s in shifts])
    i = int(np.argmin(vals))
    s2 = max(vals[i] / max(ch.n(), 1.0), 1.0)
    ok = shifts[vals <= vals[i] + CHI2_95 * s2]
    return float(shifts[i]), {}, float(vals[MAX_SHIFT] - vals[i]), [float(ok.min()),
                                                                    float(ok.max())]


def _linear(ch: _Channel, basis: dict[str, np.ndarray], tests: Sequence[str]
            ) -> tuple[float, float]:
    """Least-squares scale of ``basis`` (whitened) and its standard error."""
    num = sum(float(np.sum(ch.w[t] * basis[t] * (ch.data[t] - ch.pred[t]))) for t in tests)
    den = sum(float(np.sum(ch.w[t] * basis[t] ** 2)) for t in tests)
    if den <= 0.0:
        return 0.0, math.inf
    c = num / den
    best = ch.sse({t: ch.pred[t] + c * basis[t] for t in ch.pred})
    s2 = max(best / max(ch.n() - 1.0, 1.0), 1.0)
    return c, math.sqrt(s2 / den)


def _fit_drift(ch: _Channel) -> tuple[float, dict, float, list[float]]:
    basis = {t: _times(v.size) for t, v in ch.pred.items()}
    rate, se = _linear(ch, basis, ch.train)
    drop = ch.sse(ch.pred) - ch.sse({t: ch.pred[t] + rate * basis[t] for t in ch.pred})
    return rate, {}, drop, [rate - 1.96 * se, rate + 1.96 * se]


def _hum_coef(ch: _Channel, freq: float, test: str) -> np.ndarray:
    """Least-squares (sine, cosine) coefficients of a tone in one test's residual."""
    tone = _tone(freq, ch.pred[test].size)
    w = ch.w[test]
    a = (tone * w) @ tone.T
    b = (tone * w) @ (ch.data[test] - ch.pred[test])
    return np.linalg.lstsq(a, b, rcond=None)[0]


def _fit_mains_hum(ch: _Channel) -> tuple[float, dict, float, list[float]]:
    freqs = np.arange(HUM_BAND[0], HUM_BAND[1] + HUM_STEP / 2, HUM_STEP)
    # periodogram of the weighted residual (summed over the training tests): the drop of
    # the sum of squares a tone of each frequency gives, nearly orthogonal sine and cosine
    power = np.zeros(freqs.size)
    for t in ch.train:
        r = ch.w[t] * (ch.data[t] - ch.pred[t])
        w = 2 * math.pi * np.outer(freqs, _times(r.size))
        power += (np.sin(w) @ r) ** 2 + (np.cos(w) @ r) ** 2
    f0 = float(freqs[int(np.argmax(power))])
    fine = np.linspace(f0 - HUM_STEP, f0 + HUM_STEP, 21)

    def sse_at(f: float) -> float:
        return ch.sse({t: ch.pred[t] + _hum_coef(ch, f, t) @ _tone(f, ch.pred[t].size)
                       for t in ch.train})

    freq = float(fine[int(np.argmin([sse_at(f) for f in fine]))])
    coef = {t: _hum_coef(ch, freq, t) for t in ch.pred}
    basis = {t: coef[t] @ _tone(freq, ch.pred[t].size) for t in ch.pred}
    scale, se = _linear(ch, basis, ch.train)
    amp = float(np.mean([np.hypot(*coef[t]) for t in ch.train]))
    drop = ch.sse(ch.pred) - ch.sse({t: ch.pred[t] + basis[t] for t in ch.pred})
    detail = {"freq": freq, "coef": {t: [float(v) for v in c] for t, c in coef.items()}}
    return amp, detail, drop, [amp * (scale - 1.96 * se), amp * (scale + 1.96 * se)]


def _fit_outliers(ch: _Channel) -> tuple[float, dict, float, list[float]]:
    spikes, drop = {}, 0.0
    for t in ch.pred:
        r = np.where(ch.w[t] > 0, ch.data[t] - ch.pred[t], 0.0)
        dev = r - median_filter(r, size=5, mode="nearest")
        hit = np.abs(dev) > SPIKE_SD
        # isolated: a neighbour that is a spike too makes a burst, which is signal
        hit &= ~(np.r_[False, hit[:-1]] | np.r_[hit[1:], False])
        if hit.sum() > MAX_SPIKE_SHARE * r.size:
            hit[:] = False
        spikes[t] = [int(i) for i in np.flatnonzero(hit)]
        if t in ch.train:
            drop += float(np.sum(r[hit] ** 2))
    n = float(sum(len(spikes[t]) for t in ch.train))
    return n, {"spikes": spikes}, drop, [max(n - 1.96 * math.sqrt(n), 0.0),
                                         n + 1.96 * math.sqrt(n)]


def _stuck_onsets(ch: _Channel, t: str) -> tuple[np.ndarray, np.ndarray]:
    """Of one test: each onset ``k`` that may start a frozen span (the record flat from
    ``k`` on, the model moving there) and the whitened sum of squares of the model with the
    span frozen from ``k`` (the span's spread about its level counted, so the onset cannot
    move into live samples for free); the last entry is ``n``, no span."""
    d, p, w = ch.data[t], ch.pred[t], ch.w[t]
    n = d.size
    live = np.r_[0.0, np.cumsum(w * (d - p) ** 2)]            # sum of squares before k
    m = np.arange(n, 0, -1, dtype=float)                      # samples from k on
    s1, s2 = np.cumsum(d[::-1])[::-1], np.cumsum((d * d)[::-1])[::-1]
    spread = np.maximum(s2 - s1 * s1 / m, 0.0)                # about the span's mean
    # the model's peak-to-peak over each span (from k to the end)
    ptp = np.maximum.accumulate(p[::-1])[::-1] - np.minimum.accumulate(p[::-1])[::-1]
    ok = (m >= STUCK_MIN) & (spread <= m + STUCK_FLAT * np.sqrt(2 * m)) & (ptp > STUCK_MOVE)
    k = np.r_[np.flatnonzero(ok), n]
    return k, live[k] + np.r_[spread, 0.0][k]


def _fit_stuck(ch: _Channel) -> tuple[float, dict, float, list[float]]:
    onset, level, drop, lo, hi = {}, {}, 0.0, 0.0, 0.0
    n_train = sum(ch.data[t].size for t in ch.train)
    for t in ch.pred:
        k, sse = _stuck_onsets(ch, t)
        i = int(np.argmin(sse))
        n = ch.data[t].size
        if k[i] < n:
            onset[t], level[t] = int(k[i]), float(np.mean(ch.data[t][k[i]:]))
        if t in ch.train:
            drop += float(sse[-1] - sse[i])
            s2 = max(sse[i] / max(float(np.sum(ch.w[t] > 0)), 1.0), 1.0)
            near = k[sse <= sse[i] + CHI2_95 * s2]
            lo, hi = lo + n - near.max(), hi + n - near.min()
    share = sum(ch.data[t].size - onset[t] for t in ch.train if t in onset) / n_train
    return share, {"onset": onset, "level": level}, drop, [lo / n_train, hi / n_train]


_FITS: dict[str, Callable[[_Channel], tuple[float, dict, float, list[float]]]] = {
    "lowpass": _fit_lowpass, "time_shift": _fit_time_shift, "drift": _fit_drift,
    "mains_hum": _fit_mains_hum, "outliers": _fit_outliers, "stuck": _fit_stuck,
}


@dataclass(frozen=True)
class Estimate:
    """A fault fitted at a model's residuals: the fault, its screening score (drop of the
    channel's whitened training sum of squares) and its 95 % interval (channel unit)."""

    fault: Acquisition
    score: float
    interval: list[float]


def estimate_channel(kind: str, channel: str, raw: Mapping[str, np.ndarray],
                     measured: Mapping[str, np.ndarray], w: Mapping[str, np.ndarray],
                     train: tuple[str, ...], others: Sequence[Acquisition] = ()) -> Estimate:
    """Fit fault ``kind`` on one ``channel`` at the monitor outputs ``raw`` (test ->
    (n_samples, 4)), the ``others`` faults held at their values (arguments as
    :func:`~.acquisition.estimate`, which parses a name and passes whole-chain groups to
    :mod:`.chain`)."""
    ch = _channel(raw, measured, others, w,
                  SIGNALS.index(channel), train)
    value, detail, drop, iv = _FITS[kind](ch)
    lo, hi, _, _ = KINDS[kind].scaled(channel)
    noise = float(NOISE_STD[SIGNALS.index(channel)])
    sd = noise if KINDS[kind].per_sd else 1.0
    value = float(np.clip(value * sd, lo, hi))
    if kind == "mains_hum":
        detail = {**detail, "coef": {t: [v * sd for v in c] for t, c in detail["coef"].items()}}
    if kind == "stuck":         # the levels were fitted on the whitened record
        detail = {**detail, "level": {t: v * noise for t, v in detail["level"].items()}}
    return Estimate(Acquisition(kind, channel, value, detail), max(float(drop), 0.0),
                    [float(v) * sd for v in iv])


