"""Stick-state-aware weighting of the hold current.

While the rotor is stuck (static friction holds it), the drive's current can sit anywhere
inside the stick band: the static friction torque balances whatever the position loop's
integrator has wound up, so the hold current depends on the path that led to the stop, not
on the parameters.  At heavy stiction (Fst >= ~0.5 N m) a small change of any parameter
moves where the rotor sticks and so the hold current by amperes, which makes the fitness a
narrow V (one instance at Fst = 0.83 N m: 96x the optimum's fitness 0.005 N m above it) and
leaves the reference model and the monitor at different hold currents.

The diagnosis therefore gives the current samples taken while the measured rotor is stuck
weight zero, everywhere it compares model and data (fits, held-out fitness, residual
statistics, screening, intervals).  Position, angle and speed keep all their samples: they
carry where the rotor stuck.  Measured on that instance the valley is 16-17x flatter in Fst,
Na and the viscous friction (docs/diagnosis.md).
"""

from __future__ import annotations

import numpy as np

from ..traces import SIGNALS, Traces

# rad/s: measured motor speed below which a sample counts as stuck (the residual features'
# "moving" threshold: a few noise std of the speed sensor, 0.7 % of the 750 rad/s limit)
STICK_SPEED = 5.0
I_EQ = SIGNALS.index("i_eq")
OMEGA_M = SIGNALS.index("omega_m")


def stick_weights(measured: Traces) -> dict[str, np.ndarray]:
    """Per test, (n_samples, 4) sample weights: 0 for the current while the measured rotor is
    stuck (``|omega_m| < STICK_SPEED``), 1 elsewhere."""
    out = {}
    for t in measured.tests:
        y = measured.data[t]
        w = np.ones_like(y)
        w[np.abs(y[:, OMEGA_M]) < STICK_SPEED, I_EQ] = 0.0
        out[t] = w
    return out
