"""One root seed, spawned to every random consumer with ``numpy.random.SeedSequence``.

The tree (the README has it as a table)::

    root seed R
    ├── run node  run_seed(R, k) = SeedSequence(R, spawn_key=(k,))      leaderboard row k
    │   ├── instance   child 0   random fault vector ("seeded" case)
    │   ├── noise      child 1   sensor noise, one child per test
    │   ├── solver     one_way(node, "solver")   the solver's (and a tracker's) seed: a hash
    │   │                                         of the node, not a child (run_solver)
    │   ├── diagnosis  child 3   the missing-physics workflow on this run's traces
    │   │   ├── fit        child (4, round, candidate)   each fit (its solver: run_solver)
    │   │   └── bootstrap  child (5, round)              the bootstrap envelopes of a round
    │   ├── intervals  child 7   the parametric bootstrap of a fit's intervals
    │   └── acquisition child 8  a blind case's acquisition-chain decoy (channel, magnitude)
    └── plan  child 6 of R   the layout of a suite of runs (the blind suite's categories,
                             effects and magnitudes)

``make_problem(seed=node)`` draws the instance and the noise from the node's streams.  Code
that is not the package's own (a solver, a tracker: a plugin) never gets a stream of the node:
``run_solver(..., seed=node)`` gives the solver :func:`solver_seed` ``(node)``, a
``SeedSequence`` whose entropy is a SHA-256 hash of the node's entropy and spawn key
(:func:`one_way`), with no spawn key.  A child carries its parent's entropy (the root seed)
and spawn key (the run number), so a spawned stream would let a solver rebuild the node and
draw the instance and noise streams (a ``seeded`` case's truth) from it; the hash cannot be
walked back, and it is reproducible, so replay gives the solver the same seed.  What it does
not hide is a node anyone can name: with a public root seed (0, the committed boards') a
solver may hash the nodes ``(R, k)`` of small ``R`` and ``k`` until one matches and learn its
run number, which a public suite publishes anyway; a suite or campaign that hides its
instances needs a secret root seed drawn from a large space (``secrets.randbits(63)``).

Seed schemes (:data:`SEED_SCHEMES`): records and tracking runs carry ``seed_scheme``
(:data:`SEED_SCHEME`, 2, the hash); 1 (absent in a file) is the earlier spawn, which made the
committed boards and campaigns: their replay derives the seeds that way, and
:mod:`ema_bench.grandfather` accepts scheme 1 for their records only.  The shipped
calibration tables and the committed blind suites were made under scheme 1 too (the
diagnosis's ``Settings(seed_scheme=1)`` reproduces them).

``ema-bench solve --root-seed R --seed k`` builds the same node as the leaderboard's row
``k`` of root seed ``R``, so it replays that row bit for bit; the Gymnasium environment's
``reset(seed=k)`` (``root_seed=R``) plays the same problem.  Case ``k`` of
``ema-bench blind --seed R`` is run ``k`` of root ``R``: its traces are those of
``ema-bench simulate --root-seed R --seed k`` (a reference-model case; an acquisition decoy
is then applied with the draws of its ``acquisition`` stream) and its diagnosis that of
``ema-bench diagnose --root-seed R --seed k``.
"""

from __future__ import annotations

import hashlib
import json

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
    "solver": 2,      # seed scheme 1 only (the committed boards): the solver's spawned stream
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


# --- what code outside the package gets: one-way seeds ---------------------------------------
#: The seed schemes of a solver's (and a tracker's) seed, by the number records carry.
SEED_SCHEMES: dict[int, str] = {
    1: "spawn: the node's 'solver' stream, a child that carries the root seed and run number "
       "(the committed boards and campaigns only)",
    2: "hash: SHA-256 of the node's entropy and spawn key, which gives nothing of the node away",
}
#: The scheme of every new run.
SEED_SCHEME = 2


def one_way(seed: SeedLike, name: str) -> np.random.SeedSequence:
    """A ``SeedSequence`` derived from the node ``seed`` by a hash: its entropy is the SHA-256
    of the node's entropy, spawn key and pool size and ``name``, and it has no spawn key, so
    whoever holds it cannot rebuild the node or draw any of its streams (:func:`stream`).
    The same node and name give the same seed."""
    ss = as_seed_sequence(seed)
    entropy = ss.entropy if isinstance(ss.entropy, int) else [int(e) for e in ss.entropy]
    text = json.dumps(["ema-bench one-way seed", name, entropy,
                       [int(k) for k in ss.spawn_key], int(ss.pool_size)])
    return np.random.SeedSequence(int.from_bytes(hashlib.sha256(text.encode()).digest(), "big"))


def solver_seed(node: SeedLike, scheme: int = SEED_SCHEME) -> np.random.SeedSequence:
    """The seed a solver (or a tracker) is given at run node ``node``: :func:`one_way`
    ``(node, "solver")`` in scheme 2, the spawned ``stream(node, "solver")`` in scheme 1
    (to replay the committed records made with it)."""
    if scheme == 2:
        return one_way(node, "solver")
    if scheme == 1:
        return stream(node, "solver")
    raise ValueError(f"unknown seed scheme {scheme!r}; known: {sorted(SEED_SCHEMES)}")
