"""Red team, trackers (issue 48, item 5): a tracker runs like a solver, in a process of its
own that holds its unit's inspections and the published settings only, and a campaign that
judges untrusted trackers has a seed its files do not give away.

Real campaigns (``make_campaign``, twin track, an inspection every 50 flights to keep them
small), the red-team tracker installed as a plugin (an entry point, found by the worker
processes as any submitted tracker is), and the attack that found the committed campaign's
seed from its logged temperatures.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ema_bench.cli import main
from ema_bench.prognostics.campaign import _conditions, get_spec, make_campaign
from ema_bench.prognostics.laws import unit_history
from ema_bench.prognostics.track_io import read_track
from ema_bench.seeding import run_seed, stream

PLUGIN = Path(__file__).resolve().parent / "redteam"


@pytest.fixture(scope="module")
def secret(tmp_path_factory) -> Path:
    """A 2-unit campaign with a secret seed, made by the command."""
    out = tmp_path_factory.mktemp("secret") / "c"
    assert main(["campaign", "make", "fleet-v1", "--units", "2", "--every", "50",
                 "--secret-seed", "--out", str(out), "--quiet"]) == 0
    return out


def test_a_secret_seed_is_not_given_with_a_seed(tmp_path, capsys):
    assert main(["campaign", "make", "fleet-v1", "--seed", "3", "--secret-seed", "--out",
                 str(tmp_path / "c")]) == 2
    assert "give --seed or --secret-seed, not both" in capsys.readouterr().err
    assert not (tmp_path / "c").exists()


def search(manifest: dict, candidates: range) -> int | None:
    """The attack: unit 0's logged conditions rebuilt from each candidate root seed (its laws
    are public, its life is run ``(S, 0)``'s ``instance`` stream), until they match."""
    laws = get_spec(manifest["name"]).laws
    logged = manifest["units"][0]["inspections"]
    for s in candidates:
        h = unit_history(stream(run_seed(s, 0), "instance"), laws)
        flights = [i["flight"] for i in logged]
        if all(_conditions(h, f, flights[k - 1] if k else None)["ambient_temp_C"]
               == i["conditions"]["ambient_temp_C"] for k, (f, i) in enumerate(zip(flights,
                                                                                   logged))):
            return s
    return None


def test_the_logs_find_a_small_seed_but_not_a_secret_one(secret, tmp_path):
    public = tmp_path / "public"
    make_campaign(units=1, seed=37, inspection_every=50, out=public)
    manifest = json.loads((public / "manifest.json").read_text())
    assert search(manifest, range(64)) == 37          # the attack is real
    manifest = json.loads((secret / "manifest.json").read_text())
    truth = json.loads((secret / "truth.json").read_text())
    hidden = truth["secret_seed"]
    assert manifest["seed"] is None and truth["seed"] is None
    assert isinstance(hidden, int) and 0 <= hidden < 2**63
    assert search(manifest, range(64)) is None
    # the seed is in truth.json alone: no other file of the folder holds its digits
    files = [p for p in secret.rglob("*") if p.is_file() and p.name != "truth.json"]
    assert len(files) > 2 and not any(str(hidden).encode() in p.read_bytes() for p in files)


def test_a_tracker_holds_neither_campaign_nor_folder_nor_seed(secret, tmp_path):
    """The red-team tracker looks through its process (the garbage collector's objects, the
    callers' frames) for the campaign, a folder holding a manifest and the seed; it finds
    nothing, and runs in a child of the campaign's process; the campaign's process
    (``campaign track``, then ``campaign score --replay``, which re-tracks a unit in a fresh
    process) imports no tracker plugin.  Its lines replay."""
    truth = json.loads((secret / "truth.json").read_text())
    run = tmp_path / "run"
    code = ("import os, sys\nfrom ema_bench.cli import main\n"
            f"rc = main(['campaign', 'track', {str(secret)!r}, '--tracker', "
            f"'rt-campaign-peeker', '--out', {str(run)!r}, '--seed', '3', '--quiet'])\n"
            f"rc += main(['campaign', 'score', {str(run)!r}, '--replay', '1', '--no-oracle', "
            "'--json'])\n"
            "bad = [m for m in sys.modules if m.startswith(('ema_bench_trackers', "
            "'ema_bench_redteam'))]\n"
            "print(rc, os.getpid(), bad)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(PLUGIN)})
    rc, pid, bad = out.stdout.strip().splitlines()[-1].split(" ", 2)
    assert (rc, bad) == ("0", "[]"), out.stdout[-2000:] + out.stderr[-2000:]
    log = read_track(run)
    assert log.manifest["campaign_seed"] is None and log.manifest["seed_scheme"] == 2
    seen = {u: rows[0]["extra"] for u, rows in log.steps.items()}
    assert len(seen) == 2 and not log.failed
    for e in seen.values():
        # a child of the campaign's process, holding nothing of the campaign
        assert e["found"] == {"parent": int(pid), "objects": [], "folders": [], "frames": []}
        assert "seed" not in e["settings"] and str(truth["secret_seed"]) not in json.dumps(e)
        assert e["seed"] not in ("3", str(truth["secret_seed"]))   # a hash, not the root
