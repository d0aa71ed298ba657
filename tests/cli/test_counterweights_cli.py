"""``rcm-kin counterweights``: any robot whose sidecar marks a counterweight, one line for bad input."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import numpy as np
import pinocchio as pin
import pytest

from rcm_kin.model.loading import urdf_dir


def run(*args):
    return subprocess.run([sys.executable, "-m", "rcm_kin.cli", *args], capture_output=True, text=True)


def test_mtm_counterweight_placement_is_what_plain_pinocchio_gives_and_beats_as_built():
    """The placed J1 counterweight's RMS shoulder torque, recomputed with plain Pinocchio on the URDF with the
    counterweight moved there, is what the command reports, and below the as-built one."""
    out = run("counterweights", "mtm", "--grid", "j1=-60:60:13", "j3=-30:80:12", "--json")
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)
    assert result["model"] == "CAD (URDF inertias)"
    (design,) = result["counterweights"]
    assert design["link"] == "counterweight" and design["unit"] == "N m"
    j1 = design["joints"].index("j1")
    assert design["rms"][j1] < design["rms_as_built"][j1] < design["rms_without"][j1]
    # independent: plain Pinocchio on the MTM's URDF, the counterweight's mass moved from where it is built
    # to the designed point (both given in the mount link's frame; the mount is fixed to joint j1's body)
    model = pin.buildModelFromUrdf(str(urdf_dir() / "mtm.urdf"))
    data = model.createData()
    mount = model.frames[model.getFrameId(design["mount"])]
    joint, mass = mount.parentJoint, design["mass_kg"]
    point = mount.placement.act(np.array(design["position_m"]))          # in the joint's frame
    as_built = mount.placement.act(np.array(design["as_built_m"]))
    model.inertias[joint] = (model.inertias[joint] - pin.Inertia(mass, as_built, np.zeros((3, 3)))
                             + pin.Inertia(mass, point, np.zeros((3, 3))))
    torques = []
    for a in np.radians(np.linspace(-60, 60, 13)):
        for b in np.radians(np.linspace(-30, 80, 12)):
            q = np.zeros(model.nq)
            q[model.joints[model.getJointId("j1")].idx_q] = a
            q[model.joints[model.getJointId("j3")].idx_q] = b
            torques.append(pin.computeGeneralizedGravity(model, data, q)[model.joints[model.getJointId("j1")].idx_q])
    np.testing.assert_allclose(np.sqrt(np.mean(np.square(torques))), design["rms"][j1], rtol=1e-6)


def test_psm_counterweights_are_weighed_in_pwm_with_its_drive():
    out = run("counterweights", "psm", "--grid", "roll=-30:30:5", "pitch=-30:30:5", "--link", "main_counterweight")
    assert out.returncode == 0, out.stderr
    assert "PWM counts" in out.stdout and out.stdout.rstrip().endswith("model: calibration psm_drive.toml")


@pytest.mark.parametrize("args, match", [
    (("davinci", "--grid", "hand_roll=-10:10:3", "hand_pitch=-10:10:3"), "marks no counterweight link"),
    (("mtm", "--grid", "j1=-60:60:5", "j3=-30:80:5", "--link", "upper_arm"), "upper_arm is not a counterweight"),
    (("mtm", "--grid", "j1=-60:60:5"), "takes two joints"),
    (("mtm", "--grid", "j1=-60:60:5", "nope=0:1:2"), "nope"),
    (("mtm", "--grid", "j1=-60:60:5", "j3=-30:80:5", "--mass", "0"), "--mass"),
])
def test_bad_input_is_one_line(args, match):
    out = run("counterweights", *args)
    assert out.returncode == 2 and out.stdout == ""
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and match in lines[0], out.stderr


def test_a_drive_file_of_another_robot_is_refused(tmp_path):
    shutil.copy(urdf_dir() / "mtm.urdf", tmp_path / "mtm.urdf")
    out = run("counterweights", "mtm", "--grid", "j1=-60:60:5", "j3=-30:80:5", "--params",
              str(urdf_dir() / "psm_drive.toml"))
    assert out.returncode == 2 and "describes robot 'psm', not 'mtm'" in out.stderr
