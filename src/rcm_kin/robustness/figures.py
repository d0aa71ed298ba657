"""Figures of a robustness run (files only): empirical CDFs over the samples, one curve per
controller, of the largest roll and pitch tracking errors and of the 400 Hz loop's spectral
radius."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import numpy as np  # noqa: E402

from rcm_kin.errors import RcmKinError  # noqa: E402
from rcm_kin.robustness.statistics import Robustness  # noqa: E402


def ecdf(values) -> tuple[np.ndarray, np.ndarray]:
    """The finite ``values`` sorted and their empirical cumulative probabilities ``k / n``."""
    v = np.sort(np.asarray(values, dtype=float)[np.isfinite(values)])
    return v, np.arange(1, v.size + 1) / max(v.size, 1)


def save(fig, path: Path) -> Path:
    """Write ``fig`` as a PNG (110 dpi) and free it."""
    try:
        fig.savefig(path, dpi=110)
    except (OSError, ValueError) as exc:
        raise RcmKinError(f"cannot write the figure {path}: {exc}") from None
    finally:
        plt.close(fig)
    return path


def robustness_figure(result: Robustness, path: str | Path) -> Path:
    """Empirical CDFs of the largest roll and pitch errors (deg) and the firmware loop's spectral
    radius over the samples, a curve per controller (the PID has no radius)."""
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), layout="constrained")
    for c, name in enumerate(result.controllers):
        for a, title in enumerate(("roll", "pitch")):
            axes[a].step(*ecdf([o.max_error_deg[c, a] for o in result.outcomes]), where="post", label=name)
        radius = [o.spectral_radius[c] for o in result.outcomes]
        if np.isfinite(radius).any():
            axes[2].step(*ecdf(radius), where="post", label=name)
    for a, title in enumerate(("roll", "pitch")):
        axes[a].set(xlabel=f"largest {title} error (deg)", ylabel="fraction of samples", title=title)
    axes[2].axvline(1.0, color="k", lw=0.8, ls=":")
    axes[2].set(xlabel="spectral radius of the 400 Hz loop (worst pose)", ylabel="fraction of samples",
                title="linear stability (< 1: stable)")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{result.experiment}: {result.samples} samples of the parameter uncertainty (seed {result.seed})")
    return save(fig, Path(path))
