"""Faults of the whole recording chain: one kind on several channels as one suspect.

A recorder's fault often reaches every channel at once (one clock, one board design, one
mains supply).  Such a fault is **one suspect with one price**, named ``kind(all)`` or
``kind(c1,c2)`` (channels in :data:`~ema_bench.traces.SIGNALS` order), beside the one-channel
suspects ``kind(c)`` of :mod:`.acquisition`.  Whether its parameter is shared follows the
physics of the chain:

============  ==========================  ==================================================
kind          chain-wide parameter        why
============  ==========================  ==================================================
lowpass       one ``tau``, shared         the channels' conditioning is built alike: one
                                          anti-alias filter design on the recorder's card
time_shift    one shift, shared           the recorder stamps every channel with one clock:
                                          a late trigger or a buffer delays all alike
drift         one rate per channel        each sensor's zero creeps with its own
                                          electronics and in its own unit (a warm-up reaches
                                          every channel, each at its rate)
mains_hum     amplitude, phase and        the mains couples into each channel's wiring with
              frequency per channel       its own gain and phase; the frequency (the same
                                          mains) is found on each channel to 0.25 Hz
heavy_tailed  the share of samples        chain-wide only, chosen by a test, not screened
              rejected                    here (:mod:`.tails`)
============  ==========================  ==================================================

``outliers`` and ``stuck`` stay one channel each: spikes on several channels at any share
are ``heavy_tailed``, and a recorder frozen on every channel leaves no live sample to fit
the physics through.

A group's value is the shared parameter, or (one per channel) the **smallest** member's
size in noise sd (the group claims every member): its interval is ``[min low, min high]``
of the members' intervals of ``|value| / sd``, so it excludes zero only when every
member's does.  The screen (:func:`groups`) proposes, per kind, the group of the channels
that kind scores :data:`GROUP_SCORE` or more on alone, when there are two or more: at most
one candidate per kind, fitted from the same residuals in milliseconds; a time shift's
group of some channels is proposed on every channel too (:func:`_one_clock`), so at most
five.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..traces import SIGNALS, UNITS
from .channel_faults import (
    _FITS,
    GROUPED,
    KINDS,
    NOISE_STD,
    Acquisition,
    Estimate,
    _channel,
    estimate_channel,
    group_label,
)

#: Score each member channel needs alone for its group to be screened (the workflow's
#: ``Settings.min_score``: what a one-channel suspect needs for a fit).
GROUP_SCORE = 50.0


def _size(e: Estimate) -> tuple[float, float, float]:
    """A one-channel estimate's ``|value|`` and its interval, in noise sd."""
    sd = float(NOISE_STD[e.fault.column])
    a, b = (v / sd for v in e.interval)
    lo = a if a > 0 else (-b if b < 0 else 0.0)
    return abs(e.fault.value) / sd, lo, max(abs(a), abs(b))


def estimate_group(kind: str, label: str, raw: Mapping[str, np.ndarray],
                   measured: Mapping[str, np.ndarray], w: Mapping[str, np.ndarray],
                   train: tuple[str, ...], others: Sequence[Acquisition] = ()) -> Estimate:
    """Fit the whole-chain fault ``kind(label)`` at the monitor outputs ``raw`` (the
    ``others`` held; arguments as :func:`~.acquisition.estimate`)."""
    channels = SIGNALS if label == "all" else tuple(label.split(","))
    if kind == "heavy_tailed":
        from .tails import estimate_tails

        return estimate_tails(channels, raw, measured, w, train, others)
    if GROUPED[kind]:
        ch = _channel(raw, measured, others, w, [SIGNALS.index(c) for c in channels],
                          train)
        value, _, drop, iv = _FITS[kind](ch)
        value = float(np.clip(value, KINDS[kind].lower, KINDS[kind].upper))
        parts = tuple(Acquisition(kind, c, value) for c in channels)
        return Estimate(Acquisition(kind, label, value, {"parts": parts}), max(drop, 0.0),
                        [float(v) for v in iv])
    members = [estimate_channel(kind, c, raw, measured, w, train,
                                [o for o in others if o.name != f"{kind}({c})"])
               for c in channels]
    sizes = np.array([_size(e) for e in members])
    value, lo, hi = sizes.min(axis=0)
    parts = tuple(e.fault for e in members)
    return Estimate(Acquisition(kind, label, float(value), {"parts": parts}),
                    float(sum(e.score for e in members)), [float(lo), float(hi)])


def groups(singles: Sequence[Estimate], raw: Mapping[str, np.ndarray],
           measured: Mapping[str, np.ndarray], w: Mapping[str, np.ndarray],
           train: tuple[str, ...], others: Sequence[Acquisition] = ()) -> list[Estimate]:
    """Per kind, the group of the channels whose one-channel estimate in ``singles`` scores
    :data:`GROUP_SCORE` or more, fitted as one suspect, when two channels or more do."""
    out = []
    for kind in (k for k in GROUPED if k != "heavy_tailed"):
        chans = [e.fault.channel for e in singles
                 if e.fault.kind == kind and e.score >= GROUP_SCORE]
        if len(chans) > 1:
            e = estimate_group(kind, group_label(chans), raw, measured, w, train, others)
            out.append(e)
            if kind == "time_shift" and e.fault.channel != "all":
                out.append(_one_clock(e))
    return out


def _one_clock(e: Estimate) -> Estimate:
    """A shared time shift on some channels proposed on every channel too (one clock stamps
    them all), at the shift and score of the channels that showed it (ranked after them).

    At the base fit the physics lags to meet part of a shift of the whole record, so some
    channels show the shift and others do not (3 samples on every channel, root seed 4189
    case 3: ``theta_u``, ``theta_m`` and ``omega_m`` at 2 samples, ``i_eq`` best unshifted);
    the fit through the shift (:func:`~.fitting.fit`, which profiles it) tells."""
    value = e.fault.value
    parts = tuple(Acquisition("time_shift", c, value) for c in SIGNALS)
    return Estimate(Acquisition("time_shift", "all", value, {"parts": parts}), e.score,
                    e.interval)


def describe_group(f: Acquisition) -> str:
    """One phrase for a verdict, e.g. ``every channel recorded 2 ms late``."""
    where = "every channel" if f.channel == "all" else ", ".join(f.channels)
    if f.kind == "heavy_tailed":
        return (f"heavy-tailed noise on {where}: {100 * f.value:.2g} % of the samples "
                f"rejected (a robust loss)")
    if f.kind == "time_shift":
        return (f"{where} recorded {abs(int(f.value))} ms "
                f"{'late' if f.value > 0 else 'early'} (one clock)")
    if f.kind == "lowpass":
        return f"a low-pass of {1e3 * f.value:.2g} ms on {where} (one filter design)"
    each = ", ".join(f"{p.channel} {p.value:.3g} {UNITS[p.channel]}"
                     + ("/s" if f.kind == "drift" else "") for p in f.parts())
    what = "a drift" if f.kind == "drift" else \
        f"{f.parts()[0].detail.get('freq', 0.0):.0f} Hz hum"
    return f"{what} on {where} ({each})"
