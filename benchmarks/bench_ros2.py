"""Per-message latency and loss of ``rcm-kin ros2 teleop`` and ``ros2 gravity`` beside a bare echo
node, same run, on a loopback-only graph (:func:`rcm_kin.ros2.nodes.loopback_environment`: a FastDDS profile with one
UDPv4 transport on 127.0.0.1, ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, a random domain).

Each node is a process started as on the robot, with the robot's QoS (reliable, volatile, depth
20). This process publishes ``JointState`` messages at 400 Hz and at 1000 Hz (``--seconds`` of
them, default 3 s), each stamped with the wall clock when it is published; the nodes copy the
input's stamp onto their answers, and the middleware stamps the answer's arrival here
(``received_timestamp``). Latency = arrival of the answer - publication of the input: two hops over
loopback, the node's queueing and its work. Lost = inputs without an answer. The echo node
(rclpy, republishes what it receives, no work) is the plain call: what the graph and rclpy cost.
Printed beside: each node's own count of its work (message in -> answer published, inside the
callback), from its tally.

    python benchmarks/bench_ros2.py [--seconds 3]

Needs the ros2 extra (``pip install 'rcm-kin[ros2]'``). Targets: no message lost at 400 Hz; at
1000 Hz no more lost than the echo; the median within 0.5 ms of the echo's (docs/performance.md).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy loads OpenBLAS

import argparse  # noqa: E402
import json  # noqa: E402
import random  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from rcm_kin.ros2.nodes import loopback_environment  # noqa: E402

RATES = (400.0, 1000.0)
MTM = (["j1", "j2", "j3"], "mtm_joint_states", "psm_joint_targets")
PSM = (["roll", "pitch", "insertion"], "/psm_joint_telemetry", "psm_holding_effort")


def robot_qos(depth: int = 20):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)


def echo() -> None:
    """The bare echo node: ``bench_in`` republished on ``bench_out``, until SIGTERM; the nodes'
    executor (:func:`rcm_kin.ros2.nodes.make_executor`), no work."""
    import signal

    import rclpy
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import JointState

    from rcm_kin.ros2.nodes import make_executor

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("bench_echo")
    executor = make_executor(rclpy.get_default_context())
    executor.add_node(node)
    out = node.create_publisher(JointState, "bench_out", robot_qos())
    node.create_subscription(JointState, "bench_in", out.publish, robot_qos())
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    print("ready", file=sys.stderr, flush=True)
    while not stop:
        executor.spin_once(timeout_sec=0.05)
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown()


class Bench:
    def __init__(self):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from sensor_msgs.msg import JointState

        self.rclpy, self.JointState = rclpy, JointState
        rclpy.init()
        self.node = rclpy.create_node("bench_driver")
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)

    def run(self, command: list[str], names, topic_in: str, topic_out: str, rate: float, seconds: float) -> dict:
        arrived: dict[int, int] = {}

        def answer(msg, info) -> None:
            arrived[msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec] = info["received_timestamp"]

        pub = self.node.create_publisher(self.JointState, topic_in, robot_qos())
        sub = self.node.create_subscription(self.JointState, topic_out, answer, robot_qos(100_000))
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        try:
            self._handshake(pub, names, arrived)
            arrived.clear()
            sent = self._play(pub, names, rate, seconds)
            end = time.monotonic() + 2.0
            while time.monotonic() < end and len(arrived) < len(sent):
                self.executor.spin_once(timeout_sec=0.01)
            process.terminate()
            tally = json.loads(process.communicate(timeout=10)[0] or "{}")
        finally:
            if process.poll() is None:
                process.kill()
            self.node.destroy_publisher(pub)
            self.node.destroy_subscription(sub)
        latency = np.array([arrived[k] - k for k in sent if k in arrived]) * 1e-9
        return {"sent": len(sent), "lost": 1 - len(latency) / len(sent),
                "median": float(np.median(latency)), "p99": float(np.percentile(latency, 99)),
                "work_median": tally.get("latency_median_s"), "work_p99": tally.get("latency_p99_s")}

    def _message(self, names, k: int, stamp_ns: int):
        msg = self.JointState()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
        msg.name = list(names)
        msg.position = [5.0 * np.sin(k / 200), 3.0 * np.cos(k / 300), 80.0]
        return msg

    def _handshake(self, pub, names, arrived, timeout: float = 60.0) -> None:
        end = time.monotonic() + timeout
        while not arrived and time.monotonic() < end:
            pub.publish(self._message(names, 0, 1))
            stop = time.monotonic() + 0.05
            while time.monotonic() < stop:
                self.executor.spin_once(timeout_sec=0.005)
        if not arrived:
            raise SystemExit("a node did not answer within 60 s")
        stop = time.monotonic() + 0.5
        while time.monotonic() < stop:
            self.executor.spin_once(timeout_sec=0.005)

    def _play(self, pub, names, rate: float, seconds: float) -> list[int]:
        period, start, sent = 1.0 / rate, time.monotonic(), []
        for k in range(int(rate * seconds)):
            while (wait := start + k * period - time.monotonic()) > 0:    # answers taken while waiting, no busy loop
                self.executor.spin_once(timeout_sec=wait)
            stamp = time.time_ns()
            pub.publish(self._message(names, k, stamp))
            sent.append(stamp)
        return sent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--echo", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.echo:
        return echo()
    os.environ.update(loopback_environment(tempfile.mkdtemp(prefix="bench_ros2_"),
                                           random.SystemRandom().randint(101, 200)))
    cli = [sys.executable, "-m", "rcm_kin.cli", "ros2"]
    nodes = {"echo (rclpy, no work)": ([sys.executable, __file__, "--echo"], PSM[0], "bench_in", "bench_out"),
             "ros2 teleop": ([*cli, "teleop", "--json"], *MTM),
             "ros2 gravity": ([*cli, "gravity", "--json"], *PSM)}
    bench = Bench()
    print(f"loopback, QoS reliable/volatile/depth 20, {args.seconds:g} s of messages per run; latency = answer "
          f"arrival - input publication; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"{'node':24} {'rate':>7} {'sent':>6} {'lost':>7} {'median':>9} {'p99':>9} {'x echo':>7} "
          f"{'work median':>12} {'work p99':>9}")
    for rate in RATES:
        base = None
        for name, (command, names, topic_in, topic_out) in nodes.items():
            r = bench.run(command, names, topic_in, topic_out, rate, args.seconds)
            base = base or r["median"]
            work = (f"{r['work_median'] * 1e6:9.0f} us {r['work_p99'] * 1e6:6.0f} us" if r["work_median"] else "")
            print(f"{name:24} {rate:5.0f}Hz {r['sent']:6d} {r['lost'] * 100:6.2f}% {r['median'] * 1e3:6.3f} ms "
                  f"{r['p99'] * 1e3:6.3f} ms {r['median'] / base:6.2f}x {work}", flush=True)
    print(f"load average at the end {os.getloadavg()[0]:.1f}")
    bench.node.destroy_node()
    bench.rclpy.shutdown()


if __name__ == "__main__":
    main()
