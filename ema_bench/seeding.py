"""One root seed, spawned to every random consumer with ``numpy.random.SeedSequence``.

The tree (the README has it as a table)::

    root seed R
    ├── run node  run_seed(R, k) = SeedSequence(R, spawn_key=(k,))      leaderboard row k
    │   ├── instance   child 0   random fault vector ("seeded" case)
    │   ├── noise      child 1   sensor noise, one child per test
    │   ├── solver     child 2   the solver's seed (derived by run_solver)
    │   ├── diagnosis  child 3   the missing-physics workflow on this run's traces
    │   │   ├── fit        child (4, round, candidate)   each fit (its solver: run_solver)
    │   │   └── bootstrap  child (5, round)              the bootstrap envelopes of a round
    │   ├── intervals  child 7   the parametric bootstrap of a fit's intervals
    │   └── acquisition child 8  a blind case's acquisition-chain decoy (channel, magnitude)
    └── plan  child 6 of R   the layout of a suite of runs (the blind suite's categories,
                             effects and magnitudes)

``make_problem(seed=node)`` draws the instance and the noise, ``run_solver(..., seed=node)``
gives the solver ``stream(node, "solver")``: disjoint from the problem's streams, but not
secret from the solver: a ``SeedSequence`` child carries its parent's entropy (the root seed)
and spawn key (the run number), so a solver can rebuild the node and draw the instance and
noise streams (a ``seeded`` case's truth) from it.  A one-way derivation is open work
(issue 48); replay does not catch a solver that does this.

``ema-bench solve --root-seed R --seed k`` builds the same node as the leaderboard's row
``k`` of root seed ``R``, so it replays that row bit for bit; the Gymnasium environment's
``reset(seed=k)`` (``root_seed=R``) plays the same problem.  Case ``k`` of
``ema-bench blind --seed R`` is run ``k`` of root ``R``: its traces are those of
``ema-bench simulate --root-seed R --seed k`` (a reference-model case; an acquisition decoy
is then applied with the draws of its ``acquisition`` stream) and its diagnosis that of
``ema-bench diagnose --root-seed R --seed k``.
"""

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


# --- the seed tree -------------------------------------------------------------------------
#: Named streams of a run node, each a fixed child index.  A run node is
#: ``run_seed(root_seed, seed)``; every random consumer of that run draws from one stream.
STREAMS: dict[str, int] = {
    "instance": 0,    # the fault vector of a random ("seeded") case
    "noise": 1,       # sensor noise of the measured traces (one child per test)
    "solver": 2,      # the solver (run_solver derives it: every solver, plugins included)
    "diagnosis": 3,   # the missing-physics workflow run on the traces of this run
    "fit": 4,         # (of a diagnosis) one fit, indexed by (round, candidate)
    "bootstrap": 5,   # (of a diagnosis) the bootstrap of a round, indexed by round
    "plan": 6,        # (of a root seed) the layout of a suite of runs
    "intervals": 7,   # the parametric bootstrap of a fit's intervals
    "acquisition": 8,  # (of a blind case's run) its acquisition-chain decoy's draws
}


def run_seed(root_seed: int, seed: int) -> np.random.SeedSequence:
    """The node of run ``seed`` under ``root_seed``: what ``ema-bench leaderboard`` runs as
    its row ``seed`` and ``ema-bench solve --root-seed R --seed k`` replays."""
    for name, v in (("root seed", root_seed), ("seed", seed)):
        if isinstance(v, bool) or int(v) != v or v < 0:
            raise ValueError(f"{name} must be a non-negative integer, got {v!r}")
    return np.random.SeedSequence(int(root_seed), spawn_key=(int(seed),))


def stream(seed: SeedLike, name: str, *index: int) -> np.random.SeedSequence:
    """The named stream (:data:`STREAMS`) of a node; ``index`` picks one member of an
    indexed family (``stream(node, "fit", round, k)``)."""
    if name not in STREAMS:
        raise KeyError(f"unknown seed stream {name!r}; known: {list(STREAMS)}")
    ss = child(seed, STREAMS[name])
    for i in index:
        ss = child(ss, i)
    return ss
