"""``rcm-kin export``: what the MJCF file says, read as XML (no MuJoCo needed), and the CLI's errors.
MuJoCo's own checks of the file are in test_mjcf.py."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from rcm_kin.cli import main
from rcm_kin.model import load_robot


def test_psm_mjcf_closes_loops_with_connect_and_drives_with_motors(tmp_path, params):
    assert main(["export", "psm", "--mjcf", str(tmp_path / "psm.xml")]) == 0
    root = ET.parse(tmp_path / "psm.xml").getroot()
    psm = load_robot("psm")
    assert [c.get("name") for c in root.find("equality")] == [loop.name for loop in psm.description.loops]
    assert {c.tag for c in root.find("equality")} == {"connect"}          # no joint couplings
    assert [(m.tag, m.get("name"), m.get("joint"), m.get("gear")) for m in root.find("actuator")] == \
        [("motor", j, j, "1") for j in psm.actuated]
    # the driven motors saturate where the firmware's PWM does: PWM = R tau / (k_t N volts_per_pwm)
    for motor in root.find("actuator"):
        if motor.get("name") in ("roll", "pitch", "insertion"):
            d = params[motor.get("name")]
            limit = d.pwm_limit * d.torque_constant * d.gear_ratio * d.volts_per_pwm / d.resistance
            np.testing.assert_allclose(np.array(motor.get("forcerange").split(), dtype=float), [-limit, limit],
                                       rtol=1e-14)
        else:
            assert motor.get("forcerange") is None
    joints = {j.get("name"): j for j in root.iter("joint")}
    assert float(joints["roll"].get("damping")) == params["roll"].viscous
    assert float(joints["pitch"].get("frictionloss")) == params["pitch"].coulomb
    assert float(joints["roll"].get("armature")) == params["roll"].reflected_inertia
    assert joints["lower_fork_joint"].get("damping") is None             # passive: no drive
    keys = {k.get("name"): np.array(k.get("qpos").split(), dtype=float) for k in root.iter("key")}
    assert len(keys) == 10 and "roll30_pitch-30" in keys


def test_davinci_mimic_parallelogram_becomes_joint_equalities(tmp_path):
    assert main(["export", "davinci", "--mjcf", str(tmp_path / "d.xml")]) == 0
    equality = ET.parse(tmp_path / "d.xml").getroot().find("equality")
    assert [(e.tag, e.get("joint1"), e.get("joint2")) for e in equality] == \
        [("joint", "upper_bar", "hand_pitch"), ("joint", "instrument_holder", "hand_pitch")]


def test_export_errors_are_one_line(tmp_path, capsys):
    assert main(["export", "psm"]) == 2
    assert capsys.readouterr().err == "error: choose what to write: --mjcf FILE and/or --c DIR\n"
    assert main(["export", "mtm", "--mjcf", str(tmp_path / "m.xml"), "--params", "x.toml"]) == 2
    assert main(["export", "psm", "--mjcf", str(tmp_path / "no" / "p.xml")]) == 2
    assert main(["export", "nobot", "--mjcf", str(tmp_path / "p.xml")]) == 2
    assert capsys.readouterr().err.count("error: ") == 3
