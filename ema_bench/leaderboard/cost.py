"""What a board cost: its runs' time summed, per tier, and the wall time on the cores it ran
on (the issue's "the board's cost stated: CPU-h, wall on 2 cores").

A record keeps its run's wall time (``wall_s``: the problem made, the solver run, the record
written; a failed run's until it failed) and the solver's own (``solver_wall_s``); no CPU time.
A run is one process with numba on one thread (the record's manifest), so its CPU time is at
most about its wall time: the summed run time is the board's CPU-h, an upper bound where the
machine was shared (a run waiting for the core counts).  Run ``cores`` at a time, the board
takes the summed run time over ``cores`` of wall time at least.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass

from ..suites import find

#: The cores a board is planned for (docs/suite-v3.md: "regeneration <= 12 h on 2 cores").
CORES = 2


@dataclass(frozen=True)
class BoardCost:
    """``runs``' summed wall time (``run_h``, hours), the solvers' share of it
    (``solver_h``), the same per tier (``by_tier``: tier -> (runs, run_h)), and the wall time
    of ``cores`` running side by side (``wall_h``)."""

    runs: int
    run_h: float
    solver_h: float
    by_tier: dict[int, tuple[int, float]]
    cores: int

    @property
    def wall_h(self) -> float:
        return self.run_h / self.cores


def _tier(case: str) -> int:
    inst = find(case)
    return inst.dim if inst is not None else 0


def board_cost(records: list[dict], cores: int = CORES) -> BoardCost:
    """The cost of ``records`` (failed runs included: they took their time too)."""
    by: dict[int, list[float]] = defaultdict(list)
    solver = []
    for r in records:
        by[_tier(str(r["case"]))].append(float(r.get("wall_s") or 0.0))
        solver.append(float(r.get("solver_wall_s") or 0.0))
    return BoardCost(len(records), math.fsum(math.fsum(v) for v in by.values()) / 3600,
                     math.fsum(solver) / 3600,
                     {t: (len(v), math.fsum(v) / 3600) for t, v in sorted(by.items())}, cores)


def cost_line(c: BoardCost) -> str:
    """One sentence for the report's header."""
    tiers = ", ".join(f"tier {t} {h:.2f} ({n} runs)" if t else f"other {h:.2f} ({n} runs)"
                      for t, (n, h) in c.by_tier.items())
    return (f"Cost: the {c.runs} runs took {c.run_h:.2f} h of run time in all ({tiers}; the "
            f"solvers' own share {c.solver_h:.2f} h): {c.run_h:.2f} CPU-h at most (a run is "
            f"one single-threaded process), {c.wall_h:.2f} h of wall time on {c.cores} cores "
            f"running {c.cores} at a time.")
