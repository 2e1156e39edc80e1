"""Replay under the BLAS kernel a record was made with (ema_bench.leaderboard.replay).

The committed v3 board was made under two OpenBLAS kernels (SkylakeX, then Haswell, which one
stint's machine forced); the finite-difference solvers turn their last-bit differences into
another path, so a record replays only under its own.  Replay sends the records of another
kernel to a child process started with ``OPENBLAS_CORETYPE`` set to it.  Checked here: the
routing (which records go where, and which stay), and on a CPU with AVX-512 a real SkylakeX
record replayed from a Haswell process, with its negative control (the same record labelled
Haswell replays here, under Haswell, and is refused).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ema_bench.leaderboard import replay as rp

ROOT = Path(__file__).resolve().parents[1]
STORE = ROOT / "leaderboards" / "v3" / "runs.jsonl"
#: A tier-4 lbfgsb run made under SkylakeX whose trace differs under Haswell (evaluation 986).
SKYLAKE_RUN = "lbfgsb|v3-s10@step-only|reference|1"


def _record(key: str) -> dict:
    with STORE.open() as f:
        for line in f:
            if f'"key": "{key}"' in line:
                return json.loads(line)
    raise LookupError(key)


def _labelled(r: dict, blas: str | None, key: str) -> dict:
    return {**r, "key": key, "manifest": {**r["manifest"], "blas": blas}}


def test_records_of_another_kernel_go_to_a_child_under_it(monkeypatch):
    """Here Haswell, on a CPU without AVX-512: a SkylakeX record cannot be had (stays, its
    finding will name both kernels), a Zen one goes to a child under Zen, and Haswell,
    unrecorded and non-OpenBLAS ones stay here; results come back in sample order."""
    r = _record(SKYLAKE_RUN)
    recs = [_labelled(r, "openblas Haswell", "here"), _labelled(r, "openblas Zen", "zen"),
            _labelled(r, "openblas SkylakeX", "skylake"), _labelled(r, None, "none"),
            _labelled(r, "mkl Haswell", "mkl"), _labelled(r, "openblas Zen", "zen2")]
    monkeypatch.setattr(rp, "blas_kernel", lambda: "openblas Haswell")
    monkeypatch.setattr(rp, "_cpu_runs", lambda kernel: kernel not in rp.AVX512_KERNELS)
    sent = []

    def child(kernel, picked, workers):
        sent.append((kernel, [p["key"] for p in picked]))
        return [rp.ReplayResult(p["key"], None, 0.0) for p in picked]

    local = []

    def execute(jobs, *args, **kwargs):
        local.extend(j.key for j in jobs)
        return iter(())

    monkeypatch.setattr(rp, "_replay_under", child)
    monkeypatch.setattr(rp, "execute", execute)
    out = rp.replay(recs, None, 0)
    assert sent == [("Zen", ["zen", "zen2"])]
    assert local == ["0", "2", "3", "4"]          # sample indices of the records kept here
    assert [o.key for o in out] == ["zen", "zen2"]
    sent.clear()
    rp.replay(recs, None, 0, kernels=False)
    assert sent == []


@pytest.mark.skipif(not rp._cpu_runs("SkylakeX"), reason="this CPU has no AVX-512")
def test_a_skylake_record_replays_from_a_haswell_process_and_its_relabel_does_not(tmp_path):
    r = _record(SKYLAKE_RUN)
    assert r["manifest"]["blas"] == "openblas SkylakeX"
    env = {**os.environ, "OPENBLAS_CORETYPE": "Haswell"}
    exe = Path(sys.executable).with_name("ema-bench")
    outs = []
    for blas in ("openblas SkylakeX", "openblas Haswell"):
        runs = tmp_path / f"{blas.split()[1]}.jsonl"
        runs.write_text(json.dumps({**r, "manifest": {**r["manifest"], "blas": blas}}) + "\n")
        outs.append(subprocess.run([str(exe), "validate", str(runs), "--partial",
                                    "--no-reevaluate", "--replay", "all"],
                                   capture_output=True, text=True, env=env, timeout=600))
    made, relabelled = outs
    assert made.returncode == 0, made.stdout + made.stderr
    assert "1/1 records reproduced" in made.stdout
    assert relabelled.returncode == 1
    assert "trace at evaluation 986" in relabelled.stdout


def test_a_kernel_label_cannot_excuse_a_record(monkeypatch):
    """A forger who labels a record with a kernel whose child process then dies (a kernel
    the CPU mis-runs, a label OpenBLAS rejects) gets a finding for it, never a pass; a label
    that is not a plain name never reaches the child's environment."""
    r = _record(SKYLAKE_RUN)
    monkeypatch.setattr(rp, "blas_kernel", lambda: "openblas Haswell")
    monkeypatch.setattr(rp, "_cpu_runs", lambda kernel: True)
    monkeypatch.setattr(rp.subprocess, "run", lambda *a, **k: subprocess.CompletedProcess(
        a, -4, "", "Illegal instruction"))
    out = rp.replay([_labelled(r, "openblas Zen", "forged")], None, 0)
    assert [(o.key, o.finding) for o in out] == [
        ("forged", "replay failed under BLAS kernel Zen: Illegal instruction")]
    assert rp._elsewhere(_labelled(r, "openblas Zen;rm", "x"), "openblas Haswell") is None
    assert rp._elsewhere(_labelled(r, "openblas Zen", "x"), "openblas Haswell") == "Zen"
