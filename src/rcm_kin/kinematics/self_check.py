"""Kinematic self-checks of the bundled models: the largest discrepancies between routes that
must agree, over random configurations.

- loop closure: the passive joints by a Newton solve against the sidecar's linear relations,
  and the closure residual there;
- the constrained (tree plus loop constraints) against the reduced (mimic) model: gravity and
  mass matrix;
- the RCM: distance of the fixed remote centre from the shaft line;
- inverse kinematics round trips: the PSM's closed-form shaft-tip IK, the MTM's numeric IK of
  the wrist centre.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from rcm_kin.kinematics.fk import frame_placement
from rcm_kin.kinematics.numeric_ik import solve_ik
from rcm_kin.kinematics.psm_ik import rcm_geometry, shaft_tip_ik
from rcm_kin.model import constrained, load_robot, reduced


@dataclass(frozen=True)
class KinematicChecks:
    """Largest discrepancies over random configurations (SI units)."""

    samples: int
    loop_solve_vs_relations: float     # rad, passive joints: Newton solve vs linear relations
    closure_residual: float            # m
    gravity_constrained_vs_reduced: float   # N m
    mass_matrix_constrained_vs_reduced: float
    rcm_distance_to_shaft: float       # m
    psm_ik_round_trip: float           # m, shaft tip
    mtm_ik_round_trip: float           # m, wrist centre


def _psm_discrepancies(psm, q: np.ndarray, rcm: np.ndarray) -> tuple[float, ...]:
    """(loop, residual, gravity, mass, rcm, ik) discrepancies of the PSM at ``q``."""
    q_tree = constrained.solve_loops(psm, q)
    loop = np.max(np.abs(q_tree - reduced.tree_configuration(psm, q)))
    residual = np.max(np.abs(constrained.closure_residual(psm, q_tree)))
    g_tree = pin.computeGeneralizedGravity(psm.tree, psm.tree_data, q_tree)
    gravity = np.max(np.abs(constrained.project_torques(psm, q_tree, g_tree).tau - reduced.reduced_gravity(psm, q)))
    mass = np.max(np.abs(constrained.mass_matrix(psm, q_tree) - reduced.reduced_mass_matrix(psm, q)))
    tip = frame_placement(psm, q, "shaft_tip")
    rcm_distance = np.linalg.norm(np.cross(rcm - tip.translation, tip.rotation[:, 2]))
    q_ik = psm.check_q(shaft_tip_ik(psm, tip.translation), allow_short=True)
    ik = np.linalg.norm(frame_placement(psm, q_ik, "shaft_tip").translation - tip.translation)
    return loop, residual, gravity, mass, rcm_distance, ik


def kinematic_checks(samples: int = 200, seed: int = 0) -> KinematicChecks:
    """The checks on ``samples`` random PSM configurations (and a tenth as many, at least one,
    MTM wrist-centre IK round trips, within 60 % of its joint ranges)."""
    psm, mtm = load_robot("psm"), load_robot("mtm")
    rng = np.random.default_rng(seed)
    rcm = rcm_geometry(psm).rcm
    worst = np.zeros(6)
    for _ in range(samples):
        worst = np.maximum(worst, _psm_discrepancies(psm, rng.uniform(psm.lower, psm.upper), rcm))
    mtm_ik = 0.0
    for _ in range(max(1, samples // 10)):
        qm = rng.uniform(mtm.lower, mtm.upper) * 0.6
        target = frame_placement(mtm, qm, "wrist_center").translation
        mtm_ik = max(mtm_ik, solve_ik(mtm, "wrist_center", target, joints=("j1", "j2", "j3")).position_error)
    return KinematicChecks(samples, *(float(w) for w in worst), float(mtm_ik))
