"""Session set-up: the reference-trace cache lives in a fresh folder for the test run (child
processes of CLI tests inherit it), so tests neither read nor fill the user's cache."""

import os
import tempfile

os.environ.setdefault("EMA_BENCH_CACHE", tempfile.mkdtemp(prefix="ema-bench-test-cache-"))
