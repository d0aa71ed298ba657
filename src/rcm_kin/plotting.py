"""Matplotlib figures (files only, no display): heat maps of the holding effort and the curves of
thesis Figs 4.6/4.7 (roll effort versus roll, pitch effort versus pitch, each at several values
of the other joint), tracking, stability and barrier figures of the simulations.

Figures are drawn on matplotlib's ``Figure`` and Agg canvas (:func:`subplots`), never pyplot's
managers; those of ``torque-map`` and the report on fixed margins (no layout solved when drawn).
:func:`draw_apart` draws two groups of figures at once, one in a forked process."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Callable

import numpy as np

from rcm_kin.apart import paused_collector, run_apart
from rcm_kin.atomic import atomic_path
from rcm_kin.dynamics.drive import DRIVEN
from rcm_kin.errors import RcmKinError
from rcm_kin.figure_layout import shortfall, widen
from rcm_kin.hardware import FIRMWARE_PERIOD
from rcm_kin.thesis import FIGURES

# line styles that stay apart when curves coincide (e.g. roll -15 and +15 by symmetry)
STYLES = ({"ls": "-", "marker": "o", "ms": 4}, {"ls": "-", "lw": 2.4, "alpha": 0.7},
          {"ls": "--", "marker": "x", "ms": 6}, {"ls": ":", "marker": "^", "ms": 4}, {"ls": "-."})
IMAGE_SAMPLES = 401        # poses per axis a heat map's image is drawn from at least (or all of them)
CONTOUR_SAMPLES = 301      # poses per axis a heat map's contour lines are traced on at most
# the torque-map figures' margins (fractions of the figure), fixed for their fixed sizes: a constrained
# layout measured every label for them, a third of their drawing time (docs/performance.md)
FIXED = {"heatmaps": {"left": 0.06, "right": 0.97, "bottom": 0.11, "top": 0.87, "wspace": 0.3},
         "trends": {"left": 0.06, "right": 0.99, "bottom": 0.12, "top": 0.93, "wspace": 0.2},
         "insertion": {"left": 0.05, "right": 0.855, "bottom": 0.13, "top": 0.8, "wspace": 0.3}}


@functools.cache
def figure_classes() -> tuple[type, type]:
    """matplotlib's ``Figure`` and the Agg canvas (files only, no display), imported when the first
    figure is drawn, not when rcm_kin is: a command that draws nothing never pays for it. Not
    pyplot: its figure managers and backend switching are not needed to write files."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    return Figure, FigureCanvasAgg


def draw_apart(forked: Callable[[], object], here: Callable[[], object], fork: bool = True) -> tuple[object, object]:
    """Two groups of figures drawn at once, ``forked()`` in a forked process and ``here()`` in this
    one (:func:`rcm_kin.apart.run_apart`: their results, the child's errors and warnings raised
    here): a figure is drawn in Python, one core's work. matplotlib is imported first, once for both;
    the garbage collector is paused meanwhile (:func:`rcm_kin.apart.paused_collector`)."""
    with paused_collector():
        figure_classes()
        return run_apart(forked, here, fork, "the process drawing the figures")


def subplots(nrows: int = 1, ncols: int = 1, *, figsize: tuple[float, float], layout: str | None = None,
             margins: tuple[float, float, float, float] | None = None, **kwargs):
    """A new figure of ``figsize`` (inches) on the Agg canvas and its grid of axes, as
    ``pyplot.subplots`` makes them (``kwargs``: ``squeeze``, ``sharex``, ``gridspec_kw``, ...).
    ``margins``: the grid's (left, right, bottom, top) distances from the figure's edges in
    inches, fixed: no layout is solved when the figure is drawn (a constrained layout measures
    every label, about half the drawing time of a figure)."""
    figure, canvas = figure_classes()
    fig = figure(figsize=figsize, layout=layout)
    canvas(fig)
    if margins is not None:
        (width, height), (left, right, bottom, top) = figsize, margins
        kwargs["gridspec_kw"] = {"left": left / width, "right": 1 - right / width, "bottom": bottom / height,
                                 "top": 1 - top / height, **kwargs.get("gridspec_kw", {})}
    return fig, fig.subplots(nrows, ncols, **kwargs)


def figure_format(path: str | Path) -> str:
    """The image format matplotlib writes ``path`` in: its suffix (``png``, ``svg``, ``pdf``), PNG
    when it has none. Named when a figure is saved to a temporary path, so that matplotlib neither
    guesses it from another name nor adds a suffix to the file."""
    return Path(path).suffix[1:].lower() or "png"


def save_figure(fig, path: str | Path) -> Path:
    """Write the figure as a PNG (110 dpi; zlib level 3: a sixth larger than the default 6, the same
    pixels, written in a fraction of the time). A figure on fixed margins is widened where its y
    tick labels would not fit them (:mod:`rcm_kin.figure_layout`)."""
    path = Path(path)
    if fig.get_layout_engine() is None:
        widen(fig, *shortfall(fig))
    try:
        with atomic_path(path) as temporary:    # the format named: matplotlib would add a suffix to a bare name
            fig.savefig(temporary, dpi=110, format=figure_format(path), pil_kwargs={"compress_level": 3})
    except RcmKinError:
        raise
    except (OSError, ValueError) as exc:
        raise RcmKinError(f"cannot write the figure {path}: {exc}") from None
    return path


def effort_heatmaps(gmap, drive, path: str | Path, insertion_index: int = 0, image_samples: int = IMAGE_SAMPLES,
                    contour_samples: int = CONTOUR_SAMPLES) -> Path:
    """Holding PWM heat maps of roll and pitch over the roll x pitch grid at one insertion, each
    colour bar with a second scale in motor volts (at rest the drive is linear, V = sign x
    volts_per_pwm x PWM, from ``drive``, the map's :class:`DriveParameters`). A panel is about 450
    pixels wide, so a finer grid is drawn from samples of it that look the same
    (tests/plotting/test_heatmap_figure.py): the image from every k-th pose (:func:`image_stride`, at least
    ``image_samples`` per axis, both ends kept), the contour lines (9 levels, matplotlib's choice
    over the whole grid's range) traced on at most ``contour_samples`` evenly spread poses per axis
    (:func:`spread_samples`); the colour scale is the whole grid's."""
    pwm = gmap.effort.pwm
    fig, axes = subplots(1, 2, figsize=(11, 4.6), gridspec_kw=FIXED["heatmaps"])   # fixed: no layout solve
    extent = [*_span(gmap.roll_deg), *_span(gmap.pitch_deg)]
    rows, cols = (spread_samples(n, contour_samples) for n in (gmap.pitch_deg.size, gmap.roll_deg.size))
    pixels = tuple(slice(None, None, image_stride(n, image_samples)) for n in (gmap.pitch_deg.size, gmap.roll_deg.size))
    for ax, joint in zip(axes, ("roll", "pitch")):
        k = DRIVEN.index(joint)
        data = pwm[:, :, insertion_index, k]
        limit = np.abs(data).max()
        im = ax.imshow(data[pixels], origin="lower", extent=extent, aspect="auto", cmap="coolwarm",
                       vmin=-limit, vmax=limit)
        if min(data.shape) >= 2:                 # a 1-point axis has no contours
            ax.contour(gmap.roll_deg[cols], gmap.pitch_deg[rows], data[np.ix_(rows, cols)], colors="k",
                       linewidths=0.5, levels=contour_levels(data, 9))
        ax.set(xlabel="roll (deg)", ylabel="pitch (deg)", title=f"{joint} holding PWM")
        bar = fig.colorbar(im, ax=ax, label="PWM (counts)", pad=0.2)   # room for the volts
        volts = drive[joint].pwm_sign * drive[joint].volts_per_pwm
        bar.ax.secondary_yaxis("left", functions=(lambda p, v=volts: p * v, lambda u, v=volts: u / v)).set_ylabel(
            "motor voltage (V)")
    fig.suptitle(f"Holding effort at insertion {gmap.insertion[insertion_index] * 1e3:.0f} mm "
                 "(PWM: hardware sign, positive decreases the angle)")
    return save_figure(fig, path)


def image_stride(n: int, least: int) -> int:
    """The largest stride k that samples ``n`` poses as 0, k, 2k, ..., n - 1 (both ends, so the
    image spans the whole grid) in at least ``least`` poses: 1 (every pose) when there is none."""
    return max((k for k in range(1, n) if (n - 1) % k == 0 and (n - 1) // k + 1 >= least), default=1)


def spread_samples(n: int, most: int) -> np.ndarray:
    """Indices of at most ``most`` (>= 2) evenly spread samples of ``n``, the first and last
    included: all of them when ``n <= most``."""
    return np.arange(n) if n <= most else np.unique(np.linspace(0, n - 1, most).round().astype(int))


def contour_levels(data: np.ndarray, n: int) -> np.ndarray:
    """The levels ``ax.contour(..., levels=n)`` picks for ``data`` (matplotlib's rule: ``MaxNLocator(n
    + 1)`` over the data's range, trimmed to one level beyond each end), so that contours traced
    on samples of ``data`` keep the whole data's levels."""
    from matplotlib import ticker

    low, high = float(data.min()), float(data.max())
    levels = ticker.MaxNLocator(n + 1, min_n_ticks=1).tick_values(low, high)
    under, over = np.flatnonzero(levels < low), np.flatnonzero(levels > high)
    first, last = (under[-1] if under.size else 0), (over[0] + 1 if over.size else levels.size)
    return levels[first:last] if last - first >= 3 else levels


def _span(values: np.ndarray) -> tuple[float, float]:
    """Image extent of grid ``values``: first to last, or +-0.5 about a single value."""
    return (values[0], values[-1]) if values.size > 1 else (values[0] - 0.5, values[0] + 0.5)


def _style(k: int, n: int) -> dict:
    """Line style ``k`` of :data:`STYLES`, markers on about 12 of ``n`` samples."""
    return {**STYLES[k % len(STYLES)], "markevery": max(1, n // 12)}


def _same_as(curve: np.ndarray, earlier: dict) -> str:
    """`` (on <label>)`` when ``curve`` coincides with an earlier one (label -> curve), else ''."""
    for label, other in earlier.items():
        if np.allclose(curve, other, rtol=1e-6, atol=1e-9 * (1 + np.abs(other).max())):
            return f" (on {label})"
    return ""


def thesis_trend_curves(gmap, path: str | Path, insertion_index: int = 0, others=(-15.0, 0.0, 15.0)) -> Path:
    """Fig 4.6 (|roll voltage| vs roll) and Fig 4.7 (pitch voltage vs pitch), computed. Every
    curve has its own line style; one lying on another says so in the legend."""
    e = gmap.effort
    fig, (a, b) = subplots(1, 2, figsize=(11, 4.2), gridspec_kw=FIXED["trends"])
    drawn_a, drawn_b = {}, {}
    for k, other in enumerate(others):
        i = int(np.argmin(np.abs(gmap.pitch_deg - other)))
        y = np.abs(e.voltage[i, :, insertion_index, 0])
        label = f"pitch {gmap.pitch_deg[i]:.0f} deg"
        a.plot(gmap.roll_deg, y, label=label + _same_as(y, drawn_a), **_style(k, y.size))
        drawn_a[label] = y
        j = int(np.argmin(np.abs(gmap.roll_deg - other)))
        y = e.voltage[:, j, insertion_index, 1]
        label = f"roll {gmap.roll_deg[j]:.0f} deg"
        b.plot(gmap.pitch_deg, y, label=label + _same_as(y, drawn_b), **_style(k, y.size))
        drawn_b[label] = y
    a.set(xlabel="roll (deg)", ylabel="|roll motor voltage| (V)",
          title=f"roll holding voltage (cf. thesis {FIGURES['roll_holding']})")
    b.set(xlabel="pitch (deg)", ylabel="pitch motor voltage (V)",
          title=f"pitch holding voltage (cf. thesis {FIGURES['pitch_holding']})")
    for ax in (a, b):
        ax.grid(alpha=0.3)
        ax.legend()
    return save_figure(fig, path)


def insertion_curves(gmap, path: str | Path) -> Path:
    """Holding torque of roll and pitch and holding force of the insertion versus the insertion,
    one curve per (roll, pitch) pose of the map: colour and marker by pitch, line style by roll;
    the markers of the poses are staggered, so curves that coincide still show each pose."""
    from matplotlib import colormaps

    e = gmap.effort
    fig, axes = subplots(1, 3, figsize=(13, 3.9), gridspec_kw=FIXED["insertion"])
    colours = colormaps["viridis"](np.linspace(0.0, 0.85, len(gmap.pitch_deg)))
    quantities = (("roll holding torque", "N m"), ("pitch holding torque", "N m"), ("insertion holding force", "N"))
    for k, (ax, (name, unit)) in enumerate(zip(axes, quantities)):
        for i, roll in enumerate(gmap.roll_deg):
            for j, pitch in enumerate(gmap.pitch_deg):
                every = max(1, gmap.insertion.size // 8)
                ax.plot(gmap.insertion * 1e3, e.tau[j, i, :, k], color=colours[j], ls=("-", "--", ":", "-.")[i % 4],
                        marker="osD^v"[j % 5], ms=5, fillstyle="none" if i % 2 else "full", lw=1.6,
                        markevery=((i * len(gmap.pitch_deg) + j) * every // 6 % every, every),
                        label=f"roll {roll:.0f}, pitch {pitch:.0f} deg")
        ax.set(xlabel="insertion (mm)", ylabel=f"{name} ({unit})", title=name)
        ax.grid(alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="center right", fontsize=8)
    fig.suptitle("Holding effort versus insertion (calibrated gravity): the insertion moves weight along the shaft, "
                 "so roll torque changes only off roll 0,\npitch torque only off pitch 0, the insertion force "
                 "(weight along the shaft) not at all", fontsize=10)
    return save_figure(fig, path)


def stability_maps(surveys: dict, path: str | Path) -> Path:
    """Per survey (title -> StabilitySurvey): the 400 Hz firmware loop's slowest decay rate
    ``-ln(spectral radius) / T`` (1/s; negative = unstable) over roll x pitch, all panels on one
    symmetric colour scale (zero, the stability limit, in the middle), each with its range."""
    decays = {title: -np.log(s.spectral_radius) / FIRMWARE_PERIOD for title, s in surveys.items()}
    limit = max(float(np.abs(d).max()) for d in decays.values()) or 1.0
    size = (5 * len(surveys), 4.3)       # fixed margins, the colour bar 0.75 in from the right edge
    fig, axes = subplots(1, len(surveys), figsize=size, margins=(0.65, 1.5, 0.49, 0.27), squeeze=False,
                         gridspec_kw={"wspace": 0.21})
    for ax, (title, s) in zip(axes[0], surveys.items()):
        decay = decays[title]
        extent = [s.roll_deg[0], s.roll_deg[-1], s.pitch_deg[0], s.pitch_deg[-1]]
        im = ax.imshow(decay, origin="lower", extent=extent, aspect="auto", cmap="RdYlGn", vmin=-limit, vmax=limit)
        if decay.min() < 0 < decay.max():
            ax.contour(s.roll_deg, s.pitch_deg, decay, levels=[0.0], colors="k", linewidths=1.0)
        verdict = ("unstable everywhere" if decay.max() <= 0 else "unstable in part" if decay.min() <= 0
                   else "stable, barely (under 1 % of the scale)" if decay.min() < 0.01 * limit else "stable")
        ax.text(0.03, 0.04, f"decay {decay.min():+.3g} to {decay.max():+.3g} 1/s\n{verdict}",
                transform=ax.transAxes, fontsize=8, bbox={"facecolor": "white", "alpha": 0.85, "lw": 0})
        ax.set(xlabel="roll (deg)", ylabel="pitch (deg)", title=title)
    bar = fig.add_axes((1 - 0.75 / size[0], 0.49 / size[1], 0.18 / size[0], 1 - 0.76 / size[1]))
    fig.colorbar(im, cax=bar, label="slowest decay rate, 1/s (< 0 unstable; one scale for all)")
    return save_figure(fig, path)


def tracking_figure(result, path: str | Path, title: str = "") -> Path:
    """Thesis Figs 5.2-5.5 and 5.8-5.9: reference and measured angle per axis (top) and the
    tracking error (bottom), with the PWM sent on a second axis. One figure per process, drawn
    again with each result's data (:func:`_tracking_canvas`): its axes keep their tick objects and
    its canvas its text layouts, about 40 % of a drawing; the same pixels as a new figure's."""
    fig, axes, twins, lines, grid_made = _tracking_canvas()
    for i, axis in enumerate(("roll", "pitch")):
        reference, measured, error, pwm = lines[i]
        reference.set_data(result.time, result.reference[:, i])
        measured.set_data(result.time, result.measured[:, i])
        measured.set_label(f"measured ({result.controller})")
        error.set_data(result.time, result.error[:, i])
        pwm.set_data(result.time, result.pwm[:, i])
        axes[0, i].set_title(f"{title} {axis}".strip())
    for ax in (*axes.ravel(), *twins):
        ax.relim()
    for ax in (*axes.ravel(), *twins):
        ax.autoscale_view()
    for legend in list(fig.legends):
        legend.remove()
    handles = [h for ax in (axes[0, 0], axes[1, 0], twins[-1]) for h in ax.get_legend_handles_labels()[0]]
    fig.legend(handles=handles, loc="outside upper center", ncol=len(handles), fontsize=8)   # off the curves
    grid = axes[0, 0].get_subplotspec().get_gridspec()
    grid.update(**grid_made)             # the fixed margins again: save_figure widens them where labels need it
    fig.subplots_adjust()
    return save_figure(fig, path)


@functools.cache
def _tracking_canvas() -> tuple:
    """The tracking figure's figure, axes (2 x 2), the bottom axes' PWM twins, each column's lines
    (reference, measured, error, PWM), without data (:func:`tracking_figure` sets them), and its
    grid's parameters as made (left, right, wspace)."""
    fig, axes = subplots(2, 2, figsize=(11, 6.4), sharex=True, margins=(0.83, 0.72, 0.48, 0.55),
                         gridspec_kw={"wspace": 0.4, "hspace": 0.05})
    grid = axes[0, 0].get_subplotspec().get_gridspec()
    grid_made = {"left": grid.left, "right": grid.right, "wspace": grid.wspace}
    twins, lines = [], []
    for i, axis in enumerate(("roll", "pitch")):
        top, bottom = axes[0, i], axes[1, i]
        reference, = top.plot([], [], "k--", lw=1.2, label="reference")
        measured, = top.plot([], [], lw=1.2)
        top.set(ylabel=f"{axis} (deg)")
        error, = bottom.plot([], [], color="tab:red", lw=1.0, label="error")
        bottom.set(xlabel="time (s)", ylabel="error (deg)")
        pwm_axes = bottom.twinx()
        pwm, = pwm_axes.plot([], [], color="tab:gray", lw=0.6, alpha=0.6, label="PWM sent (right axis)")
        pwm_axes.set_ylabel("PWM (counts)", color="tab:gray")
        for ax in (top, bottom):
            ax.grid(alpha=0.3)
        twins.append(pwm_axes)
        lines.append((reference, measured, error, pwm))
    return fig, axes, tuple(twins), tuple(lines), grid_made


def error_comparison_figure(results: list, path: str | Path, title: str = "") -> Path:
    """Thesis Figs 5.6/5.7 and 5.10/5.11: the tracking error of several controllers per axis."""
    fig, axes = subplots(1, 2, figsize=(11, 3.6), margins=(0.85, 0.1, 0.49, 0.27), gridspec_kw={"wspace": 0.19})
    for i, (ax, axis) in enumerate(zip(axes, ("roll", "pitch"))):
        for r in results:
            ax.plot(r.time, r.error[:, i], lw=1.0, label=r.controller)
        ax.set(xlabel="time (s)", ylabel=f"{axis} error (deg)", title=f"{title} {axis}".strip())
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    return save_figure(fig, path)


def barrier_figure(runs: dict, path: str | Path) -> Path:
    """Barrier value along each safety scenario (``{scenario: {filter: SafetyRun}}``): B <= 0 is
    safe; the unfiltered run shows where the nominal controller would have gone."""
    fig, axes = subplots(1, len(runs), figsize=(4.2 * len(runs), 3.4), margins=(0.78, 0.1, 0.49, 0.27),
                         squeeze=False, gridspec_kw={"wspace": 0.3})
    for ax, (scenario, by_filter) in zip(axes[0], runs.items()):
        for name, run in by_filter.items():
            ax.plot(run.time, run.barrier, lw=1.0, label=name, ls=":" if name == "none" else "-")
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set(title=scenario, xlabel="time (s)", ylabel="B (> 0 unsafe)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    return save_figure(fig, path)


def torque_heatmaps(tmap, path: str | Path, drive=None, most: int = 6, image_samples: int = IMAGE_SAMPLES,
                    contour_samples: int = CONTOUR_SAMPLES) -> Path:
    """Holding-torque heat maps of a :class:`~rcm_kin.statics.holding.TorqueMap` (any robot, any two
    joints): one panel per actuated joint that carries a load over the grid (at most ``most``, in
    the robot's order), ``joint_a`` up, ``joint_b`` across (degrees for revolute joints, m for
    prismatic). With a drive (``drive``, default the map's ``params``) a driven joint's colour bar has a second
    scale in PWM counts (hardware sign). Large grids are drawn from samples as :func:`effort_heatmaps`."""
    drive = tmap.params if drive is None else drive
    scale = float(np.abs(tmap.tau).max()) if tmap.tau.size else 0.0
    loaded = [k for k in range(len(tmap.actuated)) if np.abs(tmap.tau[..., k]).max() > 1e-9 + 1e-6 * scale]
    shown = (loaded or [0])[:most]
    cols = min(3, len(shown))
    rows_n = -(-len(shown) // cols)
    fig, axes = subplots(rows_n, cols, figsize=(5.2 * cols, 4.3 * rows_n), margins=(0.75, 0.97, 0.49, 0.62),
                         squeeze=False, gridspec_kw={"wspace": 0.48, "hspace": 0.22})
    axis = [np.degrees(v) if u == "rad" else v for v, u in zip(tmap.values, tmap.units)]
    label = [f"{j} ({'deg' if u == 'rad' else 'm'})" for j, u in zip(tmap.joints, tmap.units)]
    extent = [*_span(axis[1]), *_span(axis[0])]
    rows, cols_i = (spread_samples(v.size, contour_samples) for v in axis)
    pixels = tuple(slice(None, None, image_stride(v.size, image_samples)) for v in axis)
    for ax, k in zip(axes.ravel(), shown):
        joint, data = tmap.actuated[k], tmap.tau[..., k]
        limit = max(float(np.abs(data).max()), 1e-12)
        im = ax.imshow(data[pixels], origin="lower", extent=extent, aspect="auto", cmap="coolwarm",
                       vmin=-limit, vmax=limit)
        if min(data.shape) >= 2:
            ax.contour(axis[1][cols_i], axis[0][rows], data[np.ix_(rows, cols_i)], colors="k", linewidths=0.5,
                       levels=contour_levels(data, 9))
        ax.set(xlabel=label[1], ylabel=label[0], title=f"{joint} holding torque")
        unit = tmap.tau_units[k]
        driven = drive is not None and joint in tmap.driven      # room for the PWM scale left of the bar
        bar = fig.colorbar(im, ax=ax, label=f"{'force' if unit == 'N' else 'torque'} ({unit})", fraction=0.05,
                           pad=0.2 if driven else 0.05)
        if driven:
            gain = drive[joint].pwm_per_torque
            bar.ax.secondary_yaxis("left", functions=(lambda t, c=gain: t * c, lambda p, c=gain: p / c)).set_ylabel(
                "PWM (counts, hardware sign)")
    for ax in axes.ravel()[len(shown):]:
        ax.set_visible(False)
    fig.suptitle(f"{tmap.robot}: holding torque over {tmap.joints[0]} x {tmap.joints[1]} ({tmap.model})")
    return save_figure(fig, path)

