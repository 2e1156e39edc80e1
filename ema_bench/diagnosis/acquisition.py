"""Faults of the acquisition chain as suspects: what the fitted model can carry.

A real record is made by sensors, conditioning and a recorder, and these can be faulty while
the actuator is not (or beside an actuator effect).  Each fault here acts on **one recorded
channel of the model's outputs**, never on the loop, so the fitted monitor can carry it: the
model's prediction of the record is ``carry(monitor outputs, faults)``.

===========  =================================  ===========================================
kind         parameter (bounds)                 what the channel's record becomes
===========  =================================  ===========================================
lowpass      tau, s (0-20 ms)                   first-order low-pass of the channel
time_shift   samples, 1 ms each (-8..8)         the channel ``samples`` late (early if < 0)
drift        rate, channel unit/s (+-200 sd/s)  ``+ rate * t`` from each test's start
mains_hum    amplitude, channel unit (0-50 sd)  ``+`` a tone at a fitted frequency (40-495
                                                Hz), its phase per test
outliers     spikes, count (0-2 % of samples)   isolated spikes; the samples get weight 0
stuck        share of samples frozen (0-1)      flat from an onset per test (dead from the
                                                start, or frozen at one value): the model
                                                holds the record's level; weight 0
heavy_tailed share of samples rejected (0-1)    spikes on several channels at any share:
                                                the samples get weight 0 (a robust loss,
                                                chosen by a test, :mod:`.tails`)
===========  =================================  ===========================================

Whole chain (:mod:`.chain`).  A kind may act on several channels at once, as one suspect
named ``kind(all)`` or ``kind(c1,c2)``: one shared parameter for ``lowpass`` and
``time_shift``, one per channel for ``drift`` and ``mains_hum``; ``heavy_tailed`` is only
ever chain-wide.

(``sd``: the channel's sensor-noise standard deviation, :data:`~.features.NOISE_STD`.)  A
fitted fault is an :class:`Acquisition`, named ``kind(channel)``, e.g. ``mains_hum(i_eq)``.

Fitting.  Given the monitor's outputs, every parameter is found without simulating again:
a bounded scalar search for ``tau``, all 16 shifts for ``time_shift``, least squares for the
drift rate, a periodogram over the frequency grid then least squares of a sine and a cosine
per test for the hum, a spike detector (a sample more than :data:`SPIKE_SD` noise sd from
the median of its 5-sample neighbourhood, isolated, at most 2 % of the channel) for
outliers.  The rate, ``tau``, the shift and the hum's frequency come from the training tests
alone; the hum's phase and amplitude per test and the spikes' positions are nuisances of
each record and are fitted on every test, the held-out one included; so are a stuck
channel's onset and level in each test (the latest sample from which the record is flat,
:func:`_fit_stuck`).

Screening.  :func:`screen` fits every kind on every channel at a model's residuals (24
candidates, each a few milliseconds of numpy) and scores it as the drop of the channel's
whitened sum of squares on the training tests, the chi-square scale of the physical
effects' score test (:mod:`~.screening`).

Intervals (95 %).  From the channel's profile with the residual variance estimated from the
fit (at least the sensor noise): ``+-1.96`` standard errors for the linear parameters (the
drift rate; a common scale of the fitted hum), the values whose sum of squares lies within
3.84 variances of the best for ``tau`` and the shift, ``n +- 1.96 sqrt(n)`` spikes for
outliers (so at least 4 spikes exclude zero), the shares of the onsets whose sum of
squares lies within 3.84 variances of the best for a stuck channel.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..traces import SIGNALS
from .chain import describe_group, estimate_group, groups

# the one-channel kinds, the fault type, its action on the outputs and its fits (carry and
# weights: callers use them as acquisition.<name>)
from .channel_faults import (  # noqa: F401
    GROUPED,
    KINDS,
    Acquisition,
    Estimate,
    carry,
    estimate_channel,
    is_group,
    weights,
)


def parse(name: str) -> tuple[str, str]:
    """``kind(channel)`` -> ``(kind, channel)``; :class:`ValueError` if not one.  A
    whole-chain group's channel is ``all`` or channels in :data:`SIGNALS` order joined by
    commas (:mod:`.chain`)."""
    kind, _, rest = name.partition("(")
    channel = rest[:-1] if rest.endswith(")") else ""
    single = channel in SIGNALS and kind in KINDS and kind != "heavy_tailed"
    if not single and not (kind in GROUPED and is_group(channel)):
        raise ValueError(f"{name!r} is not an acquisition fault kind(channel): kinds "
                         f"{list(KINDS)}, channels {list(SIGNALS)}, whole-chain groups "
                         f"kind(all) or kind(c1,c2) of {list(GROUPED)}")
    return kind, channel


def is_acquisition(name: str) -> bool:
    """Whether ``name`` names an acquisition fault (``kind(channel)``)."""
    try:
        parse(name)
    except ValueError:
        return False
    return True


def trivial(name: str) -> float:
    """The trivial band of ``kind(channel)`` in the channel's unit (a group's: in the kind's
    scale units, noise sd for the per-channel additive kinds)."""
    kind, channel = parse(name)
    return KINDS[kind].scaled(channel)[2] if channel in SIGNALS else KINDS[kind].trivial


def all_names() -> tuple[str, ...]:
    """Every kind on every channel (the screened one-channel candidates)."""
    return tuple(f"{k}({c})" for k in KINDS if k != "heavy_tailed" for c in SIGNALS)


# --- fitting a suspect ---------------------------------------------------------------------


def estimate(name: str, raw: Mapping[str, np.ndarray], measured: Mapping[str, np.ndarray],
             w: Mapping[str, np.ndarray], train: tuple[str, ...],
             others: Sequence[Acquisition] = ()) -> Estimate:
    """Fit fault ``kind(channel)`` at the monitor outputs ``raw`` (test -> (n_samples, 4)),
    the ``others`` faults held at their values.

    Parameters
    ----------
    measured : test -> (n_samples, 4) the record.
    w : test -> (n_samples, 4) sample weights (0: the sample is not fitted).
    train : the tests that fit the parameters the held-out test must not see.
    """
    kind, channel = parse(name)
    others = [o for o in others if o.name != name]
    if channel not in SIGNALS:
        return estimate_group(kind, channel, raw, measured, w, train, others)
    return estimate_channel(kind, channel, raw, measured, w, train, others)


def refit(faults: Sequence[Acquisition], raw: Mapping[str, np.ndarray],
          measured: Mapping[str, np.ndarray], w: Mapping[str, np.ndarray],
          train: tuple[str, ...]) -> tuple[list[Acquisition], dict[str, list[float]]]:
    """Each fault fitted again in turn at ``raw`` (the others held), outliers and stuck
    channels first (so their samples do not pull the least-squares fits); the faults and
    their intervals."""
    cur = list(faults)
    ivs = {}
    first = ("outliers", "stuck", "heavy_tailed")
    for i in sorted(range(len(cur)), key=lambda i: (cur[i].kind not in first, i)):
        e = estimate(cur[i].name, raw, measured, w, train, cur)
        cur[i] = e.fault
        ivs[e.fault.name] = e.interval
    return cur, ivs


def screen(raw: Mapping[str, np.ndarray], measured: Mapping[str, np.ndarray],
           w: Mapping[str, np.ndarray], train: tuple[str, ...],
           others: Sequence[Acquisition] = ()) -> list[Estimate]:
    """Every kind on every channel not already carried, fitted at ``raw`` (the ``others``
    held), and the whole-chain groups of the channels each kind scores on alone
    (:func:`~.chain.groups`), best score first."""
    have = {(p.kind, p.channel) for o in others for p in o.parts()}
    out = [estimate(n, raw, measured, w, train, others) for n in all_names()
           if parse(n) not in have]
    out += groups(out, raw, measured, w, train, others)
    return sorted(out, key=lambda e: -e.score)


def describe(f: Acquisition) -> str:
    """One phrase for a verdict, e.g. ``400 Hz hum of 0.3 A on i_eq``."""
    from ..traces import UNITS

    if f.channel not in SIGNALS:
        return describe_group(f)
    u = UNITS[f.channel] if isinstance(UNITS, Mapping) else ""
    text = {
        "lowpass": f"a low-pass of {1e3 * f.value:.2g} ms on {f.channel}",
        "time_shift": f"{f.channel} recorded {abs(int(f.value))} ms "
                      f"{'late' if f.value > 0 else 'early'}",
        "drift": f"a drift of {f.value:.3g} {u}/s on {f.channel}",
        "mains_hum": f"{f.detail.get('freq', 0.0):.0f} Hz hum of {f.value:.3g} {u} on "
                     f"{f.channel}",
        "outliers": f"{int(f.value)} outlier spikes on {f.channel}",
        "stuck": f"{f.channel} stuck (flat) over {100 * f.value:.0f} % of its training "
                 f"samples",
    }
    return text[f.kind]


def as_dict(f: Acquisition) -> dict[str, Any]:
    """A JSON-friendly record of a fitted fault (the hum's frequency; not its spikes)."""
    d = {"name": f.name, "kind": f.kind, "channel": f.channel, "value": f.value}
    if "freq" in f.detail:
        d["freq"] = f.detail["freq"]
    return d
