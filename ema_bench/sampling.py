"""Replay samples nobody can predict: drawn from fresh entropy, printed so a check repeats.

A replay sample drawn with a fixed seed over a file in file order tells a submitter which
records (or units) will be re-run: everything else can be forged with certainty.  Here the
sample's seed is fresh entropy (:func:`sample_seed`) unless a maintainer names one (a seed
committed before the submission, or the printed one, to repeat a check); the seed is part of
the output.  :func:`escape_chance` is the chance that ``forged`` forged items all stay
outside a uniform sample of ``k`` of ``n`` (hypergeometric), which holds only when the
sample is unpredictable.  Used by ``ema-bench validate --replay`` and ``ema-bench campaign
score --replay``.
"""

from __future__ import annotations

import math
import secrets

import numpy as np

#: Bits of a fresh sample seed: printed in full, small enough to type back.
SEED_BITS = 63


def sample_seed(seed: int | None = None) -> int:
    """``seed`` when given (to repeat a check), else a fresh one from the OS's entropy."""
    if seed is None:
        return secrets.randbits(SEED_BITS)
    if isinstance(seed, bool) or int(seed) != seed or seed < 0:
        raise ValueError(f"sample seed must be a non-negative integer, got {seed!r}")
    return int(seed)


def sample_indices(n: int, k: int | None, seed: int) -> list[int]:
    """``k`` of ``range(n)`` drawn without replacement with ``seed``, sorted (all for None
    or ``k >= n``)."""
    if k is None or k >= n:
        return list(range(n))
    pick = np.random.default_rng(np.random.SeedSequence(seed)).choice(n, size=k,
                                                                      replace=False)
    return sorted(int(i) for i in pick)


def escape_chance(n: int, k: int, forged: int = 1) -> float:
    """Chance that ``forged`` of ``n`` items all stay outside a uniform sample of ``k``
    (hypergeometric: ``C(n - forged, k) / C(n, k)``; 0 when the sample holds everything)."""
    if n <= 0:
        return 1.0
    k, forged = min(k, n), min(forged, n)
    return math.comb(n - forged, k) / math.comb(n, k)
