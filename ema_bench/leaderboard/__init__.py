"""Leaderboards: solvers x cases x tracks x seeds, scored COCO-style.

``tasks`` enumerates and seeds the runs, ``store`` keeps their records on disk (append-only
JSON lines, resumable), ``executors`` runs them (serial, processes, Dask), ``scores``
aggregates them, ``report`` writes tables, ``figures`` draws plots, ``check`` compares a run
against committed results.
"""
