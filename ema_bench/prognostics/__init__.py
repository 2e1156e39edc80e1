"""Degradation tracking across flights: campaigns, trackers, prognostics metrics.

A campaign (:func:`make_campaign`) is a fleet of actuators degrading by documented laws
(:mod:`.laws`) and inspected every few flights; a tracker (:func:`register_tracker`, entry-point
group ``ema_bench.trackers``) follows each unit inspection by inspection
(:func:`track_campaign`) and predicts its remaining useful life; :func:`score_tracking` scores
that against the hidden truth (:mod:`.metrics`).  ``EMAFault/Maintain-v0``
(:mod:`.maintain_env`) is the sequential-decision version.  Guide: ``docs/prognostics.md``.
"""

from .campaign import CAMPAIGNS, Campaign, CampaignError, load_campaign, load_truth, make_campaign
from .laws import THRESHOLDS
from .oracle import oracle_predictions
from .scoring import ScoringError, score_tracking
from .track_io import read_track
from .track_run import track_campaign
from .tracking import Inspection, TrackerError, TrackStep, available_trackers, register_tracker

__all__ = [
    "CAMPAIGNS", "THRESHOLDS", "Campaign", "CampaignError", "Inspection", "ScoringError",
    "TrackStep", "TrackerError", "available_trackers", "load_campaign", "load_truth",
    "make_campaign", "oracle_predictions", "read_track", "register_tracker", "score_tracking",
    "track_campaign",
]
