"""Named plugins from an entry-point group: the one registry behind solvers and trackers.

A plugin module registers its entries with a decorator (:func:`ema_bench.register_solver`,
:func:`ema_bench.prognostics.register_tracker`) and is named by an entry point of the group;
the built-in zoo and baselines register through ema-bench's own entry points exactly like a
third-party package.  Looking a name up imports only the module(s) its entry point names
(importing every library of the zoo costs about 1 s); listing imports them all, and a broken
plugin is a warning there, not a failure of the others.
"""

from __future__ import annotations

import importlib.metadata
import warnings
from collections.abc import Callable
from typing import Generic, TypeVar

from .escape import check_name

Info = TypeVar("Info")


class PluginRegistry(Generic[Info]):
    """The entries of one kind (``kind``: "solver", "tracker") of the entry-point ``group``.

    ``target(info)`` is the registered callable of an entry (what a second registration under
    the same name must be, with the same ``config``); ``error`` the LookupError raised for
    unknown names, broken plugins and clashing registrations."""

    def __init__(self, group: str, kind: str, error: type[Exception],
                 target: Callable[[Info], Callable]) -> None:
        self.group, self.kind, self.error, self.target = group, kind, error, target
        self.entries: dict[str, Info] = {}
        self.loaded = False

    def add(self, name: str, info: Info) -> None:
        """Register ``info`` as ``name``; the same callable and config again is a no-op (a
        module imported twice), anything else under a taken name is an error, and so is an
        unsafe name (:func:`~ema_bench.escape.check_name`: names reach tables, files and
        spreadsheets)."""
        try:
            check_name(name, self.kind)
        except ValueError as exc:
            raise self.error(str(exc)) from None
        old = self.entries.get(name)
        new = self.target(info)
        if old is not None and (self.target(old) is not new
                                or getattr(old, "config", None) != getattr(info, "config", None)):
            raise self.error(f"{self.kind} name {name!r} is registered twice "
                             f"({self.target(old).__module__} and {new.__module__})")
        self.entries[name] = info

    def load_all(self) -> None:
        """Import every module named in the group (once)."""
        if self.loaded:
            return
        self.loaded = True
        for ep in importlib.metadata.entry_points(group=self.group):
            try:
                ep.load()
            except Exception as exc:  # a broken plugin must not take the others down
                warnings.warn(f"{self.kind} plugin {ep.name!r} ({ep.value}) failed to load: "
                              f"{exc}", RuntimeWarning, stacklevel=3)

    def load_named(self, name: str) -> None:
        """Import only the plugin module(s) whose entry point is ``name``."""
        for ep in importlib.metadata.entry_points(group=self.group, name=name):
            try:
                ep.load()
            except Exception as exc:
                raise self.error(f"{self.kind} plugin {name!r} ({ep.value}) failed to load: "
                                 f"{exc}") from exc

    def available(self) -> dict[str, Info]:
        """Every registered entry, by name (sorted)."""
        self.load_all()
        return dict(sorted(self.entries.items()))

    def get(self, name: str) -> Info:
        """The entry registered as ``name``, importing its plugin module only (all of them
        when the name is unknown, for the error message, which lists the known ones)."""
        if name not in self.entries:
            self.load_named(name)
        if name in self.entries:
            return self.entries[name]
        known = self.available()
        if name not in known:
            raise self.error(f"unknown {self.kind} {name!r}; registered: {list(known)}")
        return known[name]

