"""Shipped data is read-only (DESIGN.md section 10): ``--calibrate`` writes a user table where
the user says, a user table is used only when named and is named when used, and a shipped
table is replaced only in a checkout."""

from __future__ import annotations

import hashlib
import json
import math
import shutil
from pathlib import Path

import pytest
from test_cli_solve import cli

import ema_bench
from ema_bench import interval_calibration_files as cf
from ema_bench.cli import main
from ema_bench.diagnosis import interval_table
from ema_bench.faults import FAULT_NAMES
from ema_bench.uncertainty import conformal

PACKAGE = Path(ema_bench.__file__).resolve().parent


def package_digest() -> str:
    """Every file of the installed package (numba's and Python's caches aside), by content."""
    h = hashlib.sha256()
    for f in sorted(PACKAGE.rglob("*")):
        if f.is_file() and "__pycache__" not in f.parts:
            h.update(f"{f.relative_to(PACKAGE)}\0".encode() + f.read_bytes())
    return h.hexdigest()


def split_conformal(scores: list[float], level: float = 0.95) -> float:
    """The ceil((n + 1) level)-th smallest score (the largest when that passes n)."""
    s = sorted(scores)
    return s[min(math.ceil((len(s) + 1) * level), len(s)) - 1]


def test_calibrate_writes_user_tables_and_leaves_the_package_byte_identical(tmp_path,
                                                                             monkeypatch):
    """Both ``--calibrate`` commands, smallest sizes, real runs (about 25 CPU-s): before this
    rule, 1 instance replaced the shipped 400 (a Gprop factor 1.22 -> 0.54)."""
    before = package_digest()
    cov = tmp_path / "cov"
    r = cli("coverage", "--calibrate", "--instances", "1", "--budget", "300", "--solver",
            "cmaes", "--out", str(cov))
    assert r.returncode == 0, r.stderr
    table = (cov / "calibration.json").resolve()
    data = json.loads(table.read_text())
    assert data["runs"]["twin|laplace|none"]["instances"] == 1
    assert f"calibration: twin (user file {table}, 1 instance)" in r.stdout
    blind = tmp_path / "blind"
    r = cli("blind", "--calibrate", "--cases", "1", "--out", str(blind))
    assert r.returncode == 0, r.stderr
    made = json.loads((blind / "interval_calibration.json").read_text())
    assert made["suite_cases"] == 1 and made["scores"]
    assert package_digest() == before

    # named, the user table is what calibrates the intervals, and the output says so
    r = cli("coverage", "--instances", "1", "--budget", "300", "--solver", "cmaes",
            "--calibration", str(table), "--json")
    assert r.returncode == 0, r.stderr
    summary = json.loads(r.stdout)
    scores = data["scores"]["twin|laplace|none"]
    assert summary["calibration_factor"] == pytest.approx(
        {n: split_conformal(scores[n]) for n in scores})
    assert summary["calibration_table"] == f"user file {table}, 1 instance"
    # and set in the environment, solve's intervals name it too
    r = cli("solve", "--case", "small", "--track", "twin", "--solver", "least-squares",
            "--budget", "300", "--intervals", "laplace")
    assert "calibration: twin (shipped, 400 instances)" in r.stdout, r.stderr
    monkeypatch.setenv("EMA_BENCH_CALIBRATION", str(table))
    r = cli("solve", "--case", "small", "--track", "twin", "--solver", "least-squares",
            "--budget", "300", "--intervals", "laplace")
    assert f"calibration: twin (user file {table}, 1 instance)" in r.stdout, r.stderr
    assert package_digest() == before


def test_the_active_table_is_the_shipped_one_unless_a_user_file_is_named(tmp_path,
                                                                         monkeypatch):
    shipped = json.loads(conformal.PATH.read_text())
    n = shipped["runs"]["twin|laplace|none"]["instances"]
    monkeypatch.delenv("EMA_BENCH_CALIBRATION", raising=False)
    monkeypatch.delenv("EMA_BENCH_INTERVAL_CALIBRATION", raising=False)
    assert cf.describe(conformal.TABLE, n) == f"shipped, {n} instances"
    assert conformal.calibration_size("twin", "laplace", "none") == n == 400
    ships = json.loads(interval_table.PATH.read_text())
    assert interval_table.source() == f"shipped, {ships['effect_cases']} effect cases"

    # a user table of the effect intervals: its factor, its name
    user = tmp_path / "interval_calibration.json"
    rows = [{"score": s} for s in (0.5, 2.0, 7.0)]
    user.write_text(json.dumps({"effect_cases": 1, "scores": rows}))
    with cf.using(interval_table.TABLE, user):
        assert interval_table.factor(0.95) == split_conformal([0.5, 2.0, 7.0]) == 7.0
        assert interval_table.factor(0.5) == 2.0
        assert interval_table.source() == f"user file {user.resolve()}, 1 effect case"
    # left as it was after the block
    assert interval_table.factor(0.95) == pytest.approx(ships["factor_95"])

    monkeypatch.setenv("EMA_BENCH_CALIBRATION", str(tmp_path / "missing.json"))
    with pytest.raises(ValueError, match="EMA_BENCH_CALIBRATION=.*missing.json: no such "
                                         "calibration file"):
        conformal.active_table()


@pytest.mark.parametrize("argv", [
    ["coverage", "--calibrate", "--instances", "1"],                     # no --out
    ["coverage", "--calibrate", "--instances", "1", "--out", str(PACKAGE / "uncertainty")],
    ["coverage", "--calibrate", "--out", str(PACKAGE / "uncertainty" / "new")],
    ["blind", "--calibrate", "--cases", "1"],
    ["blind", "--calibrate", "--cases", "1", "--out", str(PACKAGE / "diagnosis")],
    ["coverage", "--instances", "1", "--calibration", "no-such-table.json"],
], ids=["coverage-no-out", "coverage-into-package", "coverage-new-folder-in-package",
        "blind-no-out", "blind-into-package", "missing-user-table"])
def test_no_command_writes_into_the_package(argv, capsys):
    before = package_digest()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error:" in err
    assert package_digest() == before
    assert not (PACKAGE / "uncertainty" / "new").exists()


def _checkout(root: Path, git: bool) -> Path:
    """A copy of the package's two tables in a folder laid out like a checkout (or not)."""
    pkg = root / "ema_bench"
    for t in cf.TABLES.values():
        dest = pkg / t.shipped.relative_to(PACKAGE)
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(t.shipped, dest)
    (root / "pyproject.toml").write_text('[project]\nname = "ema-bench"\n')
    if git:
        (root / ".git").mkdir()
    return pkg


def test_shipping_a_table_is_for_a_checkout_only(tmp_path):
    made = tmp_path / "run" / "calibration.json"
    made.parent.mkdir()
    made.write_text(json.dumps({"faults": list(FAULT_NAMES),
                                "scores": {"twin|laplace|none": {"Na": [0.5, 1.5]}}}) + "\n")
    installed = _checkout(tmp_path / "site", git=False)
    before = (installed / "uncertainty" / "calibration.json").read_bytes()
    with pytest.raises(ValueError, match="installed package, not a checkout"):
        cf.ship(made, installed)
    assert (installed / "uncertainty" / "calibration.json").read_bytes() == before

    checkout = _checkout(tmp_path / "src", git=True)
    assert cf.ship(made, checkout) == checkout / "uncertainty" / "calibration.json"
    assert (checkout / "uncertainty" / "calibration.json").read_bytes() == made.read_bytes()
    # the interval table is left alone; a file of another name is no table
    assert (checkout / "diagnosis" / "interval_calibration.json").read_bytes() == \
        interval_table.PATH.read_bytes()
    other = tmp_path / "run" / "scores.json"
    other.write_text("{}")
    with pytest.raises(ValueError, match="not a calibration table"):
        cf.ship(other, checkout)
    empty = tmp_path / "empty" / "interval_calibration.json"
    empty.parent.mkdir()
    empty.write_text(json.dumps({"scores": []}))
    with pytest.raises(ValueError, match="holds no calibration scores"):
        cf.ship(empty, checkout)


def test_the_model_form_biases_are_written_only_where_named(tmp_path, monkeypatch):
    """``model_form.calibrate`` wrote into the package's ``model_form.json`` by default: now
    the path has no default, and an installed package (no checkout around it) is refused
    before any fit (one instance would cost about 15 CPU-s)."""
    import inspect

    import ema_bench.interval_calibration_files as files
    from ema_bench.uncertainty import model_form

    assert inspect.signature(model_form.calibrate).parameters["path"].default \
        is inspect.Parameter.empty
    monkeypatch.setattr(files, "checkout_root", lambda package=PACKAGE: None)
    monkeypatch.setattr("ema_bench.monitor_bias.clean_bias",
                        lambda *a, **k: pytest.fail("fitted before refusing"))
    before = package_digest()
    with pytest.raises(ValueError, match="inside the installed package, not a checkout"):
        model_form.calibrate(model_form.PATH, ["small"])
    assert package_digest() == before


@pytest.mark.parametrize("bad", [float("nan"), -0.5, "0.5", None])
def test_a_calibration_table_with_a_score_that_is_no_score_is_refused(tmp_path, capsys, bad):
    """A NaN score gave [nan, nan] intervals and a negative one inverted intervals, with exit
    0: a user table (and a table to ship) is checked value by value, in one line."""
    table = tmp_path / "calibration.json"
    table.write_text(json.dumps({"faults": list(FAULT_NAMES),
                                 "scores": {"twin|laplace|none": {"Na": [0.5, bad]}}}))
    with pytest.raises(ValueError, match=r"calibration score .* is not a finite, non-negative"):
        conformal.read.__wrapped__(table)
    with pytest.raises(ValueError, match="is not a finite, non-negative"):
        cf.ship(table, _checkout(tmp_path / "src", git=True))
    assert main(["coverage", "--instances", "1", "--calibration", str(table)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is not a finite, non-negative number" in err
    effects = tmp_path / "interval_calibration.json"
    effects.write_text(json.dumps({"scores": [{"score": 1.0}, {"score": bad}],
                                   "effect_cases": 2}))
    with pytest.raises(ValueError):
        interval_table.read.__wrapped__(effects)


@pytest.mark.parametrize("installed", [True, False])
def test_targets_never_writes_into_an_installed_package_nor_shrinks_the_shipped_table(
        installed, monkeypatch, capsys):
    """``targets --out`` inside the package: refused when installed; in a checkout, refused
    for a selection (a 460-entry table once became 1 entry)."""
    # either way on purpose, whether the tests run from a git checkout or an unpacked sdist
    monkeypatch.setattr(cf, "checkout_root",
                        lambda package=cf.PACKAGE: None if installed else package.parent)
    before = package_digest()
    assert main(["targets", "--cases", "small", "--seeds", "1", "--tracks", "twin", "--out",
                 str(PACKAGE / "suite_targets.json")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert ("installed package" if installed else "select part of the suite") in err
    assert package_digest() == before
