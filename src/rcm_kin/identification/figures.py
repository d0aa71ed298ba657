"""The drive train's figures (files only): a measured angle beside its prediction (and band), and
the grey-box fit, each measured step response beside the physics simulated with the starting and
the fitted drive parameters."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rcm_kin.plotting import save_figure, subplots


def _still_spans(time: np.ndarray, angle: np.ndarray, least: float = 0.05) -> list[tuple[float, float]]:
    """Intervals (s) over which ``angle`` does not change for at least ``least`` s."""
    moving = np.r_[True, np.diff(angle) != 0.0, True]
    edges = np.flatnonzero(moving)
    return [(time[a], time[min(b, time.size - 1)]) for a, b in zip(edges[:-1], edges[1:])
            if time[min(b, time.size - 1)] - time[a] >= least]


def prediction_figure(time, measured, predicted, path: str | Path, title: str = "", band=None,
                      band_label: str = "prediction band", median=None) -> Path:
    """Measured and predicted angle (deg) over time (s); bands along the bottom and the top of the
    axes mark where the measured angle rests and where the model is stuck. ``band``: optional
    (lower, upper) arrays (deg, same samples) shaded as ``band_label``; ``median``: an optional
    curve (deg) drawn dotted, the band's median."""
    fig, ax = subplots(figsize=(8, 3.6), layout="constrained")
    bands = ((_still_spans(time, measured), "0.8", "measured at rest (lower band)", 0.0, 0.08),
             (_still_spans(time, predicted), "#9fd49f", "model stuck (upper band)", 0.92, 1.0))
    for spans, colour, label, low, high in bands:
        for k, (a, b) in enumerate(spans):
            ax.axvspan(a, b, ymin=low, ymax=high, color=colour, lw=0, label=label if k == 0 else None)
    if band is not None:
        ax.fill_between(time, band[0], band[1], color="tab:blue", alpha=0.25, lw=0, label=band_label)
    ax.plot(time, measured, "k", lw=1.4, label="measured")
    ax.plot(time, predicted, color="tab:green", lw=1.2, ls="--", label="predicted (recorded PWM, no refit)")
    if median is not None:
        ax.plot(time, median, color="tab:blue", lw=1.0, ls=":", label="band median")
    ax.set(xlabel="time (s)", ylabel="angle (deg)", title=title)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    ax.grid(alpha=0.3)
    return save_figure(fig, path)


GREYBOX_STYLES = {"measured": {"color": "k", "lw": 1.5},
                  "starting": {"color": "tab:blue", "lw": 4.5, "alpha": 0.35},
                  "fitted": {"color": "tab:orange", "lw": 1.6, "ls": "--"},
                  "own_coulomb": {"color": "tab:green", "lw": 1.6, "ls": ":"}}
GREYBOX_LABELS = {"measured": "measured", "starting": "starting set", "fitted": "fitted set (median Coulomb)",
                  "own_coulomb": "fitted set, each log's own Coulomb"}


def _measured_limits(measured: np.ndarray) -> tuple[float, float]:
    """y-limits from the measured response (and zero), with room above and below."""
    low, high = min(float(np.min(measured)), 0.0), max(float(np.max(measured)), 0.0)
    span = (high - low) or 1.0
    return low - 0.15 * span, high + 0.25 * span


def _note_clipped(ax, response: dict, limits: tuple[float, float]) -> None:
    """Say in the panel which simulated curves leave the axes, and how far they go."""
    notes = []
    for key in ("starting", "fitted", "own_coulomb"):
        y = np.asarray(response[key])
        if y.max() > limits[1] or y.min() < limits[0]:
            far = y.max() if y.max() > limits[1] else y.min()
            notes.append(f"{GREYBOX_LABELS[key].split(' (')[0]} off scale (to {far:+.3g})")
    if notes:
        ax.text(0.98, 0.03, "\n".join(notes), transform=ax.transAxes, ha="right", va="bottom", fontsize=7,
                bbox={"facecolor": "white", "alpha": 0.85, "lw": 0})


def greybox_figure(fit, path: str | Path) -> Path:
    """Measured step responses beside the physics simulated with the starting and the fitted
    parameters (and each log's own Coulomb friction), one panel per log. The y-axis is the
    measured response's; a simulated curve beyond it is clipped and the panel says so. The
    starting set is a broad pale band under the fitted set's dashes, so both show where they agree."""
    n = len(fit.logs)
    cols = min(n, 3)
    rows = -(-n // cols)
    fig, axes = subplots(rows, cols, figsize=(4.4 * cols, 3.3 * rows + 0.5), layout="constrained", squeeze=False)
    for ax, name, r, before, after, own in zip(axes.flat, fit.logs, fit.responses, fit.fit_before, fit.fit_after,
                                               fit.fit_per_log_friction):
        for key in ("starting", "fitted", "own_coulomb", "measured"):
            ax.plot(r["time"], r[key], label=GREYBOX_LABELS[key], **GREYBOX_STYLES[key])
        limits = _measured_limits(r["measured"])
        ax.set_ylim(*limits)
        _note_clipped(ax, r, limits)
        ax.set(title=f"{name.replace('.csv', '')}\nfit: starting {before:.0f} %, fitted {after:.0f} %, "
                     f"own Coulomb {own:.0f} %", xlabel="time (s)", ylabel=f"{fit.joint} change (deg)")
        ax.title.set_fontsize(8)
        ax.grid(alpha=0.3)
    for ax in axes.flat[n:]:
        ax.axis("off")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside upper center", ncol=4, fontsize=8)
    return save_figure(fig, path)
