"""Degradation laws: how a unit's faults grow over flights, and when it reaches end of life.

Time is counted in flights.  A unit's hidden truth is ``faults[f]``, its fault vector after
``f`` flights (``f = 0``: a new unit), in :data:`~ema_bench.faults.FAULT_NAMES` order
(``Na, Fst, BLK, Gprop``) and physical units.  Each law below is a pure function of a
``numpy.random.Generator`` and the per-flight duty (flight ``f`` has duty ``duty[f - 1]``),
returning the fault at every flight ``0 .. n``.  Fleet variability comes from the unit-level
parameters :func:`draw_unit` draws from :class:`FleetLaws`.

Duty
    A dimensionless load x travel index of a flight, 1 for a standard flight: Gamma with
    shape ``duty_shape`` around the unit's mean duty (log-normal over the fleet: some
    operators fly longer or rougher sectors).
Friction ``Fst`` (N m)
    Monotone gamma process (van Noortwijk 2009, the usual law of monotone wear):
    increments ``Gamma(shape = fst_shape * duty, scale = rate / fst_shape)``, so the mean
    growth is ``rate * duty`` per flight and its coefficient of variation over ``n`` standard
    flights is ``1 / sqrt(fst_shape * n)``.
Backlash ``BLK`` (rad)
    Archard-type wear, proportional to load x travel: ``rate * duty`` per flight, plus rare
    jumps (a tooth chip, a bearing that lets go): a compound Poisson process with
    ``Poisson(jump_rate * duty)`` jumps per flight of exponential size, mean ``jump_mean``.
Coil short ``Na`` (-)
    Healthy (``Na = 1``) until a random onset flight (exponential, mean ``na_onset_mean``);
    then a first short of ``na_initial_short`` of the turns that spreads as the circulating
    current in the shorted loop heats the insulation next to it: the shorted share grows by
    ``exp(growth * duty * eps)`` per flight (``eps ~ Gamma(k, 1/k)``, mean 1), an accelerating
    (exponential) turn loss.
Gain ``Gprop`` (1/s)
    Random walk of the position-loop gain (component ageing, not wear), reflected at the fault
    box bounds: no end of life.  Units of the "gain drift only" kind have this law and no
    other, so a tracker that calls for their replacement raises a false alarm.

Operating conditions (per flight; logged by the operator at each inspection) switch on two
library effects (:mod:`ema_bench.effects`) in the inspection's model, as confounders:

* the winding temperature raises the winding resistance, ``R(T) = R20 (1 + alpha (T - 20))``
  with copper's ``alpha = 0.00393 1/K`` at 20 degC (the International Annealed Copper
  Standard, IEC 60028) -> ``resistance_rise = alpha (T_w - 20)``, clipped to the effect's
  bounds ``[0, 0.6]`` (a cold winding's lower resistance is not representable and is dropped;
  the effect is unobservable while the current loop has voltage headroom anyway);
* cold grease in the reducer adds viscous friction at the motor: grease viscosity roughly
  doubles every 20 K of cooling (Andrade/Arrhenius law, ``exp(k (20 - T))`` with
  ``k = ln 2 / 20 1/K``), so ``viscous_friction = c_ref (exp(k (20 - T_amb)) - 1)`` below
  20 degC and 0 above; with ``c_ref = 2e-5 N m s/rad`` it is 6e-5 N m s/rad at -20 degC, about
  the effect's detection level (5e-5), small against its bound (2e-3).

End of life (EOL) is the first flight at which any fault crosses its threshold
(:data:`THRESHOLDS`); the fault that crossed is the failing fault.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ..effects import EFFECT_INDEX, EFFECTS, N_EFFECTS
from ..faults import F_BLK, F_FST, F_GPROP, F_NA, FAULT_INDEX, LOWER, N_FAULTS, NOMINAL, UPPER
from ..seeding import child

#: Copper's temperature coefficient of resistance at 20 degC, 1/K (IACS, IEC 60028).
COPPER_ALPHA = 0.00393

#: Failure thresholds per failing fault, physical units; each lies 75 % of the way from
#: nominal to the paper's 'full damage' bound (its Table 1), strictly inside the fault box so
#: that a fitted estimate (and its interval) can cross it.
#:
#: ``Fst`` 0.6756 N m (4 x nominal, the paper's 'random' case): the motor must hold the surface
#: at its end stop (0.45 rad) against the hinge-moment spring (800 N m/rad): 360 N m at the
#: surface, 1.2 N m at the motor through the 1/300 reducer.  With the 2 N m torque limit, a
#: static friction of 0.6756 N m leaves 0.12 N m (6 %) for accelerating the surface and for
#: gusts: beyond it the actuator stalls short of full deflection under load.
#:
#: ``BLK`` 0.03 rad (1.7 deg of total free play at the surface): 10-12 % of the standard tests'
#: amplitudes (0.3 rad step, 0.25 rad sine), where the position loop's dead band makes it hunt.
#: Airworthiness free-play limits for flutter (MIL-A-8870C) are far tighter than the paper's
#: box (which reaches 2.3 deg); this threshold is a benchmark convention on the paper's scale.
#:
#: ``Na`` 0.85 (15 % of phase a's turns shorted): the averaged torque constant
#: ``2 Ke (Na + 2) / 3`` has lost 5 % and the drive no longer holds its rated torque at the
#: current limit; an inter-turn short also heats its neighbours, and past this share it runs
#: on quickly to a phase-to-phase or phase-to-ground failure.  The paper's 'full damage' is
#: 0.8 (20 %).
#:
#: ``Gprop`` has no threshold: a drifting gain is retuned, not replaced.
THRESHOLDS: dict[str, float] = {"Na": 0.85, "Fst": 0.6756, "BLK": 0.03}

#: Direction of damage of each failing fault: +1 fails upwards, -1 downwards.
DAMAGE_SIGN: dict[str, int] = {"Na": -1, "Fst": 1, "BLK": 1}

#: Grease viscosity e-folding constant, 1/K: viscosity doubles every 20 K of cooling.
GREASE_K = math.log(2.0) / 20.0


@dataclass(frozen=True)
class FleetLaws:
    """Fleet-level parameters of the degradation laws (the manifest's ``laws``).

    Unit-level parameters are drawn from these by :func:`draw_unit`; rates are log-normal
    (median, log-standard-deviation ``sigma``).  Units: flights, N m, rad, 1/s, degC.
    """

    max_flights: int = 3000          # flights simulated per unit (life is typically 150-600)
    # duty (dimensionless, 1 = a standard flight)
    duty_unit_sigma: float = 0.25    # log-sd of a unit's mean duty over the fleet
    duty_shape: float = 4.0          # gamma shape of one flight's duty (CV 0.5)
    # friction Fst: gamma process
    fst_initial_spread: float = 0.1  # new unit: nominal x U(1, 1 + spread)
    fst_rate_median: float = 1.15e-3  # N m per unit duty
    fst_rate_sigma: float = 0.45
    fst_shape: float = 0.5           # gamma shape per unit duty
    # backlash BLK: wear + compound Poisson jumps
    blk_initial_max: float = 0.002   # rad, new unit: U(0, max) of assembly free play
    blk_rate_median: float = 4.6e-5  # rad per unit duty
    blk_rate_sigma: float = 0.45
    blk_jump_rate: float = 0.007     # jumps per unit duty
    blk_jump_mean: float = 0.0025    # rad, exponential jump size
    # coil short Na: random onset, then exponential turn loss
    na_onset_mean: float = 600.0     # flights, exponential onset time
    na_initial_short: float = 0.01   # shorted share of turns at onset
    na_growth_median: float = 0.022  # per unit duty: e-folding of the shorted share
    na_growth_sigma: float = 0.4
    na_growth_shape: float = 4.0     # gamma shape of the per-flight growth noise
    # gain Gprop: reflected random walk
    gprop_initial_sd: float = 3e3    # 1/s, new unit: N(nominal, sd)
    gprop_step_sd: float = 1.2e3     # 1/s per flight
    # operating conditions (confounders)
    climate_mean: tuple[float, float] = (0.0, 25.0)  # degC, a unit's base: U(lo, hi)
    season_amplitude: float = 10.0   # K
    season_flights: float = 700.0    # flights per year (about two a day)
    weather_sd: float = 6.0          # K, flight-to-flight scatter of the ambient
    self_heating: tuple[float, float] = (0.0, 60.0)  # K above ambient at inspection: U(lo, hi)
    viscous_ref: float = 2e-5        # N m s/rad, c_ref of the cold-grease law

    def to_dict(self) -> dict:
        """JSON-friendly copy (tuples as lists)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}


@dataclass(frozen=True)
class UnitParams:
    """One unit's draws from :class:`FleetLaws` (hidden truth)."""

    mean_duty: float
    fst_initial: float
    fst_rate: float
    blk_initial: float
    blk_rate: float
    na_onset: int
    na_growth: float
    gprop_initial: float
    climate: float
    season_phase: float

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class UnitHistory:
    """A unit's simulated life.

    Attributes
    ----------
    faults : ndarray (n + 1, 4)
        True faults after each flight, physical units (not clipped: a fault may pass its
        box bound after end of life).
    duty : ndarray (n,)
        Duty of flights ``1 .. n``.
    ambient, winding : ndarray (n + 1,)
        Ambient and winding temperature (degC) at an inspection after each flight.
    eol : int or None
        End-of-life flight; None when no fault crosses its threshold (gain drift only, or
        no failure within ``max_flights``).
    failing_fault : str or None
    horizon : int
        Flights the unit is followed for: its EOL, or for a unit that never fails the flight
        at which its wear laws would have failed it (so its record is as long as a typical
        life and its length gives nothing away), else ``max_flights``.
    """

    params: UnitParams
    wear: bool
    faults: np.ndarray
    duty: np.ndarray
    ambient: np.ndarray
    winding: np.ndarray
    eol: int | None
    failing_fault: str | None
    horizon: int
    laws: FleetLaws

    def effects(self, flight: int) -> np.ndarray:
        """Effects vector switched on at an inspection after ``flight`` flights."""
        return confounders(self.ambient[flight], self.winding[flight], self.laws.viscous_ref)

    @property
    def kind(self) -> list[str]:
        """Faults that degrade in this unit's laws."""
        return ["Na", "Fst", "BLK", "Gprop"] if self.wear else ["Gprop"]


# --- the laws --------------------------------------------------------------------------------

def flight_duty(rng: np.random.Generator, n: int, mean: float, shape: float) -> np.ndarray:
    """Duty of ``n`` flights: ``Gamma(shape, mean / shape)`` each (dimensionless)."""
    return rng.gamma(shape, mean / shape, size=n)


def friction_path(rng: np.random.Generator, duty: np.ndarray, initial: float, rate: float,
                  shape: float) -> np.ndarray:
    """Static friction ``Fst`` (N m) at flights ``0 .. n``: a gamma process in duty.

    Increments ``Gamma(shape * duty, rate / shape)``: mean ``rate * duty`` (N m per flight),
    never negative, so the path is non-decreasing.
    """
    inc = rng.gamma(shape * duty, rate / shape)
    return initial + np.concatenate([[0.0], np.cumsum(inc)])


def backlash_path(rng: np.random.Generator, duty: np.ndarray, initial: float, rate: float,
                  jump_rate: float, jump_mean: float) -> np.ndarray:
    """Backlash ``BLK`` (rad) at flights ``0 .. n``: wear ``rate * duty`` plus compound
    Poisson jumps (``Poisson(jump_rate * duty)`` per flight, exponential sizes of mean
    ``jump_mean``); non-decreasing."""
    jumps = rng.poisson(jump_rate * duty)
    # the sum of k exponential sizes is Gamma(k, mean); k = 0 gives no jump
    size = np.where(jumps > 0, rng.gamma(np.maximum(jumps, 1), jump_mean), 0.0)
    return initial + np.concatenate([[0.0], np.cumsum(rate * duty + size)])


def coil_path(rng: np.random.Generator, duty: np.ndarray, onset: int, initial_short: float,
              growth: float, noise_shape: float) -> np.ndarray:
    """Healthy turn fraction ``Na`` (-) at flights ``0 .. n``: 1 before ``onset``, then
    ``1 - s`` with the shorted share ``s`` starting at ``initial_short`` and multiplied by
    ``exp(growth * duty * eps)`` each flight (``eps ~ Gamma(k, 1/k)``); non-increasing."""
    n = duty.size
    eps = rng.gamma(noise_shape, 1.0 / noise_shape, size=n)
    log_s = np.full(n + 1, -np.inf)
    if onset <= n:
        steps = growth * duty[onset:] * eps[onset:]  # flights onset+1 .. n
        log_s[onset:] = math.log(initial_short) + np.concatenate([[0.0], np.cumsum(steps)])
    return 1.0 - np.minimum(np.exp(log_s), 1.0)


def gain_path(rng: np.random.Generator, n: int, initial: float, step_sd: float,
              lower: float, upper: float) -> np.ndarray:
    """Position-loop gain ``Gprop`` (1/s) at flights ``0 .. n``: a Gaussian random walk
    reflected into ``[lower, upper]`` (no end of life)."""
    walk = initial + np.concatenate([[0.0], np.cumsum(rng.normal(0.0, step_sd, size=n))])
    span = upper - lower
    # reflection: fold the free walk back into the box (period 2 * span)
    y = np.mod(walk - lower, 2.0 * span)
    return lower + np.where(y > span, 2.0 * span - y, y)


def ambient_temperature(rng: np.random.Generator, n: int, climate: float, amplitude: float,
                        period: float, phase: float, sd: float) -> np.ndarray:
    """Ambient temperature (degC) at flights ``0 .. n``: the unit's climate, a seasonal
    sine and flight-to-flight weather scatter."""
    f = np.arange(n + 1)
    season = amplitude * np.sin(2.0 * np.pi * (f / period + phase))
    return climate + season + rng.normal(0.0, sd, size=n + 1)


def resistance_rise(t_winding: float | np.ndarray) -> float | np.ndarray:
    """``resistance_rise`` effect of a winding at ``t_winding`` degC: ``alpha (T - 20)``
    (copper, IEC 60028), clipped to the effect's bounds."""
    spec = EFFECTS[EFFECT_INDEX["resistance_rise"]]
    return np.clip(COPPER_ALPHA * (np.asarray(t_winding) - 20.0), spec.lower, spec.upper)


def cold_viscous_friction(t_grease: float | np.ndarray, c_ref: float) -> float | np.ndarray:
    """``viscous_friction`` effect (N m s/rad) of reducer grease at ``t_grease`` degC:
    ``c_ref (exp(k (20 - T)) - 1)`` below 20 degC, 0 above (viscosity doubles per 20 K)."""
    spec = EFFECTS[EFFECT_INDEX["viscous_friction"]]
    c = c_ref * np.expm1(GREASE_K * np.maximum(20.0 - np.asarray(t_grease), 0.0))
    return np.clip(c, spec.lower, spec.upper)


def confounders(t_ambient: float, t_winding: float, c_ref: float) -> np.ndarray:
    """Effects vector of an inspection at these temperatures (degC): resistance rise from
    the winding, viscous friction from the grease (at ambient)."""
    e = np.zeros(N_EFFECTS)
    e[EFFECT_INDEX["resistance_rise"]] = resistance_rise(t_winding)
    e[EFFECT_INDEX["viscous_friction"]] = cold_viscous_friction(t_ambient, c_ref)
    return e


# --- thresholds and end of life --------------------------------------------------------------

def crossed(name: str, value: float | np.ndarray) -> bool | np.ndarray:
    """Whether ``value`` of fault ``name`` is at or past its failure threshold."""
    thr = THRESHOLDS[name]
    return value >= thr if DAMAGE_SIGN[name] > 0 else value <= thr


def end_of_life(faults: np.ndarray,
                thresholds: dict[str, float] | None = None) -> tuple[int | None, str | None]:
    """First flight at which any fault crosses its threshold, and which fault.

    Parameters
    ----------
    faults : ndarray (n + 1, 4)
        Fault path, physical units.
    thresholds : dict, optional
        Default :data:`THRESHOLDS`.

    Returns
    -------
    (eol, failing_fault), or ``(None, None)`` when no threshold is crossed.  Two faults
    crossing at the same flight: the one further past its threshold (share of its range).
    """
    thresholds = THRESHOLDS if thresholds is None else thresholds
    best: tuple[int, float, str] | None = None
    for name, thr in thresholds.items():
        j = FAULT_INDEX[name]
        past = DAMAGE_SIGN[name] * (faults[:, j] - thr)
        hit = np.flatnonzero(past >= 0.0)
        if hit.size:
            f = int(hit[0])
            key = (f, -past[f] / (UPPER[j] - LOWER[j]), name)
            best = key if best is None or key < best else best
    return (None, None) if best is None else (best[0], best[2])


# --- one unit --------------------------------------------------------------------------------

def draw_unit(rng: np.random.Generator, laws: FleetLaws) -> UnitParams:
    """A unit's parameters, drawn from the fleet's distributions."""
    def lognormal(median: float, sigma: float) -> float:
        return float(median * math.exp(sigma * rng.standard_normal()))

    return UnitParams(
        mean_duty=lognormal(1.0, laws.duty_unit_sigma),
        fst_initial=float(NOMINAL[F_FST] * (1.0 + laws.fst_initial_spread * rng.random())),
        fst_rate=lognormal(laws.fst_rate_median, laws.fst_rate_sigma),
        blk_initial=float(laws.blk_initial_max * rng.random()),
        blk_rate=lognormal(laws.blk_rate_median, laws.blk_rate_sigma),
        na_onset=int(math.ceil(rng.exponential(laws.na_onset_mean))),
        na_growth=lognormal(laws.na_growth_median, laws.na_growth_sigma),
        gprop_initial=float(np.clip(rng.normal(NOMINAL[F_GPROP], laws.gprop_initial_sd),
                                    LOWER[F_GPROP], UPPER[F_GPROP])),
        climate=float(rng.uniform(*laws.climate_mean)),
        season_phase=float(rng.random()),
    )


def unit_history(seed: np.random.SeedSequence, laws: FleetLaws, *,
                 wear: bool = True) -> UnitHistory:
    """Simulate one unit's life from its seed (one child per law, so each law's draws do not
    shift when another law changes).

    Parameters
    ----------
    seed : SeedSequence
        The unit's law stream.
    laws : FleetLaws
    wear : bool
        False: gain drift only (friction, backlash and coil stay at the new unit's values).
    """
    rng = [np.random.default_rng(child(seed, i)) for i in range(7)]
    p = draw_unit(rng[0], laws)
    n = laws.max_flights
    duty = flight_duty(rng[1], n, p.mean_duty, laws.duty_shape)
    worn = np.empty((n + 1, N_FAULTS))
    worn[:, F_FST] = friction_path(rng[2], duty, p.fst_initial, p.fst_rate, laws.fst_shape)
    worn[:, F_BLK] = backlash_path(rng[3], duty, p.blk_initial, p.blk_rate,
                                   laws.blk_jump_rate, laws.blk_jump_mean)
    worn[:, F_NA] = coil_path(rng[4], duty, p.na_onset, laws.na_initial_short, p.na_growth,
                              laws.na_growth_shape)
    worn[:, F_GPROP] = gain_path(rng[5], n, p.gprop_initial, laws.gprop_step_sd,
                                 LOWER[F_GPROP], UPPER[F_GPROP])
    ambient = ambient_temperature(rng[6], n, p.climate, laws.season_amplitude,
                                  laws.season_flights, p.season_phase, laws.weather_sd)
    winding = ambient + rng[6].uniform(*laws.self_heating, size=n + 1)
    would_fail, fault = end_of_life(worn)
    horizon = n if would_fail is None else would_fail
    if wear:
        faults, eol = worn, would_fail
    else:
        faults = worn.copy()
        faults[:, F_NA] = worn[0, F_NA]
        faults[:, F_FST] = worn[0, F_FST]
        faults[:, F_BLK] = worn[0, F_BLK]
        eol, fault = None, None
    return UnitHistory(params=p, wear=wear, faults=faults, duty=duty, ambient=ambient,
                       winding=winding, eol=eol, failing_fault=fault, horizon=horizon,
                       laws=laws)


# --- the laws run forward, many futures at once ----------------------------------------------

class ForwardPaths:
    """Monte Carlo futures of one unit: the laws above run forward over ``n`` paths at once,
    in blocks of flights (what a law-aware tracker predicts with, and the oracle bound of
    :func:`~ema_bench.prognostics.oracle.oracle_predictions`).

    Parameters
    ----------
    rng : Generator
    x0 : ndarray (n, 4)
        Faults of every path now, physical units.
    rates : dict
        Per path (n,): ``Fst`` (N m per unit duty), ``BLK`` (rad per unit duty), ``Na`` (coil
        short growth per unit duty); a fault without a rate stays where it is.
    laws : dict
        :meth:`FleetLaws.to_dict` (shapes, jump rate and size, onset mean, initial short).
    mean_duty : float or ndarray (n,)
        The unit's mean duty per flight (or each path's).
    coil_present : ndarray (n,) of bool
        Whether a coil short has begun on each path (else it begins at the law's memoryless
        hazard, at the law's initial share).

    Per block of ``dt`` flights: the total duty ``Gamma(k dt, m / k)`` (a sum of the flights'
    gamma duties), friction's gamma increment over it, backlash's wear and compound Poisson
    jumps over it, the coil's onset with probability ``1 - exp(-dt / onset_mean)`` and its
    growth ``exp(g U eps)`` (``eps ~ Gamma(k_e dt, 1 / (k_e dt))``, the block's mean of the
    flights' noise).  Exact for friction and backlash; the coil's noise is pooled per block.
    """

    def __init__(self, rng: np.random.Generator, x0: np.ndarray, rates: dict[str, np.ndarray],
                 laws: dict, mean_duty: float | np.ndarray, coil_present: np.ndarray) -> None:
        self.rng, self.laws, self.m = rng, laws, np.asarray(mean_duty, dtype=float)
        self.x = np.array(x0, dtype=float)
        self.n = self.x.shape[0]
        self.rate = rates
        self.onset = np.array(coil_present, dtype=bool)
        s = 1.0 - self.x[:, F_NA]
        # a path without a short yet starts one at the law's initial share
        self.log_s = np.log(np.where(self.onset, np.maximum(s, 1e-6), laws["na_initial_short"]))

    def advance(self, dt: float) -> np.ndarray:
        """Move every path ``dt`` flights on; their faults (n, 4), physical units."""
        rng, n, laws = self.rng, self.n, self.laws
        k_d = laws["duty_shape"]
        u = rng.gamma(k_d * dt, self.m / k_d, size=n)
        if "Fst" in self.rate:
            a = laws["fst_shape"]
            self.x[:, F_FST] += rng.gamma(np.maximum(a * u, 1e-12), self.rate["Fst"] / a)
        if "BLK" in self.rate:
            k = rng.poisson(laws["blk_jump_rate"] * u)
            jump = np.where(k > 0, rng.gamma(np.maximum(k, 1), laws["blk_jump_mean"]), 0.0)
            self.x[:, F_BLK] += self.rate["BLK"] * u + jump
        if "Na" in self.rate:
            new = ~self.onset & (rng.random(n) < -np.expm1(-dt / laws["na_onset_mean"]))
            self.onset |= new
            ke = laws["na_growth_shape"]
            eps = rng.gamma(ke * dt, 1.0 / (ke * dt), size=n)
            self.log_s = self.log_s + np.where(self.onset & ~new,
                                               self.rate["Na"] * u * eps, 0.0)
            self.x[:, F_NA] = np.where(self.onset, 1.0 - np.minimum(np.exp(self.log_s), 1.0),
                                       self.x[:, F_NA])
        return self.x

    def first_failure(self, thresholds: dict[str, float] | None = None, step: float = 2.0,
                      horizon: float = 1500.0) -> np.ndarray:
        """Flights until each path's first fault crosses its threshold (``inf`` beyond
        ``horizon``), at a resolution of ``step`` flights; advances the paths."""
        thresholds = THRESHOLDS if thresholds is None else thresholds

        def failed() -> np.ndarray:
            return np.any([DAMAGE_SIGN[n] * (self.x[:, FAULT_INDEX[n]] - thr) >= 0.0
                           for n, thr in thresholds.items()], axis=0)
        t = np.where(failed(), 0.0, np.inf)
        now = 0.0
        while now < horizon and np.isinf(t).any():
            self.advance(step)
            now += step
            t[np.isinf(t) & failed()] = now
        return t
