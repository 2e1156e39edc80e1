"""``ema-bench campaign``: degradation campaigns, tracked to a remaining-useful-life prediction.

A campaign is a fleet of actuators whose faults grow over flights by documented degradation
laws, inspected every few flights (the step and sine tests).  ``make`` draws one and writes it
to a folder (per-inspection traces, a manifest, the hidden truth); ``track`` runs a tracker
over it, inspection by inspection, writing estimates, intervals and RUL predictions as it goes
(rerunning resumes); ``score`` compares them with the hidden truth.

Examples::

    ema-bench campaign make fleet-v1 --units 20 --track twin --seed 0 --out fleet
    ema-bench campaign track fleet --tracker particle --out fleet-particle
    ema-bench campaign score fleet-particle --json
    ema-bench campaign sealed --units 10 --out sealed --workers 2
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path

from ..jsonio import plain
from ..prognostics.campaign import (
    default_out,
    get_spec,
    load_campaign,
    load_truth,
    make_campaign,
    prepare_folder,
    truth_path,
)
from ..prognostics.scoring import score_tracking
from ..prognostics.sealed import BOARD_TRACKERS, campaign_label, run_sealed
from ..prognostics.track_io import campaign_path, read_track
from ..prognostics.track_run import track_campaign, tracker_spec
from ..prognostics.tracking import available_trackers
from . import CLIError, print_result
from .args import (
    add_json,
    add_quiet,
    check_output,
    count,
    finite,
    option_list,
    seed_number,
    worker_count,
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("campaign", help="degradation campaigns: make, track, score (RUL)")
    actions = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    _register_make(actions)
    _register_track(actions)
    _register_score(actions)
    _register_sealed(actions)
    _register_policy(actions)


def _action(actions: argparse._SubParsersAction, name: str,
            run: Callable[[argparse.Namespace], int], summary: str) -> argparse.ArgumentParser:
    """An action's parser: ``summary`` in ``campaign --help``, ``run`` its handler, whose
    docstring is its description (as a command's is its module's docstring)."""
    p = actions.add_parser(name, help=summary, description=run.__doc__)
    p.set_defaults(func=run)
    return p


# --- make (campaign drawing and files) -------------------------------------------------------

def _register_make(actions: argparse._SubParsersAction) -> None:
    p = _action(actions, "make", _run_make,
                "draw a campaign and write its inspection traces, manifest and truth")
    p.add_argument("name", metavar="NAME", help="campaign name (e.g. fleet-v1)")
    p.add_argument("--units", type=count(1, 10_000), default=20,
                   help="units of the fleet (default 20)")
    p.add_argument("--track", choices=("twin", "reference"), default="twin",
                   help="inspection traces from the monitor model plus noise (twin, default) "
                        "or from the reference model (about 0.18 s per inspection)")
    p.add_argument("--seed", type=seed_number, default=None, help="root seed (default 0)")
    p.add_argument("--secret-seed", action="store_true",
                   help="a secret root seed (63 bits of the OS's entropy) kept in truth.json "
                        "only, the manifest's seed null: for a campaign that judges untrusted "
                        "trackers (its logs cannot give the seed away)")
    p.add_argument("--split", choices=("test", "train"), default="test",
                   help="test: units stop at 50-95 %% of life, RUL hidden (default); train: "
                        "units run to failure")
    p.add_argument("--every", type=count(1, 10_000), default=None, metavar="K",
                   help="flights between inspections (default: the campaign's, 10 for "
                        "fleet-v1)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="folder to write (default ema-bench-campaign-NAME-TRACK-SPLIT-"
                        "seedS-nN)")
    add_json(p, "the summary")
    add_quiet(p)


def _run_make(args: argparse.Namespace) -> int:
    """Draw a fleet of actuators from the named campaign's degradation laws, inspect each unit
    every K flights (step and sine tests) and write DIR/manifest.json (what a tracker sees),
    DIR/uNNN/iNNN.npz (traces) and DIR/truth.json (hidden: faults, end of life, true RUL).
    Same seed, same files.  An existing campaign in DIR is replaced."""
    # --units, --every and --seed are bounded by their argparse types; before any work (a
    # CampaignError is a ValueError: one line by main())
    get_spec(args.name)
    if args.secret_seed and args.seed is not None:
        raise CLIError("give --seed or --secret-seed, not both")
    seed = None if args.secret_seed else args.seed or 0
    out = args.out or default_out(args.name, args.track, args.split, seed, args.units)
    prepare_folder(out)
    check_output(out, "--out", folder=True)
    t0 = time.perf_counter()
    c = make_campaign(args.name, units=args.units, split=args.split, track=args.track,
                      seed=seed, inspection_every=args.every, out=out, quiet=args.quiet)
    seconds = round(time.perf_counter() - t0, 2)
    inspections = sum(len(v) for v in c.units.values())
    summary = {"path": str(c.root), "name": c.name, "split": c.split, "track": c.track,
               "seed": c.seed, "units": len(c.units), "inspections": inspections,
               "inspection_every": c.inspection_every, "seconds": seconds}
    return print_result(args, summary, [
        f"campaign {c.name}: {len(c.units)} {c.split} units, {c.track} track, seed "
        f"{'secret (in truth.json)' if c.seed is None else c.seed}, "
        f"an inspection every {c.inspection_every} flights",
        f"  {inspections} inspections written to {c.root}/ in {seconds:.1f} s; hidden "
        "truth in truth.json",
        f"  next: ema-bench campaign track {c.root} --tracker NAME --out DIR2"])


# --- track (trackers) ------------------------------------------------------------------------

def _register_track(actions: argparse._SubParsersAction) -> None:
    p = _action(actions, "track", _run_track,
                "run a tracker over a campaign: fault estimates and RUL per inspection")
    p.add_argument("campaign", metavar="DIR", nargs="?", help="campaign folder")
    p.add_argument("--tracker", metavar="NAME", help="registered tracker (see --list)")
    p.add_argument("--out", metavar="DIR2", help="output folder (created; resumed if it "
                                                 "holds this same run)")
    p.add_argument("--seed", type=seed_number, default=0,
                   help="root seed: unit k's tracker gets run node (S, k) (default 0)")
    p.add_argument("--workers", type=worker_count, default=1, metavar="N",
                   help="units tracked at once in worker processes (default 1)")
    p.add_argument("--list", action="store_true", help="list the registered trackers and exit")
    add_json(p, "the summary (or the list)")
    add_quiet(p)


def _run_track(args: argparse.Namespace) -> int:
    """Run a registered tracker over every unit of the campaign in DIR, inspection by
    inspection, and write DIR2/track.jsonl (one line per unit and inspection: estimates with
    95 % intervals, RUL median and 95 % interval, failing fault, replace) as each finishes, plus
    DIR2/manifest.json.  Rerunning the same command resumes: units already complete are
    skipped.  Every inspection is tracked to the unit's cut, also after a replacement call (the
    first call is the unit's maintenance decision); a tracker that raises on a unit is recorded
    as a failed unit, a killed worker or a full disk is not (a rerun tries it again).
    'ema-bench campaign track --list' lists the trackers (the 'ema_bench.trackers' entry-point
    group: the baselines and any installed plugin)."""
    if args.list:
        trackers = available_trackers()
        width = max((len(n) for n in trackers), default=0)
        return print_result(args, [{"name": t.name, "description": t.description,
                                    "config": t.config, "module": t.factory.__module__}
                                   for t in trackers.values()],
                            [f"{t.name:<{width}}  {t.description}" for t in trackers.values()])
    missing = [o for o, v in (("DIR", args.campaign), ("--tracker", args.tracker),
                              ("--out", args.out)) if not v]
    if missing:
        raise CLIError(f"give {', '.join(missing)} (or --list)")
    # before any work (TrackerError, CampaignError: one line by main()); the tracker's plugin
    # is imported in worker processes only, never beside the campaign
    tracker_spec(args.tracker)
    campaign = load_campaign(args.campaign)
    check_output(args.out, "--out", folder=True)
    t0 = time.perf_counter()
    out = track_campaign(campaign, args.tracker, args.out, seed=args.seed,
                         workers=args.workers, quiet=args.quiet)
    seconds = round(time.perf_counter() - t0, 2)
    log = read_track(out)
    steps = sum(len(rows) for rows in log.steps.values())
    replaced = sorted(u for u, rows in log.steps.items() if rows and rows[-1]["replace"])
    summary = {"path": str(out), "tracker": args.tracker, "seed": args.seed,
               "campaign": str(campaign.root), "units": len(campaign.units),
               "steps": steps, "replaced": replaced, "failed": sorted(log.failed),
               "evaluations": sum(r["evaluations"] for rows in log.steps.values()
                                  for r in rows), "seconds": seconds}
    return print_result(args, summary, [
        f"tracker {args.tracker} on {campaign.name} ({campaign.root}): {len(campaign.units)} "
        f"units, {steps} inspections tracked in {seconds:.1f} s",
        f"  replacement called on {len(replaced)} unit(s); {len(log.failed)} failed"
        + (f" ({', '.join(sorted(log.failed))})" if log.failed else ""),
        f"  written to {out}/track.jsonl; next: ema-bench campaign score {out}"])


# --- score (metrics) -------------------------------------------------------------------------

def _register_score(actions: argparse._SubParsersAction) -> None:
    p = _action(actions, "score", _run_score,
                "score tracking runs against the campaign's hidden truth")
    p.add_argument("runs", metavar="DIR2", nargs="+", help="tracking run folder(s)")
    p.add_argument("--truth", metavar="FILE",
                   help="the campaign's truth file (default: truth.json in the campaign folder "
                        "the run names); with several runs, all must be of that campaign")
    p.add_argument("--alpha", type=finite, default=0.2,
                   help="relative half-width of the headline's accuracy (default 0.2)")
    p.add_argument("--no-oracle", action="store_true",
                   help="skip the oracle (about 0.3 s per failing unit) and the ratios to it")
    p.add_argument("--tracked-only", action="store_true",
                   help="score only the units each run has tracked to their cut (a partial "
                        "run; the table says how many); default: a missing unit is a miss")
    add_replay(p, 0, "first re-track K sampled units of each run with its registered "
                     "tracker and seed, and refuse the run (exit 1, naming unit, inspection "
                     "and field) if any line differs")
    p.add_argument("--plots", metavar="DIR", help="write PNG plots here")
    p.add_argument("--markdown", metavar="FILE", help="write the table as Markdown here")
    add_json(p, "the figures (one object per run, with per-unit rows)")


def _run_score(args: argparse.Namespace) -> int:
    """Score one or more tracking runs (DIR2 of 'ema-bench campaign track') against their
    campaign's truth (--truth, default the campaign folder's truth.json; another campaign's is
    refused).  Headline: the RUL at each failing unit's hidden cut (its last inspection): the
    expected share within +-20 % (under each unit's futures from its true state) and the
    realised one, MAE, RMSE, PHM08 per unit (predictions clipped to a horizon) and its median,
    95 % interval coverage, width and interval score, and from RUL quantiles the CRPS and
    50/80 % figures, each with a bootstrap interval over units and as a ratio to the honest Bayes
    oracle (paired bootstrap); --markdown adds tables by failing fault and cut position.  Also
    maintenance decisions (false and early replacements, failures in service, cost) and
    diagnostics (alpha-lambda over lambda 0.5-0.9, prognostic horizons, monotonicity, per-fault
    tracking, detection).  Rules: ema_bench/prognostics/scoring.py."""
    if not 0.0 < args.alpha < 1.0:
        raise CLIError("--alpha must lie in (0, 1)")
    if args.replay or args.replay_unit:
        if not _replayed(args):
            return 1
    results = [score_tracking(run, truth=args.truth, alpha=args.alpha,
                              oracle=not args.no_oracle, tracked_only=args.tracked_only)
               for run in args.runs]
    for run, r in zip(args.runs, results):
        if r["missing_at_cut"]:  # on stderr: stdout stays the table (or the JSON)
            print(f"note: {run}: {r['missing_at_cut']} failing unit(s) without a prediction "
                  "at their cut (untracked or failed): counted as infinite misses",
                  file=sys.stderr)
    if args.plots:
        _plots(args.runs, results, Path(args.plots), args.alpha, args.truth)
    from ..prognostics.tables import by_group, group_tables, score_table

    for r in results:
        r["groups"] = by_group(r)
    lines = score_table(results)
    if args.markdown:
        lines += group_tables(results)
        head = list(dict.fromkeys(_campaign_label(run, args.truth) for run in args.runs))
        Path(args.markdown).write_text("\n".join(head + [""] + lines) + "\n")
    return print_result(args, results[0] if len(results) == 1 else results, lines)


def _campaign_label(run: str, truth: str | None) -> str:
    """Which campaign a run is on: published (its seed) or sealed (its truth's digest)."""
    camp = load_campaign(campaign_path(run, read_track(run).manifest), traces=False)
    return campaign_label(camp, truth_path(camp.root if truth is None else truth))


def add_replay(p: argparse.ArgumentParser, default: int, what: str) -> None:
    """``--replay K`` and ``--replay-unit``: the re-tracking of a run's units before it is
    judged (:func:`replays`; ``score`` and ``policy``)."""
    p.add_argument("--replay", metavar="K", type=count(0 if default == 0 else 1, 10_000),
                   default=default,
                   help=f"{what} (default {default}): the steps are the submitter's, the "
                        "tracker is deterministic (needs the campaign's traces, which "
                        "'campaign make' remakes for a committed campaign; "
                        "ema_bench/prognostics/replay.py)")
    p.add_argument("--replay-unit", metavar="UNITS", type=option_list, default=None,
                   help="comma-separated units to replay instead of a sample")


def replays(args: argparse.Namespace) -> list:
    """Each run's :class:`~ema_bench.prognostics.replay.TrackReplay` (``--replay`` K sampled
    units, or ``--replay-unit``), in the order of ``args.runs``."""
    from ..prognostics.replay import replay_track

    return [replay_track(run, k=args.replay, units=args.replay_unit) for run in args.runs]


def _replayed(args: argparse.Namespace) -> bool:
    """Replay each run; print what was found (stderr); False if a line disagrees."""
    ok = True
    for r in replays(args):
        print(f"replay: {r.summary()}", file=sys.stderr)
        for line in r.findings[:20]:
            print(f"  {line}", file=sys.stderr)
        ok = ok and r.ok
    if not ok:
        print("error: a run's lines are not what its tracker gives: not scored",
              file=sys.stderr)
    return ok


def _plots(runs: list[str], results: list[dict], folder, alpha: float, truth_file=None,
           n_units: int = 3) -> None:
    from ..prognostics.plots import (
        plot_alpha_lambda,
        plot_errors,
        plot_reliability,
        plot_rul,
        plot_unit,
    )

    folder.mkdir(parents=True, exist_ok=True)
    errors: dict[str, dict[str, list[float]]] = {}
    curves: dict[str, dict[str, dict]] = {}
    reliable: dict[str, dict[str, dict]] = {}
    for run, res in zip(runs, results):
        log = read_track(run)
        camp = load_campaign(campaign_path(run, log.manifest), traces=False)
        truth = load_truth(camp.root if truth_file is None else truth_file, camp)
        tag = f"{res['tracker']}-{res['track']}"
        plot_rul(log.steps, truth, folder / f"rul_{tag}.png", alpha,
                 title=f"{res['tracker']} on {res['campaign']} ({res['track']} track)")
        failing = [u["unit"] for u in res["per_unit"] if u["eol"] is not None][:n_units]
        for unit in failing:
            plot_unit(log.steps.get(unit, []), truth[unit], camp.thresholds,
                      folder / f"unit_{tag}_{unit}.png",
                      title=f"{res['tracker']}: unit {unit} ({res['track']} track)")
        errors.setdefault(res["track"], {})[res["tracker"]] = [
            u["rul"] - u["true_rul"] for u in res["per_unit"] if u["eol"] is not None]
        curves.setdefault(res["track"], {})[res["tracker"]] = res["diagnostics"]["alpha_lambda"]
        reliable.setdefault(res["track"], {})[res["tracker"]] = res["reliability"]
        if "oracle_reliability" in res:
            reliable[res["track"]]["oracle"] = res["oracle_reliability"]
        if "oracle_per_unit" in res:
            errors[res["track"]]["oracle"] = [u["rul"] - u["true_rul"]
                                              for u in res["oracle_per_unit"]]
    for track in errors:
        plot_errors(errors[track], folder / f"rul_errors_{track}.png",
                    title=f"RUL error at the cut ({track} track)")
        plot_reliability(reliable[track], folder / f"reliability_{track}.png",
                         title=f"reliability of the RUL intervals at the cut ({track} track)")
        plot_alpha_lambda(curves[track], folder / f"alpha_lambda_{track}.png", alpha,
                          title=f"alpha-lambda over lambda, a diagnostic ({track} track)")


# --- sealed (the maintainer's board on a secret campaign) -------------------------------------

def _register_sealed(actions: argparse._SubParsersAction) -> None:
    p = _action(actions, "sealed", _run_sealed,
                "the board on a sealed campaign: secret seed, every tracker, scored")
    p.add_argument("--units", type=count(1, 10_000), required=True,
                   help="units of the sealed campaign")
    p.add_argument("--out", metavar="DIR", required=True, help="folder (created; resumed)")
    p.add_argument("--name", default="fleet-v1", help="campaign name (default fleet-v1)")
    p.add_argument("--track", choices=("twin", "reference"), default="twin",
                   help="inspection traces' track (default twin)")
    p.add_argument("--trackers", type=option_list, default=list(BOARD_TRACKERS),
                   metavar="NAMES", help="comma-separated trackers (default the board's: "
                                         f"{','.join(BOARD_TRACKERS)})")
    p.add_argument("--workers", type=worker_count, default=1, metavar="N",
                   help="units tracked at once in worker processes (default 1)")
    p.add_argument("--policy", metavar="FILE", default=None,
                   help="replacement-policy thresholds tuned on the training split ("
                        "'campaign policy --tune'): adds the policy costs to the table")
    add_replay(p, 2, "re-track K sampled units of each run (at least 1) before it is scored "
                     "or costed")
    add_json(p, "the summary")
    add_quiet(p)


def _run_sealed(args: argparse.Namespace) -> int:
    """Draw a test campaign from a secret seed (63 bits of the OS's entropy) into DIR/campaign,
    move its truth to DIR/truth.json before any tracker runs (it holds the seed: keep it, never
    publish it), track it with every board tracker in worker processes (DIR/runs/NAME), score
    every run and write DIR/scores.md and DIR/scores.json, which name the campaign as sealed
    with the SHA-256 of its truth file and never its seed.  Rerunning resumes.  Only verified
    track files are scored and costed: each run's sampled units are first re-tracked as
    'campaign policy' does (--replay K), and a run whose lines differ is refused (exit 2, one
    line, nothing written).  Trackers tune on the published campaign only
    (leaderboards/campaign/training_split.json)."""
    get_spec(args.name)
    check_output(args.out, "--out", folder=True)
    if args.policy is not None:
        from ..prognostics.policy import read_thresholds
        read_thresholds(args.policy)   # a bad file before any work
    r = run_sealed(args.out, args.units, name=args.name, track=args.track,
                   trackers=tuple(args.trackers), workers=args.workers, quiet=args.quiet,
                   policy=args.policy, replay=args.replay, replay_units=args.replay_unit)
    summary = {k: r[k] for k in ("label", "truth_sha256", "runs", "replay")}
    return print_result(args, summary, r["lines"] + [
        "", f"written to {args.out}/scores.md and scores.json; keep {args.out}/truth.json "
            "(it holds the secret seed) away from the trackers and out of any commit"])


# --- policy (replacement costs against the oracle policy) ------------------------------------

def _register_policy(actions: argparse._SubParsersAction) -> None:
    p = _action(actions, "policy", _run_policy,
                "replacement-policy costs of tracking runs beside the oracle policy's")
    p.add_argument("runs", metavar="DIR2", nargs="+", help="tracking run folder(s)")
    p.add_argument("--truth", metavar="FILE", help="the campaign's truth file (default: "
                                                   "truth.json in the campaign folder)")
    mode = p.add_mutually_exclusive_group(required=True)
    mode.add_argument("--tune", metavar="FILE", help="tune on these runs and write FILE")
    mode.add_argument("--thresholds", metavar="FILE", help="apply the thresholds of FILE")
    add_replay(p, 2, "re-track K sampled units of each run (at least 1) before costing it")
    p.add_argument("--markdown", metavar="FILE", help="write the table as Markdown here")
    add_json(p, "the figures (one object per run, with what was replayed)")


def _run_policy(args: argparse.Namespace) -> int:
    """Cost a replacement policy per tracking run (replace at the first inspection where the
    tracker's RUL signal is at most a threshold, or when its forecast at the cut runs down to
    it) and the oracle policy (the true state at the cut) on the same failing units and
    futures, with Maintain-v0's costs (inspection 0.5, replacement 40, failure 400 flights'
    revenue): cost per 100 flights, per unit, expected failures and the ratio to the oracle's.
    --tune FILE chooses each tracker's signal and threshold on these runs (the published
    training split only) and writes them; --thresholds FILE applies tuned ones.  Only
    verified track files are costed: each run's sampled units are first re-tracked as
    'campaign score --replay K' does, and a run whose lines differ is refused (exit 2, one
    line); the output says what was replayed.  Rules: ema_bench/prognostics/policy.py."""
    from ..prognostics.policy import policy_table, read_thresholds, score_policies, tune
    from ..prognostics.replay import replayed_lines, verified_runs

    if args.tune:
        check_output(args.tune, "--tune", folder=False)
    else:
        doc = read_thresholds(args.thresholds)
    if args.markdown:
        check_output(args.markdown, "--markdown", folder=False)
    # before anything is tuned or costed on the lines (ReplayError: exit 2, one line)
    checked = verified_runs(args.runs, args.replay, args.replay_unit)
    if args.tune:
        doc = tune(args.runs, args.truth)
        Path(args.tune).write_text(json.dumps(plain(doc), indent=1) + "\n")
    scored = score_policies(args.runs, doc, args.truth)
    for s, r in zip(scored, checked):
        s["replay"] = r.record()
    lines = policy_table(scored) + [""] + replayed_lines(checked, "costing")
    if args.markdown:
        Path(args.markdown).write_text("\n".join(lines) + "\n")
    return print_result(args, scored, lines)
