"""The kinds of fitness jump the landscape atlas finds, each attributed by experiment.

For each kind, a witness (an atlas case and one of its lines through ``x*``) and what the
experiment below found there.  :func:`zoom` looks at the witness line's largest jump
(:func:`landscape_atlas.jumps`) 40x closer and :func:`bisect` narrows its largest step to
two points 1e-13 of the unit box apart; :func:`first_flip` then steps both points through
the test whose fitness moved, tick by tick, with the kernels' own compiled blocks (the
integrator's loop, :func:`ema_bench.physics.integrator.integrate`, written out so that its
internal states show), and names the first state that differs between the two sides.  The atlas
(``landscape_atlas.py``) reports each kind's jump at the standard step, at half the step
(25 us) and under model version 4, which removes the numerical kind.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ema_bench.effects import MAX_DELAY_SAMPLES
from ema_bench.faults import F_GPROP
from ema_bench.monitor import test_layout
from ema_bench.monitor_plant import monitor_consts, monitor_init, monitor_step
from ema_bench.physics.ace import ace_consts, ace_update, delayed_feedback
from ema_bench.physics.effect_terms import sensor_terms
from ema_bench.physics.mechanics import contact_side


@dataclass(frozen=True)
class Kind:
    """One kind of jump: its witness line and its attribution."""

    name: str
    case: str
    line: str            # a parameter's name, or "random direction k" (the atlas's k-th)
    physics: bool        # a property of the problem (True) or of the numerics (False)
    mechanism: str
    evidence: str


KINDS: tuple[Kind, ...] = (
    Kind("dropped commutation transfer", "v3-full@prior", "random direction 0", False,
         "An accelerating rotor crosses a six-step sector boundary on the mechanics' "
         "trapezoidal path (th_m + h (w_m + w_m1) / 2) but not on the drive's straight "
         "prediction th_m + h w_m; the next step finds itself in the new sector and, in model "
         "version 3, switches the pair without the commutation transfer (the torque-constant "
         "ramp and the back-EMF deficit). One side of the jump has the transfer, the other "
         "not: a decision at step resolution.",
         "the sector index is the first discrete state to differ (the crossing is seen in "
         "step 663 of the step test on one side, at the start of step 664 on the other). "
         "Halving the step narrows the gap between the two paths (its width in angle goes "
         "as h^2), so such crossings get rarer, but each one still drops a whole transfer: "
         "the kind stays at 25 us (the table) because it is a decision at step resolution "
         "whatever the step. Version 4 starts the missed transfer where the crossing was "
         "(inside the last step, along the current speed): the zoomed step falls to the "
         "line's continuous slope and the bisected jump to rounding, at 50 and 25 us. Also "
         "on v3-t12-s00 along sensor_offset (sine test, 8e-3 f*; model version 3's data and "
         "x*)."),
    Kind("speed-loop anti-windup at a controller sample", "v3-small@prior", "Gprop", True,
         "The speed PI integrates only while its torque reference is unsaturated or the "
         "error pulls it out of saturation (conditional integration, ema_bench.physics.ace); "
         "the sample at which it leaves the 2 N m limit flips between the two sides, one "
         "sample's integral (the speed error times 50 us) more or less, and the trajectory "
         "differs from there on.",
         "whether the PI integrated is the first discrete state to differ, at a controller "
         "sample while the current reference is at its 20 A limit; the jump keeps its size "
         "at 25 us and in version 4: the controller period (20 kHz) is the ACE's, not the "
         "monitor's step, and the reference model runs the same sampled law (the real ACE "
         "decides at its samples). Also on v3-t7-s00 and v3-t12-s01 along sensor_offset "
         "(step test)."),
    Kind("creeping rotor reaches a sector boundary", "v3-t7-s01@prior", "sensor_offset",
         True,
         "In the step test's final hold the rotor creeps towards standstill near a sector "
         "boundary; a smaller sensor offset moves the hold so that it crosses into the next "
         "sector before the record ends, where the pair without the faulty phase (Na < 1) "
         "gives another torque constant: the current drops by 10 % over the last 10 ms. The "
         "fitness is continuous but its slope jumps 25-fold: a kink, which the atlas's "
         "jump measure (a difference minus its neighbours' mean) counts as a jump.",
         "zoomed 40x the largest step is 5 % of the line's jump and bisected to 1e-13 it "
         "falls to 8e-6 f* (2e-6 at 25 us): continuous up to a micro-step that shrinks with "
         "the step, five orders below the kink and below v3's finest fitness target (not "
         "attributed further); the line's values at 50, 25 and 12.5 us agree to 2e-3 f* "
         "(measured on model version 3's data and x*); "
         "between the zoomed step's ends the sector index is the first discrete state to "
         "differ, near the record's end (the table's sample, of 6000); version 4 changes "
         "nothing "
         "(the crossing is predicted)."),
)

#: The quantiser question: the monitor's prediction is not quantised.
QUANTISER = (
    "The monitor predicts clean window means (``simulate_monitor``; the objective compares "
    "them with the data, ``fitness_from_outputs``): only the data go through the ADC "
    "(``sensors.measure``, in the reference and twin data makers). The data's quantisation "
    "is a property of the problem (the real 12-bit sensor quantises: it is fixed noise in "
    "the data, and a fit cannot undo it); a monitor that quantised its own prediction would "
    "make the fitness piecewise constant in an offset, with zero gradient between codes: an "
    "artefact of the prediction, not of the sensor, which this monitor does not have.")


def direction(kind: Kind, names: tuple[str, ...], random_dirs: np.ndarray) -> np.ndarray:
    """The unit-box direction of ``kind``'s witness line (``random_dirs``: the atlas's)."""
    if kind.line.startswith("random direction"):
        return random_dirs[int(kind.line.rsplit(" ", 1)[1])]
    d = np.zeros(len(names))
    d[names.index(kind.line)] = 1.0
    return d


def zoom(f, t: np.ndarray, F: np.ndarray, factor: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """The interval of the line's largest jump (``F`` on the points ``t``,
    :func:`landscape_atlas.jumps`' measure) resampled in ``factor + 1`` points: ``(tt, f(tt))``.
    ``f`` maps line offsets (array) to fitness values."""
    d = np.diff(F)
    k = int(np.argmax(np.abs(d[1:-1] - 0.5 * (d[:-2] + d[2:])))) + 1
    tt = np.linspace(t[k], t[k + 1], factor + 1)
    return tt, f(tt)


def bisect(f, tt: np.ndarray, FF: np.ndarray, width: float = 1e-13) -> tuple[float, float]:
    """The largest step of ``FF`` (on ``tt``) narrowed by bisection to ``b - a <= width``,
    keeping the half that holds the larger part of the step."""
    j = int(np.argmax(np.abs(np.diff(FF))))
    a, b, fa, fb = tt[j], tt[j + 1], FF[j], FF[j + 1]
    while b - a > width:
        m = 0.5 * (a + b)
        fm = float(f(np.array([m]))[0])
        if abs(fm - fa) > abs(fb - fm):
            b, fb = m, fm
        else:
            a, fa = m, fm
    return a, b


def _tick_states(p, x, e, cmd, dt, steps_tick):
    """Per controller sample, the discrete states: sector index, whether the PI integrated
    (conditional integration), reducer contact side, whether the shaft slides (the
    integrator's loop, the same compiled blocks)."""
    pc = monitor_consts(p, x, e, dt)
    cc = ace_consts(p, x[F_GPROP])
    offset, _, delay = sensor_terms(e, p)
    buf = np.empty(MAX_DELAY_SAMPLES + 1)
    ps = monitor_init(pc)
    mc = pc[1]
    th_m = w_m = th_u = w_u = integ = 0.0
    rows = np.empty((cmd.size, 4))
    for k in range(cmd.size):
        fb = th_u + offset
        if delay > 0.0:
            fb = delayed_feedback(buf, k, fb, delay)
        i_ref, integ1 = ace_update(cmd[k], fb, w_m, integ, cc)
        for _ in range(steps_tick):
            th_m, w_m, th_u, w_u, ps, *_ = monitor_step(th_m, w_m, th_u, w_u, ps, i_ref, pc)
        rows[k] = (ps[1], integ1 != integ, contact_side(mc.tau * th_m - th_u, mc.half),
                   abs(w_m) >= mc.w_stick)
        integ = integ1
    return rows


FLIP_STATES = ("sector index", "PI integrating", "reducer contact side", "sliding/stuck")


def first_flip(objective, X: np.ndarray, params) -> tuple[str, str, int]:
    """The test whose fitness term moves most between the two rows of ``X`` (physical
    units), the first of :data:`FLIP_STATES` to differ there and its controller sample
    (``"none"``, -1: none differs), stepping at ``params.dt_mon``."""
    E = objective.space.effects_for(X, objective.effects)
    outs = objective.outputs(X)[0]
    moved = {}
    for t, o in outs.items():
        r = ((o - objective.measured.data[t][None]) ** 2 * objective.weights[t]).sum(axis=(1, 2))
        moved[t] = abs(r[1] - r[0])
    test = max(moved, key=moved.get)
    i = [s.name for s in objective.tests].index(test)
    cmd, start = test_layout(objective.tests, params.dt_ctrl)[:2]
    p = params.to_array()
    n = int(round(params.dt_ctrl / params.dt_mon))
    A, B = (_tick_states(p, X[r, :4], E[r], cmd[start[i]:start[i + 1]], params.dt_mon, n)
            for r in range(2))
    differ = A != B
    if not differ.any():
        return test, "none", -1
    k = int(np.argmax(differ.any(axis=1)))
    return test, FLIP_STATES[int(np.argmax(differ[k]))], k
