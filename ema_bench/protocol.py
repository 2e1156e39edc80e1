"""The test protocol: which commands are played and how outputs are sampled.

Two standard tests (DESIGN section 8): a 0.3 rad step at 10 ms, 0.3 s long, and a 0.25 rad,
1 Hz sine, 1 s long.  The largest backlash (0.04 rad) is 13-16 % of these motions.  Outputs are
the means over each 1 ms window (1 kHz) in both models.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from .physics.command import command_samples, make_command
from .traces import OUTPUT_DT


@dataclass(frozen=True)
class TestSpec:
    """One test: a command played for ``duration`` seconds."""

    __test__ = False  # not a pytest test class

    name: str
    kind: str
    amplitude: float
    duration: float
    t0: float = 0.0
    freq: float = 1.0
    freq_end: float | None = None

    def command(self) -> np.ndarray:
        return make_command(self.kind, self.amplitude, self.t0, self.freq, self.freq_end,
                            self.duration)

    def command_at_samples(self, dt_ctrl: float) -> np.ndarray:
        """The command at every controller sample of the test (rad), shared by all models and
        candidates (computed once, read-only)."""
        return _command_at_samples(self, dt_ctrl)

    def n_samples(self, dt_out: float = OUTPUT_DT) -> int:
        return int(round(self.duration / dt_out))


@functools.lru_cache(maxsize=64)
def _command_at_samples(spec: TestSpec, dt_ctrl: float) -> np.ndarray:
    n = int(math.ceil(spec.duration / dt_ctrl)) + 1
    out = command_samples(spec.command(), n, dt_ctrl)
    out.flags.writeable = False
    return out


STANDARD_TESTS: tuple[TestSpec, ...] = (
    TestSpec("step", "step", 0.3, 0.3, t0=0.01),
    TestSpec("sine", "sine", 0.25, 1.0, freq=1.0),
)
# a held-out sine of another amplitude and frequency, for validation of fitted models
HOLDOUT_TESTS: tuple[TestSpec, ...] = (TestSpec("sine2", "sine", 0.15, 1.0, freq=2.0),)


def steps_per(period: float, dt: float) -> int:
    """Integer number of steps of ``dt`` in ``period``; raise if it is not a whole number."""
    n = round(period / dt)
    if n < 1 or abs(n * dt - period) > 1e-9 * period:
        raise ValueError(f"period {period:g} s is not a whole number of steps of {dt:g} s")
    return int(n)
