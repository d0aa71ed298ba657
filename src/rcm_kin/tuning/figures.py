"""The design study drawn (files only): per experiment and axis, the empirical CDF over the draws
of the largest tracking error of each controller, on the tuning draws (solid) and the held-out
ones (dashed); and the chosen design's gains over the thesis grid beside the thesis's tables."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rcm_kin.plotting import pyplot
from rcm_kin.plotting import save_figure as save
from rcm_kin.robustness.figures import ecdf
from rcm_kin.tuning.objective import AXES
from rcm_kin.tuning.study import CONTROLLERS, DesignStudy

LABELS = {"thesis": "thesis law (flashed tables)", "lqr": "LQR/LQI schedule (scheduled-friction)",
          "fixed": "tuned, one gain set", "scheduled": "tuned, scheduled"}


def study_figure(study: DesignStudy, path: str | Path) -> Path:
    """Empirical CDFs of the largest error (deg, log scale) per experiment (rows) and axis (columns)."""
    plt = pyplot()
    experiments = study.judged["tuning"]["thesis"].outcomes.experiments
    fig, axes = plt.subplots(len(experiments), 2, figsize=(11, 3.4 * len(experiments)), layout="constrained",
                             squeeze=False)
    for c, name in enumerate(CONTROLLERS):
        for style, draws in (("-", "tuning"), ("--", "held_out")):
            errors = study.judged[draws][name].outcomes.max_error_deg
            for k in range(len(experiments)):
                for a in range(2):
                    label = f"{LABELS[name]}{' (chosen)' if name == study.chosen else ''}" if style == "-" else None
                    axes[k, a].step(*ecdf(errors[:, k, a]), where="post", ls=style, color=f"C{c}", label=label)
    for k, experiment in enumerate(experiments):
        for a, axis in enumerate(AXES):
            axes[k, a].set(xscale="log", xlabel=f"largest {axis} error from 1 s (deg, log)",
                           ylabel="fraction of draws", title=f"{experiment}, {axis}")
            axes[k, a].grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, loc="lower right")
    fig.suptitle(f"{study.samples} draws (seed {study.seeds[0]}, solid; tuned on the first {study.tune_samples}) "
                 f"and {study.samples} held out (seed {study.seeds[1]}, dashed)")
    return save(fig, Path(path))


def gains_figure(study: DesignStudy, thesis_tables: dict[str, np.ndarray], path: str | Path) -> Path:
    """The chosen design's Kp of roll and pitch over the grid (deg) beside the thesis's tables."""
    plt = pyplot()
    s = study.schedule
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6), layout="constrained")
    for ax, (axis, table) in zip(axes, (("roll", s.k_roll), ("pitch", s.k_pitch))):
        for j, pitch in enumerate(s.pitch_deg):
            ax.plot(s.roll_deg, table[j, :, 0], "o-", color=f"C{j}", label=f"tuned, pitch {pitch:g} deg")
            ax.plot(s.roll_deg, thesis_tables[axis][j, :, 0], "s:", color=f"C{j}", label=f"thesis, pitch {pitch:g}")
        ax.set(xlabel="roll (deg)", ylabel=f"{axis} Kp (PWM/deg)", title=f"{axis} Kp over the grid")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    return save(fig, Path(path))
