"""Does LLVM (through numba) vectorise a loop over candidate lanes?  It depends on the layout.

The same loop body, a step of the sliding mechanics for eight lanes with selects instead of
branches, is compiled twice: with the lanes' quantities in separate arrays (one array per
state variable and per constant), and with all of them in one flat array at fixed offsets.
The script counts packed (``vmulpd``, ``vdivpd``) and scalar (``vmulsd``) multiplies in the
generated machine code.  Measured with numba 0.68 on x86-64 (AVX-512 machine, 256-bit vectors
preferred): separate arrays 0 packed / 29 scalar, one flat array 58 packed / 0 scalar.  With
separate arrays the compiler needs a runtime alias check for every pair of arrays the loop
writes and reads; beyond a handful it gives up and the loop stays scalar.  This is why
``ema_bench/monitor_lanes.py`` keeps its lanes in one array.

Run: ``python benchmarks/vectorisation_probe.py``.

``--lanes``: the same count for every part of the lanes kernel's step
(:mod:`ema_bench.monitor_lanes`), each part's loop over the lanes compiled on its own from the
kernel's own inline functions: which parts the compiler vectorises, which it leaves scalar.
``docs/performance.md`` records the answer and why.
"""

from __future__ import annotations

import re

import numpy as np
from numba import njit

L = 8                  # lanes
H = 5e-5               # s, step
STATE = ("thm", "wm", "thu", "wu", "tm", "acc0", "acc1", "acc2", "flag")
CONSTS = ("tau", "half", "k", "bc", "i11", "i12", "i22", "jm", "ju", "fdyn", "cm", "ka", "gh",
          "imf", "iuf")

BODY = """
    for _ in range(steps):
        for l in range(L):
            delta = tau[l] * thm[l] - thu[l]
            dd = tau[l] * wm[l] - wu[l]
            sgn = 1.0 if wm[l] > 0.0 else -1.0
            r1 = jm[l] * wm[l] - H * (sgn * fdyn[l] + 0.5 * cm[l] * wm[l])
            r2 = ju[l] * wu[l] + H * (-ka[l] * thu[l] - gh[l] * wu[l])
            side = 1.0 if delta > half[l] else (-1.0 if delta < -half[l] else 0.0)
            a = k[l] * (delta - half[l] * side) + bc[l] * dd
            b1 = r1 - H * tau[l] * a
            b2 = r2 + H * a
            wm_c = i11[l] * b1 + i12[l] * b2 + i11[l] * H * tm[l]
            wu_c = i12[l] * b1 + i22[l] * b2
            wm_f = r1 * imf[l] + imf[l] * H * tm[l]
            wu_f = r2 * iuf[l]
            wm1 = wm_c if side != 0.0 else wm_f
            wu1 = wu_c if side != 0.0 else wu_f
            flag[l] = 1.0 if wm1 * wm[l] < 0.0 else 0.0
            thm[l] += 0.5 * H * (wm[l] + wm1)
            thu[l] += 0.5 * H * (wu[l] + wu1)
            acc0[l] += thm[l]
            acc1[l] += wm1
            acc2[l] += thu[l]
            wm[l] = wm1
            wu[l] = wu1
"""


def _compile(flat: bool):
    names = STATE + CONSTS
    if flat:   # every lane quantity at a fixed offset of one array
        body = BODY
        for i, name in enumerate(names):
            body = re.sub(rf"\b{name}\[l\]", f"F[{i * L} + l]", body)
        src = "def kernel(F, steps):" + body
    else:      # one array per quantity
        src = f"def kernel({', '.join(names)}, steps):" + BODY
    scope = {"L": L, "H": H}
    exec(src, scope)   # noqa: S102 - the probe's own source text, built above
    return njit(error_model="numpy")(scope["kernel"])


def count(flat: bool) -> dict[str, int]:
    """Packed and scalar arithmetic instructions in the compiled loop."""
    kernel = _compile(flat)
    n = len(STATE) + len(CONSTS)
    rng = np.random.default_rng(0)
    if flat:
        kernel(rng.random(n * L), 1)
    else:
        kernel(*(rng.random(L) for _ in range(n)), 1)
    asm = next(iter(kernel.inspect_asm().values()))
    return {op: len(re.findall(rf"\b{op}\b", asm)) for op in ("vmulpd", "vdivpd", "vmulsd")}


def _ops(kernel) -> dict[str, int]:
    """Packed and scalar double-precision arithmetic in a compiled kernel's machine code."""
    asm = next(iter(kernel.inspect_asm().values()))
    packed = ("vmulpd", "vaddpd", "vsubpd", "vdivpd", "vrndscalepd", "vroundpd")
    scalar = ("vmulsd", "vaddsd", "vsubsd", "vdivsd", "vrndscalesd", "vroundsd")
    return {"packed": sum(len(re.findall(rf"\b{op}\b", asm)) for op in packed),
            "scalar": sum(len(re.findall(rf"\b{op}\b", asm)) for op in scalar)}


def lane_parts() -> dict[str, dict[str, int]]:
    """Packed and scalar arithmetic of each part of the lanes' step, compiled as the kernel
    compiles it: a loop over the lanes calling the part's inline function on the flat array
    (the general fall-backs, scalar by design, are left out)."""
    from ema_bench import monitor_lanes as ml
    from ema_bench.faults import NOMINAL
    from ema_bench.monitor_plant import monitor_consts
    from ema_bench.params import DEFAULT_PARAMS
    from ema_bench.physics.ace import ace_consts

    lanes = ml.LANES

    @njit(error_model="numpy")
    def cogging(F, h, pp):
        for q in range(lanes):
            ml._cogging_lane(F, q, h, pp)

    @njit(error_model="numpy")
    def eccentric(F, h, ke):
        for q in range(lanes):
            ml._eccentric_lane(F, q, h, ke)

    @njit(error_model="numpy")
    def drive(F, dc0, cc0, h, c, tick):
        for q in range(lanes):
            ml._drive_fast_lane(F, q, dc0, cc0, h, c, tick)

    @njit(error_model="numpy")
    def mechanics(F, mc0):
        for q in range(lanes):
            ml._mech_fast_lane(F, q, ml._lane_mech_consts(F, q, mc0))

    @njit(error_model="numpy")
    def delay(F, buf, k, d, d0, frac):
        ml._delay_lines(F, buf, k, d, d0, frac)

    p = DEFAULT_PARAMS.to_array()
    dc0, mc0 = monitor_consts(p, NOMINAL, np.zeros(12), DEFAULT_PARAMS.dt_mon)[:2]
    cc0 = ace_consts(p, NOMINAL[3])
    F = np.random.default_rng(0).random(ml._N_BLOCKS)
    h = DEFAULT_PARAMS.dt_mon
    cogging(F, h, 2.0)
    eccentric(F, h, 0.05)
    drive(F, dc0, cc0, h, 0.1, True)
    mechanics(F, mc0)
    delay(F, np.zeros((ml._DBUF, lanes)), 3, np.ones(lanes), np.ones(lanes, np.int64),
          np.zeros(lanes))
    return {name: _ops(k) for name, k in (("cogging", cogging), ("eccentric", eccentric),
                                          ("controller + drive", drive),
                                          ("mechanics", mechanics), ("delay lines", delay))}


if __name__ == "__main__":
    import sys

    if "--lanes" in sys.argv:
        for part, ops in lane_parts().items():
            print(f"{part:20s} {ops}")
    else:
        for flat in (False, True):
            label = "one flat array  " if flat else "separate arrays "
            print(label, count(flat))
