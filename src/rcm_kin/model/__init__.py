"""The generic robot model: a description (URDF + sidecar), its loading, the ``Robot`` type, the
closed chain (constrained and reduced) and gravity. It names no particular robot.

- :mod:`.description`: the sidecar format (actuated joints, frames, loops, passive relations)
- :mod:`.robot`: the ``Robot`` type (models and index maps; scratch data per caller)
- :mod:`.loading`: URDF + sidecar -> ``Robot``, cached by the files' content
- :mod:`.constrained`: the open tree plus Pinocchio constraint models joining each cut bar
- :mod:`.reduced`: the model in actuated coordinates (passive joints as Pinocchio mimic joints)
- :mod:`.joints`: joint axes and the joint table
- :mod:`.gravity`: holding torques, one pose or vectorised over many
- :mod:`.masses`: links without inertial data (refused or warned about, never a silent zero)
- :mod:`.urdf_text`: what is read from the URDF text (mimic tags, continuous joints, inertials)
"""

from rcm_kin.model.gravity import gravity_batch, gravity_torque
from rcm_kin.model.joints import joint_axes_world, joint_table  # noqa: F401 (joint_axes_world: kept importable)
from rcm_kin.model.loading import (
           GRAVITY,
           build_robot,
           load_robot,
           robot_names,
)
from rcm_kin.model.masses import require_masses
from rcm_kin.model.reduced import tree_configuration
from rcm_kin.model.robot import JointRow, Robot, RobotData

__all__ = ["GRAVITY", "JointRow", "Robot", "RobotData", "build_robot", "gravity_batch", "gravity_torque",
           "joint_table", "load_robot", "require_masses", "robot_names", "tree_configuration"]
