"""Actuator test traces: the four recorded signals of each standard test, in canonical units.

A :class:`Traces` holds, for each test (``"step"``, ``"sine"``, ...), an array of shape
``(n_samples, 4)`` whose columns follow :data:`SIGNALS`.  Each sample is the mean of its signal
over one output window of ``dt`` seconds (1 ms by default), so sample ``k`` is stamped at the
window centre ``(k + 0.5) * dt``.

Files
-----
:meth:`Traces.save` writes ``.csv`` (long format, readable by people, pandas and Excel) or
``.npz``; :func:`load_traces` reads those, MATLAB ``.mat`` files and "plain measured" CSV files
(no comment lines, any supported unit, finer sample rates are block-averaged down to ``dt``).
Files are never unpickled.

CSV layout (read it with ``pandas.read_csv(path, comment="#")``)::

    # ema-bench traces v1
    # dt = 0.001 s
    # meta = {"model": "reference", "case": "nominal"}
    test,time [s],theta_u [rad],theta_m [rad],omega_m [rad/s],i_eq [A]
    step,0.0005,0.0,0.0,0.0,0.0

NPZ keys: ``"<test>/<signal>"`` and ``"time/<test>"`` (float arrays), ``"units"`` (strings
``"signal=unit"``), ``"dt"`` and ``"meta_json"`` (0-d string).  MATLAB variables use the same names
with ``_`` in place of ``/`` (``step_theta_u``, ``time_step``); a file holding only ``time`` and
signal-named variables is one test, named by the ``test=`` argument of :func:`load_traces`.
:func:`load_measured` gathers the tests of several such files into one :class:`Traces`.

Untrusted files
---------------
Sizes that a file declares (an ``.npy`` header's shape, a MATLAB element's byte count or
dimensions) are checked against :data:`MAX_ARRAY_BYTES` and against the bytes the file really
holds before anything is allocated, and all of a file's arrays together against
:data:`MAX_FILE_BYTES` (an ``.npz`` member's name, count and size before any member is read),
so a small crafted file cannot exhaust memory; every defect of a file raises
:class:`TracesError`.
"""

from __future__ import annotations

from .arrays import MAX_ARRAY_BYTES, MAX_FILE_BYTES
from .container import DESCRIPTIONS, OUTPUT_DT, SIGNALS, UNITS, Traces
from .errors import TracesError
from .load import MAX_OVERSAMPLING, load_measured, load_traces
from .units import UNIT_CONVERSIONS

__all__ = [
    "DESCRIPTIONS",
    "MAX_ARRAY_BYTES",
    "MAX_FILE_BYTES",
    "MAX_OVERSAMPLING",
    "OUTPUT_DT",
    "SIGNALS",
    "UNITS",
    "UNIT_CONVERSIONS",
    "Traces",
    "TracesError",
    "load_measured",
    "load_traces",
]
