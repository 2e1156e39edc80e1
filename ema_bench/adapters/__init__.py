"""Adapters into the tools optimisation researchers already run: SciPy, pymoo, ioh, nevergrad.

Every adapter runs through one :class:`~ema_bench.adapters.run.AdapterRun`: the suite
instance's :class:`~ema_bench.problem.Problem` (its budget, its evaluation count, its log),
and the same run record ``ema-bench solve`` and the leaderboard write, so an adapter's runs
pass ``ema-bench validate`` and enter the board.  Each library is an optional extra
(``pip install "ema-bench[pymoo]"``, ``[ioh]``; SciPy and nevergrad are core dependencies) and
imported only by its own module.  docs/adapters.md shows each in use.
"""
