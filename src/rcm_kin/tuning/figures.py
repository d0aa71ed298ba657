"""The design study drawn (files only): per experiment and axis, the empirical CDF over the draws
of the largest tracking error of each controller, on the tuning draws (solid) and the held-out
ones (dashed); and the chosen design's gains over the thesis grid beside the thesis's tables."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rcm_kin.control.gain_schedule import GainSchedule
from rcm_kin.plotting import save_figure as save
from rcm_kin.plotting import subplots
from rcm_kin.robustness.figures import ecdf
from rcm_kin.tuning.objective import AXES
from rcm_kin.tuning.study import CONTROLLERS

LABELS = {"thesis": "thesis law (flashed tables)", "lqr": "LQR/LQI schedule (scheduled-friction)",
          "fixed": "tuned, one gain set", "scheduled": "tuned, scheduled"}


def study_figure(study: dict, path: str | Path) -> Path:
    """Empirical CDFs of the largest error (deg, log scale) per experiment (rows) and axis (columns)
    of a study as data (:meth:`DesignStudy.to_dict`, or the shipped ``tuning.json``)."""
    from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

    experiments = study["experiments"]
    fig, axes = subplots(len(experiments), 2, figsize=(11, 3.4 * len(experiments)), margins=(0.62, 0.1, 0.49, 0.68),
                         squeeze=False, gridspec_kw={"wspace": 0.14, "hspace": 0.29})
    for c, name in enumerate(CONTROLLERS):
        for style, draws in (("-", "tuning"), ("--", "held_out")):
            errors = np.array(study["judged"][draws][name]["per_draw"]["max_error_deg"], dtype=float)
            for k in range(len(experiments)):
                for a in range(2):
                    label = f"{LABELS[name]}{' (chosen)' if name == study['chosen'] else ''}" if style == "-" else None
                    axes[k, a].step(*ecdf(errors[:, k, a]), where="post", ls=style, color=f"C{c}", label=label)
    for k, experiment in enumerate(experiments):
        for a, axis in enumerate(AXES):
            axes[k, a].set(xscale="log", xlabel=f"largest {axis} error from 1 s (deg, log)",
                           ylabel="fraction of draws", title=f"{experiment}, {axis}")
            axes[k, a].xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
            axes[k, a].xaxis.set_major_formatter(FormatStrFormatter("%g"))
            axes[k, a].xaxis.set_minor_formatter(NullFormatter())
            axes[k, a].grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, loc="lower right")
    seeds = study["seeds"]
    fig.suptitle(f"{study['samples']} draws (seed {seeds['tuning']}, solid; tuned on the first "
                 f"{study['tune_samples']}) and {study['samples']} held out (seed {seeds['held_out']}, dashed)")
    return save(fig, Path(path))


def gains_figure(s: GainSchedule, thesis_tables: dict[str, np.ndarray], path: str | Path) -> Path:
    """A schedule's Kp of roll and pitch over the grid (deg) beside the thesis's tables."""
    fig, axes = subplots(1, 2, figsize=(10, 3.6), margins=(0.65, 0.1, 0.49, 0.27), gridspec_kw={"wspace": 0.16})
    for ax, (axis, table) in zip(axes, (("roll", s.k_roll), ("pitch", s.k_pitch))):
        for j, pitch in enumerate(s.pitch_deg):
            ax.plot(s.roll_deg, table[j, :, 0], "o-", color=f"C{j}", label=f"tuned, pitch {pitch:g} deg")
            ax.plot(s.roll_deg, thesis_tables[axis][j, :, 0], "s:", color=f"C{j}", label=f"thesis, pitch {pitch:g}")
        ax.set(xlabel="roll (deg)", ylabel=f"{axis} Kp (PWM/deg)", title=f"{axis} Kp over the grid")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    return save(fig, Path(path))
