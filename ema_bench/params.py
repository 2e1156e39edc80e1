"""The one parameter set of the simulated actuator.

Every physical constant of the reference and monitor models lives here, with its unit and a
one-line source or reason.  The values follow the validated starting point of the project's
design notes, section 8: a flight-control EMA of the Dalla Vedova / Borello family (270 V
HVDC bus, BLDC motor with trapezoidal back-EMF, 300:1 reducer, aileron-class surface inertia).

The compiled kernels take the parameters as one flat ``float64`` array; the position of each
entry is looked up by name (``PARAM_INDEX``) into the module-level ``P_*`` integers below, which
numba folds as constants.  Adding a parameter is adding a field: nothing depends on its place.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np


def _p(value: float, unit: str, source: str) -> float:
    return field(default=value, metadata={"unit": unit, "source": source})


@dataclass(frozen=True)
class EMAParams:
    """Physical parameters of the EMA (fault parameters excluded: see :mod:`ema_bench.faults`)."""

    # --- power electronics and motor (per phase, star connection) ---
    V_dc: float = _p(270.0, "V", "aircraft HVDC bus (MIL-STD-704F 270 V DC)")
    R: float = _p(0.5, "ohm", "phase resistance of a ~1 kW servo BLDC; 20 A costs 20 V of "
                  "the 270 V bus")
    L: float = _p(0.5e-3, "H", "phase inductance; 2 mH made commutation eat the 60 deg sector")
    Ke: float = _p(0.05, "V s/rad", "phase back-EMF peak per motor rad/s; 2 Ke = 0.1 N m/A")
    pole_pairs: float = _p(2.0, "-", "4-pole rotor, typical of small servo BLDCs")
    hyst_band: float = _p(0.5, "A", "current hysteresis band (analog comparators: the reference "
                          "switches at the located crossing instant)")
    # --- mechanics (2-DOF: motor rotor + surface, joined by the reducer) ---
    J_m: float = _p(5e-5, "kg m^2", "motor rotor inertia")
    J_u: float = _p(1.0, "kg m^2", "surface (aileron-class) inertia about the hinge")
    tau: float = _p(1.0 / 300.0, "rad/rad", "reducer ratio, surface rad per motor rad")
    K_s: float = _p(3e5, "N m/rad", "transmission stiffness at the surface; mode above loops")
    C_s: float = _p(1000.0, "N m s/rad", "contact damping, ratio ~0.9: no impact trains")
    C_m: float = _p(1e-5, "N m s/rad", "motor viscous friction (bearings, windage)")
    C_u: float = _p(50.0, "N m s/rad", "surface aerodynamic damping")
    K_aero: float = _p(800.0, "N m/rad", "hinge-moment spring; keeps the backlash loaded")
    theta_stop: float = _p(0.45, "rad", "mechanical end stops at the surface, beyond the tests")
    K_stop: float = _p(1e6, "N m/rad", "end-stop contact stiffness")
    C_stop: float = _p(2000.0, "N m s/rad", "end-stop contact damping (ratio ~1)")
    friction_dyn_ratio: float = _p(0.5, "-", "dynamic / static dry friction (F_dyn = 0.5 F_st)")
    stick_speed: float = _p(1e-3, "rad/s", "Karnopp stick band on motor speed")
    # --- ACE (actuator control electronics) ---
    K_GP: float = _p(1e-3, "-", "fixed scaling so K_GP*Gprop = 50..150 1/s at the surface")
    w_max: float = _p(750.0, "rad/s", "motor speed limit (surface rate 2.5 rad/s)")
    Kpv: float = _p(0.05, "N m s/rad", "speed-loop proportional gain")
    Kiv: float = _p(2.0, "N m/rad", "speed-loop integral gain")
    T_max: float = _p(2.0, "N m", "torque reference limit = 20 A current limit")
    dt_ctrl: float = _p(5e-5, "s", "controller sample period (20 kHz), zero-order hold")
    # --- integration steps ---
    dt_ref: float = _p(1e-6, "s", "reference step; converged (halving changes outputs <<1 %)")
    dt_mon: float = _p(5e-5, "s", "monitor step = controller period")
    # --- monitor drive ---
    kt_factor: float = _p(1.0, "-", "monitor torque / modelled pair torque; calibrated on the "
                          "healthy actuator it fits to 1.0000 (python -m "
                          "ema_bench.monitor_bias): the "
                          "commutation transfer is modelled, nothing is left to calibrate")
    locate_commutation: float = _p(0.0, "-", "1: a sector crossing that the drive's "
                                   "straight-path prediction missed starts its commutation "
                                   "transfer where it was (model version 4, suite emafdi-v3); "
                                   "0: it is dropped (version 3, suites v1 and v2)")
    libm_trig: float = _p(0.0, "-", "1: libm's sine and cosine in the eccentric torque "
                          "constants and in cogging (model version 2, the records made "
                          "before version 3); 0: the polynomials of physics/trig.py "
                          "(version 3, within 2.2e-16 of libm)")

    def to_array(self) -> np.ndarray:
        """Flat ``float64`` array in ``P_*`` order, as the compiled kernels take it."""
        return np.array([getattr(self, n) for n in PARAM_NAMES], dtype=np.float64)

    def replace(self, **changes: float) -> EMAParams:
        """Copy with some values changed (unknown names raise ``TypeError``)."""
        return dataclasses.replace(self, **changes)

    @staticmethod
    def describe() -> list[dict[str, object]]:
        """Table of ``name, value, unit, source`` for docs and ``ema-bench params``."""
        return [
            {"name": f.name, "value": f.default, "unit": f.metadata["unit"],
             "source": f.metadata["source"]}
            for f in dataclasses.fields(EMAParams)
        ]


PARAM_NAMES: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(EMAParams))
PARAM_INDEX: dict[str, int] = {n: i for i, n in enumerate(PARAM_NAMES)}
# positions in the kernels' flat array, by name
P_VDC, P_R, P_L, P_KE, P_PP, P_HYST = (PARAM_INDEX[n] for n in (
    "V_dc", "R", "L", "Ke", "pole_pairs", "hyst_band"))
P_JM, P_JU, P_TAU, P_KS, P_CS, P_CM, P_CU, P_KAERO = (PARAM_INDEX[n] for n in (
    "J_m", "J_u", "tau", "K_s", "C_s", "C_m", "C_u", "K_aero"))
P_THSTOP, P_KSTOP, P_CSTOP, P_FDYN, P_WSTICK = (PARAM_INDEX[n] for n in (
    "theta_stop", "K_stop", "C_stop", "friction_dyn_ratio", "stick_speed"))
P_KGP, P_WMAX, P_KPV, P_KIV, P_TMAX, P_DTC = (PARAM_INDEX[n] for n in (
    "K_GP", "w_max", "Kpv", "Kiv", "T_max", "dt_ctrl"))
P_KTF = PARAM_INDEX["kt_factor"]
P_LOCATE = PARAM_INDEX["locate_commutation"]
P_LIBM = PARAM_INDEX["libm_trig"]

DEFAULT_PARAMS = EMAParams()

#: The models' parameters per model version: version 3 (suites emafdi-v1 and v2, the
#: campaigns) drops a commutation transfer whose sector crossing the drive's straight-path
#: prediction missed; version 4 starts it where the crossing was (docs/landscape-atlas.md,
#: "Kinds of jump"), bit-identical to version 3 wherever no such crossing happens; version 2
#: (``libm_trig``, the records made before version 3: replay re-runs them on it) takes
#: libm's sine and cosine in eccentricity and cogging, bit-identical to version 3 wherever
#: neither effect is on.
MODEL_PARAMS: dict[str, EMAParams] = {
    "2": DEFAULT_PARAMS.replace(libm_trig=1.0),
    "3": DEFAULT_PARAMS,
    "4": DEFAULT_PARAMS.replace(locate_commutation=1.0),
}


def model_params(version: str) -> EMAParams:
    """The parameters of model ``version`` (:data:`MODEL_PARAMS`); ``KeyError`` names the
    versions there are."""
    try:
        return MODEL_PARAMS[str(version)]
    except KeyError:
        raise KeyError(f"no model version {version!r}: {sorted(MODEL_PARAMS)}") from None
