"""Telemetry logs as ROS 2 bags (rosbag2, ``.mcap`` or sqlite3 ``.db3``), read without ROS by the
pure-Python ``rosbags`` package.

The robot publishes ``sensor_msgs/JointState`` on ``/psm_joint_telemetry`` (the topic the
PlotJuggler CSV columns are named after). The fields mean what the CSV columns mean, per joint
``roll``, ``pitch``, ``insertion`` of ``name``: ``position`` the measured angle (deg),
``velocity`` the commanded PWM (counts), ``effort`` the position setpoint (deg). Time is
``header.stamp`` (the microcontroller's clock, s) unless every stamp is zero, then the recording
time. A bag is a single ``.mcap``/``.db3`` file or a rosbag2 folder (``metadata.yaml`` beside
its storage files). Messages missing a field of a joint are left out with a warning, as the CSV
reader leaves out cut-off rows; a non-finite value is an error naming the message, as in a CSV.

The topic is :data:`DEFAULT_TOPIC` unless a caller sets another for a block of code with
:func:`telemetry_topic` (the CLI's ``--topic``), so every function that reads logs through
:func:`rcm_kin.identification.telemetry.load_telemetry` reads bags unchanged. This module reads
the messages (:func:`read_joint_states`); :func:`rcm_kin.identification.telemetry.load_bag`
makes the telemetry log of them.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

import numpy as np

from rcm_kin.errors import LogDataError, LogDataWarning, RcmKinError, WorkLimitError, warn

DEFAULT_TOPIC = "/psm_joint_telemetry"
JOINT_STATE = "sensor_msgs/msg/JointState"
BAG_SUFFIXES = (".mcap", ".db3")
FIELDS = ("position", "velocity", "effort")   # JointState arrays, named as the CSV columns
_TOPIC: ContextVar[str] = ContextVar("telemetry_topic", default=DEFAULT_TOPIC)


@contextmanager
def telemetry_topic(topic: str | None) -> Iterator[None]:
    """Bags read inside the block take their telemetry from ``topic`` (None: the default)."""
    token = _TOPIC.set(topic or DEFAULT_TOPIC)
    try:
        yield
    finally:
        _TOPIC.reset(token)


def is_bag(path: str | Path) -> bool:
    """Whether ``path`` names a bag: a ``.mcap``/``.db3`` file or a rosbag2 folder."""
    path = Path(path)
    return path.suffix in BAG_SUFFIXES or (path.is_dir() and (path / "metadata.yaml").is_file())


def _reader(path: Path):
    from rosbags.rosbag2 import Reader
    from rosbags.rosbag2.storage_mcap import McapReader
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

    if path.is_dir():
        return Reader(path)
    if not path.is_file():
        raise RcmKinError(f"no log file at {path}")
    return (McapReader if path.suffix == ".mcap" else Sqlite3Reader)(path)


def read_joint_states(path: str | Path, topic: str | None = None,
                      max_messages: int | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Time (s, from the first message) and the columns ``(joint, field)`` of the JointState
    messages on ``topic`` (default: the current :func:`telemetry_topic`); a topic with more than
    ``max_messages`` messages is a WorkLimitError (read up to the bound, not to memory's end)."""
    from rosbags.rosbag2 import ReaderError
    from rosbags.typesys import Stores, get_typestore

    path, topic = Path(path), topic or _TOPIC.get()
    typestore = get_typestore(Stores.ROS2_HUMBLE)
    rows, stamps, received = [], [], []
    try:
        reader = _reader(path)
        reader.open()
        try:
            connections = [c for c in reader.connections if c.topic == topic]
            if not connections or any(c.msgtype != JOINT_STATE for c in connections):
                found = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
                raise RcmKinError(f"{path}: no {JOINT_STATE} topic {topic} (the bag has: "
                                  f"{', '.join(found) or 'none'}); choose one with `topic`", parameter="topic")
            for connection, timestamp, raw in reader.messages(connections):
                if max_messages is not None and len(rows) >= max_messages:
                    raise WorkLimitError(f"{path}: the topic {topic} holds more than {max_messages:,} messages, the "
                                         "bound of one log: cut the recording", requested=len(rows) + 1,
                                         limit=max_messages)
                msg = typestore.deserialize_cdr(raw, connection.msgtype)
                rows.append({(name, field): float(values[i])
                             for field in FIELDS if len(values := getattr(msg, field)) == len(msg.name)
                             for i, name in enumerate(msg.name)})
                stamps.append(f"{msg.header.stamp.sec}.{msg.header.stamp.nanosec:09d}")
                received.append(timestamp)
        finally:
            reader.close()
    except (ReaderError, OSError, KeyError, ValueError) as exc:
        if isinstance(exc, RcmKinError):
            raise
        first_line = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise RcmKinError(f"{path}: not a readable rosbag2 bag ({first_line})") from None
    return message_columns(path, rows, stamps, received)


def message_columns(path: Path, rows: list[dict], stamps: list[str], received: list[int]):
    """Time (s, from the first message) and the columns of JointState messages read as ``rows``
    ({(joint, field): value}), ``stamps`` (``header.stamp`` as decimal text, s) and ``received``
    (arrival, ns): the checks of a bag's messages, whatever brought them (a bag, a live topic)."""
    if len(rows) < 2:
        raise RcmKinError(f"{path}: not a telemetry log (fewer than 2 messages on the topic)")
    keys = sorted(set().union(*rows))
    complete = [all(k in row for k in keys) for row in rows]
    if sum(complete) < 2:
        raise RcmKinError(f"{path}: not a telemetry log (fewer than 2 messages with every field of every joint)")
    if not all(complete):
        warn(f"{path}: {len(rows) - sum(complete)} messages missing a joint's field left out (of {len(rows)})",
             LogDataWarning)
    data = {k: np.array([row[k] for row, ok in zip(rows, complete) if ok], dtype=float) for k in keys}
    for key, values in data.items():
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise LogDataError(f"{path}: {bad.size} messages with a non-finite {key[0]} {key[1]}, the first the "
                               f"{bad[0] + 1}th complete one; clean the bag (messages are not dropped: the gap "
                               "would be read as dynamics)", path=path, row=int(bad[0]) + 1,
                               column=f"{key[0]}/{key[1]}")
    # the stamp as the decimal number of seconds it is (as the CSV export writes it)
    t = np.array([float(s) for s, ok in zip(stamps, complete) if ok])
    if not np.any(t):
        ns = np.array([r for r, ok in zip(received, complete) if ok], dtype=np.int64)
        return (ns - ns[0]) * 1e-9, data
    return t - t[0], data
