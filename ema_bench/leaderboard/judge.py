"""The one path from run records to any number: ``validate``, ``leaderboard --report-only``,
``--check``, ``export`` and the page admit records here, and nothing else is scored.

:func:`read_runs` reads ``runs.jsonl`` files strictly: a last line without its newline (a
torn write, or a line appended by hand) is refused, not dropped, and every line is kept, so
that two records of one run identity are seen.  :func:`judge` refuses what ``validate``
refuses (:func:`~.validate.check_record`, re-evaluation included), and more:

- **legacy records** (schema 1: no trajectory vectors, so hits are bounded, not proven) are
  refused for ranking; ``legacy=True`` admits them into a labelled legacy view (the
  committed quick baseline of ``--check``);
- **duplicates**: two finished records of one identity are a finding, not a choice made by
  file order (an error record followed by its retry's record is a resume, not a duplicate);
- **completeness** is checked per suite (:func:`~.validate.check_complete` on each suite's
  records apart: one record of another suite no longer switches a suite's check off);
- **seed scheme 1** (a solver seed spawned from the run node, which gives the node away) is
  accepted for the committed boards' records only (:mod:`ema_bench.grandfather`): a record that
  leaves ``seed_scheme`` out to claim it is refused;
- **an earlier, compatible model version** (2, :data:`~ema_bench.trace_cache.
  COMPATIBLE_VERSIONS`) likewise: the committed records were made on it and replay on it, a
  new run is made on this installation's version (else a submitter could run each task on
  both models and file the better run).

:func:`admitted` is what every writer calls: the records, or :class:`JudgeError` (one line,
``ema-bench validate`` lists every finding).  This module imports no plugin: a verdict is
never computed in a process that ran submitted code (replay runs the solvers in their own
processes, :mod:`.replay_worker`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from ..escape import terminal
from ..grandfather import accepted_record, committed_record
from ..records import schema
from ..suites import is_case, suite_of
from ..sweep.schema import SchemaError
from ..sweep.store import read_lines
from ..trace_cache import MODEL_VERSION, is_comparable
from .run_store import _schema, is_error, model_version, run_identity
from .validate import Finding, check_complete, check_record


class JudgeError(ValueError):
    """Records that cannot be admitted: one line, naming the file or the first finding."""


@dataclass
class Verdict:
    """What :func:`judge` found: the admitted ``records`` (one per run identity, when
    ``findings`` is empty) and every finding."""

    records: list[dict]
    findings: list[Finding] = field(default_factory=list)
    legacy: int = 0

    @property
    def accepted(self) -> bool:
        return not self.findings


def read_runs(paths: Sequence[str | os.PathLike]) -> list[dict]:
    """Every record line of the files, in order, type-checked; :class:`JudgeError` for a
    missing file, a broken line, or a last line without its newline."""
    out: list[dict] = []
    for path in paths:
        p = Path(path)
        if not p.is_file():
            raise JudgeError(f"{terminal(path)}: " + ("not a file (give the runs.jsonl inside "
                             "a leaderboard folder)" if p.exists() else "no such file"))
        try:
            recs, intact, line = read_lines(p, schema=_schema)
        except SchemaError as exc:
            raise JudgeError(f"{exc} (not a file of run records: one JSON object per line, "
                             "as 'ema-bench leaderboard' writes)") from None
        except (ValueError, TypeError, KeyError, AttributeError) as exc:
            raise JudgeError(f"{terminal(path)}: not a file of run records ({exc})") from None
        if not intact:
            raise JudgeError(f"{terminal(path)}, line {line}: incomplete last line (no newline "
                             "at its end, or not JSON: a torn write or an edit); complete or "
                             "remove it")
        out += recs
    return out


def _dedup(records: list[dict]) -> tuple[list[dict], list[Finding]]:
    """One record per identity: a finished record supersedes error records (a resume); two
    finished records of one identity are a finding."""
    kept: dict[tuple, dict] = {}
    found = []
    for r in records:
        ident = run_identity(r)
        old = kept.get(ident)
        if old is None or is_error(old):
            kept[ident] = r
        elif not is_error(r):
            found.append(Finding(_key(r), "two records of one run identity (a run is "
                                          "recorded once; remove the copy that is not the "
                                          "run's)"))
    return list(kept.values()), found


def _key(r: dict, i: int | None = None) -> str:
    return terminal(r.get("key", f"record {i}") if isinstance(r, dict) else f"record {i}")


def judge(records: list[dict], *, reevaluate: bool = True, complete: bool = True,
          per_tier: int | None = None, legacy: bool = False) -> Verdict:
    """Every reason to refuse ``records``, and the records admitted.

    Parameters
    ----------
    records : list of dict
        Every record line, duplicates included (:func:`read_runs`).
    reevaluate : bool
        Re-evaluate the vectors each record's figures rest on (``validate`` does; off only
        for a fast, weaker look).
    complete : bool
        Require every instance of each suite entered (``--partial``: off).
    per_tier : int, optional
        emafdi-v2: the first N instances of each tier only.
    legacy : bool
        Admit schema-1 records into a labelled legacy view (never a ranking of submissions).
    """
    recs, found = _dedup(records)
    n_legacy = 0
    for i, r in enumerate(recs):
        if isinstance(r, dict) and not is_error(r) and schema(r) < 2:
            n_legacy += 1
            if not legacy:
                found.append(Finding(_key(r, i), "legacy record (schema 1, no trajectory "
                                     "vectors): its hits cannot be proven, so it is not "
                                     "ranked (rerun it, or --legacy for a labelled legacy "
                                     "view)"))
                continue
        found += [Finding(_key(r, i), terminal(p)) for p in check_record(r, reevaluate)]
        if isinstance(r, dict) and not is_error(r) and not accepted_record(r):
            found.append(Finding(_key(r, i), "seed scheme 1 (the solver seed spawned from the "
                                 "run node, which gives the node away) is accepted for the "
                                 "committed boards' records only: rerun with this version "
                                 "(seed_scheme 2)"))
        if (isinstance(r, dict) and not is_error(r) and model_version(r) != MODEL_VERSION
                and is_comparable(model_version(r)) and not committed_record(r)):
            found.append(Finding(_key(r, i), f"model version {terminal(model_version(r))} "
                                 "(earlier, compatible) is accepted for the committed "
                                 "boards' records only: rerun with this version "
                                 f"({MODEL_VERSION})"))
    if complete:
        for suite in sorted({suite_of(r.get("case")).id for r in recs}):
            found += check_complete([r for r in recs if suite_of(r.get("case")).id == suite],
                                    per_tier)
    return Verdict(recs, found, n_legacy)


def is_suite_case(case: object) -> bool:
    """Whether ``case`` is an instance of a suite (v1's or emafdi-v2's), which the judge can
    re-derive; a sweep may also run other cases (``seeded``: an instance drawn from the run
    node), the user's own experiment, which no suite ranks."""
    return isinstance(case, str) and is_case(case)


def admitted(records: list[dict], what: str, **options: object) -> list[dict]:
    """The records ``what`` (a command) may score or export: those of :func:`judge` when it
    finds nothing, else :class:`JudgeError` with the count and the first finding."""
    v = judge(records, **options)   # type: ignore[arg-type]
    if v.findings:
        raise JudgeError(f"{what}: {len(v.findings)} finding(s) in {len(v.records)} records, "
                         f"nothing written (first: {v.findings[0]}); 'ema-bench validate' "
                         "lists them")
    return v.records
