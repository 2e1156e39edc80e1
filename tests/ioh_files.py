"""The IOHprofiler reader the export tests read back with: the package's format reader
(:func:`ema_bench.leaderboard.ioh.read_ioh`, which :func:`~ema_bench.leaderboard.ioh.optima`
uses; it parses the files alone, apart from the writer)."""

from ema_bench.leaderboard.ioh import read_ioh

__all__ = ["read_ioh"]
