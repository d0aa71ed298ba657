"""The reduced model: the closed chain in actuated coordinates.

Each passive joint of a loop follows an actuated joint linearly (``[[passive]]`` in the
sidecar); for a parallelogram this is exact. The relations become Pinocchio mimic joints, so
kinematics, RNEA, CRBA and gravity of the reduced model are Pinocchio's own. (Pinocchio's
ABA and analytic derivatives do not support mimic joints.)
"""

from __future__ import annotations

import functools

import numpy as np
import pinocchio as pin

from rcm_kin.model.description import PassiveRelation
from rcm_kin.model.robot import Robot


def build_reduced_model(tree: pin.Model, passive: tuple[PassiveRelation, ...]) -> pin.Model:
    """The open tree with every passive joint turned into a mimic of the joint it follows."""
    model = tree
    for relation in passive:
        model = pin.transformJointIntoMimic(
            model, model.getJointId(relation.follows), model.getJointId(relation.joint),
            relation.multiplier, relation.offset)
    model.gravity = tree.gravity
    return model


def tree_configuration(robot: Robot, q) -> np.ndarray:
    """Open-tree configuration(s) of actuated ``q``, passive joints from the linear relations:
    ``q_tree = S q + offsets``. ``q`` is one pose (nq,) or a stack (N, nq)."""
    S, offsets = _linear_relations(robot)
    return np.asarray(q, dtype=float) @ S.T + offsets


def relation_jacobian(robot: Robot) -> np.ndarray:
    """``S = d q_tree / d q`` of the linear relations: (tree nv) x (actuated), constant."""
    return _linear_relations(robot)[0].copy()


@functools.lru_cache(maxsize=None)
def _linear_relations(robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """``S`` and the offsets of ``q_tree = S q + offsets``, built once per robot (read-only)."""
    S = np.zeros((robot.tree.nv, robot.nq))
    S[robot.tree_q_actuated, np.arange(robot.nq)] = 1.0
    offsets = np.zeros(robot.tree.nq)
    actuated = robot.description.actuated
    for k, relation in enumerate(robot.description.passive):
        S[robot.tree_q_passive[k], actuated.index(relation.follows)] = relation.multiplier
        offsets[robot.tree_q_passive[k]] = relation.offset
    S.flags.writeable = offsets.flags.writeable = False
    return S, offsets


def reduced_mass_matrix(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Joint-space inertia of the reduced model in actuated order (kg m^2, kg).

    Uses ``Convention.WORLD``: with mimic joints, Pinocchio 4.1's default (LOCAL) CRBA
    accumulates error across calls on the same Data (tests/model/test_closure.py guards this).
    """
    M = pin.crba(robot.reduced, robot.reduced_data, robot.to_reduced(q), pin.Convention.WORLD)
    M = np.triu(M) + np.triu(M, 1).T
    i = robot.reduced_q_actuated
    return M[np.ix_(i, i)]


def reduced_gravity(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Generalised gravity of the reduced model in actuated order (N m, N)."""
    g = pin.computeGeneralizedGravity(robot.reduced, robot.reduced_data, robot.to_reduced(q))
    return robot.from_reduced(g).copy()
