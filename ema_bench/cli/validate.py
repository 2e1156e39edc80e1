"""``ema-bench validate``: check run records before they join a leaderboard.

Each record must be of this suite and model version (``ema-bench suite`` shows them), carry a
complete manifest (versions, platform, CPU, threads), stay within its budget, agree with
itself (trace, targets, truth) and, re-evaluated here, its best vector must have the fitness
it reports.  Each solver must cover every instance of the suite but the sanity case, for the
same seeds, on each track it enters (--partial skips that).  Exit 0: accepted; 1: refused,
with one line per reason; 2: the files cannot be read.  docs/submitting-results.md is the
whole submission path.

Examples::

    ema-bench validate my-solver/runs.jsonl
    ema-bench validate shard0/runs.jsonl shard1/runs.jsonl --json
    ema-bench validate leaderboards/quick/runs.jsonl --partial --legacy
    ema-bench validate leaderboards/runs.jsonl --per-tier 8 --replay 12
"""

from __future__ import annotations

import argparse

from . import CLIError, print_result


def register(sub: argparse._SubParsersAction) -> None:
    from .args import add_json, add_legacy, add_targets, count, seed_number

    p = sub.add_parser("validate", help="check third-party run records (suite, manifest, "
                                        "budget, re-evaluated fitness)")
    p.add_argument("runs", nargs="+", metavar="RUNS.jsonl", help="run records to check")
    p.add_argument("--partial", action="store_true",
                   help="do not require every instance of the suite (a shard, a quick run)")
    p.add_argument("--per-tier", type=count(1, 1000), default=None, metavar="N",
                   help="emafdi-v2: require the first N instances of each tier only (a board "
                        "swept with --per-tier N, e.g. the committed one)")
    p.add_argument("--no-reevaluate", action="store_true",
                   help="skip re-evaluating each reported vector (fast, weaker)")
    p.add_argument("--replay", metavar="K", default=None,
                   help="also re-run K records (a sample from fresh entropy; 'all': every one), "
                        "each in its own process, with the "
                        "registered solver at the record's identity and compare the trace, "
                        "best_at, final vector and trajectory (catches a solver that reads "
                        "what it was not given, and hits moved earlier)")
    p.add_argument("--replay-seed", type=seed_number, default=None, metavar="S",
                   help="seed of the replay sample (default: fresh entropy, printed; give "
                        "the printed one to repeat a check, or one committed before the "
                        "submission)")
    add_legacy(p, "admit")
    p.add_argument("--replay-key", action="append", default=None, metavar="KEY",
                   help="replay the record with this key (solver|case|track|seed; "
                        "repeatable) instead of a sample")
    add_targets(p)
    add_json(p, "the findings")


def run(args: argparse.Namespace) -> int:
    from ..escape import terminal
    from ..leaderboard.judge import JudgeError, judge, read_runs
    from ..leaderboard.validate import LEGACY_UNVERIFIABLE, Finding
    from ..sampling import escape_chance, sample_seed
    from ..suites import suite_of

    try:
        lines = read_runs(args.runs)
    except JudgeError as exc:
        raise CLIError(str(exc)) from None
    if not lines:
        raise CLIError(f"no run records in {', '.join(map(terminal, args.runs))}")
    verdict = judge(lines, reevaluate=not args.no_reevaluate, complete=not args.partial,
                    per_tier=args.per_tier, legacy=args.legacy)
    records, found = verdict.records, verdict.findings
    SUITE_ID = ", ".join(sorted({suite_of(r.get("case")).id for r in records}))  # noqa: N806
    keys = set(args.replay_key or ()) or None
    if keys:
        unknown = sorted(keys - {r.get("key") for r in records})
        if unknown:
            raise CLIError(f"--replay-key {terminal(unknown[0])!r}: no record of that key in "
                           f"{', '.join(map(terminal, args.runs))}")
    k = "all" if keys and not args.replay else args.replay
    seed = sample_seed(args.replay_seed) if k is not None and not keys else 0
    replayed = _replay(records, k, seed, keys)
    found += [Finding(r.key, f"replay: {r.finding}") for r in replayed if r.finding]
    ok = sum(r.finding is None for r in replayed)
    pool = sum(1 for r in records if r.get("status") != "error")
    chance = escape_chance(pool, len(replayed)) if replayed and not keys else None
    print_result(args, {"suite": SUITE_ID, "records": len(records), "accepted": not found,
                        "per_tier": args.per_tier,
                        "legacy_records": verdict.legacy, "replayed": len(replayed),
                        "reproduced": ok, "replay_seed": None if keys else seed,
                        "escape_chance": chance,
                        "replay_wall_s": sum(r.wall_s for r in replayed),
                        "findings": [{"key": f.key, "problem": f.problem} for f in found]}, [
        *([f"{verdict.legacy} legacy record(s) (schema 1, no trajectory vectors), admitted "
           f"to a legacy view (--legacy): their {'; '.join(LEGACY_UNVERIFIABLE)} are checked "
           "against bounds only and verified by --replay"] if verdict.legacy and args.legacy
          else []),
        *([f"replay: {ok}/{len(replayed)} records reproduced, each in its own process "
           f"({sum(r.wall_s for r in replayed):.0f} s"
           + (f"; sample seed {seed}, --replay-seed {seed} repeats it)" if not keys else ")")]
          if replayed else []),
        *([f"replay: a run with one forged record escapes a sample this size with "
           f"probability {chance:.3f}"] if chance is not None else []),
        *([f"REFUSED: {len(found)} finding(s) in {len(records)} records (suite {SUITE_ID}):",
           *(f"  {f}" for f in found)] if found else
          [f"accepted: {len(records)} records of suite {SUITE_ID}"
           + (f" (complete on the first {args.per_tier} instances of each tier only)"
              if args.per_tier and not args.partial else "")])])
    return 1 if found else 0


def _replay(records: list[dict], k: str | None, seed: int | None,
            keys: set[str] | None) -> list:
    from ..leaderboard.replay import replay

    if k is None:
        return []
    if k != "all" and not (k.isdigit() and int(k) > 0):
        raise CLIError(f"--replay takes a positive number of records or 'all', got {k!r}")
    return replay(records, None if k == "all" else int(k), seed, keys)
