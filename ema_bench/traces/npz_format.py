"""The NPZ reader: the members' names, count and total size, then each ``.npy`` header,
checked before any data is read; nothing is unpickled."""

from __future__ import annotations

import math
import tokenize
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from .arrays import MAX_ARRAY_BYTES, MAX_FILE_BYTES, _arrays_to_raw, check_keys
from .errors import _describe, _fail
from .units import _Raw, _TimeLabel

_NPY_MAGIC = b"\x93NUMPY"
_NPY_HEADER_READERS = {(1, 0): np.lib.format.read_array_header_1_0,
                       (2, 0): np.lib.format.read_array_header_2_0}
# what zipfile raises for a corrupt archive or member (bad CRC, bad deflate data, truncation,
# a "zip version needed" it does not know)
_ZIP_ERRORS = (zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error, EOFError, OSError,
               NotImplementedError)


def _read_npz(path: Path, test: str | None) -> tuple[_Raw, dict[str, Any], _TimeLabel]:
    arrays = _npz_arrays(path)
    if not arrays:
        raise _fail(path, "file is empty (no arrays)")
    return _arrays_to_raw(path, arrays, "/", "key", test)


def _npz_arrays(path: Path) -> dict[str, np.ndarray]:
    """Every array of an .npz archive (a zip of .npy files), each member's header checked
    before its data is read; nothing is unpickled."""
    try:
        with open(path, "rb") as fh:
            is_npy = fh.read(len(_NPY_MAGIC)) == _NPY_MAGIC
    except OSError as exc:
        raise _fail(path, f"cannot read file: {exc}") from exc
    if is_npy:
        raise _fail(path, "not an .npz archive (a single .npy array?)")
    if not zipfile.is_zipfile(path):
        raise _fail(path, "cannot read as .npz: not a zip archive (the file is corrupt, "
                          "truncated or of another kind)")
    arrays: dict[str, np.ndarray] = {}
    try:
        with zipfile.ZipFile(path) as archive:
            infos = archive.infolist()
            # names, count and total size from the central directory, before any member is
            # read; zipfile never inflates a member past the size listed there
            check_keys(path, [i.filename.removesuffix(".npy") for i in infos], "/", "key")
            total = sum(i.file_size for i in infos)
            if total > MAX_FILE_BYTES:
                raise _fail(path, f"its members hold {total} bytes in all, more than the limit "
                                  f"of {MAX_FILE_BYTES} bytes per file")
            for info in infos:
                key = info.filename.removesuffix(".npy")
                arrays[key] = _npy_member(path, archive, info, f"key {key!r}")
    except _ZIP_ERRORS as exc:
        raise _fail(path, f"corrupt .npz archive: {_describe(exc)}") from exc
    return arrays


def _npy_member(path: Path, archive: zipfile.ZipFile, info: zipfile.ZipInfo, where: str
                ) -> np.ndarray:
    """One .npy member of an .npz archive, refused when its header declares more than
    :data:`MAX_ARRAY_BYTES` or other than the member holds (checked before reading)."""
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        raise _fail(path, f"{where}: unsupported zip compression method {info.compress_type} "
                          "(numpy writes stored or deflated members)")
    if info.flag_bits & 0x1:
        raise _fail(path, f"{where}: the member is encrypted")
    with archive.open(info) as fh:
        shape, fortran_order, dtype = _npy_header(path, fh, where)
        n = math.prod(shape)
        nbytes = n * dtype.itemsize
        if nbytes > MAX_ARRAY_BYTES:
            raise _fail(path, f"{where} claims {n} samples of {dtype.itemsize} bytes, larger "
                              f"than the limit of {MAX_ARRAY_BYTES} bytes per array")
        held = info.file_size - fh.tell()
        if nbytes != held:
            raise _fail(path, f"{where}: its header declares {nbytes} bytes of data but the "
                              f"archive holds {held}; the file is corrupt")
        data = fh.read(nbytes)
    if len(data) != nbytes:
        raise _fail(path, f"{where}: truncated, {len(data)} of {nbytes} bytes")
    try:
        flat = np.frombuffer(data, dtype=dtype)
        return flat.reshape(shape[::-1]).T if fortran_order else flat.reshape(shape)
    except ValueError as exc:  # e.g. a zero-size dtype, too many dimensions
        raise _fail(path, f"{where}: cannot read: {exc}") from exc


def _npy_header(path: Path, fh: Any, where: str) -> tuple[tuple[int, ...], bool, np.dtype]:
    """Shape, Fortran order and dtype of the .npy stream ``fh``; object dtypes are refused."""
    try:
        version = np.lib.format.read_magic(fh)
    except ValueError:
        raise _fail(path, f"{where} is not a .npy array (no .npy magic string)") from None
    read_header = _NPY_HEADER_READERS.get(version)
    if read_header is None:
        raise _fail(path, f"{where}: unsupported .npy format version {version}")
    try:
        shape, fortran_order, dtype = read_header(fh)
    except (ValueError, tokenize.TokenError) as exc:  # numpy tokenizes a header it cannot parse
        raise _fail(path, f"{where}: corrupt .npy header: {exc}") from exc
    if dtype.hasobject:
        raise _fail(path, f"{where} holds an object array (pickled data); refusing to "
                          "unpickle, store plain numeric arrays")
    if any(d < 0 for d in shape):
        raise _fail(path, f"{where}: corrupt .npy header: negative shape {shape}")
    return shape, fortran_order, dtype
