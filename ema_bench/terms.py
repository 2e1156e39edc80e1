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

# the current loop's terms: the sign's smoothing current (the hysteresis band) and the
# order of the back-EMF harmonic (the six-step ripple of the conducting pair)
SIGN_CURRENT = 0.5          # A
EMF_ORDER = 6

EQUATIONS: dict[str, str] = {"motor": "motor torque balance",
                             "surface": "surface torque balance",
                             "current": "current loop",
                             "motor_angle": "motor-angle sensor",
                             "surface_position": "surface-position sensor",
                             "current_sensor": "current sensor"}
#: Each equation's reference size of a term (its unit): the torque balances' torques (N m),
#: the current loop's voltage (V: a PWM inverter's dead-time error is a few volts of the
#: 270 V bus) and the sensors' errors (rad, rad, A: a resolver's few arc-minutes, 0.4 % of a
#: position sensor's span, 2.5 % of the current channel's full scale).
REF_SIZE = {"motor": 0.5, "surface": 300.0, "current": 10.0, "motor_angle": 0.01,
            "surface_position": 2e-3, "current_sensor": 0.5}
#: The equations whose terms are torques (:func:`~ema_bench.physics.extra_terms.extra_torques`)
TORQUE_EQUATIONS = ("motor", "surface")


@dataclass(frozen=True)
class Term:
    """One candidate term: ``c * form`` added to ``equation`` (a torque, a voltage or a
    sensor's error: :data:`REF_SIZE`'s unit)."""

    name: str
    equation: str      # a key of EQUATIONS
    form: str          # the basis function, as the verdict writes it
    unit: str          # the coefficient's unit
    typical: float     # |basis| at a typical operating point (its unit)

    @property
    def bound(self) -> float:
        """Largest |coefficient| searched: the equation's reference size at ``typical``."""
        return REF_SIZE[self.equation] / self.typical


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
    # the current loop (appended, slots 20-23): a voltage added to the conducting pair's
    # L di/dt = v - R i - e + c phi, with i the pair current (signed): the smoothed sign of
    # an inverter's dead time and switch drops, i |i|, and the back-EMF's six-step harmonic
    Term("current_sign", "current", f"tanh(i / {SIGN_CURRENT:g})", "V", 1.0),
    Term("current_i_abs", "current", "i |i|", "V/A^2", 25.0),
    Term("current_emf_sin", "current", f"w_m sin({EMF_ORDER} p th_m)", "V s/rad", 300.0),
    Term("current_emf_cos", "current", f"w_m cos({EMF_ORDER} p th_m)", "V s/rad", 300.0),
    # the sensors (slots 24-30): an error added to a measured signal, in the loop (the
    # controller's feedback, the speed it derives from the motor angle, the drive's current)
    # and in the record: a resolver's harmonics, a position sensor's curvature, a saturating
    # current sensor
    Term("sensor_thm_sin", "motor_angle", "sin(th_m)", "rad", 1.0),
    Term("sensor_thm_cos", "motor_angle", "cos(th_m)", "rad", 1.0),
    Term("sensor_thm_sin2", "motor_angle", "sin(2 th_m)", "rad", 1.0),
    Term("sensor_thm_cos2", "motor_angle", "cos(2 th_m)", "rad", 1.0),
    Term("sensor_thu2", "surface_position", "th_u^2", "1/rad", 0.04),
    Term("sensor_thu_abs", "surface_position", "th_u |th_u|", "1/rad", 0.04),
    Term("sensor_i_abs", "current_sensor", "i |i|", "1/A", 25.0),
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
#: The first slot of the current loop's terms and of the sensors' (torque terms before them)
T_CURRENT0 = TERM_INDEX["current_sign"]
T_SENSOR0 = TERM_INDEX["sensor_thm_sin"]


def term(name: str) -> Term:
    """The dictionary entry ``name`` (``KeyError`` if it is none)."""
    return TERMS[TERM_INDEX[name]]
