"""Acquisition-chain decoys: faults of the recording, not of the actuator, for the blind suite.

Each decoy is a small pure function applied to measured :class:`~ema_bench.traces.Traces`
(reference-model data with sensor noise and ADC) after the simulation: it changes one recorded
channel only, never the loop (the controller's own sensors are fine), so no library effect
describes it.  The missing-physics workflow should call such data unexplained (or name an
effect only as a partial stand-in), never name a library effect as the whole answer.

The values each function writes are quantised again by the channel's ADC
(:func:`~ema_bench.physics.sensors.quantise`, clipped to its span) so the result looks like
real ADC data.  :data:`ACQUISITION_DECOYS` maps a name to its function, :func:`draw` draws a
decoy's channel and magnitude (clearly above the sensor noise, yet plausible) and
:func:`apply` applies a drawn decoy.

Sample rate and mains hum: the traces are sampled at 1 kHz (``OUTPUT_DT`` = 1 ms), each
sample the mean over its 1 ms window.  A 400 Hz aircraft-mains tone lies below the 500 Hz
Nyquist frequency, so it is *not* aliased: it appears at 400 Hz (2.5 samples per period),
attenuated by the window average to ``sinc(0.4) = 0.757`` of its amplitude.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from ..params import DEFAULT_PARAMS
from ..physics.sensors import SENSORS, quantise
from ..traces import SIGNALS, Traces

#: Aircraft AC mains frequency (Hz; MIL-STD-704 400 Hz systems).
MAINS_HZ = 400.0
#: Largest |value| of each channel the drive allows (clipping levels are drawn below these):
#: the speed limit (rad/s) and the current limit T_max / (2 Ke) = 20 A.
NOMINAL_PEAK: dict[str, float] = {
    "omega_m": DEFAULT_PARAMS.w_max,
    "i_eq": DEFAULT_PARAMS.T_max / (2.0 * DEFAULT_PARAMS.Ke),
}


def _column(signal: str) -> int:
    if signal not in SIGNALS:
        raise ValueError(f"unknown signal {signal!r}; known: {', '.join(SIGNALS)}")
    return SIGNALS.index(signal)


def _map_channel(tr: Traces, signal: str, fn: Callable[[np.ndarray, np.ndarray], np.ndarray],
                 requantise: bool = True) -> Traces:
    """A copy of ``tr`` whose ``signal`` column is ``fn(values, times)`` in every test,
    quantised again by that channel's ADC when ``requantise``; the other columns, ``dt``
    and ``meta`` are kept."""
    k = _column(signal)
    data = {}
    for test in tr.tests:
        block = np.array(tr.data[test], copy=True)
        y = fn(block[:, k].copy(), tr.time(test))
        block[:, k] = quantise(y, SENSORS[k]) if requantise else y
        data[test] = block
    return Traces(data=data, dt=tr.dt, meta=dict(tr.meta))


def lowpass(tr: Traces, signal: str, tau: float) -> Traces:
    """A first-order low-pass of time constant ``tau`` (s) on one recorded channel.

    Stands for an anti-alias filter (or a sensor) too slow for the signal, e.g. the
    current channel's conditioning filter built with the wrong capacitor.  Discrete form
    ``z[k] = (1 - a) z[k-1] + a y[k]`` with ``a = 1 - exp(-dt / tau)``, started at rest at
    the first sample: a unit step reaches ``1 - exp(-n dt / tau)`` at its ``n``-th sample
    (the step's own sample counted first), the continuous filter's response at the end of
    each window.

    Parameters
    ----------
    tr : Traces
        Measured traces.
    signal : str
        The channel (one of :data:`~ema_bench.traces.SIGNALS`).
    tau : float
        Time constant in s (a few ms: 1 to 6 samples).
    """
    if not tau > 0.0:
        raise ValueError(f"tau must be positive, got {tau!r} s")
    a = 1.0 - math.exp(-tr.dt / tau)

    def filt(y: np.ndarray, _t: np.ndarray) -> np.ndarray:
        z = np.empty_like(y)
        prev = y[0]
        for i, v in enumerate(y):
            prev += a * (v - prev)
            z[i] = prev
        return z

    return _map_channel(tr, signal, filt)


def mains_hum(tr: Traces, signal: str, amplitude: float, freq: float = MAINS_HZ,
              phase: float = 0.0) -> Traces:
    """A mains sinusoid picked up by one channel's analog wiring, before the ADC.

    Stands for 400 Hz aircraft AC power coupling into the current sensor's lines (a ground
    loop, a broken shield).  Each sample gets the mean of ``amplitude sin(2 pi freq t +
    phase)`` over its window: ``amplitude * sinc(freq dt) * sin(2 pi freq t_k + phase)`` at
    the window centre ``t_k`` (0.757 amplitude at 400 Hz and 1 kHz; a frequency above the
    Nyquist frequency ``1 / (2 dt)`` would alias, and this formula makes it so).

    Parameters
    ----------
    tr : Traces
        Measured traces.
    signal : str
        The channel (``"i_eq"`` for the current).
    amplitude : float
        Analog amplitude of the hum, in the channel's unit (A for the current).
    freq : float
        Hum frequency in Hz (default :data:`MAINS_HZ`).
    phase : float
        Phase at t = 0 of each test, rad.
    """
    gain = amplitude * float(np.sinc(freq * tr.dt))

    def hum(y: np.ndarray, t: np.ndarray) -> np.ndarray:
        return y + gain * np.sin(2 * math.pi * freq * t + phase)

    return _map_channel(tr, signal, hum)


def clipping(tr: Traces, signal: str, level: float) -> Traces:
    """One channel saturates at ``+-level`` (its unit), below the signal's peak.

    Stands for a sensor or conditioning amplifier whose range is too small for the signal
    (a current sensor rated below the drive's current limit, a speed output saturating
    before the speed limit).  The clipped values sit on the ADC code nearest ``level``.

    Parameters
    ----------
    tr : Traces
        Measured traces.
    signal : str
        The channel.
    level : float
        Saturation level (> 0) in the channel's unit.
    """
    if not level > 0.0:
        raise ValueError(f"level must be positive, got {level!r}")
    return _map_channel(tr, signal, lambda y, _t: np.clip(y, -level, level))


def time_shift(tr: Traces, signal: str, samples: int) -> Traces:
    """One recorded channel delayed by ``samples`` samples (not in the loop).

    Stands for a recorder that time-stamps one channel late (a buffered serial sensor
    link, a misaligned acquisition card).  Sample ``k`` holds the value of sample
    ``k - samples``; the first ``samples`` samples repeat the first value (the record
    started at rest).  The values stay ADC codes.

    Parameters
    ----------
    tr : Traces
        Measured traces.
    signal : str
        The channel.
    samples : int
        Delay in samples (``samples * dt`` s), >= 0.
    """
    s = int(samples)
    if s < 0 or s != samples:
        raise ValueError(f"samples must be a non-negative integer, got {samples!r}")

    def shift(y: np.ndarray, _t: np.ndarray) -> np.ndarray:
        if s == 0:
            return y
        return np.concatenate([np.full(min(s, y.size), y[0]), y[:-s]])[:y.size]

    return _map_channel(tr, signal, shift, requantise=False)


def drift(tr: Traces, signal: str, rate: float) -> Traces:
    """Slow linear drift of one channel's zero: ``rate * t`` added over each test.

    Stands for a sensor offset that creeps as its electronics warm up (a Hall current
    sensor's zero, an LVDT demodulator's offset), zeroed at the start of each test.

    Parameters
    ----------
    tr : Traces
        Measured traces.
    signal : str
        The channel.
    rate : float
        Drift rate in the channel's unit per second (either sign).
    """
    return _map_channel(tr, signal, lambda y, t: y + rate * t)


def outliers(tr: Traces, signal: str, size: float, fraction: float = 0.005,
             seed: int = 0) -> Traces:
    """Sparse large spikes on one channel.

    Stands for electromagnetic interference bursts or bit errors on one channel's
    transmission (a contactor switching nearby).  In each test, ``max(1, round(fraction
    n))`` samples drawn without replacement get ``+-size`` (random sign), then the ADC clips
    them to its span.

    Parameters
    ----------
    tr : Traces
        Measured traces.
    signal : str
        The channel.
    size : float
        Spike height in the channel's unit (20 to 50 noise standard deviations).
    fraction : float
        Share of the samples hit, in (0, 1].
    seed : int
        Seed of the spikes' positions and signs (one generator for all tests, in order).
    """
    if not 0.0 < fraction <= 1.0:
        raise ValueError(f"fraction must lie in (0, 1], got {fraction!r}")
    rng = np.random.default_rng(seed)

    def spikes(y: np.ndarray, _t: np.ndarray) -> np.ndarray:
        n = max(1, round(fraction * y.size))
        idx = rng.choice(y.size, size=n, replace=False)
        out = y.copy()
        out[idx] += size * rng.choice((-1.0, 1.0), size=n)
        return out

    return _map_channel(tr, signal, spikes)


def stuck(tr: Traces, signal: str, start: float = 0.0, value: float | None = None) -> Traces:
    """One channel flat from ``start`` (s) in every test: dead, or frozen at one value.

    Stands for a sensor or an acquisition channel that stops updating (a broken resolver
    cable reading a constant, a frozen serial link repeating its last word, a dead channel
    reading zero).  From the first sample at or after ``start`` the channel holds ``value``
    (default: the value recorded at that sample), on its ADC code; a test shorter than
    ``start`` is left as it was.

    Parameters
    ----------
    tr : Traces
        Measured traces.
    signal : str
        The channel.
    start : float
        Time from which the channel is flat, s (>= 0; 0: the whole record).
    value : float, optional
        The level it holds, in the channel's unit (``None``: frozen at its value at
        ``start``).
    """
    if not start >= 0.0:
        raise ValueError(f"start must be >= 0 s, got {start!r}")

    def freeze(y: np.ndarray, t: np.ndarray) -> np.ndarray:
        k = int(np.searchsorted(t, start))
        out = y.copy()
        if k < y.size:
            out[k:] = y[k] if value is None else value
        return out

    return _map_channel(tr, signal, freeze)


def heavy_tailed(tr: Traces, share: float = 0.03, low: float = 10.0, high: float = 40.0,
                 seed: int = 0, signals: tuple[str, ...] = SIGNALS) -> Traces:
    """Heavy-tailed noise on several channels at once.

    Stands for impulsive interference reaching the whole recording chain (a contactor or a
    bad ground coupling into every channel's wiring).

    In each test and on each of ``signals``, every sample is hit with probability ``share``
    (independently: neighbours may both be hit), by ``+-U(low, high)`` times the channel's
    noise sd (random sign), then the ADC clips and quantises it.

    Parameters
    ----------
    tr : Traces
        Measured traces.
    share : float
        Probability that a sample is hit, in (0, 1).
    low, high : float
        Range of the spikes' height, in the channel's noise standard deviations.
    seed : int
        Seed of the hits (one generator for all channels and tests, in order).
    signals : tuple of str
        The channels hit (default all four).
    """
    if not 0.0 < share < 1.0 or not 0.0 < low <= high:
        raise ValueError(f"need 0 < share < 1 and 0 < low <= high, got {share!r}, {low!r}, "
                         f"{high!r}")
    rng = np.random.default_rng(seed)
    for signal in signals:
        sd = _noise(signal)

        def hit(y: np.ndarray, _t: np.ndarray, sd: float = sd) -> np.ndarray:
            k = rng.random(y.size) < share
            return y + k * rng.choice((-1.0, 1.0), y.size) * rng.uniform(low, high, y.size) * sd

        tr = _map_channel(tr, signal, hit)
    return tr


#: The acquisition-chain decoys, by name (their function's).
ACQUISITION_DECOYS: dict[str, Callable[..., Traces]] = {
    f.__name__: f for f in (lowpass, mains_hum, clipping, time_shift, drift, outliers, stuck,
                            heavy_tailed)}


def _noise(signal: str) -> float:
    return SENSORS[_column(signal)].noise_std


def _pick(rng: np.random.Generator, options: tuple[str, ...]) -> str:
    return options[int(rng.integers(len(options)))]


def _draw_lowpass(rng: np.random.Generator) -> dict[str, Any]:
    # 2-6 ms against 1 ms samples: current and speed steps are smeared over several samples
    return {"signal": _pick(rng, ("i_eq", "omega_m")), "tau": float(rng.uniform(2e-3, 6e-3))}


def _draw_mains_hum(rng: np.random.Generator) -> dict[str, Any]:
    # 0.2-0.5 A (0.5-1.25 % of the 40 A span): 3.8-9.5 noise std peak once window-averaged
    return {"signal": "i_eq", "amplitude": float(rng.uniform(0.2, 0.5)), "freq": MAINS_HZ,
            "phase": float(rng.uniform(0.0, 2 * math.pi))}


def _draw_clipping(rng: np.random.Generator) -> dict[str, Any]:
    signal = _pick(rng, ("i_eq", "omega_m"))
    # 60-85 % of the limit the drive reaches in every step: a flat top on each step
    return {"signal": signal, "level": float(rng.uniform(0.6, 0.85) * NOMINAL_PEAK[signal])}


def _draw_time_shift(rng: np.random.Generator) -> dict[str, Any]:
    # 3-6 ms: several noise std of rms change on position, tens on speed and current
    return {"signal": _pick(rng, ("theta_u", "omega_m", "i_eq")),
            "samples": int(rng.integers(3, 7))}


def _draw_drift(rng: np.random.Generator) -> dict[str, Any]:
    signal = _pick(rng, ("theta_u", "omega_m", "i_eq"))
    # 10-30 noise std per second, either sign (3-9 std by the end of the 0.3 s step)
    rate = float(rng.uniform(10.0, 30.0)) * _noise(signal)
    return {"signal": signal, "rate": rate if rng.random() < 0.5 else -rate}


def _draw_outliers(rng: np.random.Generator) -> dict[str, Any]:
    signal = _pick(rng, SIGNALS)
    return {"signal": signal, "size": float(rng.uniform(20.0, 50.0)) * _noise(signal),
            "fraction": 0.005, "seed": int(rng.integers(2**31))}


def _draw_stuck(rng: np.random.Generator) -> dict[str, Any]:
    # dead from the start (reading zero) or frozen from 0.05-0.25 s (inside the 0.3 s step)
    signal = _pick(rng, SIGNALS)
    if rng.random() < 0.5:
        return {"signal": signal, "start": 0.0, "value": 0.0}
    return {"signal": signal, "start": float(rng.uniform(0.05, 0.25))}


#: Each decoy's draw of its keyword arguments (``_draw_<name>``).
_DRAWS: dict[str, Callable[[np.random.Generator], dict[str, Any]]] = {
    f.__name__.removeprefix("_draw_"): f for f in (
        _draw_lowpass, _draw_mains_hum, _draw_clipping, _draw_time_shift, _draw_drift,
        _draw_outliers, _draw_stuck)}


def draw(name: str, rng: np.random.Generator) -> dict[str, Any]:
    """The keyword arguments of decoy ``name`` (channel and magnitude, physical units),
    drawn from ``rng``: JSON-friendly, so a record holds them."""
    if name not in _DRAWS:
        raise KeyError(f"unknown acquisition decoy {name!r}; known: {list(ACQUISITION_DECOYS)}")
    return _DRAWS[name](rng)


def apply(name: str, tr: Traces, params: Mapping[str, Any]) -> Traces:
    """Decoy ``name`` with keyword arguments ``params`` applied to ``tr``."""
    if name not in ACQUISITION_DECOYS:
        raise KeyError(f"unknown acquisition decoy {name!r}; known: {list(ACQUISITION_DECOYS)}")
    return ACQUISITION_DECOYS[name](tr, **params)
