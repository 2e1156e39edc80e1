"""Nevergrad optimisers, batched ask/tell, in the normalised box [0, 1]^dim.

Each is built with ``budget`` and ``num_workers = 16``, so the optimiser expects 16 candidates
in flight: ask 16 (fewer at the end of the budget), evaluate them in one ``problem.evaluate``
call, tell each.  The parametrization is ``ng.p.Array(shape=(dim,))`` bounded to ``[0, 1]``
with its ``random_state`` seeded from the ``SeedSequence``; ``problem.start`` (the nominal
vector unless warm-started) is suggested as the first candidate.  Nevergrad's warnings (e.g.
about inefficient settings or large losses) are silenced inside the solver.

Compatibility: nevergrad 1.0.12's meta-model (used by ``NGOpt`` in low dimension) calls
``float()`` on a length-1 array, which NumPy >= 2.4 refuses with a ``TypeError`` (deprecated
since 1.25; facebookresearch/nevergrad#1612); the exception escapes ``ask()`` and leaves a
scipy-Powell helper thread blocked, so the interpreter hangs at exit.  While a solver here
runs, that module's ``float`` is one that accepts size-1 arrays (:func:`_metamodel_float_fix`).

* ``ngopt``: ``NGOpt``, nevergrad's algorithm selector (what it picks depends on the budget
  and the number of workers; it is named in ``extra["optimizer"]``).
* ``ng-de``: ``TwoPointsDE``.
* ``ng-pso``: ``RealSpacePSO``, particle swarm in the parametrization's own space.
  (Nevergrad's ``PSO`` flies in an arctan-warped space, so on a bounded array most of its
  moves land on the faces of the box: at budget 5000 it stalled 15-40 % of the range away
  from the truth on every damaged twin case.)
"""

from __future__ import annotations

import builtins
import contextlib
import time
from collections.abc import Iterator

import numpy as np

from ema_bench.registry import SolveResult, finish, register_solver

from ._common import child, evaluate_unit, global_numpy_rng, int_seed, quiet, start_unit

NUM_WORKERS = 16


def _float(value) -> float:
    """``float`` that also takes a size-1 array (as NumPy < 2.4 did)."""
    if isinstance(value, np.ndarray) and value.size == 1:
        return builtins.float(value.reshape(-1)[0])
    return builtins.float(value)


@contextlib.contextmanager
def _metamodel_float_fix() -> Iterator[None]:
    """Give nevergrad's meta-model module the size-1-tolerant ``float`` for the duration."""
    from nevergrad.optimization import metamodel

    if "float" in vars(metamodel):  # already patched (nested) or fixed upstream in some way
        yield
        return
    metamodel.float = _float
    try:
        yield
    finally:
        del metamodel.float


def solve(problem, budget: int, seed: np.random.SeedSequence, *, optimizer: str, name: str) \
        -> SolveResult:
    """Run the nevergrad ``optimizer`` (a name of its registry) on ``problem``, reported as
    solver ``name``."""
    import nevergrad as ng

    t0 = time.perf_counter()
    with global_numpy_rng(), _metamodel_float_fix(), \
            quiet(ng.errors.NevergradWarning, RuntimeWarning, UserWarning):
        # bounds at 3 sigma (sigma = 1/6), as nevergrad recommends
        param = ng.p.Array(shape=(problem.dim,), lower=0.0, upper=1.0)
        param.random_state = np.random.RandomState(int_seed(child(seed, 0)))
        opt = ng.optimizers.registry[optimizer](parametrization=param, budget=problem.remaining,
                                                num_workers=NUM_WORKERS)
        if problem.start is not None:   # without prior: nevergrad's own initialisation
            opt.suggest(start_unit(problem))
        while problem.remaining > 0:
            k = min(NUM_WORKERS, problem.remaining)
            cands = [opt.ask() for _ in range(k)]
            f = evaluate_unit(problem, np.array([c.value for c in cands]))
            for c, fi in zip(cands, f):
                try:
                    opt.tell(c, float(fi))
                except ng.errors.TellNotAskedNotSupportedError:
                    pass  # the suggested start: scored by the problem, unknown to the optimiser
    extra = {"optimizer": optimizer, "num_workers": NUM_WORKERS}
    if hasattr(opt, "optim"):  # NGOpt: the class it selected for this budget and dimension
        extra["selected"] = type(opt.optim).__name__
    return finish(problem, name, "budget", t0, libraries=("nevergrad",), **extra)


# configured variants of one function (run_solver passes the keywords)
for _name, _optimizer, _what in (("ngopt", "NGOpt", "NGOpt (algorithm selector)"),
                                 ("ng-de", "TwoPointsDE", "TwoPointsDE"),
                                 ("ng-pso", "RealSpacePSO", "RealSpacePSO (particle swarm)")):
    register_solver(_name, description=f"nevergrad {_what}, {NUM_WORKERS} workers",
                    library="nevergrad", scope="global", optimizer=_optimizer,
                    name=_name)(solve)
