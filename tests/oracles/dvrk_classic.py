"""A dVRK Classic PSM description generated from its published modified-DH table, and that
table's own forward kinematics, for tests.

The table is the dVRK's PSM kinematics (sawIntuitiveResearchKit ``psm.json`` / the dVRK user
guide; Kazanzides et al. 2014): outer yaw, outer pitch, insertion, tool roll, wrist pitch, wrist
yaw, with l_RCC = 0.4318 m, l_tool = 0.4162 m, pitch-to-yaw 0.0091 m, yaw-to-tip 0.0102 m.
The URDF is written as ``dvrk_model``'s PSM is: the pitch parallelogram an open chain of
``continuous`` joints with ``<mimic>`` tags (the third mimics the second: a mimic chain), the jaw's
second half a ``continuous`` mimic, visual meshes ``package://dvrk_model/meshes/...`` (tiny ASCII
STL boxes written into a temporary package folder) and NO ``<inertial>`` anywhere (optionally
boxes of 0.1 kg, ``inertials=True``, for tests that need masses).

Use :func:`write_dvrk_psm` (paths in a folder) and :func:`dh_frames` (4x4 poses from the table
alone). Nothing here imports rcm_kin.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

L_RCC, L_TOOL, L_PITCH2YAW, L_YAW2TIP = 0.4318, 0.4162, 0.0091, 0.0102
PI2 = np.pi / 2

# Modified DH rows (alpha, a, theta offset, d offset, kind): T_i = Rx(alpha) Tx(a) Rz(theta) Tz(d),
# q added to theta (revolute) or d (prismatic).
DH = [(PI2, 0.0, PI2, 0.0, "revolute"),
      (-PI2, 0.0, -PI2, 0.0, "revolute"),
      (PI2, 0.0, 0.0, -L_RCC, "prismatic"),
      (0.0, 0.0, 0.0, L_TOOL, "revolute"),
      (-PI2, 0.0, -PI2, 0.0, "revolute"),
      (-PI2, L_PITCH2YAW, -PI2, 0.0, "revolute")]
TIP = np.array([[0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 1.0, L_YAW2TIP], [-1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])

ACTUATED = ("outer_yaw", "outer_pitch", "outer_insertion", "outer_roll", "outer_wrist_pitch", "outer_wrist_yaw",
            "jaw")
LIMITS = {"outer_yaw": (-1.5707, 1.5707), "outer_pitch": (-0.7854, 0.7854), "outer_insertion": (0.0, 0.24),
          "outer_roll": (-4.5379, 4.5379), "outer_wrist_pitch": (-1.3963, 1.3963),
          "outer_wrist_yaw": (-1.3963, 1.3963), "jaw": (0.0, 1.0472)}
# Frames of the DH chain, by the URDF link that carries each: frame 3 (shaft, z along it),
# frame 6 (wrist yaw), the tool tip.
SHAFT, WRIST, TOOL_TIP = "tool_main_link", "tool_wrist_yaw_link", "tool_tip_link"
# Parallelogram bars in the pitch plane (m): back bar, bottom bar (arbitrary, not the dVRK's).
V1, V2 = np.array([-0.10, 0.05, 0.0]), np.array([0.04, 0.22, 0.0])


def _rx(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _rz(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _ry(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _trans(x=0.0, y=0.0, z=0.0):
    T = np.eye(4)
    T[:3, 3] = [x, y, z]
    return T


def modified_dh(alpha, a, theta, d) -> np.ndarray:
    """Craig's modified DH: Rx(alpha) Tx(a) Rz(theta) Tz(d)."""
    return _rx(alpha) @ _trans(a) @ _rz(theta) @ _trans(z=d)


def dh_frames(q) -> dict[str, np.ndarray]:
    """4x4 poses in the base (DH frame 0, at the RCM) of the shaft (frame 3), the wrist (frame 6)
    and the tool tip, from the DH table alone, for q = the six DH joints (more values ignored)."""
    T, out = np.eye(4), {}
    for i, (alpha, a, theta, d, kind) in enumerate(DH):
        moved = (theta + q[i], d) if kind == "revolute" else (theta, d + q[i])
        T = T @ modified_dh(alpha, a, *moved)
        if i == 2:
            out[SHAFT] = T.copy()
    out[WRIST], out[TOOL_TIP] = T.copy(), T @ TIP
    return out


def _rpy(T: np.ndarray) -> tuple[float, float, float]:
    """URDF rpy of a rotation R = Rz(y) Ry(p) Rx(r) (yaw 0 at pitch +-pi/2), checked to give R back."""
    R = T[:3, :3]
    pitch = float(np.arctan2(-R[2, 0], np.hypot(R[2, 1], R[2, 2])))
    if np.hypot(R[2, 1], R[2, 2]) > 1e-12:
        roll, yaw = float(np.arctan2(R[2, 1], R[2, 2])), float(np.arctan2(R[1, 0], R[0, 0]))
    else:
        roll, yaw = float(np.arctan2(np.sign(-R[2, 0]) * R[0, 1], R[1, 1])), 0.0
    back = _rz(yaw)[:3, :3] @ _ry(pitch) @ _rx(roll)[:3, :3]
    if not np.allclose(back, R, atol=1e-14):
        raise ValueError(f"no rpy found for {R}")
    return roll, pitch, yaw


def _origin(T: np.ndarray) -> str:
    xyz = " ".join(repr(float(v)) for v in T[:3, 3])
    return f'<origin xyz="{xyz}" rpy="{" ".join(repr(float(v)) for v in _rpy(T))}"/>'


def _stl(size: float) -> str:
    """An ASCII STL box of edge ``size`` (m), 12 triangles."""
    h = size / 2
    corners = np.array([[x, y, z] for x in (-h, h) for y in (-h, h) for z in (-h, h)])
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    lines = ["solid box"]
    for a, b, c, d in faces:
        for tri in ((a, b, c), (a, c, d)):
            vertices = [f"vertex {' '.join(repr(float(v)) for v in corners[k])}" for k in tri]
            lines += ["facet normal 0 0 0", "outer loop", *vertices, "endloop", "endfacet"]
    return "\n".join([*lines, "endsolid box", ""])


@dataclass(frozen=True)
class DvrkPsm:
    """The files of one generated description."""

    urdf: Path
    sidecar: Path | None      # with [rcm] (shaft tool_main_link, pivots outer_yaw and outer_pitch)
    package_dir: Path         # the dvrk_model package folder (its meshes/ inside)

    @property
    def packages(self) -> dict[str, Path]:
        """``{"dvrk_model": package_dir}``, as ``package_dirs``/``--package-dir`` take it."""
        return {"dvrk_model": self.package_dir}


# (joint, type, parent, child, 4x4 origin, axis, mimic (joint, multiplier) or None)
def links() -> list[str]:
    """The URDF's links, base first."""
    return ["psm_base_link", *(row[3] for row in _joints())]


def _joints() -> list[tuple]:
    rows = [("outer_yaw", "revolute", "psm_base_link", "outer_yaw_link", modified_dh(PI2, 0, PI2, 0), None)]
    frame2 = modified_dh(-PI2, 0, -PI2, 0)                 # DH frame 2 at q = 0, in frame 1
    rows += [("outer_pitch", "revolute", "outer_yaw_link", "outer_pitch_back_link", frame2 @ _trans(*-V2), None),
             ("outer_pitch_1", "continuous", "outer_pitch_back_link", "outer_pitch_bottom_link", _trans(*V1),
              ("outer_pitch", -1.0)),
             ("outer_pitch_2", "continuous", "outer_pitch_bottom_link", "outer_pitch_end_link", _trans(*V2),
              ("outer_pitch_1", -1.0)),
             ("outer_insertion", "prismatic", "outer_pitch_end_link", SHAFT,
              _trans(*-V1) @ modified_dh(PI2, 0, 0, -L_RCC), None),
             ("outer_roll", "revolute", SHAFT, "tool_roll_link", modified_dh(0, 0, 0, L_TOOL), None),
             ("outer_wrist_pitch", "revolute", "tool_roll_link", "tool_wrist_pitch_link",
              modified_dh(-PI2, 0, -PI2, 0), None),
             ("outer_wrist_yaw", "revolute", "tool_wrist_pitch_link", WRIST, modified_dh(-PI2, L_PITCH2YAW, -PI2, 0),
              None),
             ("tool_tip", "fixed", WRIST, TOOL_TIP, TIP, None),
             ("jaw", "revolute", WRIST, "jaw_1_link", np.eye(4), None),
             ("jaw_2", "continuous", WRIST, "jaw_2_link", np.eye(4), ("jaw", -1.0)),
             ("remote_center", "fixed", "psm_base_link", "remote_center_link", np.eye(4), None)]
    return rows


def urdf_text(robot: str = "dvrk_psm", inertials: bool = False) -> str:
    """The URDF (meshes named ``package://dvrk_model/meshes/classic/psm/<link>.stl``)."""
    joints = _joints()
    out = [f'<?xml version="1.0"?>\n<robot name="{robot}">']
    for link in links():
        body = (f'<visual><geometry><mesh filename="package://dvrk_model/meshes/classic/psm/{link}.stl"/>'
                '</geometry></visual>')
        if inertials and link != "psm_base_link" and not link.endswith(("tip_link", "center_link")):
            body += ('<inertial><origin xyz="0.01 0.02 0.03"/><mass value="0.1"/>'
                     '<inertia ixx="1e-4" iyy="1e-4" izz="1e-4" ixy="0" ixz="0" iyz="0"/></inertial>')
        out.append(f'  <link name="{link}">{body}</link>')
    for name, kind, parent, child, T, mimic in joints:
        inner = f'<parent link="{parent}"/><child link="{child}"/>{_origin(T)}'
        if kind != "fixed":
            inner += '<axis xyz="0 0 1"/>'
        if kind in ("revolute", "prismatic"):
            lo, hi = LIMITS[name]
            inner += f'<limit lower="{lo!r}" upper="{hi!r}" effort="10" velocity="2"/>'
        if mimic is not None:
            inner += f'<mimic joint="{mimic[0]}" multiplier="{mimic[1]!r}" offset="0"/>'
        out.append(f'  <joint name="{name}" type="{kind}">{inner}</joint>')
    return "\n".join([*out, "</robot>", ""])


SIDECAR = """robot = "{robot}"
urdf = "{urdf}"
frames = ["tool_main_link", "tool_wrist_yaw_link", "tool_tip_link", "remote_center_link"]

[rcm]
shaft_frame = "tool_main_link"
joints = ["outer_yaw", "outer_pitch"]
"""


def write_dvrk_psm(folder: str | Path, *, robot: str = "dvrk_psm", sidecar: bool = True, inertials: bool = False,
                   extra_sidecar: str = "") -> DvrkPsm:
    """Write ``<folder>/dvrk_model`` (package.xml, meshes), ``<folder>/<robot>.urdf`` and, when
    ``sidecar``, ``<folder>/<robot>.toml`` (robot, urdf, frames, [rcm]; ``extra_sidecar`` appended)."""
    folder = Path(folder)
    package = folder / "dvrk_model"
    meshes = package / "meshes" / "classic" / "psm"
    meshes.mkdir(parents=True, exist_ok=True)
    (package / "package.xml").write_text("<package><name>dvrk_model</name></package>\n")
    text = urdf_text(robot, inertials)
    for link in links():
        (meshes / f"{link}.stl").write_text(_stl(0.01))
    urdf = folder / f"{robot}.urdf"
    urdf.write_text(text)
    toml = None
    if sidecar:
        toml = folder / f"{robot}.toml"
        toml.write_text(SIDECAR.format(robot=robot, urdf=urdf.name) + extra_sidecar)
    return DvrkPsm(urdf, toml, package)
