"""The sweep engine under every long-running command: nothing lost, nothing run twice.

``store`` keeps records on disk (append-only JSON lines: lock, torn-tail repair, fsync),
``schema`` type-checks every line read back, ``claims`` splits tasks between processes
sharing a folder, ``executors`` runs tasks (serial, spawned processes, Dask; a dead worker
is survived) and ``loop`` is the one loop over them (:func:`~.loop.run_sweep`).  It imports
no consumer: the leaderboard, the blind suite, coverage, campaign tracking and the
best-known targets all run on it.
"""
