"""Leaderboards: solvers x cases x tracks x seeds, scored COCO-style.

``tasks`` enumerates and seeds the runs, ``store`` names their records on disk (the sweep
engine's append-only JSON lines, :mod:`ema_bench.sweep`, which also runs them), ``scores``
aggregates them, ``report`` writes tables, ``figures`` draws plots, ``check`` compares a run
against committed results.
"""
