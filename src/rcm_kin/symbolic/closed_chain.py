"""Inverse dynamics of a closed chain in its independent coordinates, on CasADi symbols.

A loop-closed mechanism whose open tree is parametrised by independent coordinates ``q``
through ``q_tree = phi(q)`` (any CasADi expression; for the bundled robots the sidecar's linear
passive-joint relations) moves with ``v_tree = J v`` and ``a_tree = J a + (dJ/dt) v``,
``J = d phi / d q``. By virtual work the generalised forces are ``tau = J^T tau_tree``.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from rcm_kin.symbolic.tree import JointKinematics, rnea


def closed_chain_rnea(joints: list[JointKinematics], gravity: np.ndarray, phi, q, v, a) -> ca.SX:
    """``tau(q, v, a)`` in independent coordinates (N m, N). ``phi``: CasADi expression of
    ``q`` giving the open-tree configuration; ``q, v, a``: CasADi symbols."""
    J = ca.jacobian(phi, q)
    v_tree = J @ v
    a_tree = J @ a + ca.jtimes(v_tree, q, v)
    return J.T @ rnea(joints, gravity, phi, v_tree, a_tree)


def linear_closure(S: np.ndarray, offsets: np.ndarray, q) -> ca.SX:
    """``phi(q) = S q + offsets``: the closure map of linear passive-joint relations."""
    return ca.DM(S) @ q + ca.DM(offsets)
