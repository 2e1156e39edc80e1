"""``ema-bench targets``: (re)compute the suite's best-known optima f* (its fixed targets).

One long multi-solver polishing run per (instance, track, noise seed) of the suite: zoo
least-squares warm-started at the truth, zoo powell from its best, zoo cmaes from nominal
(2700 evaluations in all; ema_bench/suites/best_known.py documents the method).  It writes the JSON
the package ships as ema_bench/suite_targets.json (--suite emafdi-v2: the package's
suite_targets_v2.json, seed 0 shipped, whose seed-0 reference entries also hold the
clean-data fit that picks the judged parameters; --suite emafdi-v3: suite_targets_v3.json,
v2's objectives and tier 4 with full information on model version 4, docs/suite-v3.md);
entries are appended to OUT.partial.jsonl as they
finish, so an interrupted run resumes.  v1: about 3 CPU-s per entry, 460 entries.  v2:
docs/suite-v2.md gives the cost per entry and tier.  --tiers, --conditions, --per-tier,
--seeds, --tracks (and for v1 --cases) compute a subset, e.g. to regenerate part of a
table.  --root-seed R polishes the instances of a board at root seed R (the shipped tables
are of root seed 0; another root seed draws other noise, so other optima): 'leaderboard',
'export' and 'validate' then take the table with --targets FILE.  --show prints the shipped
table's summary instead.

Examples::

    ema-bench targets --out ema_bench/suite_targets.json          # regenerate (~25 CPU-min)
    ema-bench targets --suite emafdi-v2 --out suite_targets_v2.json   # then ship it
    ema-bench targets --suite emafdi-v2 --tiers 7 --conditions prior --per-tier 2 \\
        --seeds 1 --tracks reference --out /tmp/t.json                 # a handful
    ema-bench targets --root-seed 70 --cases quick --seeds 2 --out t70.json
    ema-bench leaderboard --quick --root-seed 70 --targets t70.json --out lb70
    ema-bench targets --show --json
"""

from __future__ import annotations

import argparse
import statistics

from .. import interval_calibration_files as files
from ..instances import TRACKS
from ..suites import DEFAULT, SUITES, instance
from ..suites.base import Selection
from ..suites.targets import read_targets
from ..suites.v1 import describe
from ..suites.v2 import judged_by_entry
from . import CLIError, print_result
from .args import add_json, add_quiet, check_output, count, option_list, seed_number, worker_count


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("targets", help="compute or show the suite's best-known optima f*")
    p.add_argument("--out", default=None, metavar="FILE.json",
                   help="where to write the table (required unless --show)")
    p.add_argument("--suite", choices=tuple(SUITES), default=DEFAULT.id,
                   help="the suite whose table to compute or show (default emafdi-v1)")
    p.add_argument("--cases", type=option_list, default=None,
                   help="emafdi-v1: instances or groups (all, paper, lhs, quick; default all)")
    p.add_argument("--tiers", type=option_list, default=None,
                   help="emafdi-v2, v3: comma-separated tiers (default all)")
    p.add_argument("--conditions", type=option_list, default=None,
                   help="emafdi-v2, v3: conditions (default all; no-prior shares prior's "
                        "entries)")
    p.add_argument("--per-tier", type=count(1, 1000), default=None,
                   help="emafdi-v2, v3: the first N instances of each tier (default all)")
    p.add_argument("--seeds", type=count(1, 1000), default=None,
                   help="noise seeds 0..N-1 (default: the suite's, v1 10, v2 5, v3 the "
                        "shipped ones)")
    p.add_argument("--tracks", type=option_list, default=None,
                   help="comma-separated tracks (default reference,twin)")
    p.add_argument("--root-seed", type=seed_number, default=0,
                   help="the root seed of the board whose instances to polish (default 0, "
                        "the shipped table's); the table records it, and 'leaderboard', "
                        "'export' and 'validate' read it with --targets FILE")
    p.add_argument("--workers", type=worker_count, default=None, help="processes (default: cores)")
    p.add_argument("--show", action="store_true", help="summarise the shipped table")
    add_json(p, "the summary")
    add_quiet(p)


def _keys(args: argparse.Namespace) -> list[str] | None:
    """The keys to compute (None: every key of the suite's table)."""
    bad = [t for t in args.tracks or () if t not in TRACKS]
    if bad:
        raise CLIError(f"unknown track(s) {bad}; known: {list(TRACKS)}")
    # SuiteError, FaultError, a tier that is not a number: ValueErrors, one line by main()
    return SUITES[args.suite].target_keys(
        Selection(args.cases, args.tiers, args.conditions, args.per_tier), args.seeds,
        args.tracks)


def run(args: argparse.Namespace) -> int:
    suite = SUITES[args.suite]
    # a suite with clean-data fits (emafdi-v2) reports what they exclude and their cost
    clean = suite.clean_fits
    if args.show:
        data = read_targets(suite.targets_file(), suite.id, missing_ok=False,
                            model_version=suite.model_version)
    elif args.out is None:
        raise CLIError("--out FILE.json is required (or --show)")
    else:
        from ..suites.best_known import compute_targets

        keys = _keys(args)
        _check_not_shipped(args)
        out = check_output(args.out, "--out", folder=False, suffixes=(".json",))
        data = compute_targets(out, workers=args.workers, quiet=args.quiet, keys=keys,
                               root_seed=args.root_seed)
    entries = data["entries"]
    bias = sorted(((e["bias_range_error"], k) for k, e in entries.items()), reverse=True)
    summary = {"suite": data["suite"], "model_version": data["model_version"],
               "entries": len(entries),
               "largest_bias": [{"key": k, "bias_range_error": b} for b, k in bias[:5]]}
    if clean:
        summary["excluded"] = _excluded(entries)
        summary["cost_by_tier"] = _cost_by_tier(entries)
    else:
        summary = {**describe(), **summary}
    lines = [f"suite {summary['suite']} (model version {summary['model_version']}): "
             f"{len(entries)} best-known optima",
             *(f"  {k}: best-known point {100 * b:.2f} % of range from the truth"
               for b, k in bias[:5])]
    if clean:
        clean = sum("clean_x" in e for e in entries.values())
        lines += [f"  {clean} clean-data fits; parameters without parameter targets on the "
                  f"reference track (clean-data bias over 0.3 % of range): "
                  f"{len(summary['excluded'])} instances",
                  *(f"    {k.split('|')[0]}: {', '.join(names)}"
                    for k, names in summary["excluded"].items()),
                  *(f"  tier {d}: {c['entries']} entries, median {c['cpu_s_median']:.1f} "
                    f"CPU-s, {c['cpu_s_total']:.0f} CPU-s in all"
                    for d, c in summary["cost_by_tier"].items())]
    return print_result(args, summary, lines)


def _excluded(entries: dict) -> dict[str, list[str]]:
    """Per entry with a clean-data fit that excludes some: the parameters without
    parameter targets (:func:`~ema_bench.suites.v2.judged_by_entry`, as scoring judges)."""
    out = {}
    for k, e in entries.items():
        case = k.split("|")[0]
        inst = instance(case)
        judged = judged_by_entry(inst, e)
        if judged is not None and not judged.all():
            out[k] = [n for n, j in zip(inst.names, judged) if not j]
    return out


def _cost_by_tier(entries: dict) -> dict[str, dict[str, float]]:
    """Per tier: entries, median and total CPU seconds (those that recorded them)."""
    by: dict[int, list[float]] = {}
    for k, e in entries.items():
        if "cpu_s" in e:
            by.setdefault(instance(k.split("|")[0]).dim, []).append(e["cpu_s"])
    return {str(d): {"entries": len(v), "cpu_s_median": statistics.median(v),
                     "cpu_s_total": sum(v)} for d, v in sorted(by.items())}


def _check_not_shipped(args: argparse.Namespace) -> None:
    """``--out`` inside the package: refused in an installed copy (shipped data is
    read-only), and in a checkout for a selection (it would replace the shipped table with a
    part of it: 460 entries became 1, and validate then refused genuine records)."""
    if not files.inside_package(args.out):
        return
    if files.checkout_root() is None:   # looked up at the call (tests stand in for it)
        raise CLIError(f"--out {args.out}: inside the installed package, whose data is "
                       "read-only; write the table elsewhere")
    chosen = [f"--{n.replace('_', '-')}" for n in ("cases", "tiers", "conditions", "per_tier",
                                                    "seeds", "tracks") if getattr(args, n, None)]
    if chosen:
        raise CLIError(f"--out {args.out}: {', '.join(chosen)} select part of the suite, which "
                       "would replace the shipped table; write the selection elsewhere")
