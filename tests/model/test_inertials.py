"""A robot description's inertias are those of rigid bodies: a link mass that is negative, zero or
not a number, or principal moments that are negative or break the triangle inequality, are one
error naming the link, never a model that loads with a dropped or impossible inertial."""

from __future__ import annotations

import numpy as np
import pytest

from rcm_kin import RcmKinError, load_robot
from rcm_kin.model.inertials import check_bodies
from rcm_kin.model.loading import urdf_dir
from rcm_kin.model.urdf_text import build_tree, read_urdf

PSM = (urdf_dir() / "psm.urdf").read_text()
ROLL_MASS = '<mass value="0.875" />'                 # roll_link's
ROLL_IXX = 'ixx="0.0015166666666666666"'              # roll_link's (iyy 0.0011958, izz 0.0017792)


def psm_variant(tmp_path, old: str, new: str):
    assert PSM.count(old) == 1
    path = tmp_path / "psm_variant.urdf"
    path.write_text(PSM.replace(old, new))
    return path


@pytest.mark.parametrize("new, says", [
    ('<mass value="-0.875" />', "mass = -0.875 kg"),
    ('<mass value="nan" />', "mass = nan kg"),
    ('<mass value="0" />', "mass = 0 kg"),
    ('<mass value="heavy" />', "value must be a number"),
])
def test_a_link_mass_that_is_not_finite_and_positive_names_the_link(tmp_path, capfd, new, says):
    with pytest.raises(RcmKinError) as raised:
        load_robot(psm_variant(tmp_path, ROLL_MASS, new))
    message = str(raised.value)
    assert "link 'roll_link'" in message and says in message and "\n" not in message
    assert capfd.readouterr().err == ""            # nothing from the URDF parser on stderr


@pytest.mark.parametrize("new, says", [
    ('ixx="0.015"', "violate the triangle inequality"),     # 0.0012 + 0.0018 < 0.015
    ('ixx="-0.0015"', "each must be >= 0"),
    ('ixx="inf"', "must be finite"),
])
def test_impossible_principal_moments_name_the_link(tmp_path, new, says):
    with pytest.raises(RcmKinError, match="link 'roll_link'") as raised:
        load_robot(psm_variant(tmp_path, ROLL_IXX, new))
    assert says in str(raised.value)


def test_a_thin_rod_at_an_angle_is_a_rigid_body(tmp_path):
    # a rod along (1, 1, 0)/sqrt(2): principal moments 0, I, I (the triangle inequality's edge), I = m L^2 / 12
    inertia = 0.875 * 0.3**2 / 12
    t = (inertia * (np.eye(3) - np.outer([1, 1, 0], [1, 1, 0]) / 2)).tolist()
    old = ('<inertia ixx="0.0015166666666666666" ixy="0" ixz="0" iyy="0.0011958333333333335" iyz="0" '
           'izz="0.001779166666666667" />')
    new = f'<inertia ixx="{t[0][0]!r}" ixy="{t[0][1]!r}" ixz="0" iyy="{t[1][1]!r}" iyz="0" izz="{t[2][2]!r}" />'
    robot = load_robot(psm_variant(tmp_path, old, new))
    body = robot.tree.inertias[robot.tree.getJointId("roll")]
    assert body.mass > 0


def test_an_inertial_the_parser_dropped_is_an_error():
    # roll_link's inertial removed from the text the model is built from, still listed as given
    start = PSM.index("<inertial>", PSM.index('<link name="roll_link"'))
    text = PSM[:start] + PSM[PSM.index("</inertial>", start) + len("</inertial>"):]
    facts = read_urdf(text, "psm.urdf")
    tree = build_tree(facts, "psm.urdf")
    masses = {**facts.masses, "roll_link": 0.875}
    with pytest.raises(RcmKinError, match=r"'roll_link', 'main_counterweight' give <inertial> masses of 3.505 kg but "
                                          r"the model's body has 2.63 kg: the URDF parser dropped an inertial"):
        check_bodies(tree, masses, "psm.urdf")
    check_bodies(tree, facts.masses, "psm.urdf")     # the inertials it has are all there


def test_every_bundled_robot_passes():
    for name in ("psm", "mtm", "davinci", "davinci_rcm"):
        for counterweights in (True, False):
            load_robot(name, counterweights)
