"""One root seed, spawned to every random consumer with ``numpy.random.SeedSequence``."""

from __future__ import annotations

import numpy as np

SeedLike = int | np.random.SeedSequence | None


def as_seed_sequence(seed: SeedLike) -> np.random.SeedSequence:
    """The ``SeedSequence`` for ``seed`` (a child passes through unchanged)."""
    if isinstance(seed, np.random.SeedSequence):
        return seed
    if seed is not None and (isinstance(seed, bool) or int(seed) != seed or seed < 0):
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    return np.random.SeedSequence(seed)


def seed_repr(seed: SeedLike) -> int | dict | None:
    """JSON-friendly record of a seed, enough to recreate it."""
    if isinstance(seed, np.random.SeedSequence):
        return {"entropy": str(seed.entropy), "spawn_key": list(seed.spawn_key)}
    return None if seed is None else int(seed)
