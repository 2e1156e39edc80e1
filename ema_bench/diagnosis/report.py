"""Show the gap shrink: a Markdown report with residual and spectrum plots."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import jsonio
from ..escape import markdown
from ..plots import plt, save_figure
from ..traces import SIGNALS, UNITS, Traces
from .features import ORDERS, whiten
from .results import HOLDOUT, TRAIN, Diagnosis, Fit


def nrmse(model: Fit, measured: Traces) -> dict[str, dict[str, float]]:
    """Per test and signal: RMS residual over the range of the measured signal."""
    out = {}
    for t in measured.tests:
        y = measured.data[t]
        r = model.outputs[t] - y
        out[t] = {s: float(np.sqrt(np.mean(r[:, k] ** 2)) / (np.ptp(y[:, k]) or 1.0))
                  for k, s in enumerate(SIGNALS)}
    return out


def order_spectrum(r: np.ndarray, theta_m: np.ndarray, w: np.ndarray, orders: np.ndarray
                   ) -> np.ndarray:
    """Amplitude of a residual against rotor-angle orders (samples with the rotor moving)."""
    moving = np.abs(w) > 5.0
    if moving.sum() < 10:
        return np.zeros(orders.size)
    ph = np.exp(-1j * np.outer(orders, theta_m[moving]))
    return 2.0 * np.abs(ph @ r[moving]) / moving.sum()


def _plot_residuals(measured: Traces, before: Fit, after: Fit, path: Path) -> None:
    tests = measured.tests
    fig, axes = plt.subplots(len(SIGNALS), len(tests), figsize=(4.6 * len(tests), 8.5),
                             squeeze=False, sharex="col")
    for j, t in enumerate(tests):
        time = measured.time(t)
        for k, s in enumerate(SIGNALS):
            ax = axes[k, j]
            ax.plot(time, measured.data[t][:, k] - before.outputs[t][:, k], lw=0.8,
                    label="before (4 faults)")
            ax.plot(time, measured.data[t][:, k] - after.outputs[t][:, k], lw=0.8,
                    label="after (augmented)" if after is not before else "after")
            ax.set_ylabel(f"{s} residual [{UNITS[s]}]", fontsize=8)
            ax.grid(alpha=0.3)
        axes[0, j].set_title(f"{t} ({'held out' if t in HOLDOUT else 'training'})")
        axes[-1, j].set_xlabel("time [s]")
    axes[0, 0].legend(fontsize=7)
    save_figure(fig, path, dpi=100)


def _plot_spectra(measured: Traces, before: Fit, after: Fit, path: Path) -> None:
    orders = np.arange(1, 25)
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.6))
    for ax, k in zip(axes, (SIGNALS.index("i_eq"), SIGNALS.index("omega_m"))):
        for label, fit in (("before", before), ("after", after)):
            amp = sum(order_spectrum(whiten(measured.data[t] - fit.outputs[t])[:, k],
                                     measured.data[t][:, 1], measured.data[t][:, 2], orders)
                      for t in TRAIN)
            ax.bar(orders + (-0.2 if label == "before" else 0.2), amp, width=0.4, label=label)
        ax.set_xlabel("rotor-angle order (per revolution)")
        ax.set_ylabel("residual amplitude [noise std]")
        ax.set_title(f"{SIGNALS[k]} residual order spectrum (training tests)")
        ax.set_xticks(orders[::2])
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    save_figure(fig, path, dpi=100)


def write_report(d: Diagnosis, measured: Traces, out: str | Path, source: str = "") -> Path:
    """Write ``report.md``, ``diagnosis.json``, ``residuals.png`` and ``spectra.png``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    base, final = d.fits["base"], d.final
    _plot_residuals(measured, base, final, out / "residuals.png")
    _plot_spectra(measured, base, final, out / "spectra.png")
    (out / "diagnosis.json").write_text(jsonio.dumps(d.as_dict(), indent=1, default=float))
    n0, n1 = nrmse(base, measured), nrmse(final, measured)
    g = d.gap
    lines = [f"# Missing-physics diagnosis{': ' + markdown(source) if source else ''}", "",
             f"**Verdict: {d.verdict}.** {d.message}", "",
             f"Training tests: {', '.join(TRAIN)}; held-out test: {', '.join(HOLDOUT)} (never "
             f"fitted)."]
    if g:
        lines += ["", "| discrepancy | base model | final model |", "|---|---:|---:|",
                  f"| held-out fitness (floor {g['floor']:.3g}, threshold "
                  f"{g['threshold']:.3g}) | {g['holdout_before']:.3g} | "
                  f"{g['holdout_after']:.3g} |",
                  f"| held-out gap above the floor (0 inside the noise band) | "
                  f"{g['before']:.3g} | {g['after']:.3g} |",
                  f"| training statistics outside the envelopes | {g['flagged_before']} | "
                  f"{g['flagged_after']} |",
                  f"| their severity (sum of robust z) | {g['severity_before']:.3g} | "
                  f"{g['severity_after']:.3g} |", "",
                  f"Judged on: {g['judged_on']}; closed {100 * g['closed']:.0f} %."]
    lines.append("")
    if d.effects:
        lines += ["## Named effects", "",
                  "| effect | value | 95 % interval | discrepancy closed |",
                  "|---|---:|---|---:|"]
        for e in d.effects:
            (name, v), = e.params.items()
            name += " (partial)" if e.partial else ""
            lines.append(f"| {name} | {v:.4g} | [{e.interval[0]:.4g}, {e.interval[1]:.4g}] | "
                         f"{100 * e.gap_closed:.0f} % |")
        lines.append("")
    if d.acquisition:
        lines += ["## Named faults of the acquisition chain (the measurement, not the actuator)",
                  "", "| fault | what | value | 95 % interval |", "|---|---|---:|---|"]
        for a in d.acquisition:
            lines.append(f"| {a.name}{' (partial)' if a.partial else ''} | {a.description} | "
                         f"{a.value:.4g} | [{a.interval[0]:.4g}, {a.interval[1]:.4g}] |")
        lines.append("")
    lines += ["## Fault estimates (a missing effect biases them)", "",
              "| fault | before | after |", "|---|---:|---:|"]
    lines += [f"| {n} | {v['before']:.5g} | {v['after']:.5g} |" for n, v in d.faults.items()]
    lines += ["", "## Per-signal NRMSE (RMS residual / range), before -> after", "",
              "| test | " + " | ".join(SIGNALS) + " |", "|---|" + "---:|" * len(SIGNALS)]
    for t in measured.tests:
        lines.append(f"| {t}{' (held out)' if t in HOLDOUT else ''} | " + " | ".join(
            f"{n0[t][s]:.2e} -> {n1[t][s]:.2e}" for s in SIGNALS) + " |")
    for title, flagged in (
            ("Residual statistics outside the bootstrap envelopes (base fit)", d.flagged),
            ("Still outside the envelopes with the named effects (why partial)",
             d.flagged_after)):
        if flagged:
            lines += ["", f"## {title}", "", "| statistic | value | robust z |", "|---|---:|---:|"]
            lines += [f"| {n} | {v:.3g} | {z:.1f} |" for n, v, z in flagged[:15]]
    if d.screening:
        lines += ["", "## Screening (chi-square scale: linearised score of the effects, "
                  "sum-of-squares drop of the acquisition faults)", "",
                  "| effect or fault | score | estimate |", "|---|---:|---:|"]
        lines += [f"| {s['name']} | {s['score']:.3g} | {s['step']:.3g} |" for s in d.screening]
    if d.candidates:
        lines += ["", "## Candidate sets fitted", "",
                  "| effects | judged against | values | intervals | judged on | closed | "
                  "accepted | why not |", "|---|---|---|---|---|---:|---|---|"]
        for c in d.candidates:
            vals = ", ".join(f"{v:.4g}" for v in c.values.values())
            ivs = ", ".join(f"[{lo:.3g}, {hi:.3g}]" for lo, hi in c.intervals.values()) or "-"
            lines.append(f"| {c.name}{' (partial)' if c.partial else ''} | {c.against} | "
                         f"{vals} | {ivs} | {c.judged_on} | {100 * c.closed:.0f} % | "
                         f"{'yes' if c.accepted else 'no'} | {c.reason} |")
    lines += ["", f"Orders screened: {', '.join(map(str, ORDERS))}. "
              f"Evaluations: {d.evaluations}.", "",
              "![residuals](residuals.png)", "", "![spectra](spectra.png)", ""]
    path = out / "report.md"
    path.write_text("\n".join(lines))
    return path
