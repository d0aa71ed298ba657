"""Figures of a robustness run (files only): empirical CDFs over the samples, one curve per
controller, of the largest roll and pitch tracking errors and of the 400 Hz loop's spectral
radius."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rcm_kin.plotting import save_figure as save
from rcm_kin.plotting import subplots
from rcm_kin.robustness.statistics import Robustness


def ecdf(values) -> tuple[np.ndarray, np.ndarray]:
    """The finite ``values`` sorted and their empirical cumulative probabilities ``k / n``."""
    v = np.sort(np.asarray(values, dtype=float)[np.isfinite(values)])
    return v, np.arange(1, v.size + 1) / max(v.size, 1)


def robustness_figure(result: Robustness, path: str | Path) -> Path:
    """Empirical CDFs of the largest roll and pitch errors (deg) and the firmware loop's spectral
    radius over the samples, a curve per controller (the PID has no radius)."""
    from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

    fig, axes = subplots(1, 3, figsize=(13, 3.8), margins=(0.6, 0.1, 0.49, 0.56), gridspec_kw={"wspace": 0.17})
    for c, name in enumerate(result.controllers):
        style = {"where": "post", "label": name, "color": f"C{c}"}
        for a, title in enumerate(("roll", "pitch")):
            axes[a].step(*ecdf([o.max_error_deg[c, a] for o in result.outcomes]), **style)
        radius = [o.spectral_radius[c] for o in result.outcomes]
        if np.isfinite(radius).any():
            axes[2].step(*ecdf(radius), **style)
    for a, title in enumerate(("roll", "pitch")):
        axes[a].set(xlabel=f"largest {title} error (deg, log scale)", ylabel="fraction of samples", title=title,
                    xscale="log")
        axes[a].xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        axes[a].xaxis.set_major_formatter(FormatStrFormatter("%g"))
        axes[a].xaxis.set_minor_formatter(NullFormatter())
    axes[2].axvline(1.0, color="k", lw=0.8, ls=":")
    axes[2].set(xlabel="spectral radius of the 400 Hz loop (worst pose)", ylabel="fraction of samples",
                title="linear stability (< 1: stable)")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{result.experiment}: {result.samples} samples of the parameter uncertainty (seed {result.seed})")
    return save(fig, Path(path))


def counterweight_figure(rows, path: str | Path) -> Path:
    """RMS holding PWM of roll and pitch against the main counterweight's mass, a curve per DPM
    counterweight mass (rows: :class:`~rcm_kin.robustness.sweeps.CounterweightRow`)."""
    fig, axes = subplots(1, 2, figsize=(10, 3.8), layout="constrained", sharey=True)
    for dpm in sorted({r.dpm_mass_kg for r in rows}):
        line = sorted((r for r in rows if r.dpm_mass_kg == dpm), key=lambda r: r.main_mass_kg)
        for ax, field in zip(axes, ("rms_pwm_roll", "rms_pwm_pitch")):
            ax.plot([r.main_mass_kg for r in line], [getattr(r, field) for r in line], "o-", label=f"DPM {dpm:g} kg")
    for ax, joint in zip(axes, ("roll", "pitch")):
        ax.set(xlabel="main counterweight (kg)", title=f"{joint}: RMS holding PWM over the workspace")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("PWM counts (RMS)")
    axes[1].legend(fontsize=8)
    fig.suptitle("counterweights positioned for least holding effort: added mass against effort left")
    return save(fig, Path(path))


def weights_figure(rows, path: str | Path) -> Path:
    """Largest tracking error against RMS PWM per axis, a point per LQR/LQI budget pair, labelled
    (rows: :class:`~rcm_kin.robustness.sweeps.WeightsRow`)."""
    fig, axes = subplots(1, 2, figsize=(10, 3.8), layout="constrained")
    for ax, joint in zip(axes, ("roll", "pitch")):
        x = [getattr(r, f"rms_pwm_{joint}") for r in rows]
        y = [getattr(r, f"max_error_{joint}_deg") for r in rows]
        ax.scatter(x, y, c=[r.spectral_radius for r in rows], cmap="viridis",
                   edgecolors=["none" if r.stable else "red" for r in rows], linewidths=1.5)
        for r, xi, yi in zip(rows, x, y):
            ax.annotate(f"{r.error_budget_deg:g} deg/{r.pwm_fraction:g}", (xi, yi), fontsize=7,
                        textcoords="offset points", xytext=(3, 3))
        ax.set(xlabel="RMS PWM (counts)", ylabel="largest error (deg)", title=joint)
        ax.grid(alpha=0.3)
    fig.suptitle("LQR/LQI budgets (error budget deg / PWM fraction): tracking against PWM use\n"
                 "colour: the 400 Hz loop's spectral radius; red ring: that loop unstable", fontsize=10)
    return save(fig, Path(path))
