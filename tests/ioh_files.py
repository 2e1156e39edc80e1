"""A reader of IOHprofiler data, from the format alone (independent of the writer,
:mod:`ema_bench.leaderboard.ioh`): what the export tests read back."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any


def read_ioh(folder: Path) -> list[dict[str, Any]]:
    """The runs of the IOHprofiler data under ``folder`` (every ``IOHprofiler_*.json`` meta
    file below it and the data files it names), read from the format alone.

    Returns
    -------
    list of dict
        Per run: ``algorithm``, ``algorithm_info``, ``suite``, ``function_id``,
        ``function_name``, ``maximization``, ``dimension``, ``instance``, ``run_evals`` (the
        run's evaluations), ``evals`` and ``raw_y`` (the data lines), ``best_y``,
        ``best_evals``, ``best_x`` and the run attributes (``attributes``).

    Raises
    ------
    ValueError
        A data file's runs do not match its meta file's, or a line does not parse.
    """
    out = []
    for meta_path in sorted(Path(folder).rglob("IOHprofiler_*.json")):
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
        for scen in meta["scenarios"]:
            dat = meta_path.parent / scen["path"]
            blocks = _dat_runs(dat)
            if len(blocks) != len(scen["runs"]):
                raise ValueError(f"{dat}: {len(blocks)} runs, {meta_path} lists "
                                 f"{len(scen['runs'])}")
            for run, (header, rows) in zip(scen["runs"], blocks):
                cols = {h: [row[i] for row in rows] for i, h in enumerate(header)}
                out.append({
                    "algorithm": meta["algorithm"]["name"],
                    "algorithm_info": meta["algorithm"]["info"],
                    "suite": meta["suite"], "function_id": meta["function_id"],
                    "function_name": meta["function_name"],
                    "maximization": meta["maximization"], "dimension": scen["dimension"],
                    "instance": run["instance"], "run_evals": run["evals"],
                    "evals": [int(v) for v in cols["evaluations"]], "raw_y": cols["raw_y"],
                    "best_y": run["best"]["y"], "best_evals": run["best"]["evals"],
                    "best_x": run["best"]["x"],
                    "attributes": {a: run[a] for a in meta.get("run_attributes", [])},
                })
    return out


def _dat_runs(path: Path) -> list[tuple[list[str], list[list[float]]]]:
    """``(header, rows)`` per run of a .dat file: a line that does not start with a number
    is a header and starts a run."""
    runs: list[tuple[list[str], list[list[float]]]] = []
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        fields = line.split()
        if not fields:
            continue
        try:
            float(fields[0])
        except ValueError:
            runs.append((fields, []))
            continue
        if not runs:
            raise ValueError(f"{path}:{n}: data before the first header line")
        try:
            runs[-1][1].append([float(v) for v in fields])
        except ValueError:
            raise ValueError(f"{path}:{n}: not a number in {line!r}") from None
    return runs
