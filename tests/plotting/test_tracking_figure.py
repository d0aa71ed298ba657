"""The tracking figure is one figure per process, drawn again with each result's data: what it
shows does not depend on what it showed before."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from PIL import Image

from rcm_kin import plotting


def result(n: int, scale: float, controller: str) -> SimpleNamespace:
    time = np.linspace(0.0, 0.01 * (n - 1), n)
    wave = np.column_stack([np.sin(3 * time), np.cos(2 * time)]) * scale
    return SimpleNamespace(time=time, reference=wave, measured=0.9 * wave, error=0.1 * wave * scale,
                           pwm=-80.0 * wave / scale, controller=controller)


def test_a_tracking_figure_drawn_again_is_the_new_figure_pixel_for_pixel(tmp_path):
    """Drawn after results of other lengths, scales (margins widened for -0.000075-like labels)
    and controllers, a result's figure has the pixels of that result's figure drawn first."""
    runs = [result(801, 1.0, "p"), result(400, 1e-3, "scheduled"), result(1201, 30.0, "scheduled-gravity")]
    again = [plotting.tracking_figure(r, tmp_path / f"again_{k}.png", f"sine, {r.controller}:")
             for k, r in enumerate(runs + runs[:2])]
    for k, r in enumerate(runs):
        plotting._tracking_canvas.cache_clear()
        first = plotting.tracking_figure(r, tmp_path / f"first_{k}.png", f"sine, {r.controller}:")
        for drawn in (again[k], again[k + 3]) if k < 2 else (again[k],):
            assert np.array_equal(np.asarray(Image.open(drawn)), np.asarray(Image.open(first))), (k, drawn.name)
    legend = plotting._tracking_canvas()[0].legends
    assert len(legend) == 1 and [t.get_text() for t in legend[0].texts] == [
        "reference", "measured (scheduled-gravity)", "error", "PWM sent (right axis)"]
