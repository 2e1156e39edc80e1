"""numba's cache follows every source of the package (ema_bench.jit_cache): an edit of a module
whose functions a kernel inlines must not leave the old kernel in use."""

from __future__ import annotations

import os

from ema_bench.jit_cache import STAMP, ensure_fresh


def _package(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "physics" / "__pycache__").mkdir(parents=True)
    (pkg / "__pycache__").mkdir()
    (pkg / "monitor.py").write_text("KERNEL = 1\n")
    (pkg / "physics" / "mechanics.py").write_text("STEP = 1\n")
    return pkg


def _cached(pkg):
    for name in ("monitor.kernel-10.py311.nbi", "monitor.kernel-10.py311.1.nbc"):
        (pkg / "__pycache__" / name).write_bytes(b"kernel")
    (pkg / "physics" / "__pycache__" / "mechanics.step-5.py311.nbi").write_bytes(b"x")
    (pkg / "__pycache__" / "monitor.cpython-311.pyc").write_bytes(b"pyc")


def _left(pkg):
    return sorted(p.name for p in pkg.rglob("*") if p.suffix in (".nbi", ".nbc"))


def test_an_edit_of_an_inlined_module_drops_the_cached_kernels(tmp_path):
    pkg = _package(tmp_path)
    _cached(pkg)
    assert ensure_fresh(pkg) is True              # first check: no stamp yet
    assert _left(pkg) == [] and (pkg / "__pycache__" / STAMP).is_file()
    _cached(pkg)
    assert ensure_fresh(pkg) is False             # nothing changed: the cache stays
    assert len(_left(pkg)) == 3
    mech = pkg / "physics" / "mechanics.py"
    st = mech.stat()
    mech.write_text("STEP = 2\n")                 # same size, only the physics file
    os.utime(mech, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000))
    assert ensure_fresh(pkg) is True
    assert _left(pkg) == []
    assert (pkg / "__pycache__" / "monitor.cpython-311.pyc").is_file()   # only numba's files
    (pkg / "physics" / "new_block.py").write_text("")                    # a new module too
    _cached(pkg)
    assert ensure_fresh(pkg) is True and _left(pkg) == []


def test_a_read_only_package_is_left_alone(tmp_path, monkeypatch):
    pkg = _package(tmp_path)
    _cached(pkg)

    def refuse(*a, **k):
        raise PermissionError("read-only")
    monkeypatch.setattr(type(pkg), "unlink", refuse)
    assert ensure_fresh(pkg) is False
    assert len(_left(pkg)) == 3
