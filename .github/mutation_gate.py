"""Fail when ``mutmut results`` lists a survivor that docs/mutation-testing.md does not list
as an equivalent mutant (each listed by its mutmut name).

    python .github/mutation_gate.py mutation-results.txt docs/mutation-testing.md
"""

import sys
from pathlib import Path


def main(results: str, doc: str) -> int:
    listed = Path(doc).read_text()
    bad = []
    for line in Path(results).read_text().splitlines():
        name, _, status = line.strip().partition(": ")
        if status.strip() in ("survived", "no tests") and f"`{name}`" not in listed:
            bad.append(f"{name}: {status.strip()}")
    for b in bad:
        print(f"untriaged mutant {b}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:3]))
