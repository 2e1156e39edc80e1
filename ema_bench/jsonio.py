"""Strict JSON for what people and programs read: ``--json`` output and summary files.

``json.dumps`` writes a float that is not finite as ``Infinity`` or ``NaN``, which are not JSON
(``jq``, JavaScript's ``JSON.parse`` and most other parsers refuse the whole document).  Here
such a value is written as ``null``: an expected running time of a target never reached, a
statistic of an empty group.  numpy scalars and arrays become plain numbers and lists.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np


def numpy_default(obj: Any) -> Any:
    """``default`` for ``json.dumps``: numpy scalars and arrays as Python numbers and lists."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"object of type {type(obj).__name__} is not JSON serialisable")


def plain(obj: Any, default: Callable[[Any], Any] | None = None) -> Any:
    """``obj`` with numpy values made plain and non-finite floats made ``None``.

    Parameters
    ----------
    obj : any
        Mappings (keys made ``str``), lists and tuples are walked; numpy scalars and arrays
        become Python numbers and lists; paths become strings.
    default : callable, optional
        Called on any other object that JSON cannot hold; ``TypeError`` without it.
    """
    if isinstance(obj, float | np.floating):
        return float(obj) if math.isfinite(obj) else None
    if obj is None or isinstance(obj, str | bool | int):
        return obj
    if isinstance(obj, np.generic):
        return plain(obj.item(), default)
    if isinstance(obj, np.ndarray):
        return plain(obj.tolist(), default)
    if isinstance(obj, Mapping):
        return {str(k): plain(v, default) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [plain(v, default) for v in obj]
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    if default is not None:
        return plain(default(obj))
    raise TypeError(f"object of type {type(obj).__name__} is not JSON serialisable")


def dumps(obj: Any, *, indent: int | None = None, sort_keys: bool = False,
          default: Callable[[Any], Any] | None = None) -> str:
    """Strict JSON text of ``obj`` (see :func:`plain`)."""
    return json.dumps(plain(obj, default), indent=indent, sort_keys=sort_keys, allow_nan=False)


def write_checked(path: Path, obj: Any, schema: Mapping, end: str = "", **kw: Any) -> None:
    """Write ``obj`` to ``path`` as :func:`dumps` (keywords ``kw``) gives it, plus ``end``,
    after checking that text as a reader will read it back against the type table ``schema``
    (:func:`ema_bench.sweep.schema.check`: a summary that its schema refuses is never
    written)."""
    from .sweep.schema import check

    text = dumps(obj, **kw) + end
    check(json.loads(text), schema, str(path))
    Path(path).write_text(text)


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file beside it (of this process: two
    processes writing one file do not share it): a reader sees the old file or the new one,
    never half of one (UTF-8)."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
