"""The monitor's model-form allowance, calibrated on the twin/reference pair.

On the reference track (and on real data) the monitor model did not make the data: even on
noise-free traces its best fit lies off the truth (:func:`~ema_bench.monitor_bias.clean_bias`).
That bias is systematic, so intervals from the noise alone are over-confident however much
data there is.  The allowance of a fault at level ``p`` is the ``p`` quantile of ``|bias|``
over the calibration instances (the suite's paper cases and Latin-hypercube instances,
:mod:`~ema_bench.suites.v1`), which are disjoint from the seeded random instances coverage is
measured on; :func:`~ema_bench.uncertainty.methods.intervals` adds it in quadrature to the
noise half-width.  The biases ship as ``model_form.json`` (those of
``benchmarks/results/clean_bias_suite.txt``, made by ``python benchmarks/clean_bias.py``);
:func:`calibrate` recomputes them (about 5 CPU-minutes) into a file it is given.
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..faults import FAULT_NAMES

PATH = Path(__file__).with_name("model_form.json")


@lru_cache(maxsize=1)
def _biases() -> np.ndarray:
    """Signed clean-data biases (n_instances, 4), fractions of each fault's range."""
    data = json.loads(PATH.read_text())
    if data.get("faults") != list(FAULT_NAMES):
        raise ValueError(f"{PATH} is for faults {data.get('faults')}, not {list(FAULT_NAMES)}")
    return np.array([row["range_error"] for row in data["instances"].values()], dtype=float)


def allowance(level: float) -> np.ndarray:
    """Model-form half-width per fault at ``level``, fractions of each fault's range (4,)."""
    return np.quantile(np.abs(_biases()), level, axis=0, method="higher")


def calibrate(path: Path | str, instances: list[str] | None = None,
              evals: int = 6000) -> dict[str, object]:
    """Recompute the clean-data biases of the calibration ``instances`` (default: the
    suite's paper cases and Latin-hypercube instances) and write them to ``path``.

    ``path`` has no default: shipped data is read-only, so the shipped ``model_form.json``
    (:data:`PATH`) is regenerated only by naming it, in a checkout; a path inside an
    installed package raises ValueError (one line) before any work."""
    from ..interval_calibration_files import checkout_root, inside_package

    if inside_package(path) and checkout_root() is None:
        raise ValueError(f"{path} is inside the installed package, not a checkout: shipped "
                         "data is read-only; write the biases elsewhere, or regenerate them "
                         "in a git checkout of ema-bench")
    from ..monitor_bias import clean_bias
    from ..suites.v1 import instance_faults, instance_names

    names = list(instances or instance_names("all"))
    rows = {}
    for name in names:
        r = clean_bias(instance_faults(name), evals=evals)
        rows[name] = {"range_error": [float(v) for v in r["range_error"]],
                      "fitness_truth": float(r["fitness_truth"]),
                      "fitness_best": float(r["fitness_best"])}
    data = {"faults": list(FAULT_NAMES), "evals": evals, "instances": rows}
    Path(path).write_text(json.dumps(data, indent=1) + "\n")
    _biases.cache_clear()
    return data
