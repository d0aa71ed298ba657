"""Joints and link masses of the PSM and the MTM, and the kinematic self-checks."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import ClassVar

from rcm_kin.atomic import write_text
from rcm_kin.kinematics.self_check import KinematicChecks, kinematic_checks
from rcm_kin.model import joint_table, load_robot
from rcm_kin.report.render import Table


@dataclass(frozen=True)
class RobotModel:
    robot: str
    loops: tuple[str, ...]
    total_mass: float      # kg, every link with an inertial
    joints: Table
    masses: Table


@dataclass(frozen=True)
class ModelsSection:
    template: ClassVar[str] = "models.html.j2"
    models: tuple[RobotModel, ...]
    checks: KinematicChecks
    checks_table: Table
    files: dict[str, str]          # name -> path relative to the report folder


def model_summary(name: str) -> dict:
    """Joints with limits and the mass of every link of a bundled robot (kg), as plain data. (yourdfpy
    is imported here, not with the module: it imports trimesh, 0.6-0.8 s, which the report's
    other pieces do not need.)"""
    import yourdfpy

    robot = load_robot(name)
    urdf = yourdfpy.URDF.load(str(robot.description.urdf), build_scene_graph=False, load_meshes=False)
    masses = {link.name: link.inertial.mass for link in urdf.robot.links if link.inertial is not None}
    joints = [dict(name=j.name, kind=j.kind, role=j.role, lower=j.lower, upper=j.upper) for j in joint_table(robot)]
    return dict(robot=name, joints=joints, link_masses=masses, total_mass=float(sum(masses.values())),
                loops=[c.loop.name for c in robot.constraints])


def _model(summary: dict) -> RobotModel:
    joints = Table.of([[j["name"], j["kind"], j["role"], f"{j['lower']:.4f}", f"{j['upper']:.4f}"]
                       for j in summary["joints"]], ["joint", "type", "role", "lower", "upper"])
    masses = Table.of([[k, f"{v:.4f}"] for k, v in summary["link_masses"].items()], ["link", "mass (kg)"])
    return RobotModel(summary["robot"], tuple(summary["loops"]), summary["total_mass"], joints, masses)


def models_section(out: Path, names=("psm", "mtm"), samples: int = 200) -> ModelsSection:
    """Summaries of ``names`` and the self-checks on ``samples`` random PSM configurations;
    writes model_summary.json and kinematic_checks.json into ``out``."""
    summaries = [model_summary(n) for n in names]
    checks = kinematic_checks(samples)
    write_text(out / "model_summary.json", json.dumps(summaries, indent=1))
    write_text(out / "kinematic_checks.json", json.dumps(asdict(checks), indent=1))
    table = Table.of([[k, f"{v:.2e}"] for k, v in asdict(checks).items() if k != "samples"],
                     ["largest discrepancy", "value (SI)"])
    return ModelsSection(tuple(_model(s) for s in summaries), checks, table,
                         {"model_summary.json": "model_summary.json", "kinematic_checks.json": "kinematic_checks.json"})
