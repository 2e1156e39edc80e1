"""A sealed test campaign: the board's headline on a campaign whose seed no one knows.

The published campaigns' seeds are public, so a tracker could tune on them (or find their
lives); the trackers tune on the published campaign only (the **frozen training split**,
``leaderboards/campaign/training_split.json``), and the board's headline comes from a campaign
the maintainer draws from a secret seed (:func:`~ema_bench.prognostics.campaign.make_campaign`
with ``seed=None``: 63 bits of the OS's entropy, written to ``truth.json`` only).
:func:`run_sealed` is the one command a maintainer runs (``ema-bench campaign sealed``)::

    OUT/campaign/           the sealed campaign (manifest seed null; no truth.json)
    OUT/truth.json          its truth, moved out before any tracker runs (holds the seed:
                            keep it, never commit it)
    OUT/runs/TRACKER/       each board tracker's run (``campaign track``, worker processes)
    OUT/scores.md, .json    the table, saying "sealed" and the truth file's SHA-256, no seed

Rerunning the same command resumes: the campaign is not drawn again (its truth is beside it)
and every run resumes where it stopped.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

from .campaign import CampaignError, load_campaign, make_campaign, prepare_folder

#: The trackers of the campaign board, in board order (the no-sensing references first).
BOARD_TRACKERS = ("rul-age", "life-table", "kalman", "refit-trend", "particle", "fleet-bayes",
                  "fleet-bayes-cut", "fleet-bayes-whole")


def truth_digest(path: Path | str) -> str:
    """SHA-256 (hex) of a truth file's bytes: what a sealed table publishes of its truth, so
    that the maintainer's file can be shown later to be the one scored."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def campaign_label(camp, truth_file: Path | str | None = None) -> str:
    """One line saying which campaign a table is on: the published one (its seed) or a
    sealed one (the SHA-256 of its truth file, never its seed)."""
    what = f"{camp.name} (definition {camp.definition_version}), {camp.track} track, " \
           f"{len(camp.units)} {camp.split} units"
    if camp.seed is not None:
        return (f"Campaign: **published**, {what}, seed {camp.seed} (public: it ranks honest "
                "trackers only).")
    digest = truth_digest(truth_file) if truth_file is not None else "unknown"
    return (f"Campaign: **sealed**, {what}, secret seed (not published); truth file SHA-256 "
            f"`{digest}`.")


def make_sealed(out: Path, name: str, units: int, track: str, quiet: bool = True):
    """Draw the sealed campaign into ``out/campaign`` from a secret seed and move its truth
    to ``out/truth.json``; an existing sealed campaign there (with its truth) is reused."""
    folder, truth = out / "campaign", out / "truth.json"
    if truth.is_file() and (folder / "manifest.json").is_file():
        camp = load_campaign(folder)
        if camp.seed is not None:
            raise CampaignError(f"{folder}: not a sealed campaign (its seed {camp.seed} is "
                                "published)")
        return camp
    if truth.exists():
        raise CampaignError(f"{truth}: a truth file without its campaign; move it away")
    prepare_folder(folder)
    camp = make_campaign(name, units=units, split="test", track=track, seed=None, out=folder,
                         quiet=quiet)
    shutil.move(str(folder / "truth.json"), str(truth))   # before any tracker runs
    return camp


def run_sealed(out: Path | str, units: int, name: str = "fleet-v1", track: str = "twin",
               trackers: tuple[str, ...] = BOARD_TRACKERS, workers: int = 1,
               quiet: bool = True, policy: Path | str | None = None, replay: int = 2,
               replay_units: list[str] | None = None) -> dict:
    """Make (or resume) a sealed campaign in ``out``, track it with every tracker in worker
    processes, replay ``replay`` sampled units of every run, score every run against the
    moved truth and write ``out/scores.md`` and ``out/scores.json``.

    Only verified track files are judged: a run resumed from an earlier invocation is the
    folder's, which anyone with the folder could have edited, and a policy reads every step of
    a run.  Before anything is scored or costed each run is replayed as ``campaign policy``
    replays (:func:`~ema_bench.prognostics.replay.verified_runs`, one code path); a run whose
    lines differ is refused (``ReplayError``, one line) and nothing is written.

    Parameters
    ----------
    out : path
        The folder (module docstring); created.
    units : int
        Units of the sealed campaign (about 36 CPU-s per unit for the seven board trackers
        with a shared fit cache, scoring included: 1.4 CPU-s per inspection, 25 inspections
        per unit on fleet-v1).
    name, track : str
        Campaign definition and track.
    trackers : tuple of str
        Registered trackers, in table order.
    workers : int
        Worker processes per tracking run.
    quiet : bool
        No progress lines.
    policy : path, optional
        Replacement-policy thresholds tuned on the training split
        (:mod:`~ema_bench.prognostics.policy`): the table adds the policy costs.
    replay : int
        Units of each run re-tracked (sampled from fresh entropy) before it is judged; at
        least 1 (about a tracker's cost per unit each, in a fresh worker process).
    replay_units : list of str, optional
        Replay these units of every run instead of a sample.

    Returns
    -------
    dict
        ``label`` (the campaign line), ``truth_sha256``, ``runs`` (tracker -> run folder),
        ``results`` (scored runs without per-unit rows), ``policy`` (with ``policy``:
        :func:`~ema_bench.prognostics.policy.score_policies`, else empty), ``lines`` (the
        Markdown table, ending with what was replayed), ``replay`` (tracker -> what was
        replayed, :meth:`~ema_bench.prognostics.replay.TrackReplay.record`).
    """
    from ..jsonio import plain
    from .replay import replayed_lines, verified_runs
    from .scoring import score_tracking
    from .tables import by_group, group_tables, score_table
    from .track_run import track_campaign, tracker_spec

    out = Path(out)
    for t in trackers:
        tracker_spec(t)   # an unknown name before any work
    out.mkdir(parents=True, exist_ok=True)
    camp = make_sealed(out, name, units, track, quiet)
    truth = out / "truth.json"
    runs = {t: track_campaign(camp, t, out / "runs" / t, seed=0, workers=workers, quiet=quiet)
            for t in trackers}
    checked = dict(zip(runs, verified_runs(list(runs.values()), replay, replay_units,
                                           workers, what="scored or costed")))
    results = [score_tracking(run, truth=truth) for run in runs.values()]
    for r in results:
        r["groups"] = by_group(r)
    label = campaign_label(camp, truth)
    lines = [label, ""] + score_table(results) + group_tables(results)
    policies = []
    if policy is not None:
        from .policy import policy_table, read_thresholds, score_policies
        doc = read_thresholds(policy)
        tuned = [p for t, p in runs.items() if t in doc["trackers"]]
        policies = score_policies(tuned, doc, truth)
        for p in policies:
            p["replay"] = checked[p["tracker"]].record()
        untuned = [t for t in runs if t not in doc["trackers"]]
        lines += ["", "**Replacement policies** (thresholds tuned on the training split; "
                  "`ema-bench campaign policy`)"
                  + (f"; no threshold tuned for {', '.join(untuned)}" if untuned else ""),
                  ""] + policy_table(policies)
    lines += [""] + replayed_lines(list(checked.values()), "scoring and costing")
    (out / "scores.md").write_text("\n".join(lines) + "\n")
    kept = [{k: v for k, v in r.items() if k not in ("per_unit", "oracle_per_unit")}
            for r in results]
    doc = {"campaign": label, "truth_sha256": truth_digest(truth), "results": kept,
           "policy": policies, "replay": {t: r.record() for t, r in checked.items()}}
    (out / "scores.json").write_text(json.dumps(plain(doc), indent=1) + "\n")
    return {"label": label, "truth_sha256": doc["truth_sha256"],
            "runs": {t: str(p) for t, p in runs.items()}, "results": kept, "policy": policies,
            "lines": lines, "replay": doc["replay"]}
