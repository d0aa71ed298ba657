"""Write ``psm.urdf``, ``mtm.urdf``, ``davinci.urdf`` and ``davinci_rcm.urdf`` in this folder
from the parameter tables below.

    python urdf/generate.py           # rewrite the files
    python urdf/generate.py --check   # exit 1 if the committed files differ from the tables

Sources (as collected in the project's reference sheet): the osMDV design repository (DH
tables, CAD masses and centres of gravity of the planar COG scripts, counterweight fits) and
a SolidWorks export of the MTM. Lengths here are in mm and degrees, converted to SI on output;
the PSM's counterweights as built come in SI from ``rcm_kin.hardware`` (their one home).

ESTIMATED, stated once for every body: no inertia tensor exists in any source. Each body's
rotational inertia is that of a solid box of the stated size carrying the body's mass about
its centre of gravity. Masses of the instrument links are estimates taken out of the CAD
carriage mass (which includes the instrument) so that total mass and COG stay as in CAD.

Frames (both robots): base frame z up, gravity (0, 0, -9.81) m/s^2.
PSM base frame: origin at the remote centre of motion (RCM), x along the main (roll) axis
from the pitch pivot towards the RCM, y = z x x. The planar parallelogram model of the
osMDV COG scripts (frame CS0 at the pitch pivot, x towards the RCM, z up) is this frame
shifted by 290.816 mm along -x. The roll axis is -x so that positive roll and pitch are those
of the osMDV DH table.
MTM base frame: the osMDV DH frame 0 (y up) turned by +90 deg about x, so z is up.

da Vinci (first-generation patient-side arm "p4", AAU 2015 thesis, project digest): the chain of
Table C.1 with the mimic parallelogram (``davinci``) and the reduced active-joints chain of
Table C.7 with the hand joints at the RCM (``davinci_rcm``). Kinematics only: no source gives
masses. Table C.1 values are those of its FK code with the digest's two corrections (a10 =
0.520, frame 9 turning about -y). Setup-joint limits are in no source: +-pi (revolute) and
+-0.3 m (elevation) stand in.
"""

from __future__ import annotations

import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rcm_kin.hardware import DPM_COUNTERWEIGHT, MAIN_COUNTERWEIGHT

HERE = Path(__file__).resolve().parent
MM = 1e-3                  # m per mm
RAD_PER_DEG = np.pi / 180.0
BRASS_DENSITY = 8500.0  # kg/m^3, for the counterweight cylinders' size

# --------------------------------------------------------------------------------------------
# PSM parameter table (mm, kg, deg)
# --------------------------------------------------------------------------------------------
PSM = dict(
    # osMDV DH lengths. l_RCM is the firmware code value 455.99 (reference sheet: 456.00 in
    # the table, 455.99 in code) so that the shaft tip lies q3 - 23.49 mm beyond the RCM.
    l_rcm=455.99, l_tool=432.50, l_p2y=9.00, l_y2t=10.10,
    # double parallelogram, planar frame CS0 at the pitch pivot
    cs0_to_rcm=290.816,          # RCM on the main axis, 290.816 from CS0; fork length
    base_spacing=100.0,          # CS0 -> CS1 (support-link pivot)
    lower_fork_on_drive=(-50.0, 152.0),
    upper_fork_on_drive=(-50.0, 222.0),
    carriage_origin=(6.15, 406.9),  # CS5 in the framework frame at insertion 0
    # masses and COGs (planar, mm) in each body's own frame
    drive_link=(1.015, (-10.979, -3.734)),
    support_link=(0.071, (-25.62, 77.91)),
    lower_fork=(0.305, (130.356, 0.0)),
    upper_fork=(0.377, (126.718, 0.0)),
    framework=(1.238, (-7.0, 192.37)),
    carriage=(0.600, (35.908, -139.456)),  # sled + instrument + insertion drive
    # roll body (head): earlier simplified CAD export, "roller link"; COG assumed on the axis
    roll_link=(0.875, (-290.816, 0.0)),
    # counterweights (brass), osMDV fits: rcm_kin.hardware MAIN_COUNTERWEIGHT, DPM_COUNTERWEIGHT (SI)
    # instrument link masses (ESTIMATED, taken out of the carriage mass)
    instrument_shaft=0.040, wrist_pitch_link=0.003, wrist_yaw_link=0.002, jaw_link=0.001,
    # joint limits
    roll_limit=30.0, pitch_limit=30.0,
    insertion_range=(0.0, 160.0),   # mm: the COG model's insertion range d = 0..160
    instrument_roll_limit=180.0, wrist_limit=90.0, jaw_range=(0.0, 80.0),
)

# --------------------------------------------------------------------------------------------
# MTM parameter table (osMDV DH; left arm as in the table, d3 = -l_ball)
# --------------------------------------------------------------------------------------------
MTM = dict(
    l_sho=45.0, l_arm=217.5, l_ball=8.7, l_imu=37.4,
    shoulder=(0.150, (23.67, 0.0, 2.40)),     # COG in the proximal frame of the link
    upper_arm=(0.056, (126.57, 0.0, 0.02)),
    lower_arm=(0.039, (99.47, 0.0, 0.0)),
    gimbal=(0.0139, 0.0080, 0.0061, 0.0020),  # G3, G2, G1, G0 (sum 0.030 kg; G3 from SolidWorks)
    counterweight=(0.317, 72.5, 8.79),        # kg, mm, deg; balance M = m g l cos(q1 + phi)
    arm_limit=90.0, gimbal_limit=90.0, grip_range=(0.0, 60.0),  # no source: placeholders
)


# --------------------------------------------------------------------------------------------
# da Vinci patient-side arm, Table C.1 (m, rad): per frame (name, parent, a, b, d, fixed
# rotation as a product of (axis, angle), joint kind, actuation axis with sign (1 x, 2 y, 3 z),
# limits). T_i = [R_fixed, (a, b, d)] [free motion about / along the actuation axis].
# --------------------------------------------------------------------------------------------
TILT = 0.1745   # rad (10 deg): the parallelogram base tilt of the FK code (0.288 in the table)
DAVINCI = [
    ("elevation", "base_link", 0.0, 0.0, 0.0, (), "prismatic", 3, (-0.3, 0.3)),
    ("arm_yaw1", "elevation", 0.198, 0.0, 0.812, (("z", np.pi / 2), ("x", np.pi)), "revolute", 3, None),
    ("arm_yaw2", "arm_yaw1", 0.0, 0.583, 0.0, (("z", np.pi / 2), ("x", -np.pi)), "revolute", -3, None),
    ("arm_yaw3", "arm_yaw2", 0.435, 0.0, -0.001, (), "revolute", -3, None),
    ("arm_roll1", "arm_yaw3", 0.057, 0.0, 0.198, (), "revolute", -1, None),
    ("rcm_base", "arm_roll1", 0.352, 0.0, -0.117, (), "revolute", 3, None),          # arm_yaw4
    ("hand_roll", "rcm_base", -0.052, 0.0, 0.161, (), "revolute", 1, (-np.pi / 2, np.pi / 2)),
    ("hand_pitch", "hand_roll", 0.0, 0.0, 0.0, (("y", -TILT),), "revolute", -2, (-0.8, 1.0)),
    ("upper_bar", "hand_pitch", 0.0, 0.0, 0.186, (("y", TILT), ("x", np.pi)), "revolute", -2, (-0.8, 1.0)),
    ("instrument_holder", "upper_bar", 0.520, 0.0, 0.0, (("x", np.pi),), "revolute", -2, (-0.8, 1.0)),
    ("instrument_slide", "instrument_holder", 0.0, 0.0, -0.104, (), "prismatic", 3, (-0.12, 0.12)),
    ("instrument_roll", "instrument_slide", 0.052, 0.0, 0.0, (("z", np.pi / 2), ("x", np.pi)), "revolute", 3,
     (-1.5 * np.pi, 1.5 * np.pi)),
    ("instrument_pitch", "instrument_roll", 0.0, 0.0, 0.177, (), "revolute", -1, (-1.5, 1.5)),
    ("jaw_left", "instrument_pitch", 0.0, 0.0, 0.009, (("y", np.pi / 2), ("x", np.pi / 2)), "revolute", -3,
     (-1.8, 1.8)),
    ("jaw_right", "instrument_pitch", 0.0, 0.0, 0.009, (("y", np.pi / 2), ("x", np.pi / 2)), "revolute", 3,
     (-1.8, 1.8)),
]
# Table C.7 (reduced chain, URDF convention [Rz(yaw) Ry(pitch) Rx(roll), (a, b, d)] [Rz(q) or
# Tz(q)]): (name, parent, a, b, d, roll, pitch, kind, limits)
DAVINCI_RCM = [
    ("elevation", "base_link", 0.0, 0.0, 0.998, 0.0, 0.0, "prismatic", (-0.3, 0.3)),
    ("arm_yaw1", "elevation", 0.198, 0.0, 0.0, 0.0, 0.0, "revolute", None),
    ("arm_yaw2", "arm_yaw1", 0.582, 0.0, 0.0, 0.0, 0.0, "revolute", None),
    ("arm_yaw3", "arm_yaw2", 0.435, 0.0, 0.0, 0.0, 0.0, "revolute", None),
    ("arm_roll1", "arm_yaw3", 0.0, 0.0, 0.0, 0.0, np.pi / 2, "revolute", None),
    ("rcm_base", "arm_roll1", 0.0, 0.0, 0.412, 0.0, -np.pi / 2, "revolute", None),   # arm_yaw4
    ("hand_roll", "rcm_base", 0.482, 0.0, 0.047, 0.0, np.pi / 2, "revolute", (-np.pi / 2, np.pi / 2)),
    ("hand_pitch", "hand_roll", 0.0, 0.0, 0.0, np.pi / 2, 0.0, "revolute", (-0.8, 1.0)),
    ("instrument_slide", "hand_pitch", 0.097, 0.0, 0.0, 0.0, -np.pi / 2, "prismatic", (-0.12, 0.12)),
    ("instrument_roll", "instrument_slide", 0.0, 0.0, 0.0, 0.0, 0.0, "revolute", (-1.5 * np.pi, 1.5 * np.pi)),
    ("instrument_pitch", "instrument_roll", 0.0, 0.0, 0.0, 0.0, np.pi / 2, "revolute", (-1.5, 1.5)),
    ("jaw_left", "instrument_pitch", 0.009, 0.0, 0.0, -np.pi / 2, 0.0, "revolute", (-1.8, 1.8)),
    ("jaw_right", "instrument_pitch", 0.009, 0.0, 0.0, -np.pi / 2, 0.0, "revolute", (-1.8, 1.8)),
]


# --------------------------------------------------------------------------------------------
# Geometry helpers
# --------------------------------------------------------------------------------------------
def rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def transform(R=np.eye(3), p=(0.0, 0.0, 0.0)) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T


def dh_trailing(d: float, a: float, alpha: float) -> np.ndarray:
    """Tz(d) Tx(a) Rx(alpha): the part of a standard DH step after the joint rotation."""
    return transform(p=(0, 0, d)) @ transform(p=(a, 0, 0)) @ transform(rot_x(alpha))


def rpy_from_matrix(R: np.ndarray) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw (R = Rz(yaw) Ry(pitch) Rx(roll))."""
    pitch = float(np.arcsin(np.clip(-R[2, 0], -1.0, 1.0)))
    if abs(R[2, 0]) > 1 - 1e-12:
        roll, yaw = 0.0, float(np.arctan2(-R[0, 1], R[1, 1]))
    else:
        roll, yaw = float(np.arctan2(R[2, 1], R[2, 2])), float(np.arctan2(R[1, 0], R[0, 0]))
    assert np.allclose(rot_z(yaw) @ rot_y(pitch) @ rot_x(roll), R, atol=1e-12)
    return roll, pitch, yaw


def frame_along(u: np.ndarray) -> np.ndarray:
    """A rotation whose x axis is the unit vector u."""
    u = np.asarray(u, float) / np.linalg.norm(u)
    helper = np.array([0.0, 1.0, 0.0]) if abs(u[1]) < 0.9 else np.array([0.0, 0.0, 1.0])
    z = np.cross(u, helper)
    z /= np.linalg.norm(z)
    return np.column_stack([u, np.cross(z, u), z])


def box_inertia(mass: float, size, R=np.eye(3)) -> np.ndarray:
    sx, sy, sz = size
    diag = mass / 12.0 * np.array([sy**2 + sz**2, sx**2 + sz**2, sx**2 + sy**2])
    return R @ np.diag(diag) @ R.T


def planar(p2) -> np.ndarray:
    """(x, z) of the planar pitch-plane model, mm -> 3-D point in m (y = 0)."""
    return np.array([p2[0], 0.0, p2[1]]) * MM


# --------------------------------------------------------------------------------------------
# A minimal URDF writer
# --------------------------------------------------------------------------------------------
@dataclass
class Visual:
    kind: str            # "box" | "cylinder" | "sphere"
    dims: tuple          # box (sx, sy, sz); cylinder (radius, length) along z; sphere (r,)
    T: np.ndarray = field(default_factory=lambda: np.eye(4))
    material: str = "aluminium"


@dataclass
class Link:
    name: str
    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    visuals: list = field(default_factory=list)


@dataclass
class Joint:
    name: str
    kind: str            # "revolute" | "prismatic" | "fixed"
    parent: str
    child: str
    T: np.ndarray
    axis: tuple = (0.0, 0.0, 1.0)
    limits: tuple | None = None   # (lower, upper) in rad or m


MATERIALS = {
    "aluminium": (0.75, 0.76, 0.78, 1.0), "brass": (0.80, 0.62, 0.20, 1.0),
    "printed": (0.20, 0.45, 0.80, 1.0), "motor": (0.15, 0.15, 0.15, 1.0),
    "steel": (0.55, 0.55, 0.58, 1.0), "marker": (0.90, 0.10, 0.10, 1.0),
}


def num(x: float) -> str:
    x = float(x)
    return "0" if abs(x) < 1e-15 else f"{x:.17g}"


def vec(v) -> str:
    return " ".join(num(x) for x in v)


def origin_element(parent: ET.Element, T: np.ndarray) -> None:
    ET.SubElement(parent, "origin", xyz=vec(T[:3, 3]), rpy=vec(rpy_from_matrix(T[:3, :3])))


def write_urdf(name: str, comment: str, links: list[Link], joints: list[Joint]) -> str:
    robot = ET.Element("robot", name=name)
    robot.append(ET.Comment(comment))
    for mat, rgba in MATERIALS.items():
        ET.SubElement(ET.SubElement(robot, "material", name=mat), "color", rgba=vec(rgba))
    for link in links:
        el = ET.SubElement(robot, "link", name=link.name)
        if link.mass > 0:
            inertial = ET.SubElement(el, "inertial")
            ET.SubElement(inertial, "origin", xyz=vec(link.com), rpy="0 0 0")
            ET.SubElement(inertial, "mass", value=num(link.mass))
            I = link.inertia
            ET.SubElement(inertial, "inertia", ixx=num(I[0, 0]), ixy=num(I[0, 1]), ixz=num(I[0, 2]),
                          iyy=num(I[1, 1]), iyz=num(I[1, 2]), izz=num(I[2, 2]))
        for vis in link.visuals:
            v = ET.SubElement(el, "visual")
            origin_element(v, vis.T)
            geom = ET.SubElement(v, "geometry")
            if vis.kind == "box":
                ET.SubElement(geom, "box", size=vec(vis.dims))
            elif vis.kind == "cylinder":
                ET.SubElement(geom, "cylinder", radius=num(vis.dims[0]), length=num(vis.dims[1]))
            else:
                ET.SubElement(geom, "sphere", radius=num(vis.dims[0]))
            ET.SubElement(v, "material", name=vis.material)
    for j in joints:
        el = ET.SubElement(robot, "joint", name=j.name, type=j.kind)
        origin_element(el, j.T)
        ET.SubElement(el, "parent", link=j.parent)
        ET.SubElement(el, "child", link=j.child)
        if j.kind != "fixed":
            ET.SubElement(el, "axis", xyz=vec(j.axis))
            # effort and velocity are required by URDF; rcm_kin does not use them.
            ET.SubElement(el, "limit", lower=num(j.limits[0]), upper=num(j.limits[1]),
                          effort="0", velocity="0")
    ET.indent(robot, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


def body(name, mass, com, size, R=np.eye(3), visuals=()) -> Link:
    return Link(name, mass, np.asarray(com, float), box_inertia(mass, size, R), list(visuals))


def bar(p0, p1, width, depth, material="aluminium") -> Visual:
    """A box visual from point p0 to point p1 (m)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    R = frame_along(p1 - p0)
    return Visual("box", (np.linalg.norm(p1 - p0), width, depth), transform(R, (p0 + p1) / 2), material)


def cylinder_along(p0, p1, radius, material="aluminium") -> Visual:
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    R = frame_along(p1 - p0)
    R = R[:, [1, 2, 0]]  # cylinder axis is z
    return Visual("cylinder", (radius, np.linalg.norm(p1 - p0)), transform(R, (p0 + p1) / 2), material)


def brass_cylinder(mass: float, radius: float) -> float:
    """Length (m) of a brass cylinder of this mass and radius."""
    return mass / (BRASS_DENSITY * np.pi * radius**2)


def marker(radius=0.006) -> Visual:
    return Visual("sphere", (radius,), material="marker")


# --------------------------------------------------------------------------------------------
# PSM
# --------------------------------------------------------------------------------------------
def dh_base_rotation_psm() -> np.ndarray:
    """Orientation of the osMDV DH frame 0 in the PSM base frame: x0 up, z0 = roll axis (-x)."""
    return np.column_stack([[0, 0, 1], [0, 1, 0], [-1, 0, 0]]).astype(float)


@dataclass(frozen=True)
class PsmLayout:
    """The PSM's derived geometry (m, base frame and the frames of the URDF's links) and the
    masses that are computed rather than tabled, shared by its links and joints."""

    L: float                       # fork length: pitch pivot (CS0) to the RCM along the main axis
    cs0: np.ndarray                # pitch pivot in the base frame
    lower_on_drive: np.ndarray     # fork joints on the drive link
    upper_on_drive: np.ndarray
    rcm_in_framework: np.ndarray
    upper_on_framework: np.ndarray
    carriage_origin: np.ndarray
    R_f3: np.ndarray               # DH frame 3 in the framework frame at q = 0
    shaft_dir: np.ndarray          # from the RCM towards the tool
    interface_c: np.ndarray        # instrument interface in the carriage frame at insertion 0
    l_tool: float
    l_p2y: float
    l_y2t: float
    m_carriage: float              # kg, without the instrument
    cog_carriage: np.ndarray
    cw1_pos: np.ndarray            # DPM counterweight in the drive link's frame


def psm_layout() -> PsmLayout:
    """The derived geometry from the PSM table (mm, deg) and rcm_kin.hardware (SI), in SI."""
    P = PSM
    L = P["cs0_to_rcm"] * MM
    lower_on_drive = planar(P["lower_fork_on_drive"])
    upper_on_drive = planar(P["upper_fork_on_drive"])
    rcm_in_framework = -lower_on_drive            # (50, -152) from the distal fork joint
    carriage_origin = planar(P["carriage_origin"])

    # Instrument: DH frame 3 orientation in the framework frame at q = 0 (the framework frame
    # turns with roll and pitch exactly as DH frame 2 does).
    R_b0 = dh_base_rotation_psm()
    R_02 = rot_x(-np.pi / 2) @ rot_z(-np.pi / 2) @ rot_x(np.pi / 2)
    R_f3 = R_b0 @ R_02
    shaft_dir = R_f3[:, 2]                         # points from the RCM to the tool
    assert np.allclose(shaft_dir, [0, 0, -1])
    # Instrument interface (DH frame 3 at q4 = 0) in the carriage frame at insertion 0.
    interface_f = rcm_in_framework - (P["l_rcm"] * MM) * shaft_dir
    interface_c = interface_f - carriage_origin
    l_tool, l_p2y, l_y2t = P["l_tool"] * MM, P["l_p2y"] * MM, P["l_y2t"] * MM

    # Carriage mass without the instrument, COG chosen so total mass and COG stay as in CAD.
    m_total, cog_total = P["carriage"][0], planar(P["carriage"][1])
    instrument = [
        (P["instrument_shaft"], interface_c + 0.5 * l_tool * shaft_dir),
        (P["wrist_pitch_link"] + P["wrist_yaw_link"] + P["jaw_link"], interface_c + l_tool * shaft_dir),
    ]
    m_instr = sum(m for m, _ in instrument)
    m_carriage = m_total - m_instr
    cog_carriage = (m_total * cog_total - sum(m * c for m, c in instrument)) / m_carriage

    _, r_cw1, phi_cw1 = DPM_COUNTERWEIGHT      # kg, m from the pitch pivot, rad from straight down
    cw1_pos = np.array([r_cw1 * np.sin(phi_cw1), 0.0, -r_cw1 * np.cos(phi_cw1)])
    return PsmLayout(L, np.array([-L, 0.0, 0.0]), lower_on_drive, upper_on_drive, rcm_in_framework,
                     upper_on_drive - lower_on_drive, carriage_origin, R_f3, shaft_dir, interface_c,
                     l_tool, l_p2y, l_y2t, m_carriage, cog_carriage, cw1_pos)


def _psm_links(g: PsmLayout) -> list[Link]:
    """The PSM's links: masses (kg), centres of gravity and visuals (m) in each link's frame."""
    P = PSM
    cs0, L = g.cs0, g.L
    m_cw0, r_cw0 = MAIN_COUNTERWEIGHT              # kg, m below the main axis
    m_cw1 = DPM_COUNTERWEIGHT[0]
    cw_radius = 0.035
    cw0_len, cw1_len = brass_cylinder(m_cw0, cw_radius), brass_cylinder(m_cw1, cw_radius)

    def mass_cog(key):
        m, c = P[key]
        return m, planar(c)

    fork_end = np.array([L, 0.0, 0.0])
    support_end = g.lower_on_drive  # the support link is parallel to the drive link's lower arm
    links = [
        Link("base_link", visuals=[
            bar(cs0 + [-0.08, 0, -0.06], cs0 + [-0.08, 0, -0.40], 0.06, 0.10, "steel"),
            Visual("box", (0.30, 0.30, 0.02), transform(p=cs0 + [-0.08, 0, -0.41]), "steel")]),
        Link("rcm", visuals=[marker(0.008)]),
        body("roll_link", *mass_cog("roll_link"), (0.10, 0.12, 0.08), visuals=[
            cylinder_along(cs0 + [-0.06, 0, 0], cs0 + [0.05, 0, 0], 0.02, "steel"),
            bar(cs0 + [0, 0, 0], cs0 + [0, 0, -r_cw0], 0.015, 0.015, "steel"),
            Visual("box", (0.06, 0.12, 0.01), transform(p=cs0 + [0.05, 0, -0.01]), "aluminium")]),
        body("main_counterweight", m_cw0, [0, 0, 0], (2 * cw_radius, 2 * cw_radius, cw0_len), visuals=[
            Visual("cylinder", (cw_radius, cw0_len), transform(rot_x(np.pi / 2)), "brass")]),
        body("drive_link", *mass_cog("drive_link"), (0.07, 0.08, 0.09), visuals=[
            bar([0, 0, 0], g.upper_on_drive, 0.02, 0.03, "printed"),
            bar([0, 0, 0], g.cw1_pos, 0.012, 0.012, "steel"),
            cylinder_along([0, -0.06, 0], [0, 0.03, 0], 0.08, "aluminium"),
            cylinder_along([-0.02, 0.04, -0.02], [-0.02, 0.11, -0.02], 0.0175, "motor")]),
        body("dpm_counterweight", m_cw1, [0, 0, 0], (2 * cw_radius, 2 * cw_radius, cw1_len), visuals=[
            Visual("cylinder", (cw_radius, cw1_len), transform(rot_x(np.pi / 2)), "brass")]),
        body("support_link", *mass_cog("support_link"), (0.16, 0.015, 0.02), frame_along(support_end), visuals=[
            bar([0, 0, 0], support_end, 0.015, 0.02, "printed")]),
        body("lower_fork", *mass_cog("lower_fork"), (L, 0.03, 0.02), visuals=[
            bar([0, 0, 0], fork_end, 0.02, 0.03, "printed")]),
        body("upper_fork", *mass_cog("upper_fork"), (L, 0.03, 0.02), visuals=[
            bar([0, 0, 0], fork_end, 0.02, 0.03, "printed")]),
        body("framework", *mass_cog("framework"), (0.04, 0.06, 0.45), visuals=[
            bar([0, 0, 0], g.upper_on_framework, 0.02, 0.03, "printed"),
            bar([0.006, 0, -0.02], [0.006, 0, 0.45], 0.02, 0.04, "aluminium"),
            bar([0.0, 0, 0.0], g.rcm_in_framework + [0, 0, 0.06], 0.012, 0.012, "printed")]),
        body("carriage", g.m_carriage, g.cog_carriage, (0.06, 0.06, 0.10), visuals=[
            Visual("box", (0.06, 0.05, 0.08), transform(p=g.cog_carriage), "printed"),
            cylinder_along(g.interface_c, g.interface_c + [0, 0, 0.02], 0.02, "aluminium")]),
    ]
    # Instrument links: frames follow the osMDV DH table from DH frame 3 on.
    l_tool, l_p2y, l_y2t = g.l_tool, g.l_p2y, g.l_y2t
    links += [
        body("instrument_shaft", P["instrument_shaft"], [0, 0, 0.5 * l_tool], (0.008, 0.008, l_tool), visuals=[
            Visual("cylinder", (0.004, l_tool), transform(p=[0, 0, 0.5 * l_tool]), "steel")]),
        Link("shaft_tip", visuals=[marker(0.005)]),
        body("wrist_pitch_link", P["wrist_pitch_link"], [0.5 * l_p2y, 0, 0], (l_p2y, 0.006, 0.006), visuals=[
            bar([0, 0, 0], [l_p2y, 0, 0], 0.006, 0.006, "steel")]),
        body("wrist_yaw_link", P["wrist_yaw_link"], [0.5 * l_y2t, 0, 0], (l_y2t, 0.004, 0.004), visuals=[
            bar([0, 0, 0], [l_y2t, 0, 0], 0.003, 0.004, "steel")]),
        body("jaw_link", P["jaw_link"], [0.5 * l_y2t, 0, 0], (l_y2t, 0.003, 0.003), visuals=[
            bar([0, 0, 0], [l_y2t, 0, 0], 0.003, 0.003, "steel")]),
        Link("tool_tip", visuals=[marker(0.003)]),
    ]
    return links


def _psm_joints(g: PsmLayout) -> list[Joint]:
    """The PSM's joints: placements (m) in the parent link's frame, axes, limits (rad, m)."""
    P = PSM
    cs0, l_tool = g.cs0, g.l_tool
    roll_lim, pitch_lim = P["roll_limit"] * RAD_PER_DEG, P["pitch_limit"] * RAD_PER_DEG
    instrument_roll_lim, wrist_lim = P["instrument_roll_limit"] * RAD_PER_DEG, P["wrist_limit"] * RAD_PER_DEG
    passive = (-2 * pitch_lim, 2 * pitch_lim)
    ins_lo, ins_hi = (x * MM for x in P["insertion_range"])
    fork_end = np.array([g.L, 0.0, 0.0])
    return [
        Joint("rcm_frame", "fixed", "base_link", "rcm", np.eye(4)),
        Joint("roll", "revolute", "base_link", "roll_link", np.eye(4), (-1, 0, 0), (-roll_lim, roll_lim)),
        Joint("main_counterweight_mount", "fixed", "roll_link", "main_counterweight",
              transform(p=cs0 + [0, 0, -MAIN_COUNTERWEIGHT[1]])),
        Joint("pitch", "revolute", "roll_link", "drive_link", transform(p=cs0), (0, 1, 0), (-pitch_lim, pitch_lim)),
        Joint("dpm_counterweight_mount", "fixed", "drive_link", "dpm_counterweight", transform(p=g.cw1_pos)),
        Joint("lower_fork_joint", "revolute", "drive_link", "lower_fork", transform(p=g.lower_on_drive), (0, 1, 0),
              passive),
        Joint("framework_joint", "revolute", "lower_fork", "framework", transform(p=fork_end), (0, 1, 0), passive),
        Joint("insertion", "prismatic", "framework", "carriage", transform(p=g.carriage_origin), tuple(g.shaft_dir),
              (ins_lo, ins_hi)),
        Joint("instrument_roll", "revolute", "carriage", "instrument_shaft", transform(g.R_f3, g.interface_c),
              (0, 0, 1), (-instrument_roll_lim, instrument_roll_lim)),
        Joint("shaft_tip_frame", "fixed", "instrument_shaft", "shaft_tip", transform(p=[0, 0, l_tool])),
        Joint("wrist_pitch", "revolute", "instrument_shaft", "wrist_pitch_link",
              transform(p=[0, 0, l_tool]) @ dh_trailing(0, 0, -np.pi / 2) @ transform(rot_z(-np.pi / 2)),
              (0, 0, 1), (-wrist_lim, wrist_lim)),
        Joint("wrist_yaw", "revolute", "wrist_pitch_link", "wrist_yaw_link", dh_trailing(0, g.l_p2y, -np.pi / 2),
              (0, 0, 1), (-wrist_lim, wrist_lim)),
        Joint("jaw", "revolute", "wrist_yaw_link", "jaw_link", np.eye(4), (0, 0, 1),
              tuple(x * RAD_PER_DEG for x in P["jaw_range"])),
        Joint("tool_tip_frame", "fixed", "wrist_yaw_link", "tool_tip", dh_trailing(0, g.l_y2t, 0)),
        Joint("upper_fork_joint", "revolute", "drive_link", "upper_fork", transform(p=g.upper_on_drive), (0, 1, 0),
              passive),
        Joint("support_joint", "revolute", "roll_link", "support_link",
              transform(p=cs0 + [P["base_spacing"] * MM, 0, 0]), (0, 1, 0), passive),
    ]


def build_psm() -> str:
    """The PSM's URDF text."""
    comment = (" PSM of the rcm-kin project, written by urdf/generate.py from the osMDV parameter table:"
               " do not edit by hand. Open tree of the double parallelogram; the two loop closures and"
               " the actuated joints are in psm.toml beside this file. Inertia tensors are ESTIMATED"
               " (solid boxes carrying the CAD masses); see generate.py. ")
    layout = psm_layout()
    return write_urdf("psm", comment, _psm_links(layout), _psm_joints(layout))


# --------------------------------------------------------------------------------------------
# MTM
# --------------------------------------------------------------------------------------------
def build_mtm() -> str:
    P = MTM
    l_sho, l_arm, l_ball, l_imu = (P[k] * MM for k in ("l_sho", "l_arm", "l_ball", "l_imu"))
    R_b0 = rot_x(np.pi / 2)   # DH frame 0 (y up) in the base frame (z up)
    m_cw, r_cw, phi_cw = P["counterweight"][0], P["counterweight"][1] * MM, P["counterweight"][2] * RAD_PER_DEG
    cw_pos = np.array([-r_cw * np.cos(phi_cw), -r_cw * np.sin(phi_cw), 0.0])
    cw_radius = 0.015
    cw_len = brass_cylinder(m_cw, cw_radius)
    m_g3, m_g2, m_g1, m_g0 = P["gimbal"]
    arm_lim, gim_lim = P["arm_limit"] * RAD_PER_DEG, P["gimbal_limit"] * RAD_PER_DEG

    def link(name, key, size, visuals):
        m, c = P[key]
        return body(name, m, np.asarray(c) * MM, size, visuals=visuals)

    links = [
        Link("base_link", visuals=[
            Visual("box", (0.12, 0.12, 0.02), transform(p=[0, 0, -0.30]), "steel"),
            bar([0, 0, -0.30], [0, 0, -0.02], 0.03, 0.03, "steel")]),
        link("shoulder_link", "shoulder", (0.06, 0.04, 0.04), [
            bar([0, 0, 0], [l_sho, 0, 0], 0.03, 0.03, "printed"),
            bar([0, 0, 0], cw_pos, 0.01, 0.01, "steel")]),
        body("counterweight", m_cw, [0, 0, 0], (2 * cw_radius, 2 * cw_radius, cw_len), visuals=[
            Visual("cylinder", (cw_radius, cw_len), material="brass")]),
        link("upper_arm", "upper_arm", (l_arm, 0.015, 0.015), [
            bar([0, 0, 0], [l_arm, 0, 0], 0.015, 0.015, "aluminium")]),
        link("lower_arm", "lower_arm", (l_arm, 0.012, 0.012), [
            bar([0, 0, 0], [l_arm, 0, 0], 0.012, 0.012, "aluminium")]),
        Link("wrist_center", visuals=[marker(0.006)]),
        body("gimbal_g3", m_g3, [0, 0, 0], (0.05, 0.01, 0.05), visuals=[
            Visual("box", (0.05, 0.008, 0.05), material="printed")]),
        body("gimbal_g2", m_g2, [0, 0, 0], (0.04, 0.01, 0.04), visuals=[
            Visual("box", (0.04, 0.04, 0.008), material="printed")]),
        body("gimbal_g1", m_g1, [0, 0, 0.5 * l_imu], (0.02, 0.02, l_imu), visuals=[
            bar([0, 0, 0], [0, 0, l_imu], 0.012, 0.012, "printed")]),
        body("gimbal_g0", m_g0, [0.02, 0, 0], (0.04, 0.005, 0.01), visuals=[
            bar([0, 0, 0], [0.04, 0, 0], 0.005, 0.01, "steel")]),
        Link("tool_tip", visuals=[marker(0.004)]),
    ]
    # URDF joint origin i = trailing part of DH row i-1, then the joint offset of row i.
    joints = [
        Joint("j1", "revolute", "base_link", "shoulder_link", transform(R_b0), (0, 0, 1), (-arm_lim, arm_lim)),
        Joint("counterweight_mount", "fixed", "shoulder_link", "counterweight", transform(p=cw_pos)),
        Joint("j2", "revolute", "shoulder_link", "upper_arm", dh_trailing(0, l_sho, np.pi / 2), (0, 0, 1),
              (-arm_lim, arm_lim)),
        Joint("j3", "revolute", "upper_arm", "lower_arm",
              dh_trailing(0, l_arm, -np.pi / 2) @ transform(p=[0, 0, -l_ball]) @ transform(rot_z(-np.pi / 2)),
              (0, 0, 1), (-arm_lim, arm_lim)),
        Joint("wrist_center_frame", "fixed", "lower_arm", "wrist_center", transform(p=[l_arm, 0, 0])),
        Joint("g3", "revolute", "lower_arm", "gimbal_g3",
              dh_trailing(0, l_arm, -np.pi / 2) @ transform(rot_z(-np.pi / 2)), (0, 0, 1), (-gim_lim, gim_lim)),
        Joint("g2", "revolute", "gimbal_g3", "gimbal_g2", dh_trailing(0, 0, -np.pi / 2) @ transform(rot_z(-np.pi / 2)),
              (0, 0, 1), (-gim_lim, gim_lim)),
        Joint("g1", "revolute", "gimbal_g2", "gimbal_g1",
              dh_trailing(0, 0, -np.pi / 2) @ transform(p=[0, 0, -l_imu]) @ transform(rot_z(np.pi / 2)),
              (0, 0, 1), (-gim_lim, gim_lim)),
        Joint("tool_tip_frame", "fixed", "gimbal_g1", "tool_tip", dh_trailing(0, 0, -np.pi / 2)),
        Joint("g0", "revolute", "tool_tip", "gimbal_g0", np.eye(4), (0, 0, 1),
              tuple(x * RAD_PER_DEG for x in P["grip_range"])),
    ]
    comment = (" MTM of the rcm-kin project (left arm of the osMDV DH table), written by urdf/generate.py:"
               " do not edit by hand. Serial arm j1-j3 (shoulder pitch, shoulder yaw, elbow), gimbal g3, g2,"
               " g1 and the grip lever g0. Inertia tensors are ESTIMATED (solid boxes carrying the CAD"
               " masses); see generate.py. ")
    return write_urdf("mtm", comment, links, joints)


# --------------------------------------------------------------------------------------------
# da Vinci
# --------------------------------------------------------------------------------------------
AXES = {1: (1.0, 0.0, 0.0), 2: (0.0, 1.0, 0.0), 3: (0.0, 0.0, 1.0)}
ROT = {"x": rot_x, "y": rot_y, "z": rot_z}


def _davinci(name: str, rows, comment: str) -> str:
    """Joints named as in the thesis, links ``<joint>_link``; each link draws a bar to every
    child's origin."""
    link_name = lambda joint: joint if joint == "base_link" else f"{joint}_link"  # noqa: E731
    links = {"base_link": Link("base_link", visuals=[Visual("box", (0.3, 0.3, 0.02), material="steel")])}
    joints = []
    for joint, parent, T, kind, axis, limits in rows:
        links[joint] = Link(link_name(joint))
        offset = T[:3, 3]
        if np.linalg.norm(offset) > 1e-9:
            links[parent].visuals.append(bar([0, 0, 0], offset, 0.02, 0.02,
                                             "printed" if joint in ("upper_bar", "instrument_holder") else "aluminium"))
        limits = limits if limits is not None else ((-np.pi, np.pi) if kind == "revolute" else (-0.3, 0.3))
        joints.append(Joint(joint, kind, link_name(parent), link_name(joint), T, axis, limits))
    links["jaw_right"].visuals.append(marker(0.004))
    return write_urdf(name, comment, list(links.values()), joints)


def build_davinci() -> str:
    rows = []
    for name, parent, a, b, d, fixed, kind, ax, limits in DAVINCI:
        R = np.eye(3)
        for axis, angle in fixed:
            R = R @ ROT[axis](angle)
        rows.append((name, parent, transform(R, (a, b, d)), kind, tuple(np.sign(ax) * np.array(AXES[abs(ax)])),
                     limits))
    return _davinci("davinci", rows, " First-generation da Vinci patient-side arm p4, Table C.1 chain with the mimic"
                    " parallelogram (hand_pitch, upper_bar, instrument_holder turn together), from the AAU 2015"
                    " thesis's tables as collected in the project digest; written by urdf/generate.py: do not"
                    " edit by hand. Kinematics only (no source gives masses). ")


def build_davinci_rcm() -> str:
    rows = [(name, parent, transform(rot_z(0.0) @ rot_y(pitch) @ rot_x(roll), (a, b, d)), kind, (0.0, 0.0, 1.0),
             limits) for name, parent, a, b, d, roll, pitch, kind, limits in DAVINCI_RCM]
    return _davinci("davinci_rcm", rows, " First-generation da Vinci patient-side arm p4, the reduced chain of Table"
                    " C.7: active joints only, hand_roll and hand_pitch at the remote centre of motion, the"
                    " instrument shaft left out (the wrist sits 0.097 - slide from the RCM); written by"
                    " urdf/generate.py: do not edit by hand. Kinematics only. ")


OUTPUTS = {"psm.urdf": build_psm, "mtm.urdf": build_mtm, "davinci.urdf": build_davinci,
           "davinci_rcm.urdf": build_davinci_rcm}


def main(argv: list[str]) -> int:
    check = "--check" in argv
    stale = []
    for filename, build in OUTPUTS.items():
        text = build()
        path = HERE / filename
        if check:
            if not path.exists() or path.read_text() != text:
                stale.append(filename)
        else:
            path.write_text(text)
            print(f"wrote {path}")
    if stale:
        print(f"error: {', '.join(stale)} differ from urdf/generate.py; run: python urdf/generate.py")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
