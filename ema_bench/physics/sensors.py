"""Sensors and data acquisition: each output is averaged over its 1 ms window (integrate-and-dump
anti-aliasing, done inside the integrators), then gets white electrical noise and is quantised by
a 12-bit ADC over the sensor span.  Sensor offsets are effects (``sensor_offset``) and act inside
the loop, since the controller uses the same position sensor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SensorSpec:
    """ADC span and noise of one recorded signal."""

    lo: float
    hi: float
    bits: int = 12
    noise_frac: float = 1e-3  # std of white noise, fraction of the span (0.1 %)

    @property
    def lsb(self) -> float:
        return (self.hi - self.lo) / (2**self.bits - 1)

    @property
    def noise_std(self) -> float:
        return self.noise_frac * (self.hi - self.lo)


# order = ema_bench.traces.SIGNALS: surface position, motor angle, motor speed, equivalent current
SENSORS: tuple[SensorSpec, ...] = (
    SensorSpec(-0.5, 0.5),       # rad, surface position (LVDT/RVDT class)
    SensorSpec(-200.0, 200.0),   # rad, motor angle (resolver, unwrapped)
    SensorSpec(-1000.0, 1000.0),  # rad/s, motor speed
    SensorSpec(0.0, 40.0),       # A, equivalent current
)


def quantise(y: np.ndarray, spec: SensorSpec) -> np.ndarray:
    """ADC: clip to the span and round to the nearest code."""
    y = np.clip(y, spec.lo, spec.hi)
    return spec.lo + np.round((y - spec.lo) / spec.lsb) * spec.lsb


def measure(y: np.ndarray, rng: np.random.Generator | None, noise: bool = True,
            adc: bool = True) -> np.ndarray:
    """Apply noise and quantisation to window-averaged outputs.

    Parameters
    ----------
    y : ndarray, shape (n_samples, 4)
        Clean outputs in ``SIGNALS`` order, canonical units.
    rng : numpy Generator or None
        Noise source (a child of the run's root ``SeedSequence``); ``None`` means no noise.
    """
    out = np.array(y, dtype=np.float64, copy=True)
    for k, spec in enumerate(SENSORS):
        if noise and rng is not None:
            out[:, k] += rng.normal(0.0, spec.noise_std, size=out.shape[0])
        if adc:
            out[:, k] = quantise(out[:, k], spec)
    return out
