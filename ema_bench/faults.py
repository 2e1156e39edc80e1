"""Fault parameters, the paper's damage cases, seeded random instances and optional effects.

The fault table is the paper's Table 1 (the project's design notes, section 3).  A fault
vector is always a ``float64`` array in ``FAULT_NAMES`` order, in physical units.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Fault:
    """One identifiable fault parameter."""

    name: str
    unit: str
    lower: float
    upper: float
    nominal: float
    description: str


FAULTS: tuple[Fault, ...] = (
    Fault("Na", "-", 0.8, 1.0, 1.0, "healthy fraction of phase-a turns (coil short circuit)"),
    Fault("Fst", "N m", 0.1689, 0.8445, 0.1689, "static dry-friction torque at the motor shaft"),
    Fault("BLK", "rad", 0.0, 0.04, 0.0, "total backlash of the reducer, surface side"),
    Fault("Gprop", "1/s", 5e4, 1.5e5, 1e5, "position-loop gain (control-gain drift)"),
)
FAULT_NAMES: tuple[str, ...] = tuple(f.name for f in FAULTS)
FAULT_UNITS: dict[str, str] = {f.name: f.unit for f in FAULTS}
FAULT_INDEX: dict[str, int] = {name: i for i, name in enumerate(FAULT_NAMES)}
N_FAULTS = len(FAULT_NAMES)
# positions in a fault vector, by name (the compiled models read the vector with these)
F_NA, F_FST, F_BLK, F_GPROP = (FAULT_INDEX[n] for n in ("Na", "Fst", "BLK", "Gprop"))
LOWER = np.array([f.lower for f in FAULTS])
UPPER = np.array([f.upper for f in FAULTS])
NOMINAL = np.array([f.nominal for f in FAULTS])
# direction in which each fault progresses from nominal (+1 up, -1 down, 0 either way)
_DAMAGE_DIRECTION = np.array([-1.0, 1.0, 1.0, 0.0])


class FaultError(ValueError):
    """A fault vector, name or case that cannot be used."""


@dataclass(frozen=True)
class Case:
    """A named damage case: true fault values and where they come from."""

    name: str
    faults: tuple[float, ...]
    description: str

    @property
    def x(self) -> np.ndarray:
        return np.array(self.faults, dtype=np.float64)


CASES: dict[str, Case] = {
    "nominal": Case("nominal", (1.0, 0.1689, 0.0, 1e5), "healthy actuator (paper Table 2)"),
    "small": Case("small", (0.95, 0.3378, 0.01, 1e5), "small progressive damage (paper Table 3)"),
    "full": Case("full", (0.8, 0.8445, 0.04, 1.5e5), "every fault at its bound (paper Table 4)"),
    "random": Case("random", (0.95, 0.6756, 0.01, 1.25e5), "paper's random case (Table 5)"),
}


def check_faults(x: np.ndarray | Mapping[str, float], *, batch: bool = False) -> np.ndarray:
    """Validate fault vector(s) and return them as a float64 array.

    Parameters
    ----------
    x : array_like or mapping
        Shape ``(4,)`` (or ``(n, 4)`` with ``batch=True``) in ``FAULT_NAMES`` order, physical
        units; or a mapping ``name -> value`` (missing names take their nominal value).
    batch : bool
        Accept and return a 2-D batch.

    Raises
    ------
    FaultError
        Wrong shape, non-finite entries, values outside the bounds, or unknown names.
    """
    if isinstance(x, Mapping):
        x = faults_from_mapping(x)
    arr = np.asarray(x, dtype=np.float64)
    if batch:
        if arr.ndim != 2 or arr.shape[1] != len(FAULTS):
            raise FaultError(f"expected a batch of shape (n, {len(FAULTS)}), got {arr.shape}")
    elif arr.shape != (len(FAULTS),):
        raise FaultError(f"expected a fault vector of shape ({len(FAULTS)},), got {arr.shape}")
    rows = arr.reshape(-1, len(FAULTS))

    def where(i: int) -> str:  # a row number means something only in a batch
        return f" in row {i}" if batch else ""

    bad = ~np.isfinite(rows)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise FaultError(f"fault {FAULT_NAMES[j]} is not finite ({rows[i, j]}){where(i)}")
    # a relative slack absorbs round-off from the [0,1] <-> physical mapping
    slack = 1e-9 * (UPPER - LOWER)
    out = (rows < LOWER - slack) | (rows > UPPER + slack)
    if out.any():
        i, j = np.argwhere(out)[0]
        f = FAULTS[j]
        raise FaultError(
            f"fault {f.name}={rows[i, j]:g} {f.unit}{where(i)} is outside its bounds "
            f"[{f.lower:g}, {f.upper:g}]"
        )
    return np.clip(arr, LOWER, UPPER)


def faults_from_mapping(values: Mapping[str, float]) -> np.ndarray:
    """Fault vector from ``name -> value``; names not given take their nominal value."""
    unknown = set(values) - set(FAULT_NAMES)
    if unknown:
        raise FaultError(f"unknown fault name(s) {sorted(unknown)}; known: {list(FAULT_NAMES)}")
    return np.array([float(values.get(n, f.nominal)) for n, f in zip(FAULT_NAMES, FAULTS)])


def faults_to_dict(x: np.ndarray) -> dict[str, float]:
    """``name -> value`` for one fault vector."""
    return {n: float(v) for n, v in zip(FAULT_NAMES, np.asarray(x, dtype=float))}


def get_case(name: str) -> Case:
    """The paper case called ``name`` (``nominal``, ``small``, ``full``, ``random``)."""
    try:
        return CASES[name]
    except KeyError:
        raise FaultError(f"unknown case {name!r}; known: {list(CASES)}") from None


def random_faults(
    seed: int | np.random.SeedSequence, heterogeneity: float = 1.0, n: int | None = None
) -> np.ndarray:
    """Seeded random fault vector(s) inside the bounds.

    Each fault moves from nominal towards its damaged bound by ``heterogeneity * u`` of the way,
    ``u ~ U(0, 1)``; the control gain, which can drift either way, picks a side at random.
    ``heterogeneity=0`` gives the nominal actuator, ``1`` spans the whole damaged range.

    Returns shape ``(4,)``, or ``(n, 4)`` when ``n`` is given.
    """
    if not 0.0 <= heterogeneity <= 1.0:
        raise FaultError(f"heterogeneity must lie in [0, 1], got {heterogeneity}")
    rng = np.random.default_rng(seed)
    m = 1 if n is None else int(n)
    u = rng.random((m, len(FAULTS)))
    side = np.where(rng.random((m, len(FAULTS))) < 0.5, -1.0, 1.0)
    direction = np.where(_DAMAGE_DIRECTION == 0.0, side, _DAMAGE_DIRECTION)
    bound = np.where(direction > 0, UPPER, LOWER)
    x = NOMINAL + heterogeneity * u * (bound - NOMINAL)
    x = np.clip(x, LOWER, UPPER)
    return x[0] if n is None else x


def to_unit(x: np.ndarray) -> np.ndarray:
    """Physical fault vector(s) -> normalised box [0, 1]^4."""
    return (np.asarray(x, dtype=float) - LOWER) / (UPPER - LOWER)


def from_unit(u: np.ndarray) -> np.ndarray:
    """Normalised box [0, 1]^4 -> physical fault vector(s)."""
    return LOWER + np.asarray(u, dtype=float) * (UPPER - LOWER)
