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


def test_the_fast_loop_is_documented_and_ci_runs_every_test():
    """`pytest -m "not slow"` is the documented fast loop; the marker is registered (an
    unregistered one only warns, and a typo would keep a slow test in the loop unseen), and
    CI's pytest line selects nothing away: the slow tests run there."""
    import tomllib

    readme = (ROOT / "README.md").read_text()
    assert 'pytest -q -m "not slow" -n 2' in readme
    assert 'pytest -q -m "not slow" -n 2' in (ROOT / "CONTRIBUTING.md").read_text()
    ini = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]
    assert [m for m in ini["markers"] if m.startswith("slow:")]
    assert not {"-m", "-k", "--deselect", "--ignore"} & set(ini.get("addopts", "").split())
    # what follows "-m pytest" on CI's lines: no selection
    ci_args = [ln.split("-m pytest", 1)[1].split() for ln in
               (ROOT / ".ci" / "run").read_text().splitlines() if "-m pytest" in ln]
    assert ci_args and all(not {"-m", "-k"} & set(a) for a in ci_args), ci_args
