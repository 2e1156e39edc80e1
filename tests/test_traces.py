"""Tests of ema_bench.traces: the Traces container, its file formats and load validation."""

from __future__ import annotations

import copy
import io
import json
import math
import re
import struct
import tracemalloc
import zipfile

import numpy as np
import pytest
import scipy.io

from ema_bench.traces import (
    OUTPUT_DT,
    SIGNALS,
    UNITS,
    Traces,
    TracesError,
    load_traces,
    mat_format,
    npz_format,
)

HEADER = "time [s],theta_u [rad],theta_m [rad],omega_m [rad/s],i_eq [A]"


def make_traces(n: int = 50, seed: int = 0) -> Traces:
    rng = np.random.default_rng(seed)
    step = rng.normal(size=(n, 4)) * np.array([0.1, 30.0, 300.0, 5.0])
    step[0, 0] = -0.0  # sign of zero must survive too
    step[1, 1] = 1e-300
    sine = rng.normal(size=(n + 7, 4))
    meta = {"model": "reference", "case": "nominal", "faults": ["backlash"], "seed": 42}
    return Traces({"step": step, "sine": sine}, meta=meta)


def plain_csv(path, rows, header=HEADER):
    """Write a plain measured CSV (no comment lines) with ``rows`` of numbers/strings."""
    lines = [header] + [",".join(str(v) for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def ramp_rows(n: int = 20, dt: float = OUTPUT_DT):
    return [[k * dt, 0.01 * k, 0.1 * k, 1.0, 2.0] for k in range(n)]


def assert_bit_exact(a: Traces, b: Traces) -> None:
    assert a.tests == b.tests and a.dt == b.dt
    for t in a.tests:
        # compare bit patterns: catches -0.0 vs 0.0 and any last-digit rounding
        assert np.array_equal(a.data[t].view(np.uint64), b.data[t].view(np.uint64))
    assert dict(a.meta) == dict(b.meta)


# ---- container -------------------------------------------------------------------------------


def test_accessors_and_stacked_order():
    tr = make_traces(n=5)
    assert tr.tests == ("step", "sine")
    assert tr.n_samples("step") == 5 and tr.n_samples("sine") == 12
    np.testing.assert_array_equal(tr.time("step"), (np.arange(5) + 0.5) * OUTPUT_DT)
    np.testing.assert_array_equal(tr.signal("sine", "omega_m"), tr.data["sine"][:, 2])
    expected = np.concatenate([tr.data[t][:, j] for t in tr.tests for j in range(4)])
    np.testing.assert_array_equal(tr.stacked(), expected)
    assert tr.stacked().shape == (4 * (5 + 12),)
    assert set(UNITS) == set(SIGNALS)


def test_arrays_are_read_only_copies():
    src = np.zeros((10, 4))
    tr = Traces({"step": src})
    src[0, 0] = 1.0
    assert tr.data["step"][0, 0] == 0.0
    assert tr.data["step"].dtype == np.float64
    with pytest.raises(ValueError, match="read-only"):
        tr.data["step"][0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        tr.signal("step", "i_eq")[0] = 1.0
    with pytest.raises(TypeError):
        tr.data["new"] = src  # type: ignore[index]
    with pytest.raises(AttributeError):
        tr.dt = 2.0  # type: ignore[misc]


def test_with_meta_allclose_and_copy():
    tr = make_traces()
    tr2 = tr.with_meta(case="jam", seed=np.int64(7))
    assert tr2.meta["case"] == "jam" and tr2.meta["seed"] == 7 and tr2.meta["model"] == "reference"
    assert tr.meta["case"] == "nominal"
    assert tr.allclose(tr2) and tr.allclose(copy.deepcopy(tr))
    shifted = Traces({t: tr.data[t] + 1e-9 for t in tr.tests})
    assert not tr.allclose(shifted)
    assert tr.allclose(shifted, atol=1e-8)
    assert not tr.allclose(Traces(dict(tr.data), dt=2e-3))
    assert not tr.allclose(Traces({"step": tr.data["step"]}))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"data": {}}, "at least one test"),
        ({"data": {"step": np.zeros((5, 3))}}, r"step.*shape \(5, 3\)"),
        ({"data": {"step": np.zeros(5)}}, "step"),
        ({"data": {"step": np.full((5, 4), "x")}}, "real numbers"),
        ({"data": {"sine": np.array([[0, 0, math.nan, 0]] * 3)}}, "'sine', signal 'omega_m'.*0"),
        ({"data": {"step": np.zeros((5, 4))}, "dt": 0.0}, "dt"),
        ({"data": {"step": np.zeros((5, 4))}, "dt": math.inf}, "dt"),
        ({"data": {"bad name": np.zeros((5, 4))}}, "bad name"),
        ({"data": {"time": np.zeros((5, 4))}}, "reserved"),
        ({"data": {"step": np.zeros((5, 4))}, "meta": {"x": object()}}, "JSON"),
    ],
)
def test_traces_validation(kwargs, match):
    with pytest.raises(TracesError, match=match):
        Traces(**kwargs)


# ---- round trips -----------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_round_trip_bit_exact(tmp_path, suffix):
    tr = make_traces()
    path = tmp_path / f"ref{suffix}"
    tr.save(path)
    back = load_traces(path)
    assert_bit_exact(tr, back)
    assert back.data["step"].flags.writeable is False


def test_csv_layout(tmp_path):
    tr = make_traces(n=10)
    path = tmp_path / "ref.csv"
    tr.save(path)
    lines = path.read_text().splitlines()
    assert lines[0] == "# ema-bench traces v1"
    assert lines[1] == "# dt = 0.001 s"
    assert json.loads(lines[2].removeprefix("# meta = ")) == dict(tr.meta)
    assert lines[3] == "test," + HEADER
    assert lines[4].startswith("step,0.0005,-0.0,")
    assert len(lines) == 4 + 10 + 17


def test_npz_layout(tmp_path):
    path = tmp_path / "ref.npz"
    make_traces(n=10).save(path)
    with np.load(path, allow_pickle=False) as z:
        assert {"step/theta_u", "time/sine", "units", "dt", "meta_json"} <= set(z.files)
        assert "omega_m=rad/s" in z["units"].tolist()
        assert json.loads(str(z["meta_json"]))["model"] == "reference"



def test_npz_save_repeats_byte_for_byte_and_is_atomic(tmp_path, monkeypatch):
    """Same traces, same bytes (campaigns are regenerated and compared byte for byte); a save
    that fails midway leaves neither a file nor a temporary behind."""
    tr = make_traces(n=10)
    tr.save(tmp_path / "a.npz")
    tr.save(tmp_path / "b.npz")
    assert (tmp_path / "a.npz").read_bytes() == (tmp_path / "b.npz").read_bytes()
    with zipfile.ZipFile(tmp_path / "a.npz") as z:
        assert {i.date_time for i in z.infolist()} == {(1980, 1, 1, 0, 0, 0)}
        assert {i.compress_type for i in z.infolist()} == {zipfile.ZIP_DEFLATED}
    back = load_traces(tmp_path / "b.npz")
    assert all(np.array_equal(back.data[t], tr.data[t]) for t in tr.tests)

    def broken(*a, **k):
        raise OSError("disk full")
    monkeypatch.setattr(np.lib.format, "write_array", broken)
    with pytest.raises(OSError, match="disk full"):
        tr.save(tmp_path / "c.npz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.npz", "b.npz"]


def test_mat_round_trip_and_plain_layout(tmp_path):
    tr = make_traces()
    variables = {"units": np.array([f"{s}={UNITS[s]}" for s in SIGNALS]),
                 "meta_json": json.dumps(dict(tr.meta)), "dt": tr.dt}
    for t in tr.tests:
        variables[f"time_{t}"] = tr.time(t)
        for s in SIGNALS:
            variables[f"{t}_{s}"] = tr.signal(t, s)
    scipy.io.savemat(tmp_path / "ref.mat", variables)
    assert_bit_exact(tr, load_traces(tmp_path / "ref.mat"))

    plain = {"time": tr.time("step"), "units": variables["units"]}
    plain.update({s: tr.signal("step", s) for s in SIGNALS})
    scipy.io.savemat(tmp_path / "plain.mat", plain)
    back = load_traces(tmp_path / "plain.mat", test="step")
    np.testing.assert_array_equal(back.data["step"], tr.data["step"])
    with pytest.raises(TracesError, match="test="):
        load_traces(tmp_path / "plain.mat")


def test_save_unsupported_suffix(tmp_path):
    with pytest.raises(TracesError, match=r"\.txt"):
        make_traces().save(tmp_path / "ref.txt")


# ---- plain measured files ----------------------------------------------------------------------


def test_plain_csv_single_test_and_test_filter(tmp_path):
    path = plain_csv(tmp_path / "m.csv", ramp_rows())
    tr = load_traces(path, test="step")
    assert tr.tests == ("step",) and tr.n_samples("step") == 20
    np.testing.assert_array_equal(tr.signal("step", "theta_m"), [0.1 * k for k in range(20)])
    with pytest.raises(TracesError, match="test="):
        load_traces(path)

    rows = [["step", *r] for r in ramp_rows()] + [["sine", *r] for r in ramp_rows()]
    both = plain_csv(tmp_path / "both.csv", rows, header="test," + HEADER)
    assert load_traces(both).tests == ("step", "sine")
    assert load_traces(both, test="sine").tests == ("sine",)
    with pytest.raises(TracesError, match="'ramp' not in file"):
        load_traces(both, test="ramp")


def test_unit_conversion(tmp_path):
    header = "t [ms],theta_u [deg],theta_m [mrad],omega_m [rpm],i_eq [mA]"
    rows = [[k * 1.0, 90.0, 1000.0, 60.0, 1500.0] for k in range(12)]
    tr = load_traces(plain_csv(tmp_path / "m.csv", rows, header=header), test="step")
    np.testing.assert_allclose(tr.data["step"][0], [math.pi / 2, 1.0, 2 * math.pi, 1.5],
                               rtol=1e-15)


def test_resampling_block_average(tmp_path):
    # 10 kHz ramp x_k = k: each 1 ms window averages samples 10j..10j+9 -> 10j + 4.5
    n = 205  # the trailing partial window (5 samples) is dropped
    rows = [[k * 1e-4, k, 2.0 * k, -k, 3.0] for k in range(n)]
    tr = load_traces(plain_csv(tmp_path / "fast.csv", rows), test="step")
    expected = 10.0 * np.arange(20) + 4.5
    assert tr.n_samples("step") == 20 and tr.dt == OUTPUT_DT
    np.testing.assert_allclose(tr.signal("step", "theta_u"), expected, rtol=1e-14)
    np.testing.assert_allclose(tr.signal("step", "theta_m"), 2.0 * expected, rtol=1e-14)
    np.testing.assert_allclose(tr.signal("step", "omega_m"), -expected, rtol=1e-14)
    np.testing.assert_allclose(tr.signal("step", "i_eq"), 3.0, rtol=1e-14)


# ---- load errors -------------------------------------------------------------------------------


def bad_rows(row: int, col: int, value) -> list:
    """Ramp rows with one cell replaced."""
    rows = ramp_rows()
    rows[row][col] = value
    return rows


CSV_ERRORS = [
    # (id, header, rows, match)
    ("short row", HEADER, ramp_rows()[:3] + [[0.5, 1, 2]] + ramp_rows()[4:], "line 5.*expected 5"),
    ("non-numeric", HEADER, bad_rows(6, 2, "abc"), r"line 8.*theta_m.*'abc'"),
    ("missing signal", "time [s],theta_u [rad],theta_m [rad],i_eq [A]",
     [r[:3] + r[4:] for r in ramp_rows()], "missing signal.*omega_m.*found: time"),
    ("unknown column", HEADER + ",temp [K]", [[*r, 300] for r in ramp_rows()],
     r"temp \[K\].*unknown column.*known"),
    ("no unit", "time [s],theta_u [rad],theta_m [rad],omega_m,i_eq [A]", ramp_rows(),
     "'omega_m'.*no unit"),
    ("unknown unit", "time [s],theta_u [rad],theta_m [rad],omega_m [rps],i_eq [A]",
     ramp_rows(), r"'rps'.*omega_m.*rad/s, rpm, deg/s"),
    ("unit mismatch", "time [s],theta_u [rad],theta_m [rad],omega_m [rad/s],i_eq [rad]",
     ramp_rows(), "'rad' not accepted for i_eq"),
    ("time unit", "time [min],theta_u [rad],theta_m [rad],omega_m [rad/s],i_eq [A]",
     ramp_rows(), "time unit 'min'"),
    ("no time", "theta_u [rad],theta_m [rad],omega_m [rad/s],i_eq [A]",
     [r[1:] for r in ramp_rows()], "missing time column"),
    ("non-monotonic", HEADER, bad_rows(7, 0, 0.0055), "non-monotonic.*index 7"),
    ("repeated", HEADER, bad_rows(7, 0, 0.006), "repeated time.*index 7"),
    ("empty cell", HEADER, bad_rows(9, 3, ""), r"'omega_m'.*NaN gap.*t = 0\.009 s"),
    ("nan cell", HEADER, bad_rows(4, 4, "nan"), r"'i_eq'.*NaN gap.*t = 0\.004 s"),
    ("jitter", HEADER, bad_rows(5, 0, 0.00501), "non-uniform.*index"),
    ("coarse", HEADER, [[2e-3 * k, *r[1:]] for k, r in enumerate(ramp_rows())],
     "file rate 500 Hz, expected 1000 Hz"),
    ("non-integer", HEADER, [[4e-4 * k, *r[1:]] for k, r in enumerate(ramp_rows())],
     "integer multiple.*2500 Hz"),
    ("too short", HEADER, ramp_rows(9), "too short, 9 sample"),
    ("header only", HEADER, [], "empty"),
    ("too fine", HEADER, [[1e-6 * k, *r[1:]] for k, r in enumerate(ramp_rows())],
     "sample rate too high.*at most 100 times"),
]


@pytest.mark.parametrize(("header", "rows", "match"), [c[1:] for c in CSV_ERRORS],
                         ids=[c[0] for c in CSV_ERRORS])
def test_csv_errors(tmp_path, header, rows, match):
    path = plain_csv(tmp_path / "bad.csv", rows, header=header)
    with pytest.raises(TracesError, match=match) as info:
        load_traces(path, test="step")
    assert "bad.csv" in str(info.value)


def test_min_duration(tmp_path):
    path = plain_csv(tmp_path / "m.csv", ramp_rows(20))
    assert load_traces(path, test="step", min_duration=0.02).n_samples("step") == 20
    with pytest.raises(TracesError, match=r"'step'.*0\.02 s.*min_duration is 0\.5 s"):
        load_traces(path, test="step", min_duration=0.5)


def test_file_level_errors(tmp_path):
    with pytest.raises(TracesError, match="not found"):
        load_traces(tmp_path / "nope.csv")
    (tmp_path / "x.txt").write_text(HEADER)
    with pytest.raises(TracesError, match=r"unsupported.*\.txt"):
        load_traces(tmp_path / "x.txt")
    for name in ("empty.csv", "empty.npz", "empty.mat"):
        (tmp_path / name).write_bytes(b"")
        with pytest.raises(TracesError, match=f"{name}: file is empty"):
            load_traces(tmp_path / name)
    (tmp_path / "comments.csv").write_text("# ema-bench traces v1\n\n")
    with pytest.raises(TracesError, match="empty"):
        load_traces(tmp_path / "comments.csv")
    (tmp_path / "junk.npz").write_bytes(b"not a zip archive at all")
    with pytest.raises(TracesError, match="junk.npz.*cannot read"):
        load_traces(tmp_path / "junk.npz")
    (tmp_path / "latin1.csv").write_bytes(HEADER.encode() + b"\n\xff\xfe\n")
    with pytest.raises(TracesError, match="cannot read"):
        load_traces(tmp_path / "latin1.csv")
    with pytest.raises(TracesError, match="version '2'"):
        (tmp_path / "v2.csv").write_text("# ema-bench traces v2\n" + HEADER + "\n")
        load_traces(tmp_path / "v2.csv")


def test_npz_object_array_is_refused(tmp_path):
    path = tmp_path / "evil.npz"
    arrays = {f"step/{s}": np.zeros(20) for s in SIGNALS}
    arrays["time/step"] = np.array([{"payload": 1}] * 20, dtype=object)
    arrays["units"] = np.array([f"{s}={UNITS[s]}" for s in SIGNALS])
    np.savez(path, **arrays)  # numpy pickles object arrays inside the archive
    with pytest.raises(TracesError, match="'time/step'.*object array"):
        load_traces(path)


def test_npz_content_errors(tmp_path):
    units = np.array([f"{s}={UNITS[s]}" for s in SIGNALS])
    good = {f"step/{s}": np.zeros(20) for s in SIGNALS} | {"time/step": np.arange(20) * 1e-3}

    def load_with(**arrays):
        np.savez(tmp_path / "f.npz", **arrays)
        return load_traces(tmp_path / "f.npz")

    assert load_with(**good, units=units).n_samples("step") == 20
    missing = {k: v for k, v in good.items() if k != "step/omega_m"}
    with pytest.raises(TracesError, match="'step': missing 'omega_m'"):
        load_with(**missing, units=units)
    with pytest.raises(TracesError, match="no 'units'"):
        load_with(**good)
    with pytest.raises(TracesError, match="unknown key 'step/foo'"):
        load_with(**good, units=units, **{"step/foo": np.zeros(20)})
    with pytest.raises(TracesError, match="rps.*omega_m"):
        load_with(**good, units=np.array([*units[:2], "omega_m=rps", units[3]]))
    with pytest.raises(TracesError, match="'step/i_eq' has 19 samples"):
        load_with(**(good | {"step/i_eq": np.zeros(19)}), units=units)
    with pytest.raises(TracesError, match=r"'step/theta_u'.*shape \(20, 2\)"):
        load_with(**(good | {"step/theta_u": np.zeros((20, 2))}), units=units)


# ---- crafted and corrupt files: refused from their declared sizes, one clear error each --------

UNIT_STRINGS = np.array([f"{s}={UNITS[s]}" for s in SIGNALS])


def npy(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, arr, allow_pickle=False)
    return buf.getvalue()


def npy_claiming(shape: tuple[int, ...], payload: bytes) -> bytes:
    """A .npy file whose header declares ``shape`` (float64) whatever ``payload`` holds."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        buf, {"descr": "<f8", "fortran_order": False, "shape": shape})
    return buf.getvalue() + payload


def npz_members(n: int = 20, time_values: np.ndarray | None = None) -> dict[str, bytes]:
    """The members of a valid one-test .npz (test 'step'), as .npy bytes."""
    arrays = {f"step/{s}": np.zeros(n) for s in SIGNALS} | {"units": UNIT_STRINGS}
    arrays["time/step"] = np.arange(n) * OUTPUT_DT if time_values is None else time_values
    return {f"{k}.npy": npy(v) for k, v in arrays.items()}


def write_zip(path, members: dict[str, bytes], method: int = zipfile.ZIP_STORED):
    with zipfile.ZipFile(path, "w", method) as z:
        for name, data in members.items():
            z.writestr(name, data)
    return path


def test_npz_header_claiming_a_huge_array_is_refused_before_allocation(tmp_path):
    # 28 kB of data, 80 GB declared: refused from the header, not a MemoryError
    members = npz_members() | {"time/step.npy": npy_claiming((10**10,), bytes(28_000))}
    path = write_zip(tmp_path / "huge.npz", members)
    assert path.stat().st_size < 32_000
    with pytest.raises(TracesError, match=r"huge\.npz: key 'time/step' claims 10000000000 "
                                          r"samples of 8 bytes, larger than the limit"):
        load_traces(path)


def test_npz_header_declaring_more_than_the_member_holds_is_refused(tmp_path):
    members = npz_members() | {"time/step.npy": npy_claiming((1000,), bytes(160))}
    with pytest.raises(TracesError, match=r"key 'time/step': its header declares 8000 bytes "
                                          r"of data but the archive holds 160"):
        load_traces(write_zip(tmp_path / "lying.npz", members, zipfile.ZIP_DEFLATED))


def test_npz_array_above_the_size_limit_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(npz_format, "MAX_ARRAY_BYTES", 100)
    path = write_zip(tmp_path / "big.npz", npz_members())
    with pytest.raises(TracesError, match="claims 20 samples of 8 bytes, larger than the "
                                          "limit of 100 bytes"):
        load_traces(path)


def test_npz_of_random_bytes_is_reported_as_corrupt_not_as_pickle(tmp_path):
    path = tmp_path / "junk.npz"
    path.write_bytes(np.random.default_rng(1).bytes(3000))
    with pytest.raises(TracesError, match=r"junk\.npz: cannot read as \.npz: not a zip "
                                          r"archive \(the file is corrupt") as info:
        load_traces(path)
    assert "pickle" not in str(info.value)


def test_npz_member_that_is_not_npy_or_is_corrupt(tmp_path):
    rng = np.random.default_rng(2)
    members = npz_members() | {"time/step.npy": rng.bytes(200)}
    with pytest.raises(TracesError, match="key 'time/step' is not a .npy array") as info:
        load_traces(write_zip(tmp_path / "member.npz", members))
    assert "pickle" not in str(info.value)

    path = write_zip(tmp_path / "deflated.npz", npz_members(200), zipfile.ZIP_DEFLATED)
    with zipfile.ZipFile(path) as z:  # one byte of the first member's deflate stream flipped
        info = z.infolist()[0]
    blob = bytearray(path.read_bytes())
    start = info.header_offset + 30 + len(info.filename) + len(info.extra)
    blob[start + info.compress_size // 2] ^= 0xFF
    path.write_bytes(bytes(blob))
    with pytest.raises(TracesError, match=r"deflated\.npz: corrupt \.npz archive"):
        load_traces(path)


# ---- the limits of a whole file: names, count and total size before any member is read --------

MIB = 2**20


def loaded_peak(path, **kw) -> tuple[BaseException, int]:
    """The error of loading ``path`` and the peak of memory allocated meanwhile (bytes)."""
    tracemalloc.start()
    try:
        with pytest.raises(TracesError) as info:
            load_traces(path, **kw)
        return info.value, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_npz_members_under_the_member_limit_but_past_the_file_limit(tmp_path):
    """Five 16 MiB members, each far under the 256 MiB a member may hold, 80 MiB together:
    refused from the archive's directory before one member is read (before the file limit,
    a 2 MB archive of such members filled 2.4 GB)."""
    big = npy(np.zeros(2 * MIB))                                  # 16 MiB of float64
    members = npz_members() | {f"t{i}/theta_m.npy": big for i in range(5)}
    path = write_zip(tmp_path / "many.npz", members, zipfile.ZIP_DEFLATED)
    assert path.stat().st_size < MIB
    err, peak = loaded_peak(path)
    assert re.search(r"many\.npz: its members hold \d+ bytes in all, more than the limit of "
                     r"67108864 bytes per file", str(err))
    assert peak < 4 * MIB                 # not one 16 MiB member was inflated


def test_npz_bomb_member_is_refused_before_it_is_inflated(tmp_path):
    """One member of 200 MiB of zeros, under the 256 MiB member limit, deflated to a few
    hundred kB: refused from its listed size, never inflated."""
    path = tmp_path / "bomb.npz"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in npz_members().items():
            z.writestr(name, data)
        with z.open("t2/theta_m.npy", "w") as fh:
            n = 200 * MIB // 8
            fh.write(npy_claiming((n,), b""))
            chunk = bytes(MIB)
            for _ in range(200):
                fh.write(chunk)
    assert path.stat().st_size < 2 * MIB
    err, peak = loaded_peak(path)
    assert "more than the limit of 67108864 bytes per file" in str(err)
    assert peak < 4 * MIB


def test_npz_member_names_are_checked_before_any_member_is_read(tmp_path):
    big = npy(np.zeros(2 * MIB))
    members = {"step/theta_m.npy": big} | npz_members() | {"step/bogus.npy": npy(np.zeros(20))}
    err, peak = loaded_peak(write_zip(tmp_path / "names.npz", members, zipfile.ZIP_DEFLATED))
    assert "unknown key 'step/bogus'" in str(err)
    assert peak < 4 * MIB                 # the 16 MiB member before it was not read
    members = npz_members() | {"../x/theta_m.npy": npy(np.zeros(20))}
    err, _ = loaded_peak(write_zip(tmp_path / "path.npz", members))
    assert "key '../x/theta_m': invalid test name '../x'" in str(err)


def test_npz_with_too_many_members_is_refused(tmp_path):
    tiny = npy(np.zeros(1))
    members = npz_members() | {f"t{i}/theta_m.npy": tiny for i in range(520)}
    err, _ = loaded_peak(write_zip(tmp_path / "crowd.npz", members))
    assert len(members) == 6 + 520
    assert "526 keys, more than the limit of 512 per file" in str(err)


def test_mat_variable_names_are_checked_before_scipy_reads_the_file(tmp_path, monkeypatch):
    """An unknown or path-like variable name is refused by the walker, before scipy parses a
    single variable (as for .npz keys); a good file still reaches scipy."""
    import scipy.io

    good = {"units": np.array([f"{s}={UNITS[s]}" for s in SIGNALS]),
            "time_step": np.arange(20) * 1e-3, **{f"step_{s}": np.zeros(20) for s in SIGNALS}}
    calls = []
    real = scipy.io.loadmat
    monkeypatch.setattr(scipy.io, "loadmat", lambda *a, **k: calls.append(1) or real(*a, **k))
    for name, compress, match in (("step_bogus", False, "unknown variable 'step_bogus'"),
                                  ("step_bogus", True, "unknown variable 'step_bogus'"),
                                  ("time_", False, "invalid test name ''")):
        path = tmp_path / f"{name}-{compress}.mat"
        scipy.io.savemat(path, {**good, name: np.zeros(3)}, do_compression=compress)
        with pytest.raises(TracesError, match=match):
            load_traces(path)
    assert calls == []
    path = tmp_path / "good.mat"
    scipy.io.savemat(path, good)
    assert list(load_traces(path).tests) == ["step"] and calls == [1]


def test_mat_variables_past_the_file_limit_are_refused(tmp_path, monkeypatch):
    """Compressed variables each under the per-array limit, together over the file's (the
    limit lowered so that a small file shows it), and a file larger than the limit itself."""
    monkeypatch.setattr(mat_format, "MAX_FILE_BYTES", 8000)
    variables = {"time": np.arange(200) * OUTPUT_DT, "units": UNIT_STRINGS}
    variables |= {s: np.zeros(200) for s in SIGNALS}
    scipy.io.savemat(tmp_path / "z.mat", variables, do_compression=True)
    assert (tmp_path / "z.mat").stat().st_size < 8000
    with pytest.raises(TracesError, match="its variables hold more than the limit of 8000 "
                                          "bytes per file"):
        load_traces(tmp_path / "z.mat", test="step")
    scipy.io.savemat(tmp_path / "plain.mat", variables)
    with pytest.raises(TracesError, match=r"the file holds \d+ bytes, more than the limit of "
                                          "8000 bytes per file"):
        load_traces(tmp_path / "plain.mat", test="step")
    monkeypatch.setattr(mat_format, "MAX_FILE_BYTES", 2**26)
    assert load_traces(tmp_path / "z.mat", test="step").tests == ("step",)


def plain_mat_bytes(n: int = 20) -> bytes:
    """An uncompressed MATLAB file of one plain test, 'units' a cell array."""
    variables = {"time": np.arange(n) * OUTPUT_DT, "units": np.array(UNIT_STRINGS, dtype=object)}
    variables |= {s: np.zeros(n) for s in SIGNALS}
    buf = io.BytesIO()
    scipy.io.savemat(buf, variables)
    return buf.getvalue()


def patched(blob: bytes, old: bytes, new: bytes) -> bytes:
    assert old in blob
    return blob.replace(old, new, 1)


DIMS_1x20 = struct.pack("<IIii", 5, 8, 1, 20)  # miINT32 tag, 8 bytes, dimensions 1 x 20
DOUBLES_20 = struct.pack("<II", 9, 160)  # miDOUBLE tag, 160 bytes


@pytest.mark.parametrize(("edit", "match"), [
    # a vector of 10**9 samples declared in 4 bytes
    (lambda b: patched(b, DIMS_1x20, struct.pack("<IIii", 5, 8, 1, 10**9)),
     r"a variable claims 1000000000 samples \(1 x 1000000000\), larger than the limit"),
    # a cell array of 3000 x 3000: scipy would fill 9 million cells before reading one
    (lambda b: patched(b, struct.pack("<IIii", 5, 8, 1, 4), struct.pack("<IIii", 5, 8, 3000, 3000)),
     r"a variable claims 9000000 samples \(3000 x 3000\) but holds \d+ bytes"),
    # a data element claiming 4 GB: scipy would allocate it before finding the file short
    (lambda b: patched(b, DOUBLES_20, struct.pack("<II", 9, 2**32 - 8)),
     "a data element declares 4294967288 bytes but only"),
    # an unknown data type: scipy indexes a fixed-size table with it (garbage or a segfault)
    (lambda b: patched(b, DOUBLES_20, struct.pack("<II", 0xFF93, 160)),
     "unknown MATLAB data type 65427"),
], ids=["huge-vector", "huge-cell", "huge-element", "unknown-type"])
def test_crafted_mat_sizes_are_refused_before_scipy_allocates(tmp_path, edit, match):
    path = tmp_path / "crafted.mat"
    path.write_bytes(edit(plain_mat_bytes()))
    with pytest.raises(TracesError, match=r"crafted\.mat: " + match):
        load_traces(path, test="step")


def test_compressed_mat_variable_above_the_size_limit_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(mat_format, "MAX_ARRAY_BYTES", 64)
    monkeypatch.setattr(mat_format, "_MAT_HEADER_ROOM", 64)
    variables = {"time": np.arange(200) * OUTPUT_DT, "units": UNIT_STRINGS}
    scipy.io.savemat(tmp_path / "z.mat", variables | {s: np.zeros(200) for s in SIGNALS},
                     do_compression=True)
    with pytest.raises(TracesError, match="a compressed variable holds more than the limit "
                                          "of 64 bytes"):
        load_traces(tmp_path / "z.mat", test="step")


# ---- seconds and milliseconds mixed up -----------------------------------------------------------


@pytest.mark.parametrize(("header", "step", "match"), [
    # 1 kHz data written in ms under an [s] label
    (HEADER, 1.0, r"the time column looks like milliseconds but is labelled \[s\]; relabel it "
                  r"'time \[ms\]'"),
    # 10 kHz in ms under [s]
    (HEADER, 0.1, r"the time column looks like milliseconds but is labelled \[s\]"),
    # seconds under [ms]: read as 1 MHz, it would have been averaged into 12 samples
    ("t [ms]" + HEADER.removeprefix("time [s]"), 1e-3,
     r"the time column looks like seconds but is labelled \[ms\]; relabel it 't \[s\]'"),
], ids=["ms-as-s", "ms-as-s-10kHz", "s-as-ms"])
def test_csv_time_unit_mix_up_is_named(tmp_path, header, step, match):
    rows = [[k * step, 0.0, 0.0, 0.0, 0.0] for k in range(12_000)]
    path = plain_csv(tmp_path / "m.csv", rows, header=header)
    with pytest.raises(TracesError, match=r"m\.csv: test 'step': " + match):
        load_traces(path, test="step")


@pytest.mark.parametrize(("time_unit", "time_values", "match"), [
    ("time=s", np.arange(20) * 1.0,
     r"time looks like milliseconds but is labelled \[s\]; relabel it 'time=ms' in 'units'"),
    (None, np.arange(20) * 1.0, r"looks like milliseconds but is labelled \[s\]"),
    ("time=ms", np.arange(12_000) * 1e-3,
     r"time looks like seconds but is labelled \[ms\]; relabel it 'time=s' in 'units'"),
], ids=["ms-as-s", "ms-no-time-unit", "s-as-ms"])
def test_npz_time_unit_mix_up_is_named(tmp_path, time_unit, time_values, match):
    members = npz_members(len(time_values), time_values)
    units = [*UNIT_STRINGS, time_unit] if time_unit else list(UNIT_STRINGS)
    members["units.npy"] = npy(np.array(units))
    with pytest.raises(TracesError, match=match):
        load_traces(write_zip(tmp_path / "m.npz", members))


# ---- what the fuzz test (test_traces_fuzz.py) found: other exceptions escaping -------------------

FUZZ_FOUND = [
    # (id, file content, match)
    ("csv field over the csv module's limit", HEADER + '\n"' + "1" * 200_000 + '",0,0,0,0\n',
     r"line 2: malformed CSV: field larger than field limit"),  # was _csv.Error
    ("meta nested too deep", "# meta = " + "[" * 100_000 + "\n" + HEADER + "\n",
     r"line 1: meta is not valid JSON: maximum recursion"),  # was RecursionError
    ("meta integer too long", '# meta = {"a": ' + "1" * 5000 + "}\n" + HEADER + "\n",
     r"line 1: meta is not valid JSON: Exceeds the limit"),  # was a ValueError without file
    ("subnormal time step",
     HEADER + "\n" + "\n".join(f"{k * 5e-324!r},0,0,0,0" for k in range(20)) + "\n",
     r"sample rate too high"),  # was OverflowError, then ZeroDivisionError
    ("time step of 1e-300 s",
     HEADER + "\n" + "\n".join(f"{k * 1e-300!r},0,0,0,0" for k in range(20)) + "\n",
     r"sample rate too high"),  # was ValueError: Maximum allowed dimension exceeded
]


@pytest.mark.parametrize(("text", "match"), [c[1:] for c in FUZZ_FOUND],
                         ids=[c[0] for c in FUZZ_FOUND])
def test_pathological_csv_raises_traces_error(tmp_path, text, match):
    path = tmp_path / "odd.csv"
    path.write_text(text)
    with pytest.raises(TracesError, match=r"odd\.csv: (test 'step': )?" + match):
        load_traces(path, test="step")


def test_npz_found_by_the_fuzz_test(tmp_path):
    members = npz_members()
    # a header numpy cannot tokenize (was tokenize.TokenError)
    good = members["time/step.npy"]
    members["time/step.npy"] = good[:10] + good[10:].replace(b"'shape': (20,)", b"'shape': (20,(")
    with pytest.raises(TracesError, match="key 'time/step': corrupt .npy header"):
        load_traces(write_zip(tmp_path / "token.npz", members))
    # a member compressed with bzip2: numpy never writes one
    path = write_zip(tmp_path / "bz2.npz", npz_members(), zipfile.ZIP_BZIP2)
    with pytest.raises(TracesError, match="unsupported zip compression method 12"):
        load_traces(path)
    # a key whose test name ends in a newline (was accepted as test 'step\n')
    renamed = {k.replace("step", "step\n"): v for k, v in npz_members().items()}
    with pytest.raises(TracesError, match="invalid test name"):
        load_traces(write_zip(tmp_path / "newline.npz", renamed))
