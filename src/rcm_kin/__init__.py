"""rcm-kin: models of a low-cost da Vinci-style RCM surgical robot, turned into controllers.

Pinocchio is the numeric engine. Start with :func:`rcm_kin.robot.load_robot`.
"""

from rcm_kin.errors import RcmKinError
from rcm_kin.robot import Robot, load_robot, robot_names

__all__ = ["RcmKinError", "Robot", "load_robot", "robot_names"]
__version__ = "0.1.0"
