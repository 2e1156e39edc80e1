"""Fail when ``mutmut results --all true`` lists a mutant that no test killed and that is
neither listed in docs/mutation-testing.md as an equivalent mutant (its mutmut name, in
backquotes) nor, in a ratchet shard, a known untriaged survivor.

    python .github/mutation_gate.py RESULTS DOC [--only GLOB ...] [--untriaged FILE [--record]]

``--only``: the mutant-name globs of one shard of the weekly job (``.github/workflows/
mutation.yml``); mutants outside them are not this shard's.  A shard that finds none of its
mutants in RESULTS fails (a gate that checked nothing must not pass).

``--untriaged``: a JSON ratchet, ``{"modules": {MODULE: {"mutants": N, "caught": C,
"untriaged": [NAME, ...]}}}``, for modules whose survivors are not triaged yet (they are
labelled untriaged, not equivalent, in the document).  A survivor of such a module that is
neither listed as equivalent nor in its ``untriaged`` list fails (a new survivor), and so
does a module whose share of caught mutants fell below ``C / N`` (a score drop).  A listed
name that no longer survives is reported, so the list can shrink.  Without ``--untriaged``
(the judge's shard) every unlisted survivor fails.

``--untriaged FILE --record``: write FILE from RESULTS instead (the modules ``--only``
selects; the others' entries are kept): how the ratchet is made, and tightened.

Killed, timed-out (a mutant that hangs the tests is caught) and type-check-caught mutants
pass; every other fate (survived, no tests, suspicious, segfault, not checked, ...) needs
its name listed.  Names of methods hold mutmut's separator ``ǁ``, hence UTF-8.
"""

from __future__ import annotations

import argparse
import json
import sys
from fnmatch import fnmatchcase
from pathlib import Path

CAUGHT = ("killed", "timeout", "caught by type check")


def read_results(path: str | Path) -> dict[str, str]:
    """Mutant name -> fate, from ``mutmut results --all true``."""
    out = {}
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        name, _, status = line.strip().partition(": ")
        if "__mutmut_" in name:
            out[name] = status.strip()
    return out


def module_of(name: str) -> str:
    """``ema_bench.problem`` of ``ema_bench.problem.xǁProblemǁevaluate__mutmut_3``."""
    return name.rsplit(".", 1)[0]


def select(results: dict[str, str], only: list[str] | None) -> dict[str, str]:
    """The results of the mutants ``only``'s globs match (all of them for None)."""
    if not only:
        return results
    return {n: s for n, s in results.items() if any(fnmatchcase(n, g) for g in only)}


def gate(results: dict[str, str], listed: str, only: list[str] | None = None,
         ratchet: dict | None = None) -> tuple[list[str], list[str]]:
    """The failures and the notes of one shard (see the module's docstring)."""
    results = select(results, only)
    if not results:
        return [f"no mutant{' of ' + ' '.join(only) if only else ''} in the results: "
                "nothing was checked"], []
    modules = (ratchet or {}).get("modules", {})
    fails, notes = [], []
    for name, status in results.items():
        if status in CAUGHT or f"`{name}`" in listed:
            continue
        known = modules.get(module_of(name), {}).get("untriaged", [])
        if name not in known:
            fails.append(f"untriaged mutant {name}: {status}")
    for module, entry in modules.items():
        mine = {n: s for n, s in results.items() if module_of(n) == module}
        if not mine:
            continue   # another shard's module
        caught = sum(s in CAUGHT for s in mine.values())
        if caught * entry["mutants"] < entry["caught"] * len(mine):
            fails.append(f"score drop in {module}: {caught} of {len(mine)} mutants caught, "
                         f"the ratchet holds {entry['caught']} of {entry['mutants']}")
        for name in entry.get("untriaged", []):
            if mine.get(name, "killed") in CAUGHT:
                notes.append(f"{name} no longer survives: remove it from the untriaged list "
                             "(--record rewrites it)")
    return fails, notes


def record(results: dict[str, str], listed: str, only: list[str] | None,
           ratchet: dict) -> dict:
    """``ratchet`` with the entries of the modules in ``results`` (those ``only`` matches)
    set from them: the unlisted survivors by name and the count of caught mutants; a module
    left with none drops out.  Other modules' entries are kept."""
    results = select(results, only)
    modules = dict(ratchet.get("modules", {}))
    for module in sorted({module_of(n) for n in results}):
        mine = {n: s for n, s in results.items() if module_of(n) == module}
        open_ = sorted(n for n, s in mine.items()
                       if s not in CAUGHT and f"`{n}`" not in listed)
        modules.pop(module, None)
        if open_:
            modules[module] = {"mutants": len(mine),
                               "caught": sum(s in CAUGHT for s in mine.values()),
                               "untriaged": open_}
    return {**ratchet, "modules": dict(sorted(modules.items()))}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results")
    ap.add_argument("doc")
    ap.add_argument("--only", nargs="+", metavar="GLOB")
    ap.add_argument("--untriaged", metavar="FILE")
    ap.add_argument("--record", action="store_true",
                    help="write the modules' untriaged survivors into --untriaged FILE")
    a = ap.parse_args(argv)
    path = Path(a.untriaged) if a.untriaged else None
    ratchet = json.loads(path.read_text(encoding="utf-8")) if path and path.is_file() \
        else None
    results, listed = read_results(a.results), Path(a.doc).read_text(encoding="utf-8")
    if a.record:
        if path is None:
            ap.error("--record needs --untriaged FILE")
        out = record(results, listed, a.only, ratchet or {})
        path.write_text(json.dumps(out, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
        return 0
    fails, notes = gate(results, listed, a.only, ratchet)
    for line in notes:
        print(f"note: {line}")
    for line in fails:
        print(line)
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())
