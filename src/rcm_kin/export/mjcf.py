"""A bundled robot as a MuJoCo model (MJCF XML), the loops closed by MuJoCo's own constraints.

Bodies: one per joint of the open tree (Pinocchio's, fixed links merged), each body frame the
joint frame, placed and massed as in :attr:`Robot.tree` (m, kg, kg m^2 about the centre of
mass). Joints carry the URDF limits. Each loop of the sidecar becomes an ``equality/connect``
between two sites, ``point_a`` on ``link_a`` and ``point_b`` on ``link_b``, so MuJoCo closes
the loop from the geometry alone (the passive relations are not copied). A robot whose passive
joints close no loop (the da Vinci's mimic parallelogram) gets ``equality/joint`` couplings,
the only way MJCF says "this joint follows that one".

For the PSM the driven joints (roll, pitch, insertion) carry the drive parameters MJCF can
express: ``armature`` the reflected drive inertia (kg m^2, kg), ``damping`` the viscous
coefficient (N m s/rad, N s/m), ``frictionloss`` the Coulomb level (N m, N); the stick-slip
presliding spring and the tanh smoothing have no MJCF counterpart. One ``motor`` per actuated
joint, named after it, gear 1: its control is the joint torque (N m) or force (N); a driven
joint's motor is limited (``forcerange``) to the torque of the firmware's PWM saturation at rest,
``PWM_LIMIT / |pwm_per_torque|`` (the back-EMF's loss of torque with speed is not expressible).

Keyframes: ``home`` (every joint at 0 clipped into its range; the PSM insertion at
:data:`~rcm_kin.hardware.HOME_INSERTION`) and, for the PSM, ``roll{R}_pitch{P}`` over the
thesis grid R, P in {-30, 0, 30} deg at insertion 0.08 m. Passive joints sit at their closed
values; ``ctrl`` holds the pose against gravity (our torques, CAD masses, no calibrated offsets).

MuJoCo refuses moving bodies without mass; the da Vinci model is kinematic (no inertias), so
the compiler floors masses at 1e-9 kg and inertias at 1e-12 kg m^2, far below every PSM and MTM
link (their smallest: 1 g, 1.5e-9 kg m^2), which it leaves unchanged.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from rcm_kin.dynamics.drive import DRIVEN, DriveParameters, load_drive_parameters
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import HOME_INSERTION
from rcm_kin.model import Robot
from rcm_kin.model.constrained import solve_loops
from rcm_kin.model.gravity import gravity_torque
from rcm_kin.model.reduced import tree_configuration
from rcm_kin.symbolic.tree import joint_axis

THESIS_GRID_DEG = (-30, 0, 30)       # roll and pitch of the thesis's operating points (deg)
LOOP_SOLREF = "0.002 1"              # loop constraints: 2 ms time constant, critically damped
LOOP_SOLIMP = "0.9999 0.9999 0.001"  # impedance at MuJoCo's maximum: the loops barely give
MASS_FLOOR = (1e-9, 1e-12)           # kg, kg m^2: MuJoCo's floor for massless moving bodies (da Vinci)
TIMESTEP = 0.0005                    # s: four steps per loop time constant (MuJoCo wants >= 2)


@dataclass(frozen=True)
class Keyframe:
    name: str
    q: np.ndarray          # actuated joints (rad, m), actuated order
    q_tree: np.ndarray     # every joint of the open tree, passive ones closed
    ctrl: np.ndarray       # motor controls holding the pose against gravity (N m, N), actuated order


def _fmt(values) -> str:
    return " ".join(f"{float(v):.17g}" for v in np.atleast_1d(values))


def _pose_attributes(placement: pin.SE3) -> dict[str, str]:
    x, y, z, w = pin.Quaternion(placement.rotation).coeffs()
    return {"pos": _fmt(placement.translation), "quat": _fmt([w, x, y, z])}


def _closed(robot: Robot, q: np.ndarray) -> np.ndarray:
    """The open-tree configuration of actuated ``q`` with every loop closed (Newton on the loops
    when the robot has some, else the sidecar's passive relations)."""
    guess = tree_configuration(robot, q)
    return solve_loops(robot, q, guess) if robot.constraints else guess


def keyframes(robot: Robot) -> list[Keyframe]:
    """``home`` and, for the PSM, the thesis grid ``roll{R}_pitch{P}`` at the home insertion."""
    home = np.clip(np.zeros(robot.nq), robot.lower, robot.upper)
    poses = {"home": home}
    if robot.name == "psm":
        home[robot.actuated.index("insertion")] = HOME_INSERTION
        for roll in THESIS_GRID_DEG:
            for pitch in THESIS_GRID_DEG:
                q = home.copy()
                q[robot.actuated.index("roll")], q[robot.actuated.index("pitch")] = np.radians([roll, pitch])
                poses[f"roll{roll}_pitch{pitch}"] = q
    return [Keyframe(name, q, _closed(robot, q), gravity_torque(robot, q, allow_massless=True))
            for name, q in poses.items()]


def _link_bodies(tree: pin.Model) -> dict[int, str]:
    """Joint index -> the name of the URDF link the joint moves (the body frame on the joint)."""
    names = {0: "world"}
    for frame in tree.frames:
        if frame.type == pin.FrameType.BODY and tree.frames[frame.parentFrame].type == pin.FrameType.JOINT:
            names.setdefault(frame.parentJoint, frame.name)
    return names


def _inertial(inertia: pin.Inertia) -> dict[str, str] | None:
    if inertia.mass <= 0:
        return None
    I = inertia.inertia
    return {"pos": _fmt(inertia.lever), "mass": _fmt(inertia.mass),
            "fullinertia": _fmt([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]])}


def _geom(obj) -> dict[str, str] | None:
    """A visual geom (no contacts, no mass) of a URDF box, cylinder or sphere."""
    g = obj.geometry
    kind = type(g).__name__
    if kind == "Box":
        size = {"type": "box", "size": _fmt(g.halfSide)}
    elif kind == "Cylinder":
        size = {"type": "cylinder", "size": _fmt([g.radius, g.halfLength])}
    elif kind == "Sphere":
        size = {"type": "sphere", "size": _fmt(g.radius)}
    else:
        return None
    return {"name": obj.name, **size, **_pose_attributes(obj.placement), "rgba": _fmt(obj.meshColor),
            "contype": "0", "conaffinity": "0", "group": "1", "mass": "0"}


def _drive_attributes(robot: Robot, params: DriveParameters | None) -> tuple[dict, dict]:
    """Joint attributes (armature, damping, frictionloss) and motor attributes (forcerange) of the
    PSM's driven joints, by joint name; empty for the other robots."""
    if robot.name != "psm":
        return {}, {}
    params = params if params is not None else load_drive_parameters()
    joints = {j: {"armature": _fmt(params[j].reflected_inertia), "damping": _fmt(params[j].viscous),
                  "frictionloss": _fmt(params[j].coulomb)} for j in DRIVEN}
    saturation = {j: params[j].pwm_limit / abs(params[j].pwm_per_torque) for j in DRIVEN}   # N m, N
    motors = {j: {"forcerange": _fmt([-saturation[j], saturation[j]])} for j in DRIVEN}
    return joints, motors


def mjcf_tree(robot: Robot, params: DriveParameters | None = None) -> ET.ElementTree:
    """The MJCF document of ``robot`` (see the module docstring); ``params``: the PSM's drive
    parameters (default: the shipped set)."""
    tree = robot.tree
    bodies = _link_bodies(tree)
    root = ET.Element("mujoco", model=robot.name)
    ET.SubElement(root, "compiler", angle="radian", autolimits="true", inertiafromgeom="false",
                  boundmass=_fmt(MASS_FLOOR[0]), boundinertia=_fmt(MASS_FLOOR[1]))
    ET.SubElement(root, "option", timestep=_fmt(TIMESTEP), gravity=_fmt(tree.gravity.linear))
    worldbody = ET.SubElement(root, "worldbody")
    elements = {0: worldbody}
    drives, motors = _drive_attributes(robot, params)
    for j in range(1, tree.njoints):
        name = tree.names[j]
        body = ET.SubElement(elements[int(tree.parents[j])], "body", name=bodies.get(j, f"{name}_body"),
                             **_pose_attributes(tree.jointPlacements[j]))
        elements[j] = body
        if (inertial := _inertial(tree.inertias[j])) is not None:
            ET.SubElement(body, "inertial", **inertial)
        axis, prismatic = joint_axis(tree.joints[j])
        i = tree.joints[j].idx_q
        ET.SubElement(body, "joint", name=name, type="slide" if prismatic else "hinge", axis=_fmt(axis),
                      range=_fmt([tree.lowerPositionLimit[i], tree.upperPositionLimit[i]]), **drives.get(name, {}))

    visual = pin.buildGeomFromUrdf(tree, str(robot.description.urdf), pin.GeometryType.VISUAL)
    for obj in visual.geometryObjects:
        if (geom := _geom(obj)) is not None:
            ET.SubElement(elements[obj.parentJoint], "geom", **geom)
    for frame in tree.frames:
        if frame.name in robot.description.frames:
            ET.SubElement(elements[frame.parentJoint], "site", name=frame.name, **_pose_attributes(frame.placement))

    equality = ET.Element("equality")
    for loop in robot.description.loops:
        sites = []
        for side, link, point in (("a", loop.link_a, loop.point_a), ("b", loop.link_b, loop.point_b)):
            frame = tree.frames[tree.getFrameId(link)]
            site = f"{loop.name}_{side}"
            ET.SubElement(elements[frame.parentJoint], "site", name=site,
                          pos=_fmt((frame.placement * pin.SE3(np.eye(3), point)).translation))
            sites.append(site)
        ET.SubElement(equality, "connect", name=loop.name, site1=sites[0], site2=sites[1],
                      solref=LOOP_SOLREF, solimp=LOOP_SOLIMP)
    if not robot.description.loops:
        for p in robot.description.passive:
            ET.SubElement(equality, "joint", name=f"{p.joint}_follows_{p.follows}", joint1=p.joint,
                          joint2=p.follows, polycoef=_fmt([p.offset, p.multiplier, 0, 0, 0]),
                          solref=LOOP_SOLREF, solimp=LOOP_SOLIMP)
    if len(equality):
        root.append(equality)

    actuators = ET.SubElement(root, "actuator")
    for name in robot.actuated:
        ET.SubElement(actuators, "motor", name=name, joint=name, gear="1", **motors.get(name, {}))
    keys = ET.SubElement(root, "keyframe")
    for key in keyframes(robot):
        ET.SubElement(keys, "key", name=key.name, qpos=_fmt(key.q_tree), ctrl=_fmt(key.ctrl))
    ET.indent(root)
    return ET.ElementTree(root)


def write_mjcf(robot: Robot, path: str | Path, params: DriveParameters | None = None) -> Path:
    """Write ``robot``'s MJCF to ``path`` (see :func:`mjcf_tree`)."""
    path = Path(path)
    try:
        mjcf_tree(robot, params).write(path, encoding="unicode", xml_declaration=False)
    except OSError as exc:
        raise RcmKinError(f"cannot write the MJCF file {path}: {exc.strerror}") from None
    return path
