"""Before a release: the tag is the package's version (ema_bench/version.py, its one place)
and CHANGELOG.md has that version's section.  Exit 1 with one line otherwise.

    python .github/release_check.py 0.3.0        # the tag without its leading "v"
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def package_version() -> str:
    """``__version__`` of ema_bench/version.py, read without importing the package."""
    tree = ast.parse((ROOT / "ema_bench" / "version.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "__version__"
                                                for t in node.targets):
            return ast.literal_eval(node.value)
    raise SystemExit("release: ema_bench/version.py defines no __version__")


def problems(tag: str) -> list[str]:
    version = package_version()
    out = []
    if tag != version:
        out.append(f"tag {tag} is not the package's version {version} (ema_bench/version.py)")
    changelog = (ROOT / "CHANGELOG.md").read_text()
    if not re.search(rf"^## {re.escape(version)}( |$)", changelog, flags=re.M):
        out.append(f"CHANGELOG.md has no section '## {version} - DATE' for this release "
                   "(rename '## Unreleased')")
    return out


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    found = problems(sys.argv[1].removeprefix("v"))
    for p in found:
        print(f"release: {p}", file=sys.stderr)
    raise SystemExit(1 if found else 0)
