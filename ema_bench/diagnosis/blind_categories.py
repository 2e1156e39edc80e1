"""The blind suite's categories: their shares, their magnitudes, and which are scored how
(:mod:`ema_bench.diagnosis.blind` draws and runs them, :mod:`.blind_summary` scores them)."""

from __future__ import annotations

#: Categories and their shares of a suite, in percent (largest remainders round them).
CATEGORIES: dict[str, int] = {
    "single": 25, "near_threshold": 14, "two_effect": 19, "null": 9, "monitor_null": 8,
    "physical_decoy": 6, "acquisition_decoy": 19,
}
#: The third round's categories: ``extra`` cases of each after the ``n`` of the shares (so
#: the suites drawn before keep their cases, and the interval calibration its own).
EXTRA_CATEGORIES: tuple[str, ...] = ("effect_acquisition", "three_effect")
#: The fourth round's categories (``fourth`` cases of each after the extra ones): an effect
#: beside an acquisition fault sized by its threshold (:mod:`.sized`), 1-4x and 1-1.5x.
FOURTH_CATEGORIES: tuple[str, ...] = ("effect_acquisition_sized", "near_threshold_acquisition")
#: Faults of the whole recording chain (issue 46, item 2; ``chain`` cases of each after the
#: fourth-round ones): an effect beside a fault of one kind on several channels at once
#: (:func:`.sized.draw_chain`), and beside heavy-tailed noise on every channel.
CHAIN_CATEGORIES: tuple[str, ...] = ("whole_chain_acquisition", "heavy_tailed")
#: Multiples of the acquisition fault's threshold each fourth-round (and chain) category draws.
ACQ_MULTIPLES: dict[str, tuple[float, float]] = {
    "effect_acquisition_sized": (1.0, 4.0), "near_threshold_acquisition": (1.0, 1.5),
    "whole_chain_acquisition": (1.0, 4.0)}
#: The categories scored on an effect named and an acquisition fault named beside it.
EFFECT_ACQUISITION = ("effect_acquisition", *FOURTH_CATEGORIES, *CHAIN_CATEGORIES)
KINDS: dict[str, str] = {
    "single": "effect", "near_threshold": "effect", "two_effect": "effect", "null": "null",
    "monitor_null": "null", "physical_decoy": "decoy", "acquisition_decoy": "decoy",
    "effect_acquisition": "effect", "three_effect": "effect",
    "effect_acquisition_sized": "effect", "near_threshold_acquisition": "effect",
    **{c: "effect" for c in CHAIN_CATEGORIES},
}
#: Magnitude of the hidden effects, as a range of multiples of ``detect`` (log-uniform).
MAGNITUDES: dict[str, tuple[float, float]] = {
    "single": (1.5, 4.0), "near_threshold": (1.0, 1.5), "two_effect": (1.5, 3.0),
    "physical_decoy": (1.0, 4.0), "effect_acquisition": (1.5, 4.0), "three_effect": (2.0, 3.0),
    "effect_acquisition_sized": (1.5, 4.0), "near_threshold_acquisition": (1.5, 4.0),
    **{c: (1.5, 4.0) for c in CHAIN_CATEGORIES},
}
#: Categories whose data go through an acquisition fault (the case's ``decoy``).
ACQUIRED = ("acquisition_decoy", *EFFECT_ACQUISITION)

# --- outside-library physics (issue 46, item 4: terms no library holds) --------------------
#: ``outside`` cases of each after the fourth-round ones (``ema-bench blind --outside K``):
#: physics of a known form that no library effect holds, and nulls made by the reference and
#: by the monitor, on which nothing may be discovered.
OUTSIDE_CATEGORIES: tuple[str, ...] = ("outside_library", "outside_null",
                                       "outside_monitor_null")
#: The physics the outside-library cases cycle through: the two decoys and the
#: reference-only effects (:data:`~ema_bench.effects.OUTSIDE`).
OUTSIDE_PHYSICS: tuple[str, ...] = ("quadratic_damping", "hinge_friction",
                                    "stribeck_friction", "stiffness_position",
                                    "torque_saturation")
#: The dictionary term (:mod:`ema_bench.terms`) each is right to be named as: its equation
#: and form.  ``None``: no dictionary term has its form (a stiffness law acts inside the
#: transmission, a torque in neither balance): right when no term is named.
EXPECTED_TERMS: dict[str, str | None] = {
    "quadratic_damping": "surface_wu_abs", "hinge_friction": "surface_sign",
    "stribeck_friction": "motor_stribeck", "stiffness_position": None,
    "torque_saturation": "motor_i_abs"}
#: Outside-library physics in the current loop and a sensor (``outside`` cases of each after
#: the outside-library ones, their own plan stream: the cases drawn before stay as drawn):
#: an inverter's dead-time voltage and a resolver's second harmonic, built as reference-model
#: effects, each category one physics.
LOOP_CATEGORIES: dict[str, str] = {"outside_current_loop": "dead_time",
                                   "outside_sensor": "resolver_harmonic"}
EXPECTED_TERMS.update({"dead_time": "current_sign", "resolver_harmonic": "sensor_thm_sin2"})
#: Every category judged on the dictionary term it names.
OUTSIDE_KINDS: tuple[str, ...] = ("outside_library", *LOOP_CATEGORIES)
KINDS.update({"outside_library": "outside", "outside_null": "null",
              "outside_monitor_null": "null", **{c: "outside" for c in LOOP_CATEGORIES}})
MAGNITUDES.update({c: (1.0, 4.0) for c in OUTSIDE_KINDS})
