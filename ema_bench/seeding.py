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


def child(seed: SeedLike, i: int) -> np.random.SeedSequence:
    """The ``i``-th child of ``seed``, without mutating it (``SeedSequence.spawn`` counts its
    calls, so spawning twice from one object would give different streams)."""
    ss = as_seed_sequence(seed)
    return np.random.SeedSequence(ss.entropy, spawn_key=(*ss.spawn_key, int(i)),
                                  pool_size=ss.pool_size)


def children(seed: SeedLike, n: int) -> list[np.random.SeedSequence]:
    """The first ``n`` children of ``seed`` (the same as a first ``spawn(n)``)."""
    return [child(seed, i) for i in range(n)]
