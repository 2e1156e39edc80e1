"""Position commands for the surface: step, sine, ramp, chirp.

A command is a small ``float64`` array ``[kind, amplitude, t0, freq, freq_end, duration]`` so
that the compiled integrators can evaluate it at each controller sample.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

KINDS = {"step": 0, "sine": 1, "ramp": 2, "chirp": 3}
C_KIND, C_AMP, C_T0, C_FREQ, C_FREQ1, C_DUR = range(6)


def make_command(
    kind: str, amplitude: float, t0: float = 0.0, freq: float = 1.0,
    freq_end: float | None = None, duration: float = 1.0,
) -> np.ndarray:
    """Pack a command for the compiled kernels.

    Parameters
    ----------
    kind : {"step", "sine", "ramp", "chirp"}
    amplitude : float
        rad at the surface (step height, sine/chirp amplitude, ramp final value).
    t0 : float
        s, start time (commands are 0 before it).
    freq : float
        Hz; sine frequency, chirp start frequency, or for a ramp its rise rate in
        ``amplitude`` per second.
    freq_end : float, optional
        Hz, chirp end frequency (linear sweep over ``duration - t0``).
    duration : float
        s, length of the test.
    """
    if kind not in KINDS:
        raise ValueError(f"unknown command kind {kind!r}; known: {list(KINDS)}")
    if not (math.isfinite(amplitude) and duration > 0 and 0 <= t0 < duration and freq > 0):
        raise ValueError("command needs finite amplitude, duration > 0, 0 <= t0 < duration, "
                         "freq > 0")
    f1 = freq if freq_end is None else freq_end
    return np.array([KINDS[kind], amplitude, t0, freq, f1, duration], dtype=np.float64)


@njit(cache=True, error_model="numpy")
def command_value(cmd: np.ndarray, t: float) -> float:
    """Surface position command (rad) at time ``t`` (s)."""
    kind = int(cmd[C_KIND])
    amp = cmd[C_AMP]
    s = t - cmd[C_T0]
    if s < 0.0:
        return 0.0
    if kind == 0:
        return amp
    if kind == 1:
        return amp * math.sin(2.0 * math.pi * cmd[C_FREQ] * s)
    if kind == 2:
        return amp * min(1.0, cmd[C_FREQ] * s)
    # chirp: instantaneous frequency sweeps linearly from freq to freq_end
    span = cmd[C_DUR] - cmd[C_T0]
    k = (cmd[C_FREQ1] - cmd[C_FREQ]) / span
    return amp * math.sin(2.0 * math.pi * (cmd[C_FREQ] * s + 0.5 * k * s * s))


@njit(cache=True, error_model="numpy")
def command_samples(cmd: np.ndarray, n: int, dt_ctrl: float) -> np.ndarray:
    """The command at the ``n`` controller sample instants ``k * dt_ctrl`` (rad).

    Computed once per test and shared by every candidate of a batch."""
    out = np.empty(n)
    for k in range(n):
        out[k] = command_value(cmd, k * dt_ctrl)
    return out
