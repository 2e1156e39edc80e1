"""Acquisition faults drawn at multiples of their detection thresholds (fourth round).

The second round's decoys draw their magnitudes from fixed ranges (:func:`.decoys.draw`):
a 3-6 sample time shift, a 2-6 ms low-pass.  Here each kind of the workflow's acquisition
library is sized like the effects are: ``multiple x`` its detection threshold
:attr:`~.acquisition.AcquisitionKind.detect` (measured by
``benchmarks/acquisition_thresholds.py``), log-uniform in a range of multiples, capped at its
bound, on one of the channels the kind is drawn on (:data:`CHANNELS`).  Outliers are sized
by their spikes' height (:data:`OUTLIER_DETECT_SD` noise sd; the kind's parameter is their
count, which a 0.5 % share fixes), a stuck channel by the share of the training samples it
freezes (:func:`stuck_start`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..traces import SIGNALS
from .channel_faults import KINDS, NOISE_STD, group_label

#: The channels each kind is drawn on (the decoys' choices; a stuck channel and outliers on
#: any).
CHANNELS: dict[str, tuple[str, ...]] = {
    "lowpass": ("i_eq", "omega_m"),
    "time_shift": ("theta_u", "omega_m", "i_eq"),
    "drift": ("theta_u", "omega_m", "i_eq"),
    "mains_hum": ("i_eq",),
    "outliers": SIGNALS,
    "stuck": SIGNALS,
}
#: Spike height (noise sd) from which outliers at a 0.5 % share are detected and screened
#: first on every channel (12 sd on three channels, 16 on theta_m; the acquisition
#: thresholds' benchmark).
OUTLIER_DETECT_SD = 16.0
#: Training samples of the standard tests (the 0.3 s step and the 1 s sine, 1 ms samples).
STEP_S, SINE_S = 0.3, 1.0


def stuck_start(share: float) -> float:
    """The onset (s, the same in every test) that freezes ``share`` of the training samples:
    the sine's tail alone up to its 0.7 s beyond the step's length, then both tests'."""
    total = STEP_S + SINE_S
    if share * total <= SINE_S - STEP_S:
        return SINE_S - share * total
    return (total - share * total) / 2


def channel_sd(channel: str) -> float:
    """The noise sd of ``channel`` (its unit)."""
    return float(NOISE_STD[SIGNALS.index(channel)])


def draw(kind: str, lo: float, hi: float, rng: np.random.Generator,
         channel: str | None = None) -> dict[str, Any]:
    """The decoy keyword arguments (:func:`.decoys.apply`) of a fault of ``kind`` at ``lo``
    to ``hi`` times its detection threshold (log-uniform), on a channel of
    :data:`CHANNELS` (or on ``channel``): JSON-friendly, with ``multiple`` (the drawn
    multiple) beside them."""
    if channel is None:
        channel = CHANNELS[kind][int(rng.integers(len(CHANNELS[kind])))]
    multiple = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
    spec = KINDS[kind]
    value = min(multiple * spec.detect, spec.upper)
    if kind == "lowpass":
        params: dict[str, Any] = {"tau": value}
    elif kind == "time_shift":
        params = {"samples": max(1, int(round(value)))}
    elif kind == "drift":
        params = {"rate": value * channel_sd(channel) * (1.0 if rng.random() < 0.5 else -1.0)}
    elif kind == "mains_hum":
        params = {"amplitude": value * channel_sd(channel), "freq": 400.0,
                  "phase": float(rng.uniform(0.0, 2 * math.pi))}
    elif kind == "outliers":
        params = {"size": multiple * OUTLIER_DETECT_SD * channel_sd(channel), "fraction": 0.005,
                  "seed": int(rng.integers(2**31))}
    else:
        params = {"start": stuck_start(value)}
    return {"signal": channel, **params, "multiple": multiple}


def decoy_params(params: dict[str, Any]) -> dict[str, Any]:
    """The keyword arguments :func:`.decoys.apply` takes (``multiple`` left out)."""
    return {k: v for k, v in params.items() if k != "multiple"}


#: The channels a whole-chain fault of each kind is drawn on (:mod:`.chain`): every channel,
#: but a low-pass only on the fast ones (a 1-2 ms filter of a position is below its noise).
CHAIN_CHANNELS: dict[str, tuple[str, ...]] = {
    "lowpass": ("omega_m", "i_eq"), "time_shift": SIGNALS, "drift": SIGNALS,
    "mains_hum": SIGNALS}
#: Heavy-tailed noise on every channel: the share of samples hit and the spikes' height
#: range (noise sd), the issue's "a few per cent of samples, tens of sigma".
HEAVY_SHARE = (0.02, 0.05)
HEAVY_SD = (10.0, 40.0)


def draw_chain(kind: str, lo: float, hi: float, rng: np.random.Generator) -> dict[str, Any]:
    """A whole-chain fault of ``kind`` on :data:`CHAIN_CHANNELS`: ``signal`` its group
    label, ``parts`` one channel's decoy keyword arguments each (:func:`draw` on that
    channel; a shared parameter, the shift or ``tau``, the first part's on all), and
    ``multiple`` the smallest part's (what the group's size is); ``heavy_tailed``: the
    :func:`.decoys.heavy_tailed` keyword arguments, on every channel."""
    if kind == "heavy_tailed":
        return {"signal": "all", "share": float(rng.uniform(*HEAVY_SHARE)),
                "low": HEAVY_SD[0], "high": HEAVY_SD[1], "seed": int(rng.integers(2**31))}
    parts = []
    for c in CHAIN_CHANNELS[kind]:
        shared = parts and kind in ("lowpass", "time_shift")
        parts.append({**parts[0], "signal": c} if shared else draw(kind, lo, hi, rng, c))
    return {"signal": group_label(CHAIN_CHANNELS[kind]), "parts": parts,
            "multiple": min(p.pop("multiple") for p in parts)}


def apply_chain(kind: str, tr, params: dict[str, Any]):
    """The traces ``tr`` through a fault :func:`draw_chain` drew."""
    from . import decoys

    if kind == "heavy_tailed":
        return decoys.heavy_tailed(tr, **{k: v for k, v in params.items() if k != "signal"})
    for p in params["parts"]:
        tr = decoys.apply(kind, tr, p)
    return tr
