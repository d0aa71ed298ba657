"""The gravity model an export holds: one model per parameter set, the same one ``rcm-kin gravity`` uses.

A robot runs either on its CAD (the URDF's inertias) or on a calibration, a drive parameter file
(:class:`~rcm_kin.dynamics.drive.DriveParameters`) whose ``[gravity_offsets]`` add first moments
``h`` (kg m, in a link's frame) to some links. ``rcm-kin gravity`` adds them as torque
(:func:`~rcm_kin.model.gravity.gravity_batch`); a rigid-body file such as MJCF can only say it with
masses and centres of mass, so each offset becomes a shift of its body's centre of mass,

    c' = (m c + h) / m            (m kept: the calibration identified first moments, not masses)

which gives the same first moment ``m c' = m c + h`` and so the same gravity torque at every pose.
The rotational inertia kept is the one about the centre of mass (the body's shape carried to the
new centre). Keeping instead the one about the joint (the other textbook choice, which changes
only the identified parameters) is not physical for the PSM's calibration: its centres move by 8
and 21 cm and the inertias about them would have eigenvalues down to -0.15 kg m^2, which MuJoCo
refuses. The price: the mass matrix gains the parallel-axis terms of the shift (an MJCF holds the
calibrated gravity exactly; its inertia is the CAD's about the moved centres).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin

from rcm_kin.dynamics.drive import DriveParameters
from rcm_kin.errors import RcmKinError
from rcm_kin.model import Robot
from rcm_kin.model.gravity import offset_moments


def calibrated_inertia(inertia: pin.Inertia, moment, where: str = "a link") -> pin.Inertia:
    """``inertia`` with the first moment ``moment`` (kg m, in the inertia's frame) added as a shift of
    its centre of mass: mass and the rotational inertia about the centre kept."""
    moment = np.asarray(moment, dtype=float)
    if not np.any(moment):
        return pin.Inertia(inertia)
    if inertia.mass <= 0:
        raise RcmKinError(f"a gravity offset on {where}, which has no mass: a first moment needs a mass to carry it",
                          parameter="drive")
    return pin.Inertia(inertia.mass, inertia.lever + moment / inertia.mass, inertia.inertia)


def calibrated_inertias(robot: Robot, params: DriveParameters | None) -> list[pin.Inertia]:
    """The inertia of every joint of ``robot.tree`` (index as in the tree; 0 the universe) with the
    gravity offsets of ``params`` added (:func:`calibrated_inertia`); the CAD's when ``params`` is None."""
    tree = robot.tree
    moments = offset_moments(robot, {} if params is None else params.gravity_offsets)
    return [calibrated_inertia(tree.inertias[j], moments.get(j, np.zeros(3)), f"the body of joint {tree.names[j]}")
            for j in range(tree.njoints)]


def calibrated_robot(robot: Robot, params: DriveParameters | None) -> Robot:
    """A copy of ``robot`` whose open tree and reduced model carry :func:`calibrated_inertias`: plain
    Pinocchio on it (gravity, RNEA, CRBA) is the dynamics of the exported MJCF."""
    inertias = calibrated_inertias(robot, params)
    tree, reduced = pin.Model(robot.tree), pin.Model(robot.reduced)
    for j in range(1, tree.njoints):
        tree.inertias[j] = inertias[j]
        reduced.inertias[reduced.getJointId(tree.names[j])] = inertias[j]
    return replace(robot, tree=tree, reduced=reduced)
