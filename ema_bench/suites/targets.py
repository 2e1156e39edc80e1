"""What every suite version shares: target levels, the best-known table's keys and file.

A suite's fixed targets rest on its best-known table (``ema-bench targets``' JSON):
``{"suite", "model_version", "entries": {"case|track|seed": {"f_star", "f_nominal",
"x_star", ..}}}``.  The fitness targets are the ladder ``f* + p (f_nominal - f*)``
(:data:`FITNESS_PRECISIONS`), the parameter targets the best-so-far point within a fraction
of every judged parameter's range (:data:`PARAMETER_TARGETS`).
"""

from __future__ import annotations

import json
import math
from importlib import resources
from importlib.resources.abc import Traversable

from ..trace_cache import MODEL_VERSION

#: The model version the shipped targets were computed on.
SUITE_MODEL_VERSION = "3"
#: Fitness targets: ``f* + p (f_nominal - f*)`` for each precision ``p``.
FITNESS_PRECISIONS: tuple[float, ...] = (1e-1, 1e-2, 1e-3, 1e-4)
#: Parameter targets: the best-so-far point within this fraction of every judged range.
PARAMETER_TARGETS: tuple[float, ...] = (0.1, 0.03, 0.01)
#: Checkpoints of the fixed-budget view (evaluations), up to the run's budget.
BUDGET_CHECKPOINTS: tuple[int, ...] = (10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000,
                                       20000, 50000, 100000)
#: The root seed of the runs whose ``f*`` the suites ship.
TARGET_ROOT_SEED = 0


class SuiteError(ValueError):
    """A suite instance, version or target file that cannot be used."""


def check_model_version(suite: str) -> None:
    """The suite's targets hold only on the models they were computed on."""
    if MODEL_VERSION != SUITE_MODEL_VERSION:
        raise SuiteError(f"suite {suite} was built on model version {SUITE_MODEL_VERSION}, "
                         f"the installed models are version {MODEL_VERSION}: bump the suite")


def target_key(case: str, track: str, seed: int) -> str:
    """The key of a best-known entry (``small|twin|3``)."""
    return f"{case}|{track}|{seed}"


def package_file(name: str) -> Traversable:
    """A data file shipped in the package (``ema_bench/<name>``)."""
    return resources.files("ema_bench").joinpath(name)


def read_targets(path: Traversable, suite: str, missing_ok: bool = True) -> dict:
    """A best-known table of ``suite`` on the installed model version; an empty ``entries``
    when the file is missing and ``missing_ok`` (a checkout before ``ema-bench targets``),
    else :class:`SuiteError`; SuiteError when it is labelled for another suite or model
    version."""
    name = getattr(path, "name", str(path))
    if not path.is_file():
        if missing_ok:
            return {"suite": suite, "model_version": SUITE_MODEL_VERSION, "entries": {}}
        raise SuiteError(f"{name}: no best-known table of suite {suite} there; compute it "
                         "with 'ema-bench targets'")
    data = json.loads(path.read_text())
    if data.get("suite") != suite or data.get("model_version") != SUITE_MODEL_VERSION:
        raise SuiteError(f"{name} is for suite {data.get('suite')!r} on model version "
                         f"{data.get('model_version')!r}, not {suite} on "
                         f"{SUITE_MODEL_VERSION}: regenerate it with 'ema-bench targets'")
    return data


def fitness_targets(f_star: float, f_nominal: float) -> list[float]:
    """The ladder ``f* + p (f_nominal - f*)`` for :data:`FITNESS_PRECISIONS`."""
    gap = f_nominal - f_star
    if not (math.isfinite(gap) and gap > 0):
        raise SuiteError(f"no fitness targets: f_nominal {f_nominal!r} is not above "
                         f"f* {f_star!r}")
    return [f_star + p * gap for p in FITNESS_PRECISIONS]


def precision_key(p: float) -> str:
    """The JSON key of a target level (``1e-3``, ``0.03``)."""
    return f"{p:g}"
