"""A newcomer's probes of the command line (issue 13), runnable against any checkout.

Each probe runs real ``ema-bench`` commands in a fresh temporary folder, as a new user would,
and says whether the tool held (a clear one-line error with exit code 2, nothing lost, nothing
silently accepted, progress shown) or failed.  Run it against two checkouts to get the
before/after table of the issue::

    python benchmarks/newcomer_probes.py                       # this checkout
    python benchmarks/newcomer_probes.py --code /path/to/old   # another one (its ema_bench/)
    python benchmarks/newcomer_probes.py --json > probes.json

The code under test is imported from ``--code`` through ``PYTHONPATH``; the solver zoo is the
installed one.  About 2-4 minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Callable
from pathlib import Path

PROBES: dict[str, Callable[[Path], tuple[bool, str]]] = {}


def probe(item: str, name: str):
    def deco(func):
        PROBES[f"{item}: {name}"] = func
        return func
    return deco


class Env:
    code: Path
    timeout = 300


def run(cwd: Path, *args: str, timeout: float | None = None, wrapper: str | None = None
        ) -> subprocess.CompletedProcess:
    """``ema-bench ARGS`` (or ``python WRAPPER ARGS``) with the code under test."""
    env = {**os.environ, "PYTHONPATH": str(Env.code), "PYTHONUNBUFFERED": "1"}
    head = [sys.executable, wrapper] if wrapper else [sys.executable, "-m", "ema_bench.cli"]
    return subprocess.run([*head, *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout or Env.timeout)


def clear_error(res: subprocess.CompletedProcess, *needles: str) -> tuple[bool, str]:
    """Held when: exit code 2, no traceback, one error line containing every needle."""
    err = res.stderr.strip().splitlines()
    last = err[-1] if err else ""
    ok = (res.returncode == 2 and "Traceback" not in res.stderr and "error:" in last
          and all(n.lower() in last.lower() for n in needles))
    return ok, f"rc={res.returncode}: {last[:160]}"


def _monitor_csv(tmp: Path, name: str = "m.csv", tests: str = "step,sine") -> Path:
    path = tmp / name
    res = run(tmp, "simulate", "--model", "monitor", "--case", "small", "--tests", tests,
              "--out", str(path))
    if res.returncode:
        raise RuntimeError(res.stderr)
    return path


def _single_test_csv(tmp: Path, test: str) -> Path:
    """A plain measured CSV of one test: no 'test' column."""
    src = _monitor_csv(tmp, f"src_{test}.csv", tests=test).read_text().splitlines()
    rows = [ln for ln in src if not ln.startswith("#")]
    header = rows[0].split(",")
    keep = [i for i, h in enumerate(header) if not h.strip().startswith("test")]
    out = tmp / f"{test}.csv"
    out.write_text("\n".join(",".join(r.split(",")[i] for i in keep) for r in rows) + "\n")
    return out


# ---- 1. concurrent sweeps ----------------------------------------------------------------

LB = ("leaderboard", "--quick", "--budget", "30", "--solvers", "random", "--cases",
      "small,full", "--tracks", "twin", "--seeds", "2", "--executor", "serial", "--no-plots")


@probe("1", "two concurrent leaderboards on one --out run each task once")
def _concurrent(tmp: Path) -> tuple[bool, str]:
    out = tmp / "lb"
    env = {**os.environ, "PYTHONPATH": str(Env.code)}
    procs = [subprocess.Popen([sys.executable, "-m", "ema_bench.cli", *LB, "--out", str(out)],
                              cwd=tmp, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE) for _ in range(2)]
    for p in procs:
        p.communicate(timeout=Env.timeout)
    lines = [json.loads(ln) for ln in (out / "runs.jsonl").read_text().splitlines() if ln]
    table = (out / "leaderboard_twin.md").read_text()
    ok = len(lines) == 4 and "2/4" not in table.replace(" ", "") and "/8" not in table
    return ok, f"{len(lines)} lines for 4 runs"


# ---- 2. a failing solver -----------------------------------------------------------------

BOOM = textwrap.dedent("""
    import sys
    from ema_bench.registry import register_solver

    @register_solver("boom", description="raises", library="none")
    def solve(problem, budget, seed):
        raise RuntimeError("boom: this solver always fails")

    from ema_bench.cli import main
    raise SystemExit(main(sys.argv[1:]))
""")


@probe("2", "a failing solver is recorded and the sweep goes on (and resumes)")
def _failing_solver(tmp: Path) -> tuple[bool, str]:
    wrapper = tmp / "boom.py"
    wrapper.write_text(BOOM)
    out = tmp / "lb"
    args = ["leaderboard", "--quick", "--budget", "30", "--solvers", "boom,random", "--cases",
            "small", "--tracks", "twin", "--seeds", "1", "--executor", "serial",
            "--no-plots", "--out", str(out)]
    first = run(tmp, *args, wrapper=str(wrapper))
    again = run(tmp, *args, wrapper=str(wrapper))
    recs = [json.loads(ln) for ln in (out / "runs.jsonl").read_text().splitlines() if ln] \
        if (out / "runs.jsonl").exists() else []
    ok = ("Traceback" not in first.stderr + again.stderr
          and {r.get("solver") for r in recs} >= {"boom", "random"}
          and "boom" in first.stdout + first.stderr)
    return ok, f"rc={first.returncode}/{again.returncode}, {len(recs)} records"


# ---- 3. SIGKILL of the parent ------------------------------------------------------------

def _children(pid: int) -> set[int]:
    kids = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            kids.add(int(stat.parent.name))
    return kids


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@probe("3", "SIGKILL of a leaderboard leaves no orphan workers")
def _orphans(tmp: Path) -> tuple[bool, str]:
    env = {**os.environ, "PYTHONPATH": str(Env.code)}
    p = subprocess.Popen([sys.executable, "-m", "ema_bench.cli", "leaderboard", "--budget",
                          "3000", "--solvers", "random", "--cases", "small,full",
                          "--tracks", "twin", "--seeds", "4", "--executor", "processes",
                          "--workers", "2", "--no-plots", "--out", str(tmp / "lb")],
                         cwd=tmp, env=env, stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL)
    workers: set[int] = set()
    t0 = time.time()
    while time.time() - t0 < 60 and len(workers) < 2:
        workers = {k for k in _children(p.pid)}
        time.sleep(0.5)
    time.sleep(2)
    workers = _children(p.pid)
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    time.sleep(8)
    left = [w for w in workers if _alive(w)]
    for w in left:
        os.kill(w, signal.SIGKILL)
    return (bool(workers) and not left), f"{len(workers)} children, {len(left)} alive 8 s later"


# ---- 4. write errors ---------------------------------------------------------------------

def _write_probe(args_of: Callable[[Path, Path], list[str]], needle: str):
    def check(tmp: Path) -> tuple[bool, str]:
        a_file = tmp / "a_file"
        a_file.write_text("x")
        t0 = time.time()
        res = run(tmp, *args_of(tmp, a_file))
        ok, msg = clear_error(res, needle)
        took = time.time() - t0
        return ok and took < 20, f"{msg} ({took:.0f} s)"
    return check


for _name, _args in {
    "simulate --out under a file": lambda t, f: ["simulate", "--out", f"{f}/x.csv"],
    "simulate --out with an unknown suffix": lambda t, f: ["simulate", "--out", f"{t}/x.txt"],
    "solve --plot under a file": lambda t, f: ["solve", "--budget", "50", "--plot",
                                               f"{f}/p.png"],
    "diagnose --report on a file": lambda t, f: ["diagnose", str(_monitor_csv(
        t, tests="step,sine,sine2")), "--budget", "100", "--bootstrap", "10", "--report",
        str(f)],
    "blind --out on a file": lambda t, f: ["blind", "--cases", "1", "--out", str(f)],
    "leaderboard --out on a file": lambda t, f: [*LB, "--out", str(f)],
}.items():
    probe("4", _name)(_write_probe(_args, ""))


# ---- 5. huge budgets ---------------------------------------------------------------------

@probe("5", "solve --budget 1e12 is refused clearly")
def _huge_budget(tmp: Path) -> tuple[bool, str]:
    return clear_error(run(tmp, "solve", "--budget", str(10**12)), "budget")


@probe("5", "make_problem(budget=10**12) raises the project's error")
def _huge_budget_api(tmp: Path) -> tuple[bool, str]:
    code = ("from ema_bench import make_problem\n"
            "try:\n    make_problem('small', track='twin', budget=10**12)\n"
            "except ValueError as e:\n    print('ok', e)\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(Env.code)}, timeout=120)
    return res.stdout.startswith("ok"), (res.stdout + res.stderr).strip().splitlines()[-1][:120]


# ---- 6. a crafted .npz -------------------------------------------------------------------

@probe("6", "a 28 KB .npz claiming 1e10 samples is refused without MemoryError")
def _crafted_npz(tmp: Path) -> tuple[bool, str]:
    import io
    import zipfile

    import numpy as np

    hdr = io.BytesIO()
    np.lib.format.write_array_header_1_0(hdr, {"descr": "<f8", "fortran_order": False,
                                               "shape": (10**10,)})
    path = tmp / "crafted.npz"
    with zipfile.ZipFile(path, "w") as z:
        for key in ("time_step", "step_theta_u"):
            z.writestr(f"{key}.npy", hdr.getvalue() + bytes(28_000))
        z.writestr("units.npy", hdr.getvalue()[:0] + _npy(np.array(["time=s"])))
    return clear_error(run(tmp, "solve", "--measured", str(path), "--budget", "10"))


def _npy(arr) -> bytes:
    import io

    import numpy as np

    b = io.BytesIO()
    np.save(b, arr)
    return b.getvalue()


# ---- 7. single-test files from the CLI ---------------------------------------------------

@probe("7", "solve fits a single-test plain CSV named with --test")
def _single_csv(tmp: Path) -> tuple[bool, str]:
    step = _single_test_csv(tmp, "step")
    res = run(tmp, "solve", "--measured", str(step), "--test", "step", "--budget", "30",
              "--solver", "random")
    return res.returncode == 0, f"rc={res.returncode}: {res.stderr.strip()[-140:]}"


@probe("7", "diagnose reads three single-test files")
def _multi_files(tmp: Path) -> tuple[bool, str]:
    files = [str(_single_test_csv(tmp, t)) for t in ("step", "sine", "sine2")]
    res = run(tmp, "diagnose", *files, "--test", "step,sine,sine2", "--budget", "100",
              "--bootstrap", "10")
    return res.returncode == 0 and "verdict" in res.stdout, \
        f"rc={res.returncode}: {res.stderr.strip()[-140:]}"


# ---- 8. silent acceptance in simulate ----------------------------------------------------

@probe("8", "simulate --faults Na=0.9,Na=0.95 is refused")
def _dup(tmp: Path) -> tuple[bool, str]:
    return clear_error(run(tmp, "simulate", "--faults", "Na=0.9,Na=0.95"), "twice")


@probe("8", "simulate --faults '' is refused")
def _empty(tmp: Path) -> tuple[bool, str]:
    return clear_error(run(tmp, "simulate", "--faults", ""), "empty")


@probe("8", "simulate --model monitor --effect records the effect in the file")
def _effect_meta(tmp: Path) -> tuple[bool, str]:
    out = tmp / "m.csv"
    res = run(tmp, "simulate", "--model", "monitor", "--effect", "delay=6e-4", "--out",
              str(out))
    text = out.read_text() if out.exists() else ""
    return res.returncode == 0 and '"delay"' in text, f"rc={res.returncode}"


# ---- 9. progress and defaults ------------------------------------------------------------

@probe("9", "diagnose shows progress when not a terminal")
def _diag_progress(tmp: Path) -> tuple[bool, str]:
    res = run(tmp, "diagnose", str(_monitor_csv(tmp, tests="step,sine,sine2")), "--budget",
              "100", "--bootstrap", "10")
    n = sum("diagnose" in ln for ln in res.stderr.splitlines())
    return res.returncode == 0 and n >= 2, f"{n} progress lines"


@probe("9", "leaderboard prints a line per finished run when not a terminal")
def _lb_progress(tmp: Path) -> tuple[bool, str]:
    res = run(tmp, *LB, "--out", str(tmp / "lb"))
    n = sum("run" in ln and "/4" in ln for ln in res.stderr.splitlines())
    return res.returncode == 0 and n >= 4, f"{n} progress lines"


@probe("9", "leaderboard does not write into ./leaderboards by default")
def _lb_default(tmp: Path) -> tuple[bool, str]:
    run(tmp, *LB)
    return not (tmp / "leaderboards").exists(), \
        "wrote ./leaderboards" if (tmp / "leaderboards").exists() else "no ./leaderboards"


@probe("9", "blind writes a resumable folder by default and shows progress")
def _blind_default(tmp: Path) -> tuple[bool, str]:
    res = run(tmp, "blind", "--cases", "1")
    folders = [p for p in tmp.iterdir() if p.is_dir()]
    n = sum("blind" in ln for ln in res.stderr.splitlines())
    return res.returncode == 0 and bool(folders) and n >= 1, \
        f"folders {[p.name for p in folders]}, {n} progress lines"


# ---- 10. messages for the command line ---------------------------------------------------

@probe("10", "--faults out of bounds names no Python 'row'")
def _row(tmp: Path) -> tuple[bool, str]:
    res = run(tmp, "simulate", "--faults", "Na=5")
    ok, msg = clear_error(res, "Na")
    return ok and "row" not in res.stderr, msg


@probe("10", "a single-test CSV error speaks of --test, not test=")
def _test_hint(tmp: Path) -> tuple[bool, str]:
    res = run(tmp, "solve", "--measured", str(_single_test_csv(tmp, "step")), "--budget", "10")
    ok, msg = clear_error(res, "--test")
    return ok and "test=<" not in res.stderr, msg


@probe("10", "a time column in ms labelled [s] is reported as a unit mix-up")
def _ms(tmp: Path) -> tuple[bool, str]:
    src = _single_test_csv(tmp, "step").read_text().splitlines()
    rows = [src[0]] + [",".join([repr(float(r.split(",")[0]) * 1000), *r.split(",")[1:]])
                       for r in src[1:]]
    path = tmp / "ms.csv"
    path.write_text("\n".join(rows) + "\n")
    return clear_error(run(tmp, "solve", "--measured", str(path), "--test", "step",
                           "--budget", "10"), "ms")


@probe("10", "random bytes in an .npz are reported as a corrupt file")
def _random_npz(tmp: Path) -> tuple[bool, str]:
    path = tmp / "noise.npz"
    path.write_bytes(os.urandom(4096))
    res = run(tmp, "solve", "--measured", str(path), "--budget", "10")
    ok, msg = clear_error(res)
    return ok and "allow_pickle" not in res.stderr and "pickle" not in res.stderr, msg


@probe("10", "--help shows no raw reST markup")
def _help(tmp: Path) -> tuple[bool, str]:
    bad = []
    for c in ("simulate", "solve", "leaderboard", "diagnose", "blind", "bench", "params"):
        text = run(tmp, c, "--help").stdout
        if "``" in text or ":func:" in text or "::\n" in text:
            bad.append(c)
    return not bad, f"markup in {bad}" if bad else "clean"


@probe("10", "params cites no file outside the repository")
def _params(tmp: Path) -> tuple[bool, str]:
    text = run(tmp, "params").stdout
    return "DESIGN" not in text, "cites DESIGN" if "DESIGN" in text else "clean"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--code", default=str(Path(__file__).resolve().parents[1]),
                    help="checkout whose ema_bench/ is probed (default: this one)")
    ap.add_argument("--only", default=None, help="probes whose name contains this text")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    Env.code = Path(args.code).resolve()
    results = {}
    for name, func in PROBES.items():
        if args.only and args.only not in name:
            continue
        with tempfile.TemporaryDirectory(prefix="ema-probe-") as d:
            t0 = time.time()
            try:
                held, detail = func(Path(d))
            except Exception as exc:  # a probe that crashes is a failure of the tool
                held, detail = False, f"{type(exc).__name__}: {str(exc)[:140]}"
            results[name] = {"held": bool(held), "detail": detail,
                             "s": round(time.time() - t0, 1)}
        if not args.json:
            r = results[name]
            print(f"{'held ' if r['held'] else 'FAIL '} {name:<72} {r['detail']}", flush=True)
    n = sum(r["held"] for r in results.values())
    if args.json:
        print(json.dumps({"code": str(Env.code), "held": n, "probes": len(results),
                          "results": results}, indent=1))
    else:
        print(f"{n}/{len(results)} held ({Env.code})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
