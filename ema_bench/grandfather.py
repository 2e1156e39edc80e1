"""Seed scheme 1 is accepted for the committed records only, never for a new submission.

Records written before seed schemes were recorded (no ``seed_scheme``: scheme 1,
:data:`~ema_bench.seeding.SEED_SCHEMES`) gave the solver a spawned stream of its run node,
from which it could rebuild the node and draw its instance and noise streams.  The committed
boards and campaigns were made that way by the maintainers, with the zoo; they still validate
and replay (replay derives the seed by the record's scheme).  Anyone else could claim the old
scheme simply by leaving the field out, so scheme 1 is accepted only for a record whose
digest (:func:`record_digest`: SHA-256 of the record's canonical JSON, every field) is in the
shipped list ``grandfathered.json``, made once from the committed files by this module's
command (``python -m ema_bench.grandfather --check`` confirms it, in a checkout; run
again, it only drops digests: a record added to a committed file later is never
grandfathered).
A copy of a committed record with any field changed (its solver, a hit, a vector) has another
digest and is refused; a verbatim copy is the committed run itself, a duplicate of its
identity on a board that holds it.  The committed records are model version 2's too, and
that earlier, compatible version is accepted for them only (:mod:`ema_bench.leaderboard.
judge`): a new run is made on this installation's version.  Tracking runs (``campaign
score``) are bound the same way, by :func:`track_digest` of their manifest and steps.
"""

from __future__ import annotations

import argparse
import functools
import hashlib
import json
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path

from .jsonio import write_atomic
from .records import seed_scheme

FILE = Path(__file__).resolve().parent / "grandfathered.json"
FORMAT = "ema-bench-grandfathered"
#: Hex digits of a digest kept: 96 bits, beyond any search for a second preimage.
DIGEST_HEX = 24
#: The committed files made under seed scheme 1, relative to the checkout.
RUN_FILES = ("leaderboards/runs.jsonl", "leaderboards/quick/runs.jsonl",
             "leaderboards/check-pool/runs.jsonl", "leaderboards/paper-ga-10k/runs.jsonl")
TRACK_RUNS = "leaderboards/campaign/*/*/track.jsonl"


def _digest(value: object) -> str:
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=True,
                      allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()[:DIGEST_HEX]


def record_digest(record: dict) -> str:
    """The digest of a run record: every field, canonical JSON (key order and spacing do not
    matter, any value does)."""
    return _digest(record)


def track_digest(manifest: dict, steps: Iterable[dict]) -> str:
    """The digest of a tracking run: its manifest and every line of its ``track.jsonl``, as
    read (line order does not matter: units finish in any order)."""
    return _digest({"manifest": manifest, "steps": sorted(map(_digest, steps))})


@functools.cache
def _shipped() -> tuple[frozenset[str], frozenset[str]]:
    data = json.loads(FILE.read_text(encoding="utf-8"))
    return frozenset(data["records"]), frozenset(data["track_runs"])


def committed_record(record: dict) -> bool:
    """Whether ``record`` is one of the committed files' (its digest is shipped)."""
    return record_digest(record) in _shipped()[0]


def accepted_record(record: dict) -> bool:
    """Whether ``record``'s seed scheme is accepted: the current one always, scheme 1 for a
    committed record only."""
    return seed_scheme(record) != 1 or committed_record(record)


def _read_lines(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines()
            if line.strip()]


def _track_files(run: Path) -> tuple[dict, Path]:
    return json.loads((run / "manifest.json").read_text(encoding="utf-8")), run / "track.jsonl"


def accepted_track(run: str | Path) -> bool:
    """Whether the seed scheme of the tracking run in folder ``run`` (``manifest.json``,
    ``track.jsonl``) is accepted, as :func:`accepted_record`."""
    manifest, steps = _track_files(Path(run))
    return (manifest.get("seed_scheme", 1) != 1
            or track_digest(manifest, _read_lines(steps)) in _shipped()[1])


def compute(root: Path) -> dict:
    """The grandfathered digests of the committed files under the checkout ``root``: every
    scheme-1 record of :data:`RUN_FILES` and every scheme-1 tracking run of
    :data:`TRACK_RUNS`."""
    records = {record_digest(r) for f in RUN_FILES for r in _read_lines(root / f)
               if seed_scheme(r) == 1}
    tracks = set()
    for f in sorted(root.glob(TRACK_RUNS)):
        manifest, _ = _track_files(f.parent)
        if manifest.get("seed_scheme", 1) == 1:
            tracks.add(track_digest(manifest, _read_lines(f)))
    return {"format": FORMAT, "seed_scheme": 1,
            "digest": f"sha256 of the canonical JSON, first {DIGEST_HEX} hex digits",
            "run_files": list(RUN_FILES), "track_runs_glob": TRACK_RUNS,
            "records": sorted(records), "track_runs": sorted(tracks)}


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m ema_bench.grandfather [--check]``: write (or check) the shipped
    list from the committed files; in a checkout only."""
    from .interval_calibration_files import checkout_root

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true",
                    help="exit 1 when the shipped list differs from the committed files'")
    args = ap.parse_args(argv)
    root = checkout_root()
    if root is None:
        print("grandfather: not a checkout (the list is made from the committed files)",
              file=sys.stderr)
        return 2
    data = compute(root)
    if args.check:
        same = json.loads(FILE.read_text(encoding="utf-8")) == data
        print(f"{FILE.name}: {'matches' if same else 'differs from'} the committed files "
              f"({len(data['records'])} records, {len(data['track_runs'])} tracking runs)")
        return 0 if same else 1
    if FILE.exists():   # the list only shrinks: a record added later is never grandfathered
        shipped = json.loads(FILE.read_text(encoding="utf-8"))
        for k in ("records", "track_runs"):
            data[k] = sorted(set(data[k]) & set(shipped[k]))
    write_atomic(FILE, json.dumps(data, indent=0) + "\n")
    print(f"wrote {FILE} ({len(data['records'])} records, {len(data['track_runs'])} tracking "
          "runs)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
