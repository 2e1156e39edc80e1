"""Registers the suite's plans in ``nevergrad.benchmark``'s experiment registry.

``python -m nevergrad.benchmark`` loads this file by path (``--imports``), so its imports are
absolute::

    python -m nevergrad.benchmark ema_bench_quick --cap_index 4 --seed 1 \\
        --imports "$(python -c 'import ema_bench.adapters.nevergrad_plan as m; print(m.__file__)')"

Each experiment's record is appended to ``$EMA_BENCH_RUNS`` (default
``ema_bench_runs.jsonl``); ``ema-bench validate`` checks them.  ``nevergrad.benchmark`` needs
torch, torchvision and OpenCV installed (it imports them at start-up).
"""

from __future__ import annotations

from collections.abc import Iterator

from nevergrad.benchmark import registry
from nevergrad.benchmark.xpbase import Experiment, create_seed_generator

from ema_bench.adapters.nevergrad import plan


def _experiments(name: str, seed: int | None) -> Iterator[Experiment]:
    seedg = create_seed_generator(seed)
    for func, optimizer, budget in plan(name):
        # the generator yields numpy.uint32, which random.seed refuses (nevergrad 1.0.12)
        seed_k = next(seedg)
        yield Experiment(func, optimizer, budget=budget, num_workers=1,
                         seed=None if seed_k is None else int(seed_k))


def ema_bench(seed: int | None = None) -> Iterator[Experiment]:
    """The suite's leaderboard sweep (plan ``full``)."""
    yield from _experiments("full", seed)


def ema_bench_quick(seed: int | None = None) -> Iterator[Experiment]:
    """A smoke run (plan ``quick``)."""
    yield from _experiments("quick", seed)


for _fn in (ema_bench, ema_bench_quick):
    if _fn.__name__ not in registry:
        registry.register(_fn)
