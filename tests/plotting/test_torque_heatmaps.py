"""``torque_heatmaps``: one panel per loaded joint of any robot's torque map, each image the map's own
torque (checked against the array drawn), a PWM scale only where a drive is described."""

from __future__ import annotations

import numpy as np

from rcm_kin import load_robot
from rcm_kin import plotting as figures
from rcm_kin.statics.holding import torque_map


def drawn(monkeypatch, tmap):
    built = []
    monkeypatch.setattr(figures, "save_figure", lambda fig, path: built.append(fig) or path)
    figures.torque_heatmaps(tmap, "unused.png")
    return built[0]


def test_one_panel_per_loaded_joint_with_its_torque(monkeypatch):
    mtm = load_robot("mtm")
    tmap = torque_map(mtm, {"j2": np.radians(np.linspace(-40, 60, 6)), "j3": np.radians(np.linspace(-30, 80, 5))},
                      q=np.radians([20, 0, 0, 0, 0, 0, 0]))
    fig = drawn(monkeypatch, tmap)
    panels = [ax for ax in fig.axes if ax.get_visible() and ax.get_title().endswith("holding torque")]
    loaded = [j for k, j in enumerate(mtm.actuated) if np.abs(tmap.tau[..., k]).max() > 1e-9]
    assert [ax.get_title().split()[0] for ax in panels] == loaded[:6]
    for ax in panels:
        k = mtm.actuated.index(ax.get_title().split()[0])
        np.testing.assert_array_equal(ax.images[0].get_array(), tmap.tau[..., k])
        assert ax.get_xlabel() == "j3 (deg)" and ax.get_ylabel() == "j2 (deg)"
    assert not any("PWM" in a.get_ylabel() for a in fig.axes)


def test_a_driven_joint_has_its_pwm_scale(monkeypatch):
    psm = load_robot("psm")
    tmap = torque_map(psm, {"roll": np.radians([-20, 0, 20]), "pitch": np.radians([-10, 10])}, q=[0, 0, 0.08, 0, 0, 0,
                                                                                                   0])
    fig = drawn(monkeypatch, tmap)
    labels = [a.get_ylabel() for a in fig.axes] + [c.get_ylabel() for a in fig.axes for c in a.child_axes]
    assert sum("PWM" in label for label in labels) == 3          # roll, pitch, insertion
    assert "calibration psm_drive.toml" in fig._suptitle.get_text()
