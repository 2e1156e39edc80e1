"""Fail when ``mutmut results`` lists a mutant that no test killed and docs/mutation-testing.md
does not list as an equivalent mutant (each listed by its mutmut name, in backquotes).

    python .github/mutation_gate.py mutation-results.txt docs/mutation-testing.md

Killed, timed-out (a mutant that hangs the tests is caught) and type-check-caught mutants
pass; every other fate (survived, no tests, suspicious, segfault, not checked, ...) needs
its name in the document.  Names of methods hold mutmut's separator ``ǁ``, hence UTF-8.
"""

import sys
from pathlib import Path

CAUGHT = ("killed", "timeout", "caught by type check")


def main(results: str, doc: str) -> int:
    listed = Path(doc).read_text(encoding="utf-8")
    bad = []
    for line in Path(results).read_text(encoding="utf-8").splitlines():
        name, _, status = line.strip().partition(": ")
        if "__mutmut_" in name and status.strip() not in CAUGHT and f"`{name}`" not in listed:
            bad.append(f"{name}: {status.strip()}")
    for b in bad:
        print(f"untriaged mutant {b}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:3]))
