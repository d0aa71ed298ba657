"""A bundled robot as a MuJoCo model (MJCF XML), the loops closed by MuJoCo's own constraints.

Bodies: one per joint of the open tree (Pinocchio's, fixed links merged), each body frame the
joint frame, placed and massed as in :attr:`Robot.tree` (m, kg, kg m^2 about the centre of
mass). Joints carry the URDF limits. Each loop of the sidecar becomes an ``equality/connect``
between two sites, ``point_a`` on ``link_a`` and ``point_b`` on ``link_b``, so MuJoCo closes
the loop from the geometry alone (the passive relations are not copied). A robot whose passive
joints close no loop (the da Vinci's mimic parallelogram) gets ``equality/joint`` couplings,
the only way MJCF says "this joint follows that one".

The model it holds is one parameter set, the same as ``rcm-kin gravity``'s: the robot's CAD
(URDF inertias) or a calibration, a drive parameter file (default: the robot's own, its sidecar's
``drive``). A calibration's gravity offsets become centre-of-mass shifts of their bodies
(:mod:`rcm_kin.export.calibrated`); the file says which model it holds in an XML comment and in a
``<custom><text name="rcm_kin_model">`` MuJoCo reads (``model.text("rcm_kin_model").data``).

The driven joints of a drive file carry the drive parameters MJCF can express: ``armature`` the
reflected drive inertia (kg m^2, kg), ``damping`` the viscous coefficient (N m s/rad, N s/m),
``frictionloss`` the Coulomb level (N m, N); the stick-slip presliding spring and the tanh
smoothing have no MJCF counterpart. One ``motor`` per actuated joint, named after it, gear 1: its
control is the joint torque (N m) or force (N); a driven joint's motor is limited (``forcerange``)
to the torque of the firmware's PWM saturation at rest, ``PWM_LIMIT / |pwm_per_torque|`` (the
back-EMF's loss of torque with speed is not expressible). A CAD export has no drives.

Visuals: the URDF's boxes, cylinders and spheres, and its OBJ and binary STL meshes as MuJoCo mesh
assets (found by :func:`~rcm_kin.model.geometry.visual_geometry`: ``package://`` through
``package_dirs`` or ``ROS_PACKAGE_PATH``; a mesh not found is an error). MuJoCo reads no other mesh
(COLLADA, PLY, ASCII STL): such a visual is left out with a warning naming the files (the bodies,
masses and joints are whole), not an error: the model's physics does not need it.

Keyframes: ``home`` (every joint at 0 clipped into its range; the PSM insertion at
:data:`~rcm_kin.hardware.HOME_INSERTION`) and, for the PSM, ``roll{R}_pitch{P}`` over the
thesis grid R, P in {-30, 0, 30} deg at insertion 0.08 m. Passive joints sit at their closed
values; ``ctrl`` holds the pose against gravity: the torques ``rcm-kin gravity`` prints for the
model the file holds (:func:`~rcm_kin.model.gravity.gravity_batch` with its offsets).

MuJoCo refuses moving bodies without mass; the da Vinci model is kinematic (no inertias), so
the compiler floors masses at 1e-9 kg and inertias at 1e-12 kg m^2, far below every PSM and MTM
link (their smallest: 1 g, 1.5e-9 kg m^2), which it leaves unchanged.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from rcm_kin.atomic import atomic_path
from rcm_kin.dynamics.drive import DriveParameters, model_label, resolve_drive
from rcm_kin.errors import RcmKinError, RcmKinWarning, warn
from rcm_kin.export.calibrated import calibrated_inertias
from rcm_kin.hardware import HOME_INSERTION
from rcm_kin.model import Robot
from rcm_kin.model.constrained import solve_loops
from rcm_kin.model.geometry import visual_geometry
from rcm_kin.model.gravity import gravity_batch
from rcm_kin.model.reduced import tree_configuration
from rcm_kin.symbolic.tree import joint_axis

THESIS_GRID_DEG = (-30, 0, 30)       # roll and pitch of the thesis's operating points (deg)
LOOP_SOLREF = "0.002 1"              # loop constraints: 2 ms time constant, critically damped
LOOP_SOLIMP = "0.9999 0.9999 0.001"  # impedance at MuJoCo's maximum: the loops barely give
MASS_FLOOR = (1e-9, 1e-12)           # kg, kg m^2: MuJoCo's floor for massless moving bodies (da Vinci)
TIMESTEP = 0.0005                    # s: four steps per loop time constant (MuJoCo wants >= 2)
MESH_FORMATS = (".stl", ".obj")      # mesh files MuJoCo reads, STL binary (others: the visual left out, a warning)
MODEL_TEXT = "rcm_kin_model"         # <custom><text name=...>: the model the file holds


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


def keyframes(robot: Robot, params: DriveParameters | None = None) -> list[Keyframe]:
    """``home`` and, for the PSM, the thesis grid ``roll{R}_pitch{P}`` at the home insertion; the
    controls are the holding torques of the model of ``params`` (None: the CAD)."""
    home = np.clip(np.zeros(robot.nq), robot.lower, robot.upper)
    poses = {"home": home}
    if robot.name == "psm":
        home[robot.actuated.index("insertion")] = HOME_INSERTION
        for roll in THESIS_GRID_DEG:
            for pitch in THESIS_GRID_DEG:
                q = home.copy()
                q[robot.actuated.index("roll")], q[robot.actuated.index("pitch")] = np.radians([roll, pitch])
                poses[f"roll{roll}_pitch{pitch}"] = q
    ctrl = gravity_batch(robot, np.array(list(poses.values())), None if params is None else params.gravity_offsets,
                         allow_massless=True)
    return [Keyframe(name, q, _closed(robot, q), tau) for (name, q), tau in zip(poses.items(), ctrl)]


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


def _geom(obj, meshes: dict[tuple, str]) -> dict[str, str] | None:
    """A visual geom (no contacts, no mass) of a URDF box, cylinder, sphere or mesh; a mesh is named
    after its asset in ``meshes`` ((file, scale) -> asset name), None for one MuJoCo cannot read."""
    g = obj.geometry
    kind = type(g).__name__
    if kind == "Box":
        size = {"type": "box", "size": _fmt(g.halfSide)}
    elif kind == "Cylinder":
        size = {"type": "cylinder", "size": _fmt([g.radius, g.halfLength])}
    elif kind == "Sphere":
        size = {"type": "sphere", "size": _fmt(g.radius)}
    elif (key := _mesh_key(obj)) in meshes:
        size = {"type": "mesh", "mesh": meshes[key]}
    else:
        return None
    return {"name": obj.name, **size, **_pose_attributes(obj.placement), "rgba": _fmt(obj.meshColor),
            "contype": "0", "conaffinity": "0", "group": "1", "mass": "0"}


def _mesh_key(obj) -> tuple[str, str] | None:
    """(mesh file, scale) of a mesh visual, None for a primitive shape."""
    if type(obj.geometry).__name__ in ("Box", "Cylinder", "Sphere") or not Path(obj.meshPath).suffix:
        return None
    return obj.meshPath, _fmt(obj.meshScale)


def mujoco_reads(path: str | Path) -> bool:
    """Whether MuJoCo reads the mesh file: OBJ, or binary STL (84 bytes of header and count, then
    50 bytes a triangle; an ASCII STL is refused by MuJoCo's decoder)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_FORMATS:
        return False
    if suffix == ".stl":
        with path.open("rb") as f:
            head = f.read(84)
        return len(head) == 84 and path.stat().st_size == 84 + 50 * int.from_bytes(head[80:84], "little")
    return True


def _mesh_assets(visual: pin.GeometryModel) -> dict[tuple, str]:
    """(file, scale) -> asset name of the visuals' meshes MuJoCo reads; a warning lists the other
    mesh files, whose visuals are left out."""
    meshes, unread = {}, []
    for obj in visual.geometryObjects:
        if (key := _mesh_key(obj)) is None or key in meshes or key[0] in unread:
            continue
        if mujoco_reads(key[0]):
            meshes[key] = f"mesh{len(meshes)}_{Path(key[0]).stem}"
        else:
            unread.append(key[0])
    if unread:
        warn(f"MJCF: MuJoCo reads OBJ and binary STL meshes only; the visual{'s' if len(unread) > 1 else ''} of "
             f"{', '.join(unread[:3])}{f' and {len(unread) - 3} more' if len(unread) > 3 else ''} "
             f"{'are' if len(unread) > 1 else 'is'} left out "
             "(masses and joints are whole)", RcmKinWarning)
    return meshes


def _drive_attributes(params: DriveParameters | None) -> tuple[dict, dict]:
    """Joint attributes (armature, damping, frictionloss) and motor attributes (forcerange) of the
    driven joints of ``params``, by joint name; empty for a CAD export."""
    if params is None:
        return {}, {}
    joints = {j: {"armature": _fmt(params[j].reflected_inertia), "damping": _fmt(params[j].viscous),
                  "frictionloss": _fmt(params[j].coulomb)} for j in params.driven}
    saturation = {j: params[j].pwm_limit / abs(params[j].pwm_per_torque) for j in params.driven}   # N m, N
    motors = {j: {"forcerange": _fmt([-saturation[j], saturation[j]])} for j in params.driven}
    return joints, motors


def _bodies(robot: Robot, params: DriveParameters | None, worldbody: ET.Element) -> dict[int, ET.Element]:
    """The body of every open-tree joint (joint index -> element), massed by the model of ``params``."""
    tree = robot.tree
    names, inertias = _link_bodies(tree), calibrated_inertias(robot, params)
    drives = _drive_attributes(params)[0]
    elements = {0: worldbody}
    for j in range(1, tree.njoints):
        name = tree.names[j]
        body = ET.SubElement(elements[int(tree.parents[j])], "body", name=names.get(j, f"{name}_body"),
                             **_pose_attributes(tree.jointPlacements[j]))
        elements[j] = body
        if (inertial := _inertial(inertias[j])) is not None:
            ET.SubElement(body, "inertial", **inertial)
        axis, prismatic = joint_axis(tree.joints[j])
        i = tree.joints[j].idx_q
        ET.SubElement(body, "joint", name=name, type="slide" if prismatic else "hinge", axis=_fmt(axis),
                      range=_fmt([tree.lowerPositionLimit[i], tree.upperPositionLimit[i]]), **drives.get(name, {}))
    return elements


def _equality(robot: Robot, elements: dict[int, ET.Element]) -> ET.Element:
    """The loops as ``connect`` between two new sites, or (no loops) the passive joints as ``joint``."""
    tree = robot.tree
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
    return equality


def mjcf_tree(robot: Robot, params: DriveParameters | str | Path | None = None,
              package_dirs: Mapping[str, str | Path] | None = None) -> ET.ElementTree:
    """The MJCF document of ``robot`` (see the module docstring). ``params``: the drive parameters
    whose model it holds (:func:`~rcm_kin.dynamics.drive.resolve_drive`: None the robot's own,
    ``"cad"`` the URDF inertias, else a drive of this robot); ``package_dirs``: {package: folder}
    for ``package://`` meshes."""
    params = resolve_drive(robot, params)
    visual = visual_geometry(robot, package_dirs)
    root = ET.Element("mujoco", model=robot.name)
    root.append(ET.Comment(f" rcm-kin: {robot.name}, model {model_label(params)} ".replace("--", "- -")))
    ET.SubElement(root, "compiler", angle="radian", autolimits="true", inertiafromgeom="false",
                  boundmass=_fmt(MASS_FLOOR[0]), boundinertia=_fmt(MASS_FLOOR[1]))
    ET.SubElement(root, "option", timestep=_fmt(TIMESTEP), gravity=_fmt(robot.tree.gravity.linear))
    ET.SubElement(ET.SubElement(root, "custom"), "text", name=MODEL_TEXT, data=model_label(params))
    meshes = _mesh_assets(visual)
    if meshes:
        asset = ET.SubElement(root, "asset")
        for (file, scale), name in meshes.items():
            ET.SubElement(asset, "mesh", name=name, file=file, scale=scale)
    elements = _bodies(robot, params, ET.SubElement(root, "worldbody"))
    for obj in visual.geometryObjects:
        if (geom := _geom(obj, meshes)) is not None:
            ET.SubElement(elements[obj.parentJoint], "geom", **geom)
    for frame in robot.tree.frames:
        if frame.name in robot.description.frames:
            ET.SubElement(elements[frame.parentJoint], "site", name=frame.name, **_pose_attributes(frame.placement))
    if len(equality := _equality(robot, elements)):
        root.append(equality)
    actuators = ET.SubElement(root, "actuator")
    motors = _drive_attributes(params)[1]
    for name in robot.actuated:
        ET.SubElement(actuators, "motor", name=name, joint=name, gear="1", **motors.get(name, {}))
    keys = ET.SubElement(root, "keyframe")
    for key in keyframes(robot, params):
        ET.SubElement(keys, "key", name=key.name, qpos=_fmt(key.q_tree), ctrl=_fmt(key.ctrl))
    ET.indent(root)
    return ET.ElementTree(root)


def write_mjcf(robot: Robot, path: str | Path, params: DriveParameters | str | Path | None = None,
               package_dirs: Mapping[str, str | Path] | None = None) -> Path:
    """Write ``robot``'s MJCF to ``path`` (see :func:`mjcf_tree`); nothing is written on an error."""
    path = Path(path)
    document = mjcf_tree(robot, params, package_dirs)
    try:
        with atomic_path(path) as temporary:
            document.write(temporary, encoding="unicode", xml_declaration=False)
    except OSError as exc:
        raise RcmKinError(f"cannot write the MJCF file {path}: {exc.strerror}") from None
    return path
