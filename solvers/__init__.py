"""The built-in solver zoo.

Each module registers one or more solvers with :func:`ema_bench.registry.register_solver` and is
named in ema-bench's own ``[project.entry-points."ema_bench.solvers"]`` table, exactly as a
third-party solver package would be (see ``docs/writing-a-solver.md``).  Run one with
``ema_bench.run_solver(name, problem, seed=...)`` or ``ema-bench solve --solver NAME``; list
them with ``ema-bench solvers``.

Conventions shared by the zoo: search in the normalised box ``[0, 1]^4`` (``faults.to_unit`` /
``faults.from_unit``); evaluate whole populations in one ``problem.evaluate`` call; never ask
for more than ``problem.remaining``; derive every random number from the given
``SeedSequence``; return ``registry.finish(...)`` (the problem's own best and count).
"""
