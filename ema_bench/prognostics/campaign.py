"""Campaigns: a fleet of actuators degrading over flights, inspected every few flights.

:func:`make_campaign` draws a fleet from a named :class:`CampaignSpec` (:data:`CAMPAIGNS`),
simulates each unit's life with :mod:`~ema_bench.prognostics.laws`, runs the standard step and
sine tests at every inspection and writes a folder::

    DIR/manifest.json   what a tracker may see (format "ema-bench-campaign", version 2)
    DIR/u000/i000.npz   the traces of unit u000's inspection 0 (Traces.save)
    DIR/truth.json      the hidden truth: faults, effects, end of life, true RUL

:func:`load_campaign` reads the manifest back (checked) as a :class:`Campaign`;
:func:`load_truth` reads the truth.  Trackers see the settings (:meth:`Campaign.info`) and the
inspections only, in a process of their own (:mod:`.track_worker`); the truth is bound to its
manifest by :func:`manifest_digest`, so scoring refuses another campaign's truth.

The cut rule (published in the manifest as ``cut_rule``): a test unit's last inspection (its
*cut*) is the inspection before end of life nearest to ``u x horizon``, ``u ~ U(lo, hi)``
(``test_stop``), among those within ``[lo, hi] x horizon`` (ties: the earlier);
:func:`cut_likelihood` is its probability given the life.

Seeds: one root seed ``S``; unit ``u`` is run ``u`` of it (``run_seed(S, u)``, as a
leaderboard row): its laws come from that node's ``instance`` stream, its stopping point from
its ``plan`` stream and inspection ``i``'s sensor noise from ``stream(node, "noise", i)``.
Which units drift in gain only is the root's ``plan`` stream.  Same seed, same files.  One
judging untrusted trackers has a *secret* seed (``campaign make --secret-seed``): 63 bits of
entropy in ``truth.json`` only (manifest ``"seed": null``), beyond any search.
"""

from __future__ import annotations

import hashlib
import json
import re
import secrets
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..faults import FAULT_NAMES, LOWER, UPPER
from ..jsonio import write_atomic
from ..seeding import as_seed_sequence, run_seed, stream
from ..sweep.schema import check, opt
from ..traces import Traces, load_traces
from .laws import THRESHOLDS, FleetLaws, UnitHistory, unit_history

FORMAT = "ema-bench-campaign"
TRUTH_FORMAT = "ema-bench-campaign-truth"
#: A unit's truth, by JSON type, members too (``faults.0: "abc"``: refused in one line)
TRUTH_SCHEMA = {"eol": opt("int|null"), "failing_fault": opt("str|null"),
                "true_rul": opt("int|null"), "life_fraction": opt("number|null"),
                "kind": opt("list", "str"), "faults": opt("dict", "list"),
                "faults_after": opt("dict", "list"), "params": opt("dict", "number")}
VERSION = 2
#: The cut rule's name in the manifest (:func:`cut_likelihood`).
CUT_RULE = "nearest-inspection-to-uniform-share"
SPLITS = ("train", "test")
TRACKS = ("twin", "reference")
#: Marker of a folder being written (removed when the manifest is in place).
PARTIAL = ".ema-bench-campaign-partial"
_UNIT_DIR = re.compile(r"u\d{3,}")
_NPZ = re.compile(r"i\d{3,}\.npz")


class CampaignError(ValueError):
    """A campaign that cannot be made or read; the message names the file and the fault."""


@dataclass(frozen=True)
class CampaignSpec:
    """A named campaign design.

    Attributes
    ----------
    inspection_every : int
        Flights between inspections.
    drift_share : float
        Share of units that degrade by gain drift only (never fail): ``round(share * units)``.
    test_stop : (float, float)
        Test units stop at a share of their life drawn uniformly in this range.
    version : int
        Revision of the definition (written to the manifest as ``definition_version``): a
        change to the laws or the rules is a new revision or a new name, never a silent edit.
        fleet-v1 revision 2 has revision 1's laws and rules; it publishes the cut rule and
        binds the truth to the manifest.
    """

    name: str
    description: str
    laws: FleetLaws = field(default_factory=FleetLaws)
    inspection_every: int = 10
    drift_share: float = 0.15
    test_stop: tuple[float, float] = (0.5, 0.95)
    tests: tuple[str, ...] = ("step", "sine")
    version: int = 2


#: The named campaigns.  fleet-v1: median life about 300 flights, an inspection every 10.
CAMPAIGNS: dict[str, CampaignSpec] = {
    "fleet-v1": CampaignSpec(
        "fleet-v1",
        "friction, backlash and coil-short wear with gain drift; life 150-520 flights "
        "(10-90 %), an inspection every 10 flights (about 30 per life); 15 % gain-drift-only "
        "units"),
}


@dataclass(frozen=True)
class InspectionRecord:
    """One inspection of one unit, as the manifest lists it.

    ``conditions``: what the operator logged (``ambient_temp_C``, ``winding_temp_C`` in
    degC; ``flights_since_last``, ``duty_since_last`` in flights and standard-flight
    equivalents)."""

    unit: str
    index: int
    flight: int
    path: Path
    conditions: dict


@dataclass(frozen=True)
class Campaign:
    """What a tracker sees of a campaign: its settings and its inspections (no truth)."""

    root: Path
    name: str
    track: str
    seed: int | None   # None: a secret seed (truth.json holds it)
    split: str
    inspection_every: int
    thresholds: dict[str, float]
    laws: dict
    units: dict[str, list[InspectionRecord]]
    tests: tuple[str, ...] = ("step", "sine")
    model_version: str = ""
    definition_version: int = 0
    cut_rule: dict = field(default_factory=dict)
    digest: str = ""

    def traces(self, rec: InspectionRecord) -> Traces:
        """The measured traces of an inspection."""
        return load_traces(rec.path)

    def info(self) -> dict:
        """The published settings (for tracker factories): plain JSON, deep-copied, with no
        inspection list, no folder and no seed (with it a tracker could simulate the lives)."""
        return json.loads(json.dumps({
            "name": self.name, "track": self.track, "split": self.split,
            "inspection_every": self.inspection_every, "thresholds": dict(self.thresholds),
            "laws": self.laws, "tests": list(self.tests), "model_version": self.model_version,
            "definition_version": self.definition_version, "cut_rule": self.cut_rule}))


def get_spec(name: str) -> CampaignSpec:
    """The registered campaign ``name``; CampaignError listing the known ones."""
    try:
        return CAMPAIGNS[name]
    except KeyError:
        raise CampaignError(f"unknown campaign {name!r}; known: {list(CAMPAIGNS)}") from None


def default_out(name: str, track: str, split: str, seed: int | None, units: int) -> Path:
    """The folder :func:`make_campaign` writes to without ``out``: named by what it holds."""
    return Path(f"ema-bench-campaign-{name}-{track}-{split}-seed"
                f"{'secret' if seed is None else seed}-n{units}")


# --- making ----------------------------------------------------------------------------------

def make_campaign(name: str = "fleet-v1", *, units: int = 20, split: str = "test",
                  track: str = "twin", seed: int | None = 0, inspection_every: int | None = None,
                  out: Path | str | None = None, quiet: bool = True) -> Campaign:
    """Draw a campaign, write it to ``out`` and return it.

    Parameters
    ----------
    name : str
        A registered campaign (:data:`CAMPAIGNS`).
    units : int
        Units of the fleet (``u000`` ...).
    split : {"test", "train"}
        Train units run to failure (inspections up to the last one before EOL); test units
        stop at a random share of their life (``spec.test_stop``), their RUL hidden.
    track : {"twin", "reference"}
        Traces from the monitor plus noise, or the reference model (0.18 s an inspection).
    seed : int or None
        Root seed: same seed, same files.  None: a secret one (63 bits of the OS's entropy),
        in ``truth.json`` only (``secret_seed``), the manifest's ``seed`` null.
    inspection_every : int, optional
        Flights between inspections (default: the spec's).
    out : path, optional
        Folder (created; a campaign there is replaced, another non-empty folder refused).
        Default :func:`default_out`.
    quiet : bool
        No progress bar / lines.
    """
    from ..progress import progress
    from ..trace_cache import MODEL_VERSION

    spec = get_spec(name)
    public, units = seed is not None, _count(units, "units")
    seed = _count(seed, "seed", minimum=0) if public else secrets.randbits(63)
    every = spec.inspection_every if inspection_every is None else _count(
        inspection_every, "inspection_every")
    if split not in SPLITS:
        raise CampaignError(f"unknown split {split!r}; known: {list(SPLITS)}")
    if track not in TRACKS:
        raise CampaignError(f"unknown track {track!r}; known: {list(TRACKS)}")
    shown = seed if public else None   # what the manifest (every file a tracker sees) says
    root = Path(out) if out is not None else default_out(name, track, split, shown, units)
    prepare_folder(root)
    (root / PARTIAL).write_text(json.dumps({"name": name, "seed": shown}))

    node = as_seed_sequence(seed)
    drift = _drift_units(node, units, spec.drift_share)
    manifest_units, truth_units = [], {}
    with progress(units, f"campaign {name}", unit="unit", quiet=quiet) as bar:
        for u in range(units):
            label = f"u{u:03d}"
            inspections, truth = _make_unit(root, label, run_seed(seed, u), spec, every,
                                            split, track, wear=u not in drift)
            manifest_units.append({"unit": label, "inspections": inspections})
            truth_units[label] = truth
            bar.update(label)

    from ..version import __version__
    manifest = {"format": FORMAT, "version": VERSION, "name": name,
                "definition_version": spec.version, "track": track,
                "seed": shown, "split": split, "inspection_every": every,
                "tests": list(spec.tests), "thresholds": dict(THRESHOLDS),
                "laws": spec.laws.to_dict(), "description": spec.description,
                "cut_rule": cut_rule(spec, split), "drift_share": spec.drift_share,
                "model_version": MODEL_VERSION, "package_version": __version__,
                "units": manifest_units}
    truth = {"format": TRUTH_FORMAT, "version": VERSION, "name": name, "seed": shown,
             **({} if public else {"secret_seed": seed}), "track": track, "split": split,
             "manifest_digest": manifest_digest(manifest), "units": truth_units}
    write_atomic(root / "truth.json", json.dumps(truth, indent=1) + "\n")
    write_atomic(root / "manifest.json", json.dumps(manifest, indent=1) + "\n")
    (root / PARTIAL).unlink()
    return load_campaign(root)


def cut_rule(spec: CampaignSpec, split: str) -> dict:
    """The manifest's ``cut_rule``: how a unit's last inspection was chosen (public)."""
    if split == "train":
        return {"rule": "run-to-failure", "stop": [1.0, 1.0]}
    return {"rule": CUT_RULE, "stop": [float(v) for v in spec.test_stop]}


def manifest_digest(manifest: dict) -> str:
    """SHA-256 of a manifest's content (canonical JSON, ``package_version`` left out): what
    binds a truth file to its campaign."""
    doc = {k: v for k, v in manifest.items() if k != "package_version"}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def cut_likelihood(cut: float, life: float | np.ndarray, every: int,
                   stop: tuple[float, float]) -> np.ndarray:
    """P(a test unit's last inspection is at flight ``cut`` | its life ``life``), flights.

    The rule of :func:`_inspection_flights`: inspections at ``0, every, ...`` strictly before
    ``life``; ``u ~ U(lo, hi)``; the cut is the inspection nearest to ``u life`` among those
    in ``[lo life, hi life]`` (ties: the earlier, a set of measure zero); when none lies
    there, the first at or after ``lo life`` (else the last before ``life``), with
    probability 1.

    Parameters
    ----------
    cut : float
        The observed last inspection's flight.
    life : float or array
        Candidate lives (end-of-life flights); ``inf`` gives 0.
    every : int
        Flights between inspections.
    stop : (lo, hi)
        The manifest's ``cut_rule["stop"]``.

    Returns
    -------
    ndarray
        Probabilities, the shape of ``life``.
    """
    lo, hi = float(stop[0]), float(stop[1])
    L = np.atleast_1d(np.asarray(life, dtype=float))
    out = np.zeros(L.shape)
    ok = np.isfinite(L) & (L > cut) & (cut % every == 0)
    if hi <= lo:  # a degenerate rule: the cut is the last inspection before the life
        return (ok & (L <= cut + every)).astype(float).reshape(np.shape(life))
    a, b = lo * L, hi * L
    # the first and last grid flights inside [a, b] (strictly before the life)
    first = np.ceil(a / every) * every
    last = np.minimum(np.floor(b / every) * every, np.ceil(L / every) * every - every)
    inside = ok & (first <= last)
    on = inside & (cut >= first) & (cut <= last)
    left = np.where(cut > first, cut - every / 2.0, a)
    right = np.where(cut < last, cut + every / 2.0, b)
    cell = np.clip(np.minimum(right, b) - np.maximum(left, a), 0.0, None)
    out[on] = (cell / ((hi - lo) * L))[on]
    # no inspection inside: the first at or after lo x life, else the last before the life
    none = ok & ~inside
    if none.any():
        before_last = np.ceil(L / every) * every - every
        fallback = np.where(first < L, first, before_last)
        out[none] = (fallback == cut)[none].astype(float)
    return out.reshape(np.shape(life))


def _count(v: Any, what: str, minimum: int = 1) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < minimum:
        raise CampaignError(f"{what} must be an integer >= {minimum}, got {v!r}")
    return int(v)


def _drift_units(node: np.random.SeedSequence, units: int, share: float) -> set[int]:
    """Which units degrade by gain drift only: a fixed count, placed by the plan stream."""
    rng = np.random.default_rng(stream(node, "plan"))
    order = rng.permutation(units)
    return {int(u) for u in order[:int(round(share * units))]}


def _inspection_flights(h: UnitHistory, every: int, split: str, stop: tuple[float, float],
                        rng: np.random.Generator) -> list[int]:
    """Flights of a unit's inspections: every ``every`` flights before its horizon (EOL, or
    the would-be EOL of a unit that never fails); a test unit stops at an inspection drawn
    uniformly among those in ``stop`` (shares of the horizon)."""
    # the draw is made for every unit so one unit's split does not shift another's streams
    u = rng.uniform(*stop)
    before = list(range(0, h.horizon, every))  # strictly before EOL
    if split == "train":
        return before
    lo, hi = stop
    inside = [f for f in before if lo * h.horizon <= f <= hi * h.horizon]
    if not inside:  # a life shorter than the spacing allows: the first at or after lo
        inside = [f for f in before if f >= lo * h.horizon] or before[-1:]
    last = min(inside, key=lambda f: (abs(f - u * h.horizon), f))   # nearest u (ties: earlier)
    return before[:before.index(last) + 1]


def _conditions(h: UnitHistory, flight: int, previous: int | None) -> dict:
    start = 0 if previous is None else previous
    return {"ambient_temp_C": round(float(h.ambient[flight]), 1),
            "winding_temp_C": round(float(h.winding[flight]), 1),
            "flights_since_last": flight - start,
            "duty_since_last": round(float(h.duty[start:flight].sum()), 3)}


def _make_unit(root: Path, label: str, node: np.random.SeedSequence, spec: CampaignSpec,
               every: int, split: str, track: str, *, wear: bool) -> tuple[list[dict], dict]:
    """Simulate one unit, write its inspection files; (manifest entries, truth record)."""
    from ..effects import effects_to_dict
    from ..protocol import STANDARD_TESTS

    tests = tuple(t for t in STANDARD_TESTS if t.name in spec.tests)
    h = unit_history(stream(node, "instance"), spec.laws, wear=wear)
    flights = _inspection_flights(h, every, split, spec.test_stop,
                                  np.random.default_rng(stream(node, "plan")))
    (root / label).mkdir(exist_ok=True)
    entries, faults, effects = [], {}, {}
    for i, f in enumerate(flights):
        # the laws may pass a box bound only after EOL; clip anyway so the models accept it
        x = np.clip(h.faults[f], LOWER, UPPER)
        e = h.effects(f)
        traces = simulate_inspection(x, e, stream(node, "noise", i), tests, track)
        meta = {k: traces.meta[k] for k in ("model", "noise", "adc") if k in traces.meta}
        traces = Traces(traces.data, dt=traces.dt,
                        meta={**meta, "unit": label, "inspection": i, "flight": f})
        rel = f"{label}/i{i:03d}.npz"
        traces.save(root / rel)
        entries.append({"index": i, "flight": f, "file": rel,
                        "conditions": _conditions(h, f, flights[i - 1] if i else None)})
        faults[str(f)] = [float(v) for v in x]
        effects[str(f)] = effects_to_dict(e)
    last = flights[-1]
    after = range(last + every, h.horizon, every) if h.eol is not None else range(0)
    truth = {"unit": label, "eol": h.eol, "failing_fault": h.failing_fault,
             "last_flight": last, "true_rul": None if h.eol is None else h.eol - last,
             "life_fraction": None if h.eol is None else last / h.eol,
             "kind": h.kind, "horizon": h.horizon,
             "faults": faults, "effects": effects,
             # the hidden future of a test unit, at the inspection spacing, and at its EOL
             "faults_after": {str(f): [float(v) for v in np.clip(h.faults[f], LOWER, UPPER)]
                              for f in after},
             "faults_at_eol": None if h.eol is None else [float(v) for v in h.faults[h.eol]],
             "params": h.params.to_dict()}
    return entries, truth


def simulate_inspection(x: np.ndarray, e: np.ndarray, seed: np.random.SeedSequence,
                        tests: tuple, track: str) -> Traces:
    """One inspection's measured traces at faults ``x`` and effects ``e``: the monitor (``twin``)
    or the reference model (``reference``) through the sensors, noise from ``seed``."""
    if track == "twin":
        from ..instances import twin_traces

        return twin_traces(x, e, seed, tests)
    from ..reference import simulate_reference

    return simulate_reference(x, e, seed=seed, tests=tests)


def prepare_folder(root: Path) -> None:
    """Make ``root`` ready for a campaign: created when absent; an earlier campaign (or a
    partly written one) there is removed, file by file; CampaignError for a file, or a
    non-empty folder that holds something else."""
    root = Path(root)
    if root.exists() and not root.is_dir():
        raise CampaignError(f"{root}: exists and is not a folder")
    if root.is_dir() and any(root.iterdir()):
        manifest = root / "manifest.json"
        if not (root / PARTIAL).exists():
            if not manifest.is_file():
                raise CampaignError(f"{root}: exists and is not a campaign folder (no "
                                    "manifest.json); give a new or empty folder")
            _read_json(manifest, FORMAT, "manifest")  # refuses another tool's manifest
        _clear(root)
    root.mkdir(parents=True, exist_ok=True)


def _clear(root: Path) -> None:
    """Remove what a campaign writes (and nothing else) from ``root``."""
    for name in ("manifest.json", "truth.json", PARTIAL):
        (root / name).unlink(missing_ok=True)
    for tmp in (*root.glob("*.json.tmp"), *root.glob(".*.json.*.tmp")):   # a write cut short
        tmp.unlink()
    for d in root.iterdir():
        if d.is_dir() and _UNIT_DIR.fullmatch(d.name):
            for f in d.iterdir():
                if f.is_file() and (_NPZ.fullmatch(f.name) or f.name.endswith(".npz.tmp")):
                    f.unlink()
            if not any(d.iterdir()):
                shutil.rmtree(d)


# --- reading ---------------------------------------------------------------------------------

def _read_json(path: Path, fmt: str, what: str) -> dict:
    """A JSON document of format ``fmt`` and a supported version; CampaignError otherwise."""
    if not path.is_file():
        raise CampaignError(f"{path}: no such file")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise CampaignError(f"{path}: broken {what}: not valid JSON ({exc.msg} at line "
                            f"{exc.lineno})") from None
    except UnicodeDecodeError:
        raise CampaignError(f"{path}: broken {what}: not a text file") from None
    if not isinstance(doc, dict) or doc.get("format") != fmt:
        got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        hint = (" (a tracking run's manifest: give the campaign folder it names)"
                if isinstance(doc, dict) and "tracker" in doc else "")
        raise CampaignError(f"{path}: not a campaign {what} (format {got!r}, expected "
                            f"{fmt!r}){hint}")
    if doc.get("version") != VERSION:
        raise CampaignError(f"{path}: {what} version {doc.get('version')!r} is not supported "
                            f"(this ema-bench reads version {VERSION}); remake the campaign")
    return doc


def _folder(path: Path | str) -> Path:
    path = Path(path)
    if path.is_file() and path.name in ("manifest.json", "truth.json"):
        path = path.parent
    if not path.exists():
        raise CampaignError(f"{path}: no such campaign folder")
    if not path.is_dir():
        raise CampaignError(f"{path}: not a campaign folder")
    if (path / PARTIAL).exists():
        raise CampaignError(f"{path}: the campaign was not finished (interrupted while being "
                            "made); make it again")
    if not (path / "manifest.json").exists():
        raise CampaignError(f"{path}: not a campaign folder (no manifest.json; make one with "
                            "'ema-bench campaign make')")
    return path


def _need(doc: dict, key: str, kind: type | tuple[type, ...], where: str) -> Any:
    if key not in doc:
        raise CampaignError(f"{where}: missing {key!r}")
    v = doc[key]
    if not isinstance(v, kind) or (kind is int and isinstance(v, bool)):
        raise CampaignError(f"{where}: {key!r} has the wrong type ({type(v).__name__})")
    return v


def load_campaign(path: Path | str, traces: bool = True) -> Campaign:
    """Read a campaign folder (or its manifest.json), checking the manifest and (``traces``)
    that every inspection file is there.  CampaignError (one line naming the file) otherwise.

    ``traces=False`` is for what needs the settings only (scoring: a committed leaderboard
    keeps a campaign's manifest and truth, not its traces, which ``campaign make``
    regenerates byte for byte)."""
    root = _folder(path)
    mpath = root / "manifest.json"
    doc = _read_json(mpath, FORMAT, "manifest")
    where = str(mpath)
    # the settings, each checked in this order (the first missing or mistyped one is named)
    name, track, split, seed, every, thresholds, laws, tests = (
        _need(doc, key, kind, where) for key, kind in (
            ("name", str), ("track", str), ("split", str), ("seed", (int, type(None))),
            ("inspection_every", int), ("thresholds", dict), ("laws", dict), ("tests", list)))
    if track not in TRACKS or split not in SPLITS or every < 1:
        raise CampaignError(f"{where}: bad track, split or inspection_every "
                            f"({track!r}, {split!r}, {every!r})")
    bad = [k for k, v in thresholds.items()
           if k not in FAULT_NAMES or isinstance(v, bool) or not isinstance(v, (int, float))]
    if bad:
        raise CampaignError(f"{where}: bad threshold(s) {bad}; faults: {list(FAULT_NAMES)}")
    units: dict[str, list[InspectionRecord]] = {}
    for k, u in enumerate(_need(doc, "units", list, where)):
        if not isinstance(u, dict):
            raise CampaignError(f"{where}: unit entry {k} is not an object")
        label = _need(u, "unit", str, f"{where}: unit entry {k}")
        if label in units:
            raise CampaignError(f"{where}: unit {label} is listed twice")
        units[label] = _records(root, label, _need(u, "inspections", list,
                                                   f"{where}: unit {label}"), where, traces)
    return Campaign(root=root, name=name, track=track, seed=seed, split=split,
                    inspection_every=every,
                    thresholds={k: float(v) for k, v in thresholds.items()}, laws=laws,
                    units=units, tests=tuple(tests),
                    model_version=str(doc.get("model_version", "")),
                    definition_version=int(doc.get("definition_version", 0)),
                    cut_rule=dict(_need(doc, "cut_rule", dict, where)),
                    digest=manifest_digest(doc))


def _records(root: Path, label: str, items: list, where: str,
             traces: bool = True) -> list[InspectionRecord]:
    out: list[InspectionRecord] = []
    for i, item in enumerate(items):
        at = f"{where}: unit {label} inspection {i}"
        if not isinstance(item, dict):
            raise CampaignError(f"{at}: not an object")
        index, flight, rel, conditions = (_need(item, key, kind, at) for key, kind in (
            ("index", int), ("flight", int), ("file", str), ("conditions", dict)))
        if index != i:
            raise CampaignError(f"{at}: index {index} out of order (expected {i})")
        if out and flight <= out[-1].flight:
            raise CampaignError(f"{at}: flight {flight} is not after the previous "
                                f"inspection's ({out[-1].flight})")
        file = root / rel
        if Path(rel).is_absolute() or ".." in Path(rel).parts:
            raise CampaignError(f"{at}: file {rel!r} must lie inside the campaign folder")
        if traces and not file.is_file():
            raise CampaignError(f"{at}: file {rel} is missing")
        out.append(InspectionRecord(label, index, flight, file, conditions))
    return out


def truth_path(path: Path | str) -> Path:
    """The truth file named by ``path``: the file itself, or ``truth.json`` in a folder."""
    path = Path(path)
    return path / "truth.json" if path.is_dir() else path


def read_truth(path: Path | str, campaign: Campaign | None = None) -> dict:
    """The whole truth document (``truth.json`` of a campaign folder, or a truth file
    anywhere); with ``campaign``, checked to be that campaign's (its manifest's digest, name,
    seed, track and split): CampaignError naming both otherwise."""
    file = truth_path(path)
    if file.parent.is_dir() and (file.parent / PARTIAL).exists():
        raise CampaignError(f"{file.parent}: the campaign was not finished (interrupted while "
                            "being made); make it again")
    if not file.is_file():
        raise CampaignError(f"{file}: no such truth file (the campaign's truth is given "
                            "explicitly: 'campaign score --truth FILE')")
    doc = _read_json(file, TRUTH_FORMAT, "truth file")
    for name, unit in _need(doc, "units", dict, str(file)).items():
        check(unit, TRUTH_SCHEMA, f"{file}, unit {name}")
    if campaign is not None:
        ours = {"manifest_digest": campaign.digest, "name": campaign.name,
                "seed": campaign.seed, "track": campaign.track, "split": campaign.split}
        diff = sorted(k for k, v in ours.items() if doc.get(k) != v)
        if diff:
            raise CampaignError(
                f"{file}: the truth of another campaign than {campaign.root} (differs in "
                f"{diff}: truth {doc.get('name')!r} seed {doc.get('seed')!r}, campaign "
                f"{campaign.name!r} seed {campaign.seed!r}); give that campaign's truth file")
        missing = sorted(set(campaign.units) - set(doc["units"]))
        if missing:
            raise CampaignError(f"{file}: no truth for units {missing[:5]} of {campaign.root}")
    return doc


def load_truth(path: Path | str, campaign: Campaign | None = None) -> dict[str, dict]:
    """The hidden truth of a campaign, per unit (``truth.json``; :func:`read_truth`):
    ``eol`` (flight or None), ``failing_fault``, ``last_flight``, ``true_rul``,
    ``life_fraction``, ``kind``, ``horizon``, ``faults`` and ``effects`` per inspection flight
    (keys are flights as strings), ``faults_after`` (the future at the inspection spacing,
    before EOL), ``faults_at_eol`` and the unit's law ``params``."""
    return read_truth(path, campaign)["units"]
