"""CPU seconds OpenBLAS's idle threads burn: a loop of threaded matrix products with
single-threaded Python work between them, run in a fresh interpreter with OpenBLAS's default
thread timeout and with ``OPENBLAS_THREAD_TIMEOUT=4`` (what ``tests/conftest.py`` sets for
the test session).  The products, and their thread count, are the same in both.

Usage::

    python benchmarks/blas_spin.py [--rounds 60] [--repeat 2]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys

LOOP = """
import time, numpy as np
a = np.random.default_rng(0).random((300, 300))
t, w = time.process_time(), time.perf_counter()
for _ in range({rounds}):
    a @ a                       # threaded in OpenBLAS: its threads then wait for work
    x = 0
    for i in range(200000):     # the calling thread alone
        x += i
print(f"{{time.process_time() - t:.2f}} {{time.perf_counter() - w:.2f}}")
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=60)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    code = LOOP.format(rounds=args.rounds)
    base = {k: v for k, v in os.environ.items() if k != "OPENBLAS_THREAD_TIMEOUT"}
    for _ in range(args.repeat):
        for label, env in (("default", base), ("OPENBLAS_THREAD_TIMEOUT=4",
                                               {**base, "OPENBLAS_THREAD_TIMEOUT": "4"})):
            out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                                 text=True, check=True).stdout.split()
            print(f"{label:<26} CPU {out[0]} s  wall {out[1]} s  load {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
