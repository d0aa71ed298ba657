"""Matplotlib figures (files only, no display): heat maps of the holding effort and the curves of
thesis Figs 4.6/4.7 (roll effort versus roll, pitch effort versus pitch, each at several values
of the other joint)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import numpy as np  # noqa: E402


def _save(fig, path: str | Path) -> Path:
    """Write the figure as a PNG (110 dpi) and free it."""
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def effort_heatmaps(gmap, path: str | Path, insertion_index: int = 0) -> Path:
    """PWM and voltage heat maps of roll and pitch over the roll x pitch grid at one insertion."""
    e = gmap.effort
    fig, axes = plt.subplots(2, 2, figsize=(10, 8), constrained_layout=True)
    extent = [gmap.roll_deg[0], gmap.roll_deg[-1], gmap.pitch_deg[0], gmap.pitch_deg[-1]]
    for col, (joint, k) in enumerate((("roll", 0), ("pitch", 1))):
        for row, (quantity, unit) in enumerate((("pwm", "counts"), ("voltage", "V"))):
            data = getattr(e, quantity)[:, :, insertion_index, k]
            ax = axes[row, col]
            im = ax.imshow(data, origin="lower", extent=extent, aspect="auto", cmap="coolwarm",
                           vmin=-np.abs(data).max(), vmax=np.abs(data).max())
            ax.contour(gmap.roll_deg, gmap.pitch_deg, data, colors="k", linewidths=0.5, levels=9)
            ax.set(xlabel="roll (deg)", ylabel="pitch (deg)", title=f"{joint} holding {quantity} ({unit})")
            fig.colorbar(im, ax=ax)
    fig.suptitle(f"Holding effort at insertion {gmap.insertion[insertion_index] * 1e3:.0f} mm "
                 "(PWM: hardware sign, positive decreases the angle)")
    return _save(fig, path)


def thesis_trend_curves(gmap, path: str | Path, insertion_index: int = 0, others=(-15.0, 0.0, 15.0)) -> Path:
    """Fig 4.6 (|roll voltage| vs roll) and Fig 4.7 (pitch voltage vs pitch), computed."""
    e = gmap.effort
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    for other in others:
        i = int(np.argmin(np.abs(gmap.pitch_deg - other)))
        a.plot(gmap.roll_deg, np.abs(e.voltage[i, :, insertion_index, 0]), label=f"pitch {gmap.pitch_deg[i]:.0f} deg")
        j = int(np.argmin(np.abs(gmap.roll_deg - other)))
        b.plot(gmap.pitch_deg, e.voltage[:, j, insertion_index, 1], label=f"roll {gmap.roll_deg[j]:.0f} deg")
    a.set(xlabel="roll (deg)", ylabel="|roll motor voltage| (V)", title="roll holding voltage (cf. thesis Fig 4.6)")
    b.set(xlabel="pitch (deg)", ylabel="pitch motor voltage (V)", title="pitch holding voltage (cf. thesis Fig 4.7)")
    for ax in (a, b):
        ax.grid(alpha=0.3)
        ax.legend()
    return _save(fig, path)


def insertion_curves(gmap, path: str | Path) -> Path:
    """Holding force of the insertion and torques of roll and pitch versus insertion."""
    e = gmap.effort
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6), constrained_layout=True)
    for k, (ax, name, unit) in enumerate(zip(axes, ("roll", "pitch", "insertion"), ("N m", "N m", "N"))):
        ax.plot(gmap.insertion * 1e3, e.tau[0, 0, :, k])
        ax.set(xlabel="insertion (mm)", ylabel=f"{name} holding ({unit})",
               title=f"roll {gmap.roll_deg[0]:.0f}, pitch {gmap.pitch_deg[0]:.0f} deg")
        ax.grid(alpha=0.3)
    return _save(fig, path)


def stability_maps(surveys: dict, path: str | Path) -> Path:
    """Per survey (title -> StabilitySurvey): the 400 Hz firmware loop's slowest decay rate
    ``-ln(spectral radius) / T`` (1/s; negative = unstable) over roll x pitch."""
    from rcm_kin.control.stability import FIRMWARE_PERIOD

    fig, axes = plt.subplots(1, len(surveys), figsize=(5 * len(surveys), 4), constrained_layout=True, squeeze=False)
    for ax, (title, s) in zip(axes[0], surveys.items()):
        decay = -np.log(s.spectral_radius) / FIRMWARE_PERIOD
        extent = [s.roll_deg[0], s.roll_deg[-1], s.pitch_deg[0], s.pitch_deg[-1]]
        im = ax.imshow(decay, origin="lower", extent=extent, aspect="auto", cmap="RdYlGn",
                       vmin=-np.abs(decay).max(), vmax=np.abs(decay).max())
        ax.set(xlabel="roll (deg)", ylabel="pitch (deg)", title=title)
        fig.colorbar(im, ax=ax, label="slowest decay rate (1/s)")
    return _save(fig, path)


def tracking_figure(result, path: str | Path, title: str = "") -> Path:
    """Thesis Figs 5.2-5.5 and 5.8-5.9: reference and measured angle per axis (top) and the
    tracking error (bottom), with the PWM sent on a second axis."""
    fig, axes = plt.subplots(2, 2, figsize=(11, 6), sharex=True, constrained_layout=True)
    for i, axis in enumerate(("roll", "pitch")):
        top, bottom = axes[0, i], axes[1, i]
        top.plot(result.time, result.reference[:, i], "k--", lw=1.2, label="reference")
        top.plot(result.time, result.measured[:, i], lw=1.2, label=f"measured ({result.controller})")
        top.set(ylabel=f"{axis} (deg)", title=f"{title} {axis}".strip())
        top.legend(loc="upper right", fontsize=8)
        bottom.plot(result.time, result.error[:, i], color="tab:red", lw=1.0, label="error")
        bottom.set(xlabel="time (s)", ylabel="error (deg)")
        pwm = bottom.twinx()
        pwm.plot(result.time, result.pwm[:, i], color="tab:gray", lw=0.6, alpha=0.6)
        pwm.set_ylabel("PWM (counts)", color="tab:gray")
        for ax in (top, bottom):
            ax.grid(alpha=0.3)
    return _save(fig, path)


def error_comparison_figure(results: list, path: str | Path, title: str = "") -> Path:
    """Thesis Figs 5.6/5.7 and 5.10/5.11: the tracking error of several controllers per axis."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.6), constrained_layout=True)
    for i, (ax, axis) in enumerate(zip(axes, ("roll", "pitch"))):
        for r in results:
            ax.plot(r.time, r.error[:, i], lw=1.0, label=r.controller)
        ax.set(xlabel="time (s)", ylabel=f"{axis} error (deg)", title=f"{title} {axis}".strip())
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    return _save(fig, path)


def greybox_figure(fit, path: str | Path) -> Path:
    """Measured step responses beside the physics simulated with the starting and the fitted
    parameters (and each log's own Coulomb friction), one panel per log."""
    n = len(fit.logs)
    cols = min(n, 3)
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.2 * rows), constrained_layout=True, squeeze=False)
    for ax, name, r, before, after, own in zip(axes.flat, fit.logs, fit.responses, fit.fit_before, fit.fit_after,
                                               fit.fit_per_log_friction):
        ax.plot(r["time"], r["measured"], "k", lw=1.5, label="measured")
        ax.plot(r["time"], r["starting"], ":", label=f"starting set ({before:.0f} %)")
        ax.plot(r["time"], r["fitted"], label=f"fitted set ({after:.0f} %)")
        ax.plot(r["time"], r["own_coulomb"], "--", label=f"own Coulomb ({own:.0f} %)")
        ax.set(title=name.replace(".csv", ""), xlabel="time (s)", ylabel=f"{fit.joint} change (deg)")
        low, high = np.min(r["measured"]), np.max(r["measured"])
        ax.set_ylim(min(low, 0) - 0.5 * (high - low), high + 1.5 * (high - low))   # the measured scale
        ax.title.set_fontsize(8)
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    for ax in axes.flat[n:]:
        ax.axis("off")
    return _save(fig, path)


def barrier_figure(runs: dict, path: str | Path) -> Path:
    """Barrier value along each safety scenario (``{scenario: {filter: SafetyRun}}``): B <= 0 is
    safe; the unfiltered run shows where the nominal controller would have gone."""
    fig, axes = plt.subplots(1, len(runs), figsize=(4.2 * len(runs), 3.4), constrained_layout=True, squeeze=False)
    for ax, (scenario, by_filter) in zip(axes[0], runs.items()):
        for name, run in by_filter.items():
            ax.plot(run.time, run.barrier, lw=1.0, label=name, ls=":" if name == "none" else "-")
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set(title=scenario, xlabel="time (s)", ylabel="B (> 0 unsafe)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    return _save(fig, path)
