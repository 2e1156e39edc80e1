"""Optional physical effects the reference model can switch on (zero = off).

They make the "real" actuator differ from the monitor model in named ways: the
missing-physics workflow looks for them.  An effects vector is a ``float64`` array in
``EFFECT_NAMES`` order; both integrators take it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Effect:
    """One switchable effect: its parameter, unit, bounds and what it does."""

    name: str
    unit: str
    lower: float
    upper: float
    description: str
    library: bool = True  # False: a decoy, outside the missing-physics library


EFFECTS: tuple[Effect, ...] = (
    Effect("eccentricity", "-", 0.0, 0.2,
           "static rotor eccentricity zeta: ke_x *= 1 + zeta cos(th_m - phi_x)"),
    Effect("sensor_offset", "rad", -0.02, 0.02,
           "surface-position sensor offset (in the loop and in the record)"),
    Effect("viscous_friction", "N m s/rad", 0.0, 2e-3, "extra viscous friction at the motor"),
    Effect("aero_spring", "N m/rad", -400.0, 2000.0, "extra aerodynamic hinge-moment spring"),
    Effect("delay", "s", 0.0, 2e-3, "position-feedback transport delay in the controller"),
    Effect("current_gain", "-", -0.2, 0.2,
           "current-sensor gain error: loop and record see (1+g) i"),
    Effect("resistance_rise", "-", 0.0, 0.6, "winding resistance rise with temperature, R*(1+x)"),
    Effect("cogging", "N m", 0.0, 0.1, "cogging torque amplitude, 12 periods per revolution"),
    Effect("voltage_sag", "-", 0.0, 0.5, "DC bus voltage sag, V_dc*(1-x)"),
    Effect("gear_stiffness", "-", 0.0, 0.9, "transmission stiffness loss, K_s*(1-x)"),
    # decoys: physics outside the library, for blind tests of the workflow
    Effect("quadratic_damping", "N m s^2/rad^2", 0.0, 200.0,
           "quadratic aerodynamic damping of the surface, -c w_u |w_u|", library=False),
    Effect("hinge_friction", "N m", 0.0, 20.0,
           "dry friction in the surface hinge bearing (smoothed Coulomb)", library=False),
)
EFFECT_NAMES: tuple[str, ...] = tuple(e.name for e in EFFECTS)
(E_ECC, E_OFFSET, E_VISC, E_AERO, E_DELAY, E_IGAIN, E_RRISE, E_COG, E_VSAG,
 E_GEAR, E_QDAMP, E_HFRIC) = range(len(EFFECTS))
LIBRARY: tuple[str, ...] = tuple(e.name for e in EFFECTS if e.library)
DECOYS: tuple[str, ...] = tuple(e.name for e in EFFECTS if not e.library)
N_EFFECTS = len(EFFECTS)
MAX_DELAY_SAMPLES = 64  # controller samples kept for the delay effect (3.2 ms at 20 kHz)


class EffectError(ValueError):
    """An unknown effect name or a value outside its bounds."""


def effects_vector(values: Mapping[str, float] | None = None) -> np.ndarray:
    """Effects vector from ``name -> value`` (unnamed effects are off)."""
    e = np.zeros(N_EFFECTS)
    for name, value in (values or {}).items():
        if name not in EFFECT_NAMES:
            raise EffectError(f"unknown effect {name!r}; known: {list(EFFECT_NAMES)}")
        spec = EFFECTS[EFFECT_NAMES.index(name)]
        v = float(value)
        if not (np.isfinite(v) and spec.lower <= v <= spec.upper):
            raise EffectError(f"effect {name}={v:g} {spec.unit} is outside its bounds "
                              f"[{spec.lower:g}, {spec.upper:g}]")
        e[EFFECT_NAMES.index(name)] = v
    return e


def effects_to_dict(e: np.ndarray) -> dict[str, float]:
    """The effects that are on, ``name -> value``."""
    return {n: float(v) for n, v in zip(EFFECT_NAMES, e) if v != 0.0}
