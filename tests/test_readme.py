"""The README's two commands are what CI runs, verbatim."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _bash_blocks(text: str) -> list[str]:
    return [b.strip() for b in re.findall(r"```bash\n(.*?)```", text, flags=re.S)]


def test_readme_commands_are_run_by_ci():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    install_and_run, run_tests = _bash_blocks(readme)[:2]
    assert "pip install" in install_and_run and "ema-bench" in install_and_run
    assert "pytest" in run_tests and ".[test]" in run_tests
    assert install_and_run in ci, "README command 1 differs from .ci/run"
    assert run_tests in ci, "README command 2 differs from .ci/run"


def test_readme_links_are_absolute():
    """The README is also PyPI's project page, where a relative link leads nowhere."""
    readme = (ROOT / "README.md").read_text()
    relative = [m for m in re.findall(r"\]\(([^)\s]+)\)", readme)
                if not m.startswith(("https://", "http://", "#", "mailto:"))]
    assert relative == []
    for link in re.findall(r"\]\(https://github.com/ema-bench/ema-bench/blob/main/([^)#]+)",
                           readme):
        assert (ROOT / link).exists(), link   # and each names a file of the repository
