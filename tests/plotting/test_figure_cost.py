"""What a figure costs (issue 30): matplotlib is imported only when a figure is drawn, and then not
pyplot (its figure managers and backend switch) but the ``Figure`` and the Agg canvas; the
torque map's and the report's figures are drawn on fixed margins (no layout engine solving them at
each draw) that keep every label inside the figure and apart from the others."""

from __future__ import annotations

import itertools
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from rcm_kin import apart, figure_layout, load_robot
from rcm_kin import plotting as figures
from rcm_kin.dynamics.drive import load_drive_parameters
from rcm_kin.statics.holding import torque_map
from rcm_kin.statics.maps import gravity_map, write_gravity_maps


def imported_by(*argv: str) -> set[str]:
    """The modules a fresh interpreter holds after ``rcm-kin argv`` (which must succeed)."""
    code = ("import sys; from rcm_kin.cli import main; code = main(sys.argv[1:]); "
            "print(code, ' '.join(sorted(sys.modules)))")
    out = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, check=True).stdout
    status, _, modules = out.strip().rpartition("\n")[2].partition(" ")
    assert status == "0", out
    return set(modules.split())


def test_torque_map_imports_matplotlib_only_to_draw_and_never_pyplot(tmp_path):
    grid = ["--roll=-10:10:5", "--pitch=-10:10:5"]
    tables = imported_by("torque-map", "psm", *grid, "--out", str(tmp_path / "tables"), "--no-figures")
    assert not {m for m in tables if m.split(".")[0] in ("matplotlib", "mpl_toolkits")}
    drawn = imported_by("torque-map", "psm", *grid, "--out", str(tmp_path / "figures"))
    assert {"matplotlib.figure", "matplotlib.backends.backend_agg"} <= drawn
    assert "matplotlib.pyplot" not in drawn
    assert {p.name for p in (tmp_path / "figures").glob("*.png")} == {"torque_map.png", "trend_curves.png",
                                                                      "insertion_map.png"}


def drawn_texts(fig) -> tuple[list, list]:
    """The labels (titles, axis labels, the figure's title) and all the texts drawn (those and the
    tick labels of the ticks in view, offset texts, legends) of a drawn figure, with their boxes in
    pixels."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    every_axes = [a for ax in fig.axes for a in (ax, *ax.child_axes) if a.get_visible()]
    labels = [fig._suptitle] + [t for a in every_axes for t in (a.title, a.xaxis.label, a.yaxis.label)]
    others = [t for a in every_axes for t in (a.xaxis.offsetText, a.yaxis.offsetText, *in_view(a, renderer))]
    others += [t for legend in [*fig.legends, *(a.get_legend() for a in every_axes)] if legend for t in legend.texts]
    boxed = [[(t, t.get_window_extent(renderer)) for t in group if t is not None and t.get_visible()
              and t.get_text().strip()] for group in (labels, others)]
    return boxed[0], boxed[0] + boxed[1]


def in_view(ax, renderer) -> list:
    """The tick labels of ``ax`` that are drawn: those beside the axes (the others are laid out
    for ticks beyond its limits and not drawn)."""
    box = ax.get_window_extent(renderer)
    x = [t for t in ax.xaxis.get_majorticklabels() if box.x0 - 1 <= t.get_window_extent(renderer).x0 / 2
         + t.get_window_extent(renderer).x1 / 2 <= box.x1 + 1]
    y = [t for t in ax.yaxis.get_majorticklabels() if box.y0 - 1 <= t.get_window_extent(renderer).y0 / 2
         + t.get_window_extent(renderer).y1 / 2 <= box.y1 + 1]
    return x + y


def assert_laid_out(fig) -> None:
    """No layout engine; everything drawn inside the figure; titles and axis labels overlap no
    other text by more than 2 pixels (tick labels of one axis may touch each other: matplotlib's choice)."""
    assert fig.get_layout_engine() is None
    labels, texts = drawn_texts(fig)
    width, height = fig.get_size_inches()
    drawn = fig.get_tightbbox(fig.canvas.get_renderer())            # inches
    assert drawn.x0 >= -0.01 and drawn.y0 >= -0.01 and drawn.x1 <= width + 0.01 and drawn.y1 <= height + 0.01, drawn
    for (a, box_a), (b, box_b) in itertools.product(labels, texts):      # boxes with their descent: 2 px spare
        overlap = a is not b and box_a.padded(-1.0).overlaps(box_b.padded(-1.0))
        assert not overlap, f"{a.get_text()!r} overlaps {b.get_text()!r}"


@pytest.fixture(scope="module")
def psm_maps():
    robot, drive = load_robot("psm"), load_drive_parameters()
    grid = np.linspace(-30, 30, 61)
    return robot, drive, gravity_map(robot, drive, grid, grid, [0.08])


def built(monkeypatch, draw, *arguments) -> list:
    """The figures ``draw(*arguments)`` saves, not written (all drawn in this process)."""
    saved = []
    monkeypatch.setattr(figures, "save_figure", lambda fig, path: saved.append(fig) or path)
    monkeypatch.setattr(apart, "cores", lambda: 1)
    draw(*arguments)
    monkeypatch.undo()
    return saved


def test_the_torque_maps_figures_have_their_panels_and_labels(psm_maps, monkeypatch, tmp_path):
    robot, drive, _ = psm_maps
    saved = built(monkeypatch, write_gravity_maps, robot, drive, np.linspace(-30, 30, 61), np.linspace(-30, 30, 61),
                  0.08, tmp_path)
    heat, trends, insertion = saved
    assert [a.get_title() for a in heat.axes if a.get_title()] == ["roll holding PWM", "pitch holding PWM"]
    assert [a.get_title().split(" (")[0] for a in trends.axes] == ["roll holding voltage", "pitch holding voltage"]
    assert [a.get_ylabel() for a in insertion.axes] == ["roll holding torque (N m)", "pitch holding torque (N m)",
                                                        "insertion holding force (N)"]
    for fig in saved:
        assert_laid_out(fig)


def tracking_result(scale: float) -> SimpleNamespace:
    time = np.linspace(0.0, 4.0, 401)
    wave = np.column_stack([np.sin(time), np.cos(time)]) * scale
    return SimpleNamespace(time=time, reference=wave, measured=0.9 * wave, error=0.1 * wave, pwm=-80.0 * wave / scale,
                           controller="scheduled-gravity")


def report_figures(monkeypatch, scale: float, draw=built) -> list:
    """The report's figures on fixed margins, from data ``scale`` times the usual."""
    result = tracking_result(scale)
    survey = SimpleNamespace(roll_deg=np.linspace(-20, 20, 5), pitch_deg=np.linspace(-15, 15, 4),
                             spectral_radius=np.full((4, 5), 0.99) + 0.02 * np.arange(5) / 4)
    run = SimpleNamespace(time=np.linspace(0, 2, 50), barrier=scale * np.sin(np.linspace(0, 2, 50)) - 0.5 * scale)
    mtm = load_robot("mtm")
    tmap = torque_map(mtm, {"j1": np.radians(np.linspace(-90, 90, 7)), "j3": np.radians(np.linspace(-90, 90, 7))})
    return (draw(monkeypatch, figures.tracking_figure, result, "t.png", "target, scheduled-gravity:")
            + draw(monkeypatch, figures.error_comparison_figure, [result, result], "e.png", "target:")
            + draw(monkeypatch, figures.stability_maps, {"model-based": survey, "thesis gains": survey,
                                                         "thesis gains, Kd sign flipped": survey}, "s.png")
            + draw(monkeypatch, figures.barrier_figure, {k: {"qp": run, "none": run} for k in ("a", "b", "c")},
                   "b.png")
            + draw(monkeypatch, figures.torque_heatmaps, tmap, "m.png"))


@pytest.mark.parametrize("scale", [1.0, 1e3])
def test_the_reports_figures_keep_their_labels_inside_and_apart(monkeypatch, scale):
    for fig in report_figures(monkeypatch, scale):
        assert figure_layout.shortfall(fig) == (0.0, 0.0, 0.0)
        assert_laid_out(fig)


def test_labels_wider_than_the_margins_widen_them(monkeypatch, tmp_path):
    """Tick labels such as -0.000075 do not fit the fixed margins: those figures are saved with
    their margins or columns widened, nothing outside them and no label on another; the others
    keep their margins."""
    def saved(monkeypatch, draw, *arguments):
        kept, save = [], figures.save_figure
        monkeypatch.setattr(figures, "save_figure", lambda fig, path: kept.append(fig) or save(fig, tmp_path / path))
        draw(*arguments)
        monkeypatch.undo()
        return kept

    narrow = [max(figure_layout.shortfall(fig)) > 0 for fig in report_figures(monkeypatch, 1e-3)]
    assert narrow == [True, True, False, True, False]
    for fig in report_figures(monkeypatch, 1e-3, saved):
        assert max(figure_layout.shortfall(fig)) < 1e-9
        assert_laid_out(fig)


def test_the_width_of_a_y_axis_is_read_from_its_labels(monkeypatch):
    """The estimate of a y axis's width from its tick labels' text is never short of the drawn
    width and at most 0.07 in over it, on axes with labels of 2 to 9 characters."""
    for fig in report_figures(monkeypatch, 1.0) + report_figures(monkeypatch, 1e-3):
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        for ax in fig.axes:
            if ax.name != "rectilinear" or not ax.get_ylabel():
                continue
            drawn, box = ax.yaxis.get_tightbbox(renderer), ax.get_window_extent(renderer)
            width = (box.x0 - drawn.x0 if ax.yaxis.get_ticks_position() != "right" else drawn.x1 - box.x1) / fig.dpi
            assert width - 0.01 <= figure_layout.y_axis_width(ax) <= width + 0.07, (ax.get_ylabel(), width)


def test_subplots_margins_are_inches_from_the_edges():
    fig, axes = figures.subplots(1, 2, figsize=(10.0, 4.0), margins=(1.0, 0.5, 0.8, 0.4), gridspec_kw={"wspace": 0.2})
    assert fig.get_layout_engine() is None and type(fig.canvas).__name__ == "FigureCanvasAgg"
    left, right = axes[0].get_position(), axes[1].get_position()
    np.testing.assert_allclose([left.x0 * 10, (1 - right.x1) * 10, left.y0 * 4, (1 - left.y1) * 4],
                               [1.0, 0.5, 0.8, 0.4])


def pixels(fig) -> np.ndarray:
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba()).copy()


def panels(kind: str):
    """A figure whose titled axes has: nothing above it (``plain``), a y offset text (``offset``),
    x ticks on top (``top``), a twin with its x axis on top (``twin``), or a title that would
    overlap the offset text (``wide``)."""
    fig, (ax, other) = figures.subplots(1, 2, figsize=(8, 3), margins=(0.7, 0.2, 0.5, 0.5))
    values = {"offset": [2.1000, 2.1003], "wide": [1e-6, 3e-6]}.get(kind, [0.0, 1.0])
    ax.plot([0, 1], values)
    other.plot([0, 1], [1.0, 0.0])
    ax.set_title("a title as wide as the whole panel, from one side to the other" if kind == "wide" else "title")
    other.set_title("other")
    if kind == "top":
        ax.xaxis.tick_top()
    if kind == "twin":
        ax.twiny().plot([5, 6], [0, 1])
    return fig, ax
