"""Optional physical effects the reference model can switch on (zero = off).

They make the "real" actuator differ from the monitor model in named ways: the
missing-physics workflow looks for them.  An effects vector is a ``float64`` array in
``EFFECT_NAMES`` order; both integrators take it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .terms import EQUATIONS, TERM_NAMES, TERMS


@dataclass(frozen=True)
class Effect:
    """One switchable effect: its parameter, unit, bounds and what it does."""

    name: str
    unit: str
    lower: float
    upper: float
    description: str
    library: bool = True  # False: a decoy, outside the missing-physics library
    trivial: float = 0.0  # |value| below this is physically negligible
    detect: float = 0.0   # |value| the workflow reliably detects and names (inf: it cannot)
    signature: str = ""   # where it shows in the residuals
    # "" (the library or a decoy, by ``library``), "outside" (reference-model physics of a
    # known form, the blind suite's outside-library cases: the monitor ignores it) or "term"
    # (a coefficient of the term dictionary, :mod:`ema_bench.terms`)
    kind: str = ""


EFFECTS: tuple[Effect, ...] = (
    Effect("eccentricity", "-", 0.0, 0.2,
           "static rotor eccentricity zeta: ke_x *= 1 + zeta cos(th_m - phi_x)",
           trivial=0.005, detect=0.05,
           signature="once-per-revolution ripple of current and speed against rotor angle"),
    Effect("sensor_offset", "rad", -0.02, 0.02,
           "surface-position sensor offset (in the loop and in the record)",
           trivial=2.5e-4, detect=1e-3,
           signature="motor angle shifted by -offset/tau at hold; position bias hidden by loop"),
    Effect("viscous_friction", "N m s/rad", 0.0, 2e-3, "extra viscous friction at the motor",
           trivial=2e-6, detect=5e-5,
           signature="current excess growing with |speed|, odd in speed"),
    Effect("aero_spring", "N m/rad", -400.0, 2000.0, "extra aerodynamic hinge-moment spring",
           trivial=5.0, detect=50.0,
           signature="current residual proportional to surface position"),
    Effect("delay", "s", 0.0, 2e-3, "position-feedback transport delay in the controller",
           trivial=5e-5, detect=4e-4,
           signature="lag in the residual's cross-correlation with the command; overshoot"),
    Effect("current_gain", "-", -0.2, 0.2,
           "gain error of the recorded current channel (1+g); the drive's own sensor is fine",
           trivial=0.005, detect=0.03,
           signature="current residual proportional to current, same in every sector"),
    Effect("resistance_rise", "-", 0.0, 0.6, "winding resistance rise with temperature, R*(1+x)",
           trivial=0.05, detect=math.inf,
           signature="none while the current loop has voltage headroom (unobservable here)"),
    Effect("cogging", "N m", 0.0, 0.1, "cogging torque amplitude, 12 periods per revolution",
           trivial=0.003, detect=0.03,
           signature="order-12 ripple of speed and current against rotor angle at low speed"),
    Effect("voltage_sag", "-", 0.0, 0.6, "DC bus voltage sag, V_dc*(1-x)",
           trivial=0.02, detect=math.inf,
           signature="slower current rise at step onset once the sag leaves no voltage "
                     "headroom (> ~40 %): detected there, but too weak to size"),
    Effect("gear_stiffness", "-", 0.0, 0.9, "transmission stiffness loss, K_s*(1-x)",
           trivial=0.05, detect=0.5,
           signature="motor-to-surface angle difference growing with hinge load"),
    # decoys: physics outside the library, for blind tests of the workflow
    Effect("quadratic_damping", "N m s^2/rad^2", 0.0, 100.0,
           "quadratic aerodynamic damping of the surface, -c w_u |w_u|", library=False,
           trivial=0.5, detect=5.0, signature="current excess growing with surface speed^2"),
    Effect("hinge_friction", "N m", 0.0, 20.0,
           "dry friction in the surface hinge bearing (smoothed Coulomb)", library=False,
           trivial=0.1, detect=1.0, signature="current step at each surface speed reversal"),
    # outside the library and the decoys: reference-model physics of a known form, which
    # the monitor does not compute (only the term dictionary can stand in for it)
    Effect("stribeck_friction", "N m", 0.0, 0.3,
           "Stribeck peak of the motor's dry friction: -F exp(-(w_m/w_s)^2) tanh(w_m/w_0)",
           library=False, kind="outside", trivial=0.005, detect=0.03,
           signature="extra friction torque at low motor speed, vanishing at speed"),
    Effect("stiffness_position", "-", 0.0, 0.9,
           "transmission stiffness falling with surface position, "
           "K_s (1 - x min((th_u/0.2)^2, 1))",
           library=False, kind="outside", trivial=0.05, detect=0.5,
           signature="motor-to-surface angle difference growing with |th_u|"),
    Effect("torque_saturation", "1/A", 0.0, 0.03,
           "torque constant falling with current, K_t (1 - x |i|)", library=False,
           kind="outside", trivial=5e-4, detect=5e-3,
           signature="current excess growing with |current|^2 under load"),
) + tuple(Effect(t.name, t.unit, -t.bound, t.bound,
                 f"dictionary term of the {EQUATIONS[t.equation]}: c {t.form}",
                 library=False, kind="term", trivial=2e-3 * t.bound, detect=2e-2 * t.bound,
                 signature="a term no library effect holds") for t in TERMS) + (
    # outside the library in the current loop and a sensor (appended after the dictionary:
    # every earlier slot keeps its place)
    Effect("dead_time", "V", 0.0, 10.0,
           "inverter dead time and switch drops: each switching leg's voltage "
           "-V tanh(i_x / 0.5)", library=False, kind="outside", trivial=0.5,
           detect=math.inf,
           signature="none while the hysteresis current loop has voltage headroom: 8 V per "
                     "leg moves the recorded current by 3.6 noise sigma at most"),
    Effect("resolver_harmonic", "rad", 0.0, 0.005,
           "resolver second-harmonic error: measured motor angle th_m + a sin(2 th_m), its "
           "rate the speed feedback", library=False, kind="outside", trivial=2e-5,
           detect=2e-4,
           signature="twice-per-revolution ripple of the measured speed and the current"),
)
EFFECT_NAMES: tuple[str, ...] = tuple(e.name for e in EFFECTS)
EFFECT_INDEX: dict[str, int] = {n: i for i, n in enumerate(EFFECT_NAMES)}
# positions in an effects vector, by name (numba folds the module-level ints as constants)
(E_ECC, E_OFFSET, E_VISC, E_AERO, E_DELAY, E_IGAIN, E_RRISE, E_COG, E_VSAG, E_GEAR, E_QDAMP,
 E_HFRIC) = (EFFECT_INDEX[n] for n in (
    "eccentricity", "sensor_offset", "viscous_friction", "aero_spring", "delay", "current_gain",
    "resistance_rise", "cogging", "voltage_sag", "gear_stiffness", "quadratic_damping",
    "hinge_friction"))
LIBRARY: tuple[str, ...] = tuple(e.name for e in EFFECTS if e.library)
DECOYS: tuple[str, ...] = tuple(e.name for e in EFFECTS if not e.library and not e.kind)
OUTSIDE: tuple[str, ...] = tuple(e.name for e in EFFECTS if e.kind == "outside")
E_STRIBECK, E_KPOS, E_KTSAT, E_DEADTIME, E_RESOLVER2 = (EFFECT_INDEX[n] for n in (
    "stribeck_friction", "stiffness_position", "torque_saturation", "dead_time",
    "resolver_harmonic"))
#: the first dictionary term's slot: the terms are N_TERMS entries from there
E_TERM0 = EFFECT_INDEX[TERM_NAMES[0]]
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
