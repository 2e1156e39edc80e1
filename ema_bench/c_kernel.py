"""The plain-C port of the monitor kernel (``benchmarks/c/monitor.c``): find, build, load, run.

The C source is not part of the installed package: it lives in a source checkout, for the speed
comparison of ``ema-bench bench`` and for the test that the two kernels agree.  Building needs a
C compiler (``$CC``, else ``cc``/``gcc``/``clang``); without one the caller gets a
:class:`CKernelUnavailable` with the reason, and reports the C figures as missing.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path

import numpy as np

from . import effects as _effects
from . import params as _params
from .effects import N_EFFECTS
from .params import DEFAULT_PARAMS, EMAParams
from .protocol import STANDARD_TESTS, TestSpec, steps_per
from .terms import TERM_NAMES
from .traces import OUTPUT_DT

SOURCE_NAME = "benchmarks/c/monitor.c"
# -O3 vectorises the lanes' loops; -ffp-contract=off: no fused multiply-add (numba's LLVM does
# not contract without fastmath); -fno-trapping-math -fno-math-errno let GCC vectorise floor
# (round to an integer) and change no result
CFLAGS = ("-O3", "-march=native", "-ffp-contract=off", "-fno-trapping-math", "-fno-math-errno",
          "-fPIC", "-shared")
# the order of the C enum IDX_*: parameter positions, then effect positions
_PARAM_ORDER = ("V_dc", "R", "L", "Ke", "pole_pairs", "hyst_band", "J_m", "J_u", "tau", "K_s",
                "C_s", "C_m", "C_u", "K_aero", "theta_stop", "K_stop", "C_stop",
                "friction_dyn_ratio", "stick_speed", "K_GP", "w_max", "Kpv", "Kiv", "T_max",
                "dt_ctrl", "kt_factor", "locate_commutation", "libm_trig")
_EFFECT_ORDER = ("eccentricity", "sensor_offset", "viscous_friction", "aero_spring", "delay",
                 "current_gain", "resistance_rise", "cogging", "voltage_sag", "gear_stiffness",
                 "quadratic_damping", "hinge_friction", TERM_NAMES[0],
                 "resolver_harmonic")


class CKernelUnavailable(RuntimeError):
    """The C reference cannot be built or loaded here (the message says why)."""


def index_table() -> np.ndarray:
    """Positions of the parameters and effects the C kernel reads, in its ``IDX_*`` order."""
    return np.array([_params.PARAM_INDEX[n] for n in _PARAM_ORDER]
                    + [_effects.EFFECT_INDEX[n] for n in _EFFECT_ORDER], dtype=np.int64)


def find_source() -> Path:
    """``benchmarks/c/monitor.c`` of a source checkout: ``$EMA_BENCH_C_SOURCE``, else under the
    working directory, else beside the package (an editable install)."""
    candidates = [os.environ.get("EMA_BENCH_C_SOURCE"), Path.cwd() / SOURCE_NAME,
                  Path(__file__).resolve().parent.parent / SOURCE_NAME]
    for c in candidates:
        if c and Path(c).is_file():
            return Path(c)
    raise CKernelUnavailable(f"C source {SOURCE_NAME} not found (run from a source checkout or "
                             "set EMA_BENCH_C_SOURCE)")


def find_compiler() -> str:
    """The C compiler to use: ``$CC``, else the first of cc, gcc, clang on the PATH."""
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return name
    raise CKernelUnavailable("no C compiler found (set CC, or install cc/gcc/clang)")


@lru_cache(maxsize=4)
def build(source: Path | None = None) -> Path:
    """Compile the C kernel into a shared library (cached by source and flags) and return its
    path."""
    source = Path(source) if source else find_source()
    if not source.is_file():
        raise CKernelUnavailable(f"C source {source} not found")
    cc = find_compiler()
    text = source.read_bytes()
    key = hashlib.sha256(text + " ".join((cc, *CFLAGS)).encode()).hexdigest()[:16]
    out_dir = Path(tempfile.gettempdir()) / "ema-bench-c"
    out_dir.mkdir(parents=True, exist_ok=True)
    lib = out_dir / f"libmonitor-{key}.so"
    if not lib.is_file():
        tmp = out_dir / f".{lib.name}.{os.getpid()}"
        proc = subprocess.run([cc, *CFLAGS, str(source), "-o", str(tmp), "-lm"],
                              capture_output=True, text=True)
        if proc.returncode != 0:
            raise CKernelUnavailable(f"{cc} failed to build {source}: {proc.stderr.strip()}")
        tmp.replace(lib)   # atomic: concurrent builds never load a half-written file
    return lib


@lru_cache(maxsize=4)
def _library(path: Path) -> ctypes.CDLL:
    lib = ctypes.CDLL(str(path))
    fn = lib.monitor_batch
    fn.restype = ctypes.c_int64
    return lib


def simulate_c(X: np.ndarray, E: np.ndarray | None = None, *,
               tests: Sequence[TestSpec] = STANDARD_TESTS,
               params: EMAParams = DEFAULT_PARAMS, dt: float | None = None,
               library: Path | None = None,
               lanes: bool = False) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """:func:`ema_bench.monitor.simulate_monitor` through the C kernel (one thread).

    ``lanes``: the 8-lane C twin of :mod:`ema_bench.monitor_lanes` (``monitor_lanes_batch``,
    vectorised by the compiler) instead of the scalar C; it takes only the lanes' effects
    (:data:`~ema_bench.monitor_lanes.LANE_EFFECTS`)."""
    from .monitor import test_layout
    from .monitor_lanes import LANE_EFFECTS, lane_groups

    lib = _library(library or build())
    X = np.ascontiguousarray(X, dtype=np.float64)
    n = X.shape[0]
    E = np.zeros((n, N_EFFECTS)) if E is None else np.ascontiguousarray(
        np.broadcast_to(np.asarray(E, dtype=np.float64), (n, N_EFFECTS)))
    dt = params.dt_mon if dt is None else float(dt)
    cmd, cmd_start, n_out, out_start = test_layout(tests, params.dt_ctrl)
    total = int(n_out.sum())
    out = np.empty((n, total, 4))
    ok = np.empty(n, dtype=np.uint8)
    p = params.to_array()
    ix = index_table()

    def ptr(a: np.ndarray, kind: type) -> ctypes._Pointer:
        return a.ctypes.data_as(ctypes.POINTER(kind))

    layout = (ptr(cmd, ctypes.c_double), ptr(cmd_start, ctypes.c_int64),
              ptr(n_out, ctypes.c_int64), ptr(out_start, ctypes.c_int64),
              ctypes.c_int64(len(tests)), ctypes.c_int64(total),
              ctypes.c_int64(steps_per(OUTPUT_DT, params.dt_ctrl)),
              ctypes.c_int64(steps_per(params.dt_ctrl, dt)), ctypes.c_double(dt),
              ptr(out, ctypes.c_double), ptr(ok, ctypes.c_uint8))
    if lanes:
        lane_columns = [_effects.EFFECT_INDEX[e] for e in LANE_EFFECTS]
        others = np.setdiff1d(np.arange(N_EFFECTS), lane_columns)
        if np.any(E[:, others] != 0.0):
            raise ValueError(f"the C lanes take only the effects {', '.join(LANE_EFFECTS)}")
        groups = np.ascontiguousarray(lane_groups(np.arange(n)))
        lib.monitor_lanes_batch(ptr(p, ctypes.c_double), ptr(ix, ctypes.c_int64),
                                ptr(X, ctypes.c_double), ptr(E, ctypes.c_double),
                                ctypes.c_int64(N_EFFECTS), ptr(groups, ctypes.c_int64),
                                ctypes.c_int64(groups.shape[0]), *layout)
    else:
        lib.monitor_batch(ptr(p, ctypes.c_double), ptr(ix, ctypes.c_int64),
                          ptr(X, ctypes.c_double), ptr(E, ctypes.c_double), ctypes.c_int64(n),
                          ctypes.c_int64(N_EFFECTS), *layout)
    outputs = {spec.name: out[:, s:s + k] for spec, s, k in zip(tests, out_start, n_out)}
    return outputs, ok.astype(bool)
