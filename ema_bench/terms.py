"""The dictionary of candidate terms no library effect holds, and the reference-model physics
outside the library that the blind suite builds from them.

Each dictionary term is ``c * phi(state)``, a torque (N m) added to one equation of the block
diagram: the **motor** torque balance (rotor side, states ``th_m``, ``w_m`` and the drive's
torque current ``i``, signed: its torque over the nominal torque constant ``2 Ke``) or the
**surface** torque balance (load side, ``th_u``, ``w_u``).  The terms are state polynomials
to degree 2, odd powers with ``|x|``, a smoothed sign, a Stribeck curve (a smoothed sign
fading with speed) and harmonics of the mechanical and electrical angles; the linear terms
the library already holds (motor viscous friction ``w_m``, the aero spring ``th_u``) are
left out.  Each coefficient is one slot of the effects
vector (:mod:`ema_bench.effects`, after the library and the decoys), so the reference and
the monitor evaluate the same term in the same compiled function
(:func:`ema_bench.physics.extra_terms.extra_torques`) and the workflow fits it by name like
an effect (:mod:`ema_bench.diagnosis.discovery`).

The coefficient bounds are a reference torque over the basis function's typical size (the
motor ``0.5 N m``, a quarter of its torque limit; the surface ``300 N m``, about the hinge
moment at full stroke), so every term can reach the same torque.
"""

from __future__ import annotations

from dataclasses import dataclass

# smoothing speeds of the sign terms: the hinge friction decoy's, and the same surface speed
# seen at the motor (reducer ratio 1/300)
SIGN_SPEED_SURFACE = 0.01   # rad/s
SIGN_SPEED_MOTOR = 3.0      # rad/s
# the Stribeck curve's decay speed at the motor and the stiffness law's reference angle
STRIBECK_SPEED = 30.0       # rad/s (0.1 rad/s at the surface)
STIFFNESS_ANGLE = 0.2       # rad at the surface

EQUATIONS: dict[str, str] = {"motor": "motor torque balance",
                             "surface": "surface torque balance"}
_REF_TORQUE = {"motor": 0.5, "surface": 300.0}   # N m


@dataclass(frozen=True)
class Term:
    """One candidate term: ``c * form`` added to ``equation``'s torque balance."""

    name: str
    equation: str      # a key of EQUATIONS
    form: str          # the basis function, as the verdict writes it
    unit: str          # the coefficient's unit
    typical: float     # |basis| at a typical operating point (its unit)

    @property
    def bound(self) -> float:
        """Largest |coefficient| searched: the equation's reference torque at ``typical``."""
        return _REF_TORQUE[self.equation] / self.typical


# order = the slots of the effects vector = the order extra_torques reads them in
TERMS: tuple[Term, ...] = (
    Term("motor_wm2", "motor", "w_m^2", "N m s^2/rad^2", 9e4),
    Term("motor_wm_abs", "motor", "w_m |w_m|", "N m s^2/rad^2", 9e4),
    Term("motor_sign", "motor", f"tanh(w_m / {SIGN_SPEED_MOTOR:g})", "N m", 1.0),
    Term("motor_i", "motor", "i", "N m/A", 5.0),
    Term("motor_i2", "motor", "i^2", "N m/A^2", 25.0),
    Term("motor_i_abs", "motor", "i |i|", "N m/A^2", 25.0),
    Term("motor_sin_m", "motor", "sin(th_m)", "N m", 1.0),
    Term("motor_cos_m", "motor", "cos(th_m)", "N m", 1.0),
    Term("motor_sin_e", "motor", "sin(p th_m)", "N m", 1.0),
    Term("motor_cos_e", "motor", "cos(p th_m)", "N m", 1.0),
    Term("motor_sin_2e", "motor", "sin(2 p th_m)", "N m", 1.0),
    Term("motor_cos_2e", "motor", "cos(2 p th_m)", "N m", 1.0),
    Term("surface_wu", "surface", "w_u", "N m s/rad", 1.0),
    Term("surface_thu2", "surface", "th_u^2", "N m/rad^2", 0.04),
    Term("surface_thu_wu", "surface", "th_u w_u", "N m s/rad^2", 0.2),
    Term("surface_wu2", "surface", "w_u^2", "N m s^2/rad^2", 1.0),
    Term("surface_thu_abs", "surface", "th_u |th_u|", "N m/rad^2", 0.04),
    Term("surface_wu_abs", "surface", "w_u |w_u|", "N m s^2/rad^2", 1.0),
    Term("surface_sign", "surface", f"tanh(w_u / {SIGN_SPEED_SURFACE:g})", "N m", 1.0),
    # the Stribeck form (appended: the slots before it keep their places): a smoothed sign
    # whose level decays with speed, the peak of dry friction at low speed that neither the
    # Fst fault's constant dynamic level nor tanh(w_m / 3) has
    Term("motor_stribeck", "motor",
         f"exp(-(w_m / {STRIBECK_SPEED:g})^2) tanh(w_m / {SIGN_SPEED_MOTOR:g})", "N m", 1.0),
)
TERM_NAMES: tuple[str, ...] = tuple(t.name for t in TERMS)
#: Kinematic twins: a speed term at the motor and the same term at the surface (``w_m = w_u
#: / tau`` through the gear, the sign terms' speeds matched) differ in the data only through
#: the transmission's twist, which the linearised selection may not resolve; the workflow
#: fits both and lets the training fit decide.
TWINS: dict[str, str] = {a: b for p in (("motor_wm2", "surface_wu2"),
                                         ("motor_wm_abs", "surface_wu_abs"),
                                         ("motor_sign", "surface_sign"))
                         for a, b in (p, p[::-1])}
TERM_INDEX: dict[str, int] = {n: i for i, n in enumerate(TERM_NAMES)}
N_TERMS = len(TERMS)


def term(name: str) -> Term:
    """The dictionary entry ``name`` (``KeyError`` if it is none)."""
    return TERMS[TERM_INDEX[name]]
