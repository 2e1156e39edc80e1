"""The MATLAB ``.mat`` reader, with the walker that checks the sizes a v5 file declares
before scipy allocates from them."""

from __future__ import annotations

import io
import itertools
import math
import struct
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from .arrays import MAX_ARRAY_BYTES, MAX_FILE_ARRAYS, MAX_FILE_BYTES, _arrays_to_raw, check_keys
from .errors import _describe, _fail
from .units import _Raw, _TimeLabel


def _read_mat(path: Path, test: str | None) -> tuple[_Raw, dict[str, Any], _TimeLabel]:
    import scipy.io  # only .mat files need scipy.io; keep the module import light

    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:   # before reading it into memory
            raise _fail(path, f"the file holds {size} bytes, more than the limit of "
                              f"{MAX_FILE_BYTES} bytes per file")
        data = path.read_bytes()
    except OSError as exc:
        raise _fail(path, f"cannot read file: {exc}") from exc
    _check_mat_sizes(path, data)
    try:
        # from memory: a size read in the file cannot make scipy read (and allocate) past it
        content = scipy.io.loadmat(io.BytesIO(data), squeeze_me=False, chars_as_strings=True)
    except NotImplementedError as exc:
        raise _fail(path, f"MATLAB v7.3 (HDF5) files are not supported; save with '-v7': "
                          f"{exc}") from exc
    except Exception as exc:  # scipy raises many kinds for a corrupt file
        raise _fail(path, f"cannot read as .mat: {_describe(exc)}") from exc
    arrays = {k: v for k, v in content.items() if not k.startswith("__")}
    if not arrays:
        raise _fail(path, "file is empty (no variables)")
    return _arrays_to_raw(path, arrays, "_", "variable", test)


# MATLAB v5 data types and array classes (MAT-file format, "Data Element" and "Array Flags")
_MI_INT32, _MI_MATRIX, _MI_COMPRESSED = 5, 14, 15
# what a matrix may hold: numbers (miINT8 .. miUINT64, miUTF8 .. miUTF32) and matrices; scipy
# indexes a fixed-size table with the code, so others read past it (a segmentation fault)
_MI_INNER_TYPES = frozenset({1, 2, 3, 4, 5, 6, 7, 9, 12, 13, 16, 17, 18, _MI_MATRIX})
_MX_SPARSE_CLASS = 5
_MAT_MAX_DEPTH = 16  # nested cells and structs; traces files hold plain arrays
_MAT_HEADER_ROOM = 2**16  # bytes of a variable beyond its data: flags, dimensions, name


def _check_mat_sizes(path: Path, data: bytes) -> None:
    """Check the sizes a MATLAB v5 file declares before scipy allocates from them.

    scipy sizes its buffers by each data element's declared byte count and cell and struct
    arrays by their declared dimensions, so a few crafted bytes could make it fill gigabytes.
    Here every element must fit in what holds it (the file, a decompressed variable, a
    matrix), and every matrix's element count in :data:`MAX_ARRAY_BYTES` and in its bytes;
    the variables' names (in each top-level matrix) must be a traces file's
    (:func:`~ema_bench.traces.arrays.check_keys`), all before scipy reads the file.
    v4 files are read from memory and bounded by their data; v7.3 files scipy refuses.
    """
    if len(data) < 128 or data[126:128] not in (b"IM", b"MI"):
        return
    order = "<" if data[126:128] == b"IM" else ">"
    if struct.unpack_from(order + "H", data, 124)[0] != 0x0100:
        return
    pos, total, count, names = 128, 0, 0, []
    while len(data) - pos >= 8:
        mtype, nbytes = struct.unpack_from(order + "II", data, pos)
        if mtype not in (_MI_MATRIX, _MI_COMPRESSED):
            return  # scipy refuses anything else at the top level
        count += 1
        if count > MAX_FILE_ARRAYS:
            raise _fail(path, f"more than the limit of {MAX_FILE_ARRAYS} variables per file")
        end = pos + 8 + nbytes
        if end > len(data):
            raise _fail(path, f"a variable declares {nbytes} bytes but only "
                              f"{len(data) - pos - 8} follow; the file is truncated or corrupt")
        if mtype == _MI_COMPRESSED:
            # scipy inflates every variable at once: their total is bounded, not each alone
            inflated = _inflate(path, data[pos + 8: end], MAX_FILE_BYTES - total)
            total += len(inflated)
            _check_mat_elements(path, inflated, 0, len(inflated), order, 0, names)
            del inflated
        else:
            total += nbytes
            _check_mat_elements(path, data, pos, end, order, 0, names)
        if total > MAX_FILE_BYTES:
            raise _fail(path, f"its variables hold more than the limit of {MAX_FILE_BYTES} "
                              "bytes per file")
        pos = end
    check_keys(path, names, "_", "variable")


def _inflate(path: Path, blob: bytes, room: int) -> bytes:
    """A compressed MATLAB variable, decompressed up to its largest allowed size (and at most
    ``room`` bytes, what the file's limit leaves, plus one so that passing it shows)."""
    inflater = zlib.decompressobj()
    try:
        out = inflater.decompress(blob, min(MAX_ARRAY_BYTES + _MAT_HEADER_ROOM, room + 1))
    except zlib.error as exc:
        raise _fail(path, f"a compressed variable is corrupt: {exc}") from exc
    if inflater.unconsumed_tail and len(out) < MAX_ARRAY_BYTES + _MAT_HEADER_ROOM:
        raise _fail(path, f"its variables hold more than the limit of {MAX_FILE_BYTES} bytes "
                          "per file")
    if inflater.unconsumed_tail:
        raise _fail(path, f"a compressed variable holds more than the limit of "
                          f"{MAX_ARRAY_BYTES} bytes per array")
    return out


def _mat_elements(
    path: Path, buf: bytes, start: int, end: int, order: str
) -> Iterator[tuple[int, int, int]]:
    """(data type, data offset, byte count) of each data element in ``buf[start:end]``,
    each checked to be of a known type and to fit there."""
    pos = start
    while end - pos >= 8:
        word, nbytes = struct.unpack_from(order + "II", buf, pos)
        mtype = word & 0xFFFF if word >> 16 else word
        if mtype not in _MI_INNER_TYPES:
            raise _fail(path, f"unknown MATLAB data type {mtype}; the file is corrupt")
        if word >> 16:  # small element: byte count and type in one word, data in the next
            yield mtype, pos + 4, min(word >> 16, 4)
            pos += 8
            continue
        if nbytes > end - pos - 8:
            raise _fail(path, f"a data element declares {nbytes} bytes but only "
                              f"{end - pos - 8} follow; the file is truncated or corrupt")
        yield mtype, pos + 8, nbytes
        pos += 8 + nbytes + (-nbytes % 8)  # elements inside a matrix are padded to 8 bytes


def _check_mat_elements(
    path: Path, buf: bytes, start: int, end: int, order: str, depth: int,
    names: list[str] | None = None
) -> None:
    """Check the elements of ``buf[start:end]`` and, recursively, of the matrices there;
    the names of the matrices at ``depth`` 0 (the file's variables) go to ``names``."""
    for mtype, body, nbytes in _mat_elements(path, buf, start, end, order):
        if mtype != _MI_MATRIX:
            continue
        if depth == 0 and names is not None:
            names.append(_mat_name(path, buf, body, body + nbytes, order))
        if depth >= _MAT_MAX_DEPTH:
            raise _fail(path, f"variables nested deeper than {_MAT_MAX_DEPTH} levels")
        _check_mat_dims(path, buf, body, body + nbytes, order)
        _check_mat_elements(path, buf, body, body + nbytes, order, depth + 1)


def _mat_name(path: Path, buf: bytes, start: int, end: int, order: str) -> str:
    """The name of a matrix (its third element: array flags, dimensions, name)."""
    parts = list(itertools.islice(_mat_elements(path, buf, start, end, order), 3))
    if len(parts) < 3 or parts[2][0] not in (1, 2, 16):   # miINT8, miUINT8, miUTF8
        raise _fail(path, "a variable without a name; the file is corrupt")
    _, at, n = parts[2]
    return buf[at:at + n].decode("latin-1")


def _check_mat_dims(path: Path, buf: bytes, start: int, end: int, order: str) -> None:
    """A matrix (array flags, dimensions, name, data) may not declare more elements than
    :data:`MAX_ARRAY_BYTES` of float64, nor more than it has bytes (sparse ones excepted)."""
    parts = list(itertools.islice(_mat_elements(path, buf, start, end, order), 2))
    if len(parts) < 2 or parts[1][0] != _MI_INT32 or parts[0][2] < 4:
        return  # not the usual layout (e.g. an opaque object): scipy judges it
    (_, flags_at, _), (_, dims_at, dims_bytes) = parts
    dims = struct.unpack_from(f"{order}{dims_bytes // 4}i", buf, dims_at)
    if any(d < 0 for d in dims):
        raise _fail(path, f"a variable declares negative dimensions {dims}")
    n = math.prod(dims)
    if struct.unpack_from(order + "I", buf, flags_at)[0] & 0xFF == _MX_SPARSE_CLASS:
        return  # a sparse matrix stores only its non-zeros
    shape = " x ".join(map(str, dims))
    if n * 8 > MAX_ARRAY_BYTES:
        raise _fail(path, f"a variable claims {n} samples ({shape}), larger than the limit "
                          f"of {MAX_ARRAY_BYTES} bytes per array")
    held = end - dims_at - dims_bytes
    if n > held:  # every element takes at least a byte
        raise _fail(path, f"a variable claims {n} samples ({shape}) but holds {held} bytes; "
                          "the file is corrupt")
