"""The meshcat page in a real browser: headless Chromium draws the PSM, its parallelogram bars
cover the area their boxes project to, and the picture follows the pose. Skips only where no
Chromium is installed (``.ci/run`` installs Debian's ``chromium``)."""

from __future__ import annotations

import matplotlib.colors as mcolors
import numpy as np
import pinocchio as pin
import pytest
from matplotlib.image import imread

from rcm_kin.cli import main
from rcm_kin.model.reduced import tree_configuration
from rcm_kin.visualization.browser import browser_png, find_browser, side_camera

needs_browser = pytest.mark.skipif(find_browser() is None, reason="no Chromium on PATH (Debian: apt-get install "
                                                                  "chromium; .ci/run installs it)")

SIZE = (800, 600)


def pose(pitch_deg: float) -> np.ndarray:
    return np.array([0.0, np.radians(pitch_deg), 0.08, 0.0, 0.0, 0.0, 0.0])


def bar_boxes(psm, q):
    """The visual boxes in the parallelogram bars' colour (the lower fork's) at ``q``: (colour, [(size, R)])."""
    visual = pin.buildGeomFromUrdf(psm.tree, str(psm.description.urdf), pin.GeometryType.VISUAL)
    data = visual.createData()
    pin.forwardKinematics(psm.tree, psm.tree_data, tree_configuration(psm, q))
    pin.updateGeometryPlacements(psm.tree, psm.tree_data, visual, data)
    colour = visual.geometryObjects[visual.getGeometryId("lower_fork_0")].meshColor[:3]
    boxes = [(2 * np.asarray(o.geometry.halfSide), m.rotation) for o, m in zip(visual.geometryObjects, data.oMg)
             if np.allclose(o.meshColor[:3], colour) and type(o.geometry).__name__ == "Box"]
    return colour, boxes


def projected_area(boxes) -> float:
    """Area (m^2) of the boxes seen along y, orthographic, overlaps counted twice: each box shows
    one face per axis, weighted by |y . axis|."""
    return sum(abs(R[1, k]) * np.prod(np.delete(size, k)) for size, R in boxes for k in range(3))


def colour_mask(png, colour) -> np.ndarray:
    """Pixels of ``colour``'s hue (within 15 deg), shaded any way, saturated (not the greys)."""
    hsv = mcolors.rgb_to_hsv(imread(png)[..., :3])
    hue = mcolors.rgb_to_hsv(np.asarray(colour))[0]
    return (np.abs(hsv[..., 0] - hue) < 15 / 360) & (hsv[..., 1] > 0.4) & (hsv[..., 2] > 0.15)


@pytest.fixture(scope="module")
def shots(psm, tmp_path_factory):
    """Chromium screenshots at pitch -20 and +20 deg, one camera (framed at pitch 0)."""
    folder = tmp_path_factory.mktemp("browser")
    camera = side_camera(psm, pose(0.0))
    return camera, {p: browser_png(psm, pose(p), folder / f"pitch{p}.png", size=SIZE, camera=camera) for p in (-20, 20)}


@needs_browser
def test_chromium_draws_the_parallelogram_bars(psm, shots):
    camera, pngs = shots
    scale = camera.pixels_per_metre(SIZE[1])
    for pitch, png in pngs.items():
        colour, boxes = bar_boxes(psm, pose(pitch))
        expected = projected_area(boxes) * scale**2
        drawn = colour_mask(png, colour).sum()
        # overlaps (forks over the framework, the carriage on its rail) hide some of the boxes, the
        # perspective enlarges what is nearer than the target, shading and antialiasing lose edge
        # pixels: 0.75 to 1.25 of the estimate (measured: 0.97 at -20 deg, 1.04 at +20 deg)
        assert 0.75 * expected < drawn < 1.25 * expected, (pitch, drawn, expected)


@needs_browser
def test_the_picture_follows_the_pose(psm, shots):
    _, pngs = shots
    colour, _ = bar_boxes(psm, pose(0.0))
    low, high = (colour_mask(pngs[p], colour) for p in (-20, 20))
    assert (low ^ high).sum() > 0.3 * (low | high).sum()
    # pitching forward (+) carries the bars' centroid to the right of the picture (+x seen from -y)
    assert np.nonzero(high)[1].mean() > np.nonzero(low)[1].mean()


@needs_browser
def test_view_cli_browser_renderer(tmp_path, capsys):
    assert main(["view", "mtm", "--q", "0.3", "0.2", "--png", str(tmp_path / "m.png"), "--renderer", "browser"]) == 0
    image = imread(tmp_path / "m.png")
    assert image.shape[:2] == (SIZE[1], SIZE[0]) and (image[..., :3] < 0.9).any()


def test_without_a_browser_the_renderer_says_what_to_install(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))          # no browser on it
    assert main(["view", "psm", "--png", str(tmp_path / "p.png"), "--renderer", "browser"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: no Chromium") and "apt-get install chromium" in err and err.count("\n") == 1


FAKE_CHROMIUM = """#!/bin/sh
# a stand-in for Chromium: logs like it, exits 0, and writes {writes} to the --screenshot path
for a in "$@"; do case "$a" in --screenshot=*) out="${{a#--screenshot=}}";; esac; done
echo '[12577:12610:1129/211500.123456:ERROR:bus.cc(407)] Failed to connect to the bus' >&2
echo '[12577:12610:1129/211500.234567:ERROR:headless_shell.cc(215)] Failed to write file' >&2
echo '[12577:12577:1129/211500.345678:WARNING:sandbox_linux.cc(430)] InitializeSandbox() called' >&2
{write}
exit 0
"""
WRITES = {"nothing": "", "text": 'echo "not a picture" > "$out"',
          "png": "printf '\\211PNG\\r\\n\\032\\nfake' > \"$out\""}


def fake_chromium(folder, writes: str):
    """A fake ``chromium`` in ``folder`` (put it alone on PATH)."""
    script = folder / "chromium"
    script.write_text(FAKE_CHROMIUM.format(writes=writes, write=WRITES[writes]))
    script.chmod(0o755)


@pytest.mark.parametrize("writes", ["nothing", "text"])
def test_a_browser_that_writes_no_png_is_one_line_error_and_the_old_picture_stays(tmp_path, capsys, monkeypatch,
                                                                                  writes):
    """Chromium exits 0 even when it fails to write: with --force over an existing PNG the command
    still fails (exit 2), on one line without Chromium's log prefix, and leaves the old file as it was."""
    bin_folder = tmp_path / "bin"
    bin_folder.mkdir()
    fake_chromium(bin_folder, writes)
    monkeypatch.setenv("PATH", str(bin_folder))
    old = tmp_path / "p.png"
    old.write_bytes(b"the old picture")
    assert main(["view", "psm", "--png", str(old), "--renderer", "browser", "--force"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ")
    assert err.rstrip().endswith("could not render view.html (no PNG written): Failed to write file")
    assert old.read_bytes() == b"the old picture"


def test_a_png_from_the_browser_is_moved_into_place(tmp_path, capsys, monkeypatch):
    bin_folder = tmp_path / "bin"
    bin_folder.mkdir()
    fake_chromium(bin_folder, "png")
    monkeypatch.setenv("PATH", str(bin_folder))
    png = tmp_path / "p.png"
    png.write_bytes(b"the old picture")
    assert main(["view", "psm", "--png", str(png), "--renderer", "browser", "--force"]) == 0
    assert png.read_bytes() == b"\x89PNG\r\n\x1a\nfake"
    assert capsys.readouterr().out.strip() == f"wrote {png}"
