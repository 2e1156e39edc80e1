"""How far each dictionary term moves the outputs at its bound, and the current loop's and the
resolver's outside-library physics in the reference (issue 46, item 4), measured.

At the nominal faults, on noise-free reference data of the training tests: the norm of each
term's output sensitivity (:func:`ema_bench.diagnosis.discovery.sensitivities`, whitened,
per unit coefficient) times the term's bound, in noise units, the number
:func:`~ema_bench.diagnosis.discovery.visible` compares with ``VISIBLE_NORM``; then the
reference with an inverter dead time and with a resolver second harmonic against the
reference without, each channel's largest change in noise sigmas and the summed ``z^2`` over
the step and sine tests.  About 130 CPU-s (1 where the trace cache already holds the
reference's runs, as for the committed figures).

    python benchmarks/term_visibility.py --json benchmarks/results/term_visibility.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from ema_bench.diagnosis.discovery import VISIBLE_NORM, sensitivities, visible
from ema_bench.diagnosis.results import TRAIN, Fit
from ema_bench.faults import NOMINAL
from ema_bench.objective import KNOWN_TESTS
from ema_bench.physics.sensors import SENSORS
from ema_bench.reference import simulate_reference
from ema_bench.terms import TERM_NAMES, term

OUTSIDE = ({"dead_time": 8.0}, {"dead_time": 2.0}, {"resolver_harmonic": 1e-3},
           {"resolver_harmonic": 2e-4})


def measure() -> dict:
    tests = tuple(KNOWN_TESTS[t] for t in TRAIN)
    base = simulate_reference(NOMINAL, tests=tests, noise=False, adc=False)
    _, _, S = sensitivities(base, Fit((), NOMINAL.copy(), 0.0, {}, 0))
    at_bound = {n: float(np.linalg.norm(S[:, k]) * term(n).bound)
                for k, n in enumerate(TERM_NAMES)}
    sigma = np.array([s.noise_std for s in SENSORS])
    outside = []
    for e in OUTSIDE:
        tr = simulate_reference(NOMINAL, e, tests=tests, noise=False, adc=False)
        z = {t: (np.asarray(tr.data[t]) - np.asarray(base.data[t])) / sigma for t in tr.data}
        outside.append({"effect": e,
                        "max_sigma": {t: np.abs(v).max(axis=0).round(3).tolist()
                                      for t, v in z.items()},
                        "sum_z2": float(sum((v ** 2).sum() for v in z.values()))})
    return {"norm_at_bound": at_bound, "visible_norm": VISIBLE_NORM,
            "hidden": [n for n in TERM_NAMES if n not in visible(S)], "outside": outside}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", help="write the figures here")
    args = ap.parse_args(argv)
    c0 = time.process_time()
    res = measure()
    res["cpu_s"] = round(time.process_time() - c0, 1)
    for n, v in res["norm_at_bound"].items():
        print(f"{n:18s} {v:10.4g}")
    print("hidden:", ", ".join(res["hidden"]))
    for o in res["outside"]:
        print(o["effect"], "max sigma", o["max_sigma"], "sum z^2", round(o["sum_z2"], 1))
    print(f"{res['cpu_s']} CPU-s")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(res, f, indent=1)
            f.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
