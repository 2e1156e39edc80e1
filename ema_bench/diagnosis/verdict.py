"""The verdict's rules: what counts as a discrepancy, how much of it a model closes, and
when a set of effects may be named.  Pure functions of numbers the workflow measured, so
each rule can be checked at its edge without fitting anything.

A discrepancy shows in one or both of two places:

* the **held-out test** (never fitted): its fitness against its bootstrap distribution
  (the fitted model plus sensor noise); a held-out fitness at or below the detection
  threshold is noise, never a gap;
* the **training residual statistics** outside their bootstrap envelopes; their *severity*
  is the sum of the robust z-scores of the statistics flagged.

A candidate model closes the held-out gap when there is one (it is the test the fits never
saw), the flagged statistics' severity otherwise (an effect that shows only in the training
residuals, e.g. a short delay).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Discrepancy:
    """Where a fitted model leaves the data (one assessment)."""

    holdout: float          # held-out fitness
    floor: float            # median bootstrap held-out fitness
    threshold: float        # held-out fitness the model plus noise reaches at worst
    severity: float         # sum of |z| of the training statistics outside the envelopes
    n_flagged: int

    @property
    def holdout_significant(self) -> bool:
        return self.holdout > self.threshold

    @property
    def detected(self) -> bool:
        """Something is missing: a statistic leaves its envelope *or* the held-out fitness
        exceeds its threshold (an effect may show only on the held-out test)."""
        return self.n_flagged > 0 or self.holdout_significant

    @property
    def gap(self) -> float:
        """Held-out fitness above the floor; zero when it lies inside the noise band."""
        return self.holdout - self.floor if self.holdout_significant else 0.0

    @property
    def noise_band(self) -> float:
        """What noise alone moves the held-out fitness by (threshold minus floor)."""
        return self.threshold - self.floor


def discrepancy(holdout: float, floor: float, threshold: float,
                flagged: Sequence[tuple[str, float, float]]) -> Discrepancy:
    """A :class:`Discrepancy` from an assessment's numbers; ``flagged`` holds
    ``(statistic, value, z)`` of the statistics outside their envelopes."""
    return Discrepancy(float(holdout), float(floor), float(threshold),
                       float(sum(abs(z) for _, _, z in flagged)), len(flagged))


def holdout_test(ho: float, boot_ho: np.ndarray, z_max: float) -> tuple[float, float, float]:
    """The held-out fitness ``ho`` against its bootstrap distribution ``boot_ho`` (the fitted
    model plus noise): median, robust z-score and the detection threshold (``z_max`` robust
    spreads above the median, and never below the largest bootstrap value)."""
    med = float(np.median(boot_ho))
    spread = max(1.4826 * float(np.median(np.abs(boot_ho - med))), 0.5 * float(boot_ho.std()),
                 1e-12)
    return med, float((ho - med) / spread), max(med + z_max * spread, float(boot_ho.max()))


def closed_share(before: float, after: float, floor: float) -> float:
    """Share of the held-out gap above ``floor`` that a model closes (at most 1; with no gap
    to close, 1 if the held-out fit did not get worse, else 0)."""
    gap = before - floor
    if gap <= 0.0:
        return 1.0 if after <= before else 0.0
    return min((before - after) / gap, 1.0)


def closure(base: Discrepancy, after: Discrepancy) -> tuple[str, float]:
    """Which discrepancy a model is judged on, and the share of it that it closes.

    ``("held-out", share)`` when the base model's held-out fitness exceeds its threshold,
    ``("statistics", share)`` when only training statistics left their envelopes (the
    share of their severity gone), ``("none", 1.0)`` when the base model was not
    detected at all."""
    if base.holdout_significant:
        return "held-out", closed_share(base.holdout, after.holdout, base.floor)
    if base.severity > 0.0:
        return "statistics", max(1.0 - after.severity / base.severity, 0.0)
    return "none", 1.0


def acceptance_reasons(*, base: Discrepancy, after: Discrepancy, fit_before: float,
                       fit_after: float, values: dict[str, float],
                       trivial: dict[str, float],
                       intervals: dict[str, tuple[float, float]] | None,
                       accept_closed: float) -> list[str]:
    """Why a candidate set of effects is *not* accepted (empty: accepted).

    ``base``/``after``: the discrepancy of the model before and with the candidate (each
    assessed against its own bootstrap); ``fit_before``/``fit_after``: training fitness;
    ``values``: the fitted effects, each outside its ``+-trivial`` band; ``intervals``:
    their 95 % intervals, each excluding zero (``None``: not computed yet, no reason)."""
    reasons = []
    where, closed = closure(base, after)
    if closed < accept_closed:
        reasons.append(f"closes {100 * closed:.0f} % of the {where} discrepancy "
                       f"(< {100 * accept_closed:.0f} %)")
    elif where == "held-out" and base.holdout - after.holdout <= base.noise_band:
        # the improvement must beat what noise alone moves the held-out fitness
        reasons.append("held-out improvement within the bootstrap spread")
    elif where == "statistics" and after.holdout > base.threshold:
        reasons.append("makes the held-out fit worse than noise allows")
    if fit_after >= fit_before:
        reasons.append("does not improve the training fit")
    for name, v in values.items():
        if abs(v) <= trivial[name]:
            reasons.append(f"{name} {v:.3g} inside its trivial band +-{trivial[name]:g}")
    for name, (lo, hi) in (intervals or {}).items():
        if lo <= 0.0 <= hi:
            reasons.append(f"{name}: interval includes zero")
    return reasons


def parsimony_reasons(closed: float, sub_closed: dict[str, float], penalty: float,
                      holdout: float | None = None, sub_holdout: dict[str, float] | None = None,
                      noise_band: float = 0.0) -> list[str]:
    """The price of every added parameter: a set of effects must close at least ``penalty``
    more of the discrepancy than each of its subsets one effect smaller that was fitted
    (``sub_closed``, by the subset's name), and, judged on the held-out test, improve its
    fitness by more than the noise band over each (``holdout``, ``sub_holdout``).  Noise
    and decoys then cannot buy a second name."""
    reasons = []
    for name, c in sub_closed.items():
        if closed - c < penalty:
            reasons.append(f"adds {100 * (closed - c):.0f} % over {name} "
                           f"(< {100 * penalty:.0f} % per added effect)")
        elif holdout is not None and sub_holdout is not None and \
                sub_holdout[name] - holdout <= noise_band:
            reasons.append(f"held-out improvement over {name} within the bootstrap spread")
    return reasons


def penalised(closed: float, size: int, penalty: float) -> float:
    """The ranking score of an accepted set: share closed less ``penalty`` per effect
    beyond the first (the smaller set wins a tie)."""
    return closed - penalty * (size - 1)
