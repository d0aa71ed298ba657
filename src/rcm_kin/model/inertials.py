"""Physically possible link inertias, checked once where a URDF is loaded, each error naming the link.

- :func:`check_inertials`: every ``<inertial>`` of the URDF's XML, before urdfdom sees it (urdfdom
  drops an inertial it cannot read, a ``nan`` mass, with lines on stderr and no error): a mass that
  is a finite number > 0 (a massless link has no ``<inertial>``, or the all-zero placeholder many
  ROS URDFs give frame links: zero mass and zero inertia), a finite rotational inertia whose
  principal moments are >= 0 and satisfy the triangle inequality (each at most the sum of the other
  two, as every rigid body's do: I_a + I_b - I_c = 2 * integral of c^2 dm >= 0).
- :func:`check_bodies`: the model Pinocchio built, after merging the links fixed to each other into
  one body per joint: each body has the mass its links' ``<inertial>`` elements give (else the
  parser dropped one) and a positive semidefinite pseudo-inertia (Pinocchio's
  ``toPseudoInertia``: the condition for a physically consistent body, mass, lever and inertia
  together).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin

from rcm_kin.errors import RcmKinError

MOMENTS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
RELATIVE_TOL = 1e-9   # of the largest principal moment (or pseudo-inertia eigenvalue): rounding in the file


def _value(element: ET.Element, key: str, what: str) -> float:
    """The number ``key`` of ``element`` (``what``: the link and element, for the error)."""
    text = element.get(key)
    if text is None:
        raise RcmKinError(f"{what} has no {key}")
    try:
        return float(text)
    except ValueError:
        raise RcmKinError(f"{what}: {key} must be a number, got {text!r}"[:300]) from None


def principal_moments(inertial: ET.Element, what: str) -> np.ndarray:
    """The principal moments (kg m^2, ascending) of an ``<inertial>``'s ``<inertia>`` element."""
    element = inertial.find("inertia")
    if element is None:
        raise RcmKinError(f"{what} has no <inertia> (ixx ... izz, kg m^2)")
    xx, xy, xz, yy, yz, zz = (_value(element, key, f"{what} <inertia>") for key in MOMENTS)
    tensor = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    if not np.all(np.isfinite(tensor)):
        raise RcmKinError(f"{what}: <inertia> must be finite, got {dict(zip(MOMENTS, tensor[np.triu_indices(3)]))}")
    return np.linalg.eigvalsh(tensor)


def check_inertials(root: ET.Element, where: str) -> dict[str, float]:
    """Every link's ``<inertial>`` in the URDF ``root`` (``where``: its file): mass finite > 0 (kg),
    principal moments >= 0 satisfying the triangle inequality; else one error naming the link.
    Returns each link's mass (kg), for the links that give one."""
    masses: dict[str, float] = {}
    for link in root.findall("link"):
        for inertial in link.findall("inertial"):
            name = link.get("name", "")
            what = f"{where}: link '{name}'"
            mass_element = inertial.find("mass")
            if mass_element is None:
                raise RcmKinError(f"{what}: <inertial> has no <mass> (kg; leave the <inertial> out of a massless link)")
            mass = _value(mass_element, "value", f"{what} <mass>")
            moments = principal_moments(inertial, what)
            if mass == 0.0 and not moments.any():
                continue                     # an all-zero placeholder (ROS frame links, UR's ee_link): no mass
            if not np.isfinite(mass) or mass <= 0.0:
                raise RcmKinError(f"{what}: mass = {mass:g} kg; a link's mass is a finite number > 0 (leave the "
                                  "<inertial> out of a massless link)")
            tol = RELATIVE_TOL * max(abs(moments).max(), np.finfo(float).tiny)
            a, b, c = moments
            if a < -tol:
                raise RcmKinError(f"{what}: principal moments {a:.6g}, {b:.6g}, {c:.6g} kg m^2: each must be >= 0")
            if a + b < c - tol:
                raise RcmKinError(f"{what}: principal moments {a:.6g}, {b:.6g}, {c:.6g} kg m^2 violate the triangle "
                                  f"inequality ({a:.6g} + {b:.6g} < {c:.6g}); every rigid body has each at most the "
                                  "sum of the other two")
            masses[name] = masses.get(name, 0.0) + mass
    return masses


def body_links(tree: pin.Model) -> dict[int, list[str]]:
    """Joint index -> the links of the rigid body it moves (links fixed to each other), tree order."""
    bodies: dict[int, list[str]] = {}
    for frame in tree.frames:
        if frame.type == pin.FrameType.BODY and frame.parentJoint > 0:
            bodies.setdefault(frame.parentJoint, []).append(frame.name)
    return bodies


def check_bodies(tree: pin.Model, masses: dict[str, float], where: str) -> None:
    """Each moving body of ``tree`` has the mass its links' ``<inertial>`` elements give (``masses``,
    kg: :func:`check_inertials`; else the URDF parser dropped one) and a positive semidefinite
    pseudo-inertia; one error naming the links otherwise."""
    for j, links in sorted(body_links(tree).items()):
        given = [link for link in links if link in masses]
        if not given:
            continue
        body, expected = tree.inertias[j], sum(masses[link] for link in given)
        what = f"{where}: link{'s' if len(given) > 1 else ''} {', '.join(repr(x) for x in given)}"
        if not np.isfinite(body.mass) or abs(body.mass - expected) > RELATIVE_TOL * expected:
            raise RcmKinError(f"{what} give <inertial> masses of {expected:g} kg but the model's body has "
                              f"{body.mass:g} kg: the URDF parser dropped an inertial")
        pseudo = np.asarray(body.toPseudoInertia().toMatrix())
        eigenvalues = np.linalg.eigvalsh(0.5 * (pseudo + pseudo.T)) if np.all(np.isfinite(pseudo)) else [-np.inf]
        if min(eigenvalues) < -RELATIVE_TOL * max(abs(np.asarray(eigenvalues)).max(), 1.0):
            raise RcmKinError(f"{what}: the body's mass, centre of mass and inertia are not those of a rigid body "
                              "(Pinocchio's pseudo-inertia is not positive semidefinite)")
