"""rcm-kin on a ROS 2 graph: the teleoperation, gravity-feedforward, live-view and capture nodes.

- :mod:`.messages`: ``JointState`` fields <-> SI arrays (the firmware's and the CRTK conventions),
  malformed messages, the per-node tally of messages and latencies;
- :mod:`.teleop`, :mod:`.gravity`: one message's work as arrays, the models built once (no rclpy);
- :mod:`.view`: the live meshcat view of both robots;
- :mod:`.nodes`: the rclpy plumbing (QoS, topics, parameters, clean stop on SIGINT/SIGTERM);
  rclpy is imported when a node starts (the ``ros2`` extra: ``pip install 'rcm-kin[ros2]'``).
"""

import lazy_loader

__all__ = ["GravityStep", "MalformedMessage", "NodeOptions", "TeleopStep", "loopback_environment", "run_gravity",
           "run_record", "run_teleop", "run_view"]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "messages": ["MalformedMessage"],
        "teleop": ["TeleopStep"],
        "gravity": ["GravityStep"],
        "nodes": ["NodeOptions", "run_teleop", "run_gravity", "run_record", "loopback_environment"],
        "view": ["run_view"],
    },
)
