"""Fuzz test of ``load_traces``: mutated CSV, NPZ and MAT files load or raise TracesError.

Every file is a valid traces file mutated one to three times (byte flips, truncation, inserted
and deleted bytes, header and unit edits, duplicated lines, swapped columns, NaN/inf/huge
numbers, zip-member and .npy-header corruption, MATLAB tag and dimension words, ...).  Any
exception other than :class:`~ema_bench.traces.TracesError`, a TracesError caused by a
MemoryError, or a load slower than :data:`MAX_LOAD_S` is a loader bug.

The loop runs in a child process whose address space is capped (:data:`MEMORY_HEADROOM` above
what its imports use), so a loader that allocates from a crafted size fails here instead of
exhausting the machine.  Case ``i`` is drawn from ``SeedSequence([SEED, i])``; reproduce one
with ``python tests/test_traces_fuzz.py --case i`` (writes the file, loads it, shows the
traceback).
"""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
import time
import traceback
import warnings
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from ema_bench.traces import UNITS, Traces, TracesError, load_traces

SEED = 20240617
N_FILES = 6000  # mutated files per run, over the six base files
MAX_LOAD_S = 2.0  # a few-kB file loads in milliseconds; seconds mean work sized by a claim
MEMORY_HEADROOM = 2 * 2**30  # bytes of address space the loop may add to its imports'
TIMEOUT_S = 300  # the whole child (about 12 s on a shared 2-core machine)

# ---- base files ------------------------------------------------------------------------------


def _traces() -> Traces:
    rng = np.random.default_rng(SEED)
    return Traces({"step": rng.normal(size=(40, 4)), "sine": rng.normal(size=(30, 4))},
                  meta={"model": "reference", "case": "nominal", "seed": 3})


def _plain_vars(tr, time_unit: str = "s") -> dict[str, np.ndarray]:
    scale = 1e3 if time_unit == "ms" else 1.0
    out = {"time": tr.time("step") * scale}
    out |= {s: np.array(tr.signal("step", s)) for s in UNITS}
    return out


def _units(time_unit: str = "s") -> list[str]:
    return [f"time={time_unit}", *(f"{s}={u}" for s, u in UNITS.items())]


def _named_vars(tr, sep: str) -> dict[str, np.ndarray]:
    out = {}
    for t in tr.tests:
        out[f"time{sep}{t}"] = tr.time(t)
        out |= {f"{t}{sep}{s}": np.array(tr.signal(t, s)) for s in UNITS}
    return out


def _csv_plain(tr) -> bytes:
    """A plain measured CSV: ms, degrees, rpm, mA, at 2 kHz (block-averaged on load)."""
    factors = [180.0 / np.pi, 1e3, 60.0 / (2.0 * np.pi), 1e3]
    lines = ["t [ms],theta_u [deg],theta_m [mrad],omega_m [rpm],i_eq [mA]"]
    for k, row in enumerate(np.repeat(tr.data["step"], 2, axis=0).tolist()):
        lines.append(",".join([repr(0.5 * k), *(repr(v * f) for v, f in zip(row, factors))]))
    return ("\n".join(lines) + "\n").encode()


def _npz(arrays: dict[str, np.ndarray]) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, allow_pickle=False, **arrays)  # stored: Traces.save deflates
    return buf.getvalue()


def _mat(variables: dict, compress: bool) -> bytes:
    import scipy.io

    buf = io.BytesIO()
    scipy.io.savemat(buf, variables, do_compression=compress)
    return buf.getvalue()


def base_files() -> dict[str, tuple[str, bytes, bool]]:
    """name -> (suffix, content, needs_test): two files per format, named and plain."""
    tr = _traces()
    npz_plain = {**_plain_vars(tr, "ms"), "units": np.array(_units("ms"))}
    mat_named = {**_named_vars(tr, "_"), "units": np.array(_units()),
                 "meta_json": json.dumps(dict(tr.meta))}
    mat_plain = {**_plain_vars(tr), "units": np.array(_units(), dtype=object)}  # a cell array
    return {
        "csv_saved": (".csv", _saved(tr, ".csv"), False),
        "csv_plain": (".csv", _csv_plain(tr), True),
        "npz_saved": (".npz", _saved(tr, ".npz"), False),
        "npz_plain": (".npz", _npz(npz_plain), True),
        "mat_named": (".mat", _mat(mat_named, compress=False), False),
        "mat_plain": (".mat", _mat(mat_plain, compress=True), True),
    }


def _saved(tr: Traces, suffix: str) -> bytes:
    """The file that Traces.save writes."""
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        tr.save(Path(d) / f"t{suffix}")
        return (Path(d) / f"t{suffix}").read_bytes()


# ---- byte mutations (every format) -------------------------------------------------------------

INTERESTING_WORDS = (0, 1, 7, 8, 0xFF, 0x7FFF, 0xFFFF, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF,
                     0xFFFFFFF8, 10**9, 2**28, 2**31 - 8)


def flip_bits(rng: np.random.Generator, b: bytes) -> bytes:
    a = bytearray(b)
    for _ in range(rng.integers(1, 9)):
        i = rng.integers(len(a))
        a[i] ^= 1 << int(rng.integers(8))
    return bytes(a)


def set_bytes(rng: np.random.Generator, b: bytes) -> bytes:
    a = bytearray(b)
    i = int(rng.integers(len(a)))
    values = rng.choice([0x00, 0xFF, 0x7F, 0x80, 0x2C, 0x0A, 0x22, 0x93, 0x50],
                        size=int(rng.integers(1, 5)))
    a[i: i + len(values)] = bytes(int(v) for v in values)
    return bytes(a)


def truncate(rng: np.random.Generator, b: bytes) -> bytes:
    return b[: int(rng.integers(len(b)))]


def insert_bytes(rng: np.random.Generator, b: bytes) -> bytes:
    i = int(rng.integers(len(b) + 1))
    return b[:i] + rng.bytes(int(rng.integers(1, 65))) + b[i:]


def delete_bytes(rng: np.random.Generator, b: bytes) -> bytes:
    i = int(rng.integers(len(b)))
    return b[:i] + b[i + int(rng.integers(1, 65)):]


def duplicate_range(rng: np.random.Generator, b: bytes) -> bytes:
    i, j = sorted(int(v) for v in rng.integers(len(b), size=2))
    k = int(rng.integers(len(b) + 1))
    return b[:k] + b[i: j + 1] + b[k:]


def set_word(rng: np.random.Generator, b: bytes) -> bytes:
    """An aligned 32-bit word (a zip size, an .npy header length, a MATLAB tag or dimension)
    set to a boundary value."""
    if len(b) < 8:
        return b
    i = int(rng.integers(len(b) // 4)) * 4
    word = int(rng.choice(INTERESTING_WORDS)).to_bytes(4, "little")
    return b[:i] + word + b[i + 4:]


BYTE_MUTATIONS: tuple[Callable[[np.random.Generator, bytes], bytes], ...] = (
    flip_bits, set_bytes, truncate, insert_bytes, delete_bytes, duplicate_range, set_word)

# ---- CSV mutations ---------------------------------------------------------------------------

ODD_CELLS = ("nan", "inf", "-inf", "1e308", "-1e308", "1e999", "-0", "", " ", "abc", "1" * 5000,
             "9" * 200_000,  # above the csv module's field size limit
             "0x10", "1_000", '"', '"1,2"', "1e-320", "+-1", "\x00", "NaN", "∞", "1e-3",
             "12345678901234567890")
ODD_UNITS = ("s", "ms", "us", "min", "", "deg", "rad", "rad/s", "rpm", "mA", "A", "[s]", "µs")
ODD_LINES = ("# meta = {", "# meta = []", '# meta = {"a": ' + "1" * 5000 + "}",
             "# meta = " + "[" * 5000, "# ema-bench traces v2", "#", "", ",,,,", "test",
             '"' * 7, "\ufeffx", "# dt = abc s")


def _lines(b: bytes) -> list[str]:
    return b.decode("utf-8", errors="replace").split("\n")


def _join(lines: list[str]) -> bytes:
    return "\n".join(lines).encode("utf-8", errors="replace")


def _pick_line(rng: np.random.Generator, lines: list[str]) -> int:
    return int(rng.integers(len(lines))) if lines else 0


def dup_line(rng, b):
    lines = _lines(b)
    i = _pick_line(rng, lines)
    return _join(lines[: i + 1] + lines[i:])


def del_line(rng, b):
    lines = _lines(b)
    i = _pick_line(rng, lines)
    return _join(lines[:i] + lines[i + 1:])


def swap_lines(rng, b):
    lines = _lines(b)
    if len(lines) > 1:
        i, j = (int(v) for v in rng.integers(len(lines), size=2))
        lines[i], lines[j] = lines[j], lines[i]
    return _join(lines)


def swap_columns(rng, b):
    """Swap two columns in every line, or in the header alone (labels no longer match)."""
    lines = _lines(b)
    header_only = rng.random() < 0.5
    i, j = (int(v) for v in rng.integers(6, size=2))
    out = []
    for line in lines:
        cells = line.split(",")
        if max(i, j) < len(cells) and (not header_only or "[" in line):
            cells[i], cells[j] = cells[j], cells[i]
        out.append(",".join(cells))
    return _join(out)


def edit_cell(rng, b):
    lines = _lines(b)
    for _ in range(int(rng.integers(1, 4))):
        i = _pick_line(rng, lines)
        cells = lines[i].split(",")
        cells[int(rng.integers(len(cells)))] = str(rng.choice(ODD_CELLS))
        lines[i] = ",".join(cells)
    return _join(lines)


def edit_unit(rng, b):
    lines = _lines(b)
    i = next((n for n, line in enumerate(lines) if "[" in line and not line.startswith("#")), 0)
    cells = lines[i].split(",")
    c = int(rng.integers(len(cells)))
    name = cells[c].split("[")[0].strip()
    cells[c] = f"{name} [{rng.choice(ODD_UNITS)}]" if rng.random() < 0.8 else name
    lines[i] = ",".join(cells)
    return _join(lines)


def scale_time(rng, b):
    """Times x1000 or /1000 (the seconds / milliseconds mix-up) or x2 (another rate)."""
    factor = float(rng.choice([1e3, 1e-3, 2.0, 0.5, 1e-300, 1e300]))
    out = []
    for line in _lines(b):
        cells = line.split(",")
        col = 1 if len(cells) == 6 else 0
        try:
            cells[col] = repr(float(cells[col]) * factor)
        except (ValueError, IndexError):
            pass
        out.append(",".join(cells))
    return _join(out)


def insert_line(rng, b):
    lines = _lines(b)
    i = _pick_line(rng, lines)
    return _join(lines[:i] + [str(rng.choice(ODD_LINES))] + lines[i:])


def rename_test(rng, b):
    name = str(rng.choice(["", "time", "units", "bad name", "x" * 300, "step\r", "é", "1"]))
    return b.replace(b"sine,", name.encode() + b",", int(rng.integers(1, 50)))


def line_endings(rng, b):
    return rng.choice([b.replace(b"\n", b"\r\n"), b.replace(b"\n", b"\r"), b"\xef\xbb\xbf" + b,
                       b.replace(b",", b";"), b.replace(b",", b"\t"), b + b"\xff\xfe"])


CSV_MUTATIONS = (dup_line, del_line, swap_lines, swap_columns, edit_cell, edit_unit, scale_time,
                 insert_line, rename_test, line_endings)

# ---- NPZ mutations ---------------------------------------------------------------------------

ODD_DESCRS = ("'|O'", "'<U5'", "'<c16'", "'>f8'", "'<f2'", "'|V8'", "'<i8'", "'|b1'", "'x'",
              "[('a', '<f8')]", "('<f8', (1000000000,))", "'|V0'", "'<M8[s]'", "1")
ODD_SHAPES = ("()", "(0,)", "(-1,)", "(10000000000,)", "(40, 2)", "(1,) * 40", "(2**62, 2**62)",
              "(" + "1, " * 64 + ")", "(1e3,)", "'a'", "(True,)", "(41,)", "(39,)")


def _members(b: bytes) -> list[tuple[zipfile.ZipInfo, bytes]]:
    with zipfile.ZipFile(io.BytesIO(b)) as z:
        return [(info, z.read(info)) for info in z.infolist()]


def _zip(members: list[tuple[zipfile.ZipInfo, bytes]]) -> bytes:
    buf = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # duplicate names are a mutation here
        with zipfile.ZipFile(buf, "w") as z:
            for info, data in members:
                z.writestr(info, data)
    return buf.getvalue()


def _edit_member(rng, b: bytes, edit: Callable[[np.random.Generator, bytes], bytes]) -> bytes:
    members = _members(b)
    k = int(rng.integers(len(members)))
    info, data = members[k]
    members[k] = (info, edit(rng, data))
    return _zip(members)


def _npy_header_edit(rng, data: bytes) -> bytes:
    """Replace the descr, shape or fortran_order of a .npy header (its length kept valid)."""
    end = data.find(b"}") + 1
    header = data[10:end].decode("latin1")
    field = rng.choice(["descr", "shape", "fortran_order"])
    value = {"descr": lambda: str(rng.choice(ODD_DESCRS)),
             "shape": lambda: str(rng.choice(ODD_SHAPES)),
             "fortran_order": lambda: str(rng.choice(["True", "1", "None"]))}[field]()
    start = header.find(f"'{field}':")
    stop = header.find(", '", start + 1)
    stop = len(header) - 1 if stop < 0 else stop
    header = header[:start] + f"'{field}': {value}" + header[stop:]
    header = header.rstrip(" \n").rstrip("}").rstrip(", ") + "}"
    pad = (-(10 + len(header) + 1)) % 64
    header = header + " " * pad + "\n"
    return data[:8] + len(header).to_bytes(2, "little") + header.encode("latin1") + data[end:]


def npy_header(rng, b):
    return _edit_member(rng, b, lambda r, d: _npy_header_edit(r, d) if len(d) > 10 else d)


def member_bytes(rng, b):
    return _edit_member(rng, b, lambda r, d: r.choice(BYTE_MUTATIONS)(r, d) if d else d)


def member_random(rng, b):
    return _edit_member(rng, b, lambda r, d: r.bytes(len(d)))


def member_names(rng, b):
    members = _members(b)
    k = int(rng.integers(len(members)))
    info, data = members[k]
    action = rng.choice(["drop", "dup", "rename", "method"])
    if action == "drop":
        del members[k]
    elif action == "dup":
        members.append(members[k])
    elif action == "rename":
        new = zipfile.ZipInfo(str(rng.choice(["x.npy", "units", "step\n/theta_u.npy",
                                               "../units.npy", "time/.npy", "/.npy", "a/b/c.npy",
                                               info.filename.upper()])))
        new.compress_type = info.compress_type
        members[k] = (new, data)
    else:
        info.compress_type = int(rng.choice([zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED,
                                             zipfile.ZIP_BZIP2, zipfile.ZIP_LZMA]))
    return _zip(members)


def npz_content(rng, b):
    """Replace one array by another kind of array (numeric units, bad JSON, a 2-D time...)."""
    members = _members(b)
    k = int(rng.integers(len(members)))
    info, _ = members[k]
    candidates = [np.array(["time=s", "omega_m=rpm"]), np.array(["time=ms"] * 6),
                  np.arange(5.0), np.zeros((40, 2)), np.array("{" * 3000),
                  np.array('{"a": ' + "1" * 5000 + "}"), np.array([np.inf] * 40),
                  np.arange(40) * 1e-3 * float(rng.choice([1e3, 1e-3, 1e-300])),
                  np.array([1 + 2j] * 40), np.array(b"bytes"), np.ones(40, dtype=bool),
                  np.arange(40, dtype=np.int8), np.array([]), np.array(["tim€=s"])]
    buf = io.BytesIO()
    np.save(buf, candidates[int(rng.integers(len(candidates)))], allow_pickle=False)
    members[k] = (info, buf.getvalue())
    return _zip(members)


NPZ_MUTATIONS = (npy_header, member_bytes, member_random, member_names, npz_content)

# ---- MAT mutations ---------------------------------------------------------------------------


def mat_word(rng, b):
    """A 32-bit word after the 128-byte header (tags, sizes, dimensions) set to a boundary
    value, as in a crafted file."""
    if len(b) <= 136:
        return b
    i = 128 + int(rng.integers((len(b) - 128) // 4)) * 4
    return b[:i] + int(rng.choice(INTERESTING_WORDS)).to_bytes(4, "little") + b[i + 4:]


def mat_version(rng, b):
    word = rng.choice([b"\x00\x02IM", b"\x01\x00MI", b"\x00\x01XX", b"\x00\x00\x00\x00"])
    return b[:124] + word + b[128:]


MAT_MUTATIONS = (mat_word, mat_word, mat_version)

FORMAT_MUTATIONS = {".csv": CSV_MUTATIONS, ".npz": NPZ_MUTATIONS, ".mat": MAT_MUTATIONS}

# ---- the loop --------------------------------------------------------------------------------


def make_case(i: int, bases: dict) -> tuple[str, bytes, str | None, list[str]]:
    """(suffix, content, test argument, mutation names) of case ``i``."""
    rng = np.random.default_rng(np.random.SeedSequence([SEED, i]))
    name = list(bases)[i % len(bases)]
    suffix, content, needs_test = bases[name]
    done = [name]
    for _ in range(int(rng.integers(1, 4))):
        if not content:
            break  # truncated to nothing: the loader's "file is empty"
        own = FORMAT_MUTATIONS[suffix]
        pool = own + BYTE_MUTATIONS if rng.random() < 0.6 else BYTE_MUTATIONS + own
        mutate = pool[int(rng.integers(len(own) + 2))] if rng.random() < 0.7 else \
            pool[int(rng.integers(len(pool)))]
        try:
            content = mutate(rng, content)
        except Exception:  # noqa: BLE001 - a structure edit of a file already broken
            content = flip_bits(rng, content) if content else content
        done.append(mutate.__name__)
    if rng.random() < 0.03:  # the wrong suffix
        suffix = str(rng.choice([".csv", ".npz", ".mat"]))
        done.append(f"as{suffix}")
    test = "step" if needs_test or rng.random() < 0.3 else None
    return suffix, content, test, done


def _check_one(path: Path, test: str | None) -> tuple[str, str | None]:
    """("loaded" or "refused", None) when the load passes (a Traces, or a one-line TracesError
    not caused by a MemoryError), else ("failed", what went wrong)."""
    try:
        result = load_traces(path, test=test)
    except TracesError as exc:
        cause = exc.__cause__ or exc.__context__
        while cause is not None:
            if isinstance(cause, MemoryError):
                return "failed", f"TracesError from a MemoryError: {exc}"
            cause = cause.__cause__ or cause.__context__
        if "\n" in str(exc):
            return "failed", f"TracesError message of several lines: {exc!r}"
        return "refused", None
    except Exception:  # noqa: BLE001 - any other exception is what the fuzz looks for
        return "failed", traceback.format_exc(limit=-3)
    if not isinstance(result, Traces):
        return "failed", f"returned {type(result).__name__}"
    return "loaded", None


def run_cases(folder: Path, indices: range) -> dict:
    """Load every case; the report counts outcomes per base file and lists the failures.
    Each case number goes to stderr first, so a crash (a segfault in a library) names it."""
    bases = base_files()
    failures, slowest = [], 0.0
    outcomes = {name: {"loaded": 0, "refused": 0, "failed": 0} for name in bases}
    for i in indices:
        suffix, content, test, mutations = make_case(i, bases)
        path = folder / f"case{suffix}"
        path.write_bytes(content)
        print(f"case {i}", file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        outcome, problem = _check_one(path, test)
        elapsed = time.perf_counter() - t0
        slowest = max(slowest, elapsed)
        if problem is None and elapsed > MAX_LOAD_S:
            outcome, problem = "failed", f"took {elapsed:.1f} s (limit {MAX_LOAD_S} s)"
        outcomes[mutations[0]][outcome] += 1
        if problem is not None:
            failures.append({"case": i, "mutations": mutations, "test": test,
                             "problem": problem})
    return {"n_files": len(indices), "outcomes": outcomes, "failures": failures,
            "slowest_s": slowest}


def _cap_address_space() -> None:
    """Cap this process's address space at its current size plus MEMORY_HEADROOM (Linux)."""
    import resource

    try:
        pages = int(Path("/proc/self/statm").read_text().split()[0])
    except OSError:
        return  # no /proc: the per-file time limit still applies
    limit = pages * resource.getpagesize() + MEMORY_HEADROOM
    resource.setrlimit(resource.RLIMIT_AS, (limit, resource.RLIM_INFINITY))


def _child(folder: str, n_files: int) -> None:
    import scipy.io  # noqa: F401 - imported before the cap, as the loader would

    warnings.simplefilter("ignore")
    _cap_address_space()
    print(json.dumps(run_cases(Path(folder), range(n_files))))


def test_base_files_load(tmp_path):
    """The fuzz starts from valid files: each loads unmutated."""
    for name, (suffix, content, needs_test) in base_files().items():
        path = tmp_path / f"{name}{suffix}"
        path.write_bytes(content)
        assert "step" in load_traces(path, test="step" if needs_test else None).tests


# slow (about 7 CPU-s): hundreds of mutated files in a child interpreter; the fast loop loads
# the unmutated base files (test_base_files_load)
@pytest.mark.slow
def test_load_traces_fuzz(tmp_path):
    t0 = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-X", "faulthandler", __file__, "--child", str(tmp_path), str(N_FILES)],
        capture_output=True, text=True, timeout=TIMEOUT_S,
        env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    if done.returncode != 0:  # a crash: the last case number on stderr is the culprit
        lines = done.stderr.splitlines()
        last = ([ln for ln in lines if ln.startswith("case ")] or ["start-up"])[-1]
        detail = "\n".join(ln for ln in lines if not ln.startswith("case "))[-3000:]
        raise AssertionError(f"the fuzz process died (exit code {done.returncode}) at {last} "
                             f"(seed {SEED}); reproduce: python tests/test_traces_fuzz.py "
                             f"--{last}\n{detail}")
    report = json.loads(done.stdout)
    assert report["n_files"] == N_FILES
    for name, counts in report["outcomes"].items():  # the mutations neither all break a file
        assert counts["loaded"] > 0 and counts["refused"] > 0, (name, counts)  # nor all miss
    shown = "\n\n".join(f"case {f['case']} ({' + '.join(f['mutations'])}, test={f['test']!r}): "
                        f"{f['problem']}\nreproduce: python tests/test_traces_fuzz.py --case "
                        f"{f['case']}" for f in report["failures"][:5])
    assert not report["failures"], (f"{len(report['failures'])} of {N_FILES} mutated files "
                                    f"broke the loader (seed {SEED}):\n{shown}")
    print(f"{N_FILES} mutated files in {time.perf_counter() - t0:.1f} s, slowest load "
          f"{report['slowest_s'] * 1e3:.0f} ms")


def _reproduce(i: int) -> None:
    suffix, content, test, mutations = make_case(i, base_files())
    path = Path(f"fuzz_case_{i}{suffix}")
    path.write_bytes(content)
    print(f"case {i}: {' + '.join(mutations)}, test={test!r}; written to {path}")
    print(load_traces(path, test=test))


if __name__ == "__main__":
    if sys.argv[1] == "--child":
        _child(sys.argv[2], int(sys.argv[3]))
    elif sys.argv[1] == "--case":
        _reproduce(int(sys.argv[2]))
