"""IK on a URDF alone: the default frame is one the joints move (a leaf such as the dVRK's
remote_center_link, fixed to the base, has no IK)."""

from __future__ import annotations

import numpy as np
from oracles.dvrk_classic import write_dvrk_psm

import rcm_kin as rk
from rcm_kin.kinematics.ik import default_frame, moving_joints


def test_dvrk_urdf_alone_default_frame_is_moved_and_reached(tmp_path):
    dvrk = write_dvrk_psm(tmp_path, sidecar=False)
    robot = rk.load_robot(dvrk.urdf)
    frame = default_frame(robot)
    assert moving_joints(robot, frame)
    q = np.random.default_rng(5).uniform(0.3 * robot.lower, 0.3 * robot.upper)
    assert frame in robot.description.frames                 # a leaf link: a frame of interest
    target = rk.forward_kinematics(robot, q).frames[frame].translation
    solution = rk.inverse_kinematics(robot, target)
    assert solution.frame == frame and solution.position_error < 1e-9
