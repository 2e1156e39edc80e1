"""Plots a person would rather look at than read (matplotlib, non-interactive backend)."""

from __future__ import annotations

import os
from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")  # files only: no display on CI machines or servers
import matplotlib.pyplot as plt  # noqa: E402

from .traces import DESCRIPTIONS, SIGNALS, UNITS, Traces  # noqa: E402


def save_figure(fig: plt.Figure, path: str | os.PathLike, dpi: int = 110,
                rect: tuple[float, float, float, float] | None = None) -> None:
    """Lay ``fig`` out (inside ``rect``, figure fractions, when given), save it to ``path``
    at ``dpi`` dots per inch and close it (a long sweep draws hundreds)."""
    fig.tight_layout(rect=rect)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


def plot_traces(traces: Sequence[Traces], labels: Sequence[str], path: str | os.PathLike,
                title: str = "") -> None:
    """The 8 compared outputs (4 signals x tests) of one or more ``Traces``, overlaid.

    Saves a PNG to ``path``.
    """
    tests = traces[0].tests
    fig, axes = plt.subplots(len(SIGNALS), len(tests), figsize=(5.5 * len(tests), 9),
                             sharex="col", squeeze=False)
    for tr, label in zip(traces, labels):
        for j, test in enumerate(tests):
            if test not in tr.tests:
                continue
            t = tr.time(test)
            for i, sig in enumerate(SIGNALS):
                axes[i, j].plot(t, tr.signal(test, sig), lw=1.0, label=label)
    for j, test in enumerate(tests):
        axes[0, j].set_title(f"{test} test")
        axes[-1, j].set_xlabel("time [s]")
        for i, sig in enumerate(SIGNALS):
            axes[i, j].set_ylabel(f"{sig} [{UNITS[sig]}]")
            axes[i, j].grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(title or " / ".join(DESCRIPTIONS[s] for s in SIGNALS[:2]), fontsize=10)
    save_figure(fig, path)
