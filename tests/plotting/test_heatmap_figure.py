"""The torque map's heat maps (``effort_heatmaps``): a large grid drawn from samples (the image
from every k-th pose, the contour lines from at most ``CONTOUR_SAMPLES`` poses per axis, levels
and colours from the whole grid) looks as the whole grid's rendering does (pixel-wise); small
maps are drawn from the whole grid, as the plain matplotlib calls draw them."""

from __future__ import annotations

import matplotlib.axes
import numpy as np
import pytest
from PIL import Image

from rcm_kin import load_robot
from rcm_kin import plotting as figures
from rcm_kin.dynamics.drive import load_drive_parameters
from rcm_kin.statics.maps import gravity_map

PANELS = (("roll", 0), ("pitch", 1))   # (joint, index in the map's driven joints), as drawn


@pytest.fixture(scope="module")
def psm_drive():
    return load_robot("psm"), load_drive_parameters()


def drawn(monkeypatch, gmap, drive, **options):
    """The figure ``effort_heatmaps`` builds (not saved) and the (x, y, z) of each contour call."""
    built, traced = [], []
    monkeypatch.setattr(figures, "save_figure", lambda fig, path: built.append(fig) or path)
    contour = matplotlib.axes.Axes.contour

    def recording(ax, x, y, z, **kwargs):
        traced.append((x, y, z))
        return contour(ax, x, y, z, **kwargs)

    monkeypatch.setattr(matplotlib.axes.Axes, "contour", recording)
    figures.effort_heatmaps(gmap, drive, "not-written.png", **options)
    monkeypatch.undo()
    return built[0], traced


def plain_contour(x, y, z):
    """matplotlib's own contour of the whole data, 9 levels, on a figure of its own."""
    _, ax = figures.subplots(figsize=(6.4, 4.8))
    return ax.contour(x, y, z, levels=9)


def panels(fig, traced):
    """(axes, (x, y, z) of its contour, joint, joint index) of each heat map, in :data:`PANELS` order."""
    by_title = {ax.get_title(): ax for ax in fig.axes if ax.get_label() != "<colorbar>"}
    assert len(by_title) == len(traced) == 2
    return [(by_title[f"{joint} holding PWM"], xyz, joint, k) for xyz, (joint, k) in zip(traced, PANELS)]


def test_small_map_is_drawn_from_the_whole_grid(psm_drive, monkeypatch):
    gmap = gravity_map(*psm_drive, np.linspace(-30, 30, 61), np.linspace(-20, 25, 41), [0.1])
    fig, traced = drawn(monkeypatch, gmap, psm_drive[1])
    for ax, (x, y, z), joint, k in panels(fig, traced):
        data = gmap.effort.pwm[:, :, 0, k]
        image = ax.images[0]
        assert np.array_equal(image.get_array(), data)                 # the image: every pose
        assert image.get_clim() == (-np.abs(data).max(), np.abs(data).max())
        assert np.array_equal(x, gmap.roll_deg) and np.array_equal(y, gmap.pitch_deg) and np.array_equal(z, data)
        ours, plain = ax.collections[0], plain_contour(gmap.roll_deg, gmap.pitch_deg, data)
        assert np.array_equal(ours.levels, plain.levels)                # matplotlib's own choice of 9 levels
        for a, b in zip(ours.get_paths(), plain.get_paths(), strict=True):
            assert np.array_equal(a.vertices, b.vertices)


def pixel_difference(a, b) -> tuple[float, float, float]:
    """Mean and largest absolute difference (of 255) of two PNGs' RGB values, and the fraction of
    pixels that differ at all."""
    a, b = (np.asarray(Image.open(p).convert("RGB"), dtype=float) for p in (a, b))
    assert a.shape == b.shape == (506, 1210, 3)
    difference = np.abs(a - b)
    return difference.mean(), difference.max(), (difference.max(axis=2) > 0).mean()


def test_large_map_drawn_from_samples_looks_the_same(psm_drive, monkeypatch, tmp_path):
    """801 x 801: the image from every second pose (401, both ends), the contours traced on 301
    poses per axis (every third but for the last one, which must still be drawn). Against the whole
    grid's rendering, measured: contours alone sampled, mean absolute difference 0.0025 of 255, at
    most 2, on 0.4 % of the pixels (where a line moves by a fraction of a pixel); image and
    contours sampled, mean 0.035, at most 3, on 7.7 %. Asserted: mean < 0.01, max <= 4, under 1 %;
    mean < 0.06, max <= 4, under 10 %."""
    grid = np.linspace(-30, 30, 801)
    gmap = gravity_map(*psm_drive, grid, grid, [0.08])
    fig, traced = drawn(monkeypatch, gmap, psm_drive[1])
    for ax, (x, y, z), joint, k in panels(fig, traced):
        data = gmap.effort.pwm[:, :, 0, k]
        assert np.array_equal(ax.images[0].get_array(), data[::2, ::2])
        assert ax.images[0].get_extent() == [-30.0, 30.0, -30.0, 30.0]
        assert ax.images[0].get_clim() == (-np.abs(data).max(), np.abs(data).max())
        assert z.shape == (y.size, x.size) and 200 <= x.size <= figures.CONTOUR_SAMPLES
        assert (x[0], x[-1], y[0], y[-1]) == (-30.0, 30.0, -30.0, 30.0)
        rows, cols = (np.searchsorted(grid, v) for v in (y, x))
        assert np.array_equal(z, data[np.ix_(rows, cols)])
        levels = ax.collections[0].levels
        assert np.array_equal(levels, plain_contour(grid, grid, data).levels)   # the whole grid's levels
    drive = psm_drive[1]
    whole = figures.effort_heatmaps(gmap, drive, tmp_path / "whole.png", image_samples=801, contour_samples=801)
    contours = figures.effort_heatmaps(gmap, drive, tmp_path / "contours.png", image_samples=801)
    sampled = figures.effort_heatmaps(gmap, drive, tmp_path / "sampled.png")
    mean, largest, share = pixel_difference(contours, whole)
    assert mean < 0.01 and largest <= 4 and share < 0.01
    mean, largest, share = pixel_difference(sampled, whole)
    assert mean < 0.06 and largest <= 4 and share < 0.1


def test_contour_levels_are_matplotlibs(psm_drive):
    """The levels of ``contour(levels=9)`` on data of several ranges, one near-constant."""
    rng = np.random.default_rng(3)
    for data in (rng.normal(size=(20, 30)), 1e3 * rng.uniform(size=(5, 5)) - 7.0,
                 np.full((4, 6), 2.5) + 1e-9 * np.arange(24).reshape(4, 6)):
        x, y = np.arange(data.shape[1]), np.arange(data.shape[0])
        assert np.array_equal(figures.contour_levels(data, 9), plain_contour(x, y, data).levels)


def test_image_stride_keeps_both_ends():
    assert [figures.image_stride(n, 401) for n in (61, 400, 801, 1001, 1000, 1201)] == [1, 1, 2, 2, 1, 3]
    assert figures.image_stride(998, 401) == 1          # 997 is prime: every pose


def test_spread_samples():
    assert np.array_equal(figures.spread_samples(5, 301), np.arange(5))
    assert np.array_equal(figures.spread_samples(7, 4), [0, 2, 4, 6])
    picked = figures.spread_samples(1001, 301)
    assert picked.size == 301 and picked[0] == 0 and picked[-1] == 1000 and np.all(np.diff(picked) >= 3)


def test_contours_on_samples_keep_the_whole_grids_levels_and_colours(psm_drive, monkeypatch):
    """A field whose peak lies between the samples (41 poses per axis traced on 11): the levels and
    the colour limits are the whole grid's, not the samples' (which would be lower)."""
    from rcm_kin.dynamics.drive import DriveEffort
    from rcm_kin.statics.maps import GravityMap

    grid = np.linspace(-30, 30, 41)
    field = np.add.outer(np.sin(np.radians(3 * grid)), np.cos(np.radians(2 * grid)))
    field[1, 2] = 9.0                                         # pose (1, 2): not one of the samples
    stack = np.repeat(field[:, :, None, None], 3, axis=3)
    gmap = GravityMap(grid, grid, np.array([0.08]), DriveEffort(*([stack] * 5), stack > 0))
    fig, traced = drawn(monkeypatch, gmap, psm_drive[1], contour_samples=11)
    for ax, (x, y, z), _, _ in panels(fig, traced):
        assert x.size == y.size == 11 and z.max() < 3.0
        assert np.array_equal(ax.collections[0].levels, plain_contour(grid, grid, field).levels)
        assert not np.array_equal(ax.collections[0].levels, plain_contour(x, y, z).levels)
        assert ax.images[0].get_clim() == (-9.0, 9.0)


def test_colour_bars_read_the_drives_voltage(psm_drive, monkeypatch):
    """Each colour bar's second scale (V) puts the voltage the drive model gives at the pose of the
    panel's largest |PWM| level with that PWM (both ends of the bar, sign included), to 1e-9 of
    the bar's height."""
    gmap = gravity_map(*psm_drive, np.linspace(-30, 30, 31), np.linspace(-30, 30, 21), [0.12])
    fig, traced = drawn(monkeypatch, gmap, psm_drive[1])
    fig.canvas.draw()
    for ax, _, joint, k in panels(fig, traced):
        pwm, voltage = (getattr(gmap.effort, q)[:, :, 0, k].ravel() for q in ("pwm", "voltage"))
        at = np.argmax(np.abs(pwm))
        bar = ax.images[0].colorbar.ax
        (volts,) = bar.child_axes
        assert volts.get_ylabel() == "motor voltage (V)"
        height = bar.get_window_extent().height
        for end in (1.0, -1.0):                              # PWM = +-max|PWM|: the same pose up to sign
            on_bar = bar.transData.transform((0.0, end * abs(pwm[at])))[1]
            on_volts = volts.transData.transform((0.0, end * np.sign(pwm[at]) * voltage[at]))[1]
            assert abs(on_bar - on_volts) < 1e-9 * height
