"""Code lines of ``ema_bench/`` at git revisions: lines that hold a token other than a
comment or a docstring (a string expression statement), blank lines left out.  Issue 43's
measure of whether a refactor made the package smaller.

    python benchmarks/code_lines.py 170a328 HEAD
"""

from __future__ import annotations

import ast
import io
import subprocess
import sys
import tokenize

SKIP = (tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
        tokenize.ENDMARKER)


def code_lines(src: str) -> int:
    """Lines of ``src`` holding a token that is neither a comment nor part of a docstring."""
    doc = set()
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) \
                and isinstance(node.value.value, str):
            doc.update(range(node.lineno, node.end_lineno + 1))
    lines = set()
    for tok in tokenize.generate_tokens(io.StringIO(src).readline):
        if tok.type not in SKIP:
            lines.update(ln for ln in range(tok.start[0], tok.end[0] + 1) if ln not in doc)
    return len(lines)


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], capture_output=True, text=True, check=True).stdout


def at(rev: str, root: str = "ema_bench") -> int:
    """Code lines of the ``.py`` files under ``root`` at git revision ``rev``."""
    files = [f for f in _git("ls-tree", "-r", "--name-only", rev, root).split()
             if f.endswith(".py")]
    return sum(code_lines(_git("show", f"{rev}:{f}")) for f in files)


if __name__ == "__main__":
    for rev in sys.argv[1:] or ["HEAD"]:
        print(rev, at(rev))
