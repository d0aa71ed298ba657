"""ROS 2 bags as telemetry logs: a bag written with ``rosbags`` from a measured CSV log reads back
as the same log and gives the same ``sysid`` fit; topics, missing fields and bad files."""

from __future__ import annotations

import csv
import json
from decimal import Decimal
from pathlib import Path

import numpy as np
import pytest

from rcm_kin.cli import main
from rcm_kin.errors import RcmKinError
from rcm_kin.identification.calibration import calibration_logs
from rcm_kin.identification.rosbag import telemetry_topic
from rcm_kin.identification.telemetry import load_telemetry, telemetry_files

rosbag2 = pytest.importorskip("rosbags.rosbag2")
from rosbags.typesys import Stores, get_typestore  # noqa: E402

TYPES = get_typestore(Stores.ROS2_HUMBLE)
JOINT_STATE = TYPES.types["sensor_msgs/msg/JointState"]
HEADER, STAMP = TYPES.types["std_msgs/msg/Header"], TYPES.types["builtin_interfaces/msg/Time"]
JOINTS = ["roll", "pitch", "insertion"]
ROLL_STEP = "psm-sysid/roll-step/roll_step_response_roll_0_pitch_0.csv"


def _joint_state(stamp: Decimal, names, position, velocity, effort):
    sec = int(stamp)
    return JOINT_STATE(header=HEADER(stamp=STAMP(sec=sec, nanosec=int((stamp - sec) * 10**9)), frame_id=""),
                       name=list(names), position=np.array(position, dtype=float),
                       velocity=np.array(velocity, dtype=float), effort=np.array(effort, dtype=float))


def write_bag(folder: Path, storage: str, messages: dict[str, list[tuple[int, object]]]) -> Path:
    """A rosbag2 folder (``storage``: MCAP or SQLITE3) with ``messages[topic] = [(ns, msg), ...]``;
    returns its one storage file."""
    with rosbag2.Writer(folder, version=9, storage_plugin=getattr(rosbag2.StoragePlugin, storage)) as writer:
        for topic, items in messages.items():
            connection = writer.add_connection(topic, JOINT_STATE.__msgtype__, typestore=TYPES)
            for ns, msg in items:
                writer.write(connection, ns, TYPES.serialize_cdr(msg, JOINT_STATE.__msgtype__))
    return next(p for p in folder.iterdir() if p.suffix in (".mcap", ".db3"))


def csv_as_messages(path: Path) -> list[tuple[int, object]]:
    """One JointState per row of a PlotJuggler export, the text values as they are written."""
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    value = lambda row, j, f: float(row[f"/psm_joint_telemetry/{j}/{f}"])  # noqa: E731
    return [(int(Decimal(row["__time"]) * 10**9),
             _joint_state(Decimal(row["/psm_joint_telemetry/header/stamp"]), JOINTS,
                          *([value(row, j, f) for j in JOINTS] for f in ("position", "velocity", "effort"))))
            for row in rows]


@pytest.fixture(scope="module")
def measured_bags(shared_data, tmp_path_factory):
    """The roll step log at (0, 0) as an MCAP and a sqlite3 bag, named like the CSV (the pose is
    read from the name)."""
    source = shared_data / ROLL_STEP
    messages = {"/psm_joint_telemetry": csv_as_messages(source)}
    folder = tmp_path_factory.mktemp("bags")
    return source, [write_bag(folder / storage.lower() / source.stem, storage, messages)
                    for storage in ("MCAP", "SQLITE3")]


def test_bag_reads_as_the_csv_log(measured_bags):
    source, bags = measured_bags
    expected = load_telemetry(source)
    for bag in bags:
        log = load_telemetry(bag)
        np.testing.assert_array_equal(log.time, expected.time)
        for field in ("position", "pwm", "setpoint"):
            assert getattr(log, field).keys() == getattr(expected, field).keys()
            for joint, values in getattr(expected, field).items():
                np.testing.assert_array_equal(getattr(log, field)[joint], values)


def _sysid_json(log: Path, capsys, *extra) -> dict:
    assert main(["sysid", str(log), "--joint", "roll", "--json", *extra]) == 0
    return json.loads(capsys.readouterr().out)


def test_sysid_of_the_bag_equals_sysid_of_the_csv(measured_bags, capsys):
    source, bags = measured_bags
    expected = _sysid_json(source, capsys)
    assert expected["fit_percent"] > 80          # a real fit, not an empty one
    for bag in bags:
        assert _sysid_json(bag, capsys) == expected


@pytest.fixture()
def two_topic_bag(tmp_path) -> Path:
    """A small synthetic bag: telemetry on /arm/joints (one message lacks its efforts), an
    unrelated JointState topic, and zero header stamps (time from the recording)."""
    zero = Decimal(0)
    telemetry = [(10**9 + k * 2_500_000,
                  _joint_state(zero, ["pitch", "roll"], [k, -k], [5 * k, 7], [0, 1] if k != 2 else []))
                 for k in range(5)]
    other = [(10**9, _joint_state(zero, ["j1"], [0.0], [0.0], [0.0]))] * 3
    return write_bag(tmp_path / "bag", "MCAP", {"/arm/joints": telemetry, "/other": other})


def test_topic_choice_missing_fields_and_recording_time(two_topic_bag):
    with pytest.raises(RcmKinError, match=r"no sensor_msgs/msg/JointState topic /psm_joint_telemetry .*/arm/joints") \
            as caught:
        load_telemetry(two_topic_bag)
    assert caught.value.parameter == "topic" and str(caught.value).endswith("choose one with `topic`")
    with telemetry_topic("/arm/joints"), pytest.warns(UserWarning, match="1 messages missing a joint's field"):
        log = load_telemetry(two_topic_bag)
    keep = [0, 1, 3, 4]                      # message 2 has no efforts: left out with a warning, as a cut CSV row
    np.testing.assert_allclose(log.time, np.array(keep) * 2.5e-3, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(log.position["pitch"], keep)
    np.testing.assert_array_equal(log.position["roll"], -np.array(keep))
    np.testing.assert_array_equal(log.pwm["pitch"], 5 * np.array(keep))
    np.testing.assert_array_equal(log.setpoint["roll"], np.ones(4))
    assert "insertion" not in log.position


def test_a_non_finite_message_is_an_error(tmp_path):
    """A NaN in a bag is refused like a NaN cell in a CSV, naming the field: never a silent gap."""
    from rcm_kin.errors import LogDataError

    stamp = Decimal(1)
    messages = [(10**9 + k, _joint_state(stamp + Decimal(k) / 400, ["roll"], [float("nan") if k == 3 else k],
                                         [1.0], [0.0])) for k in range(6)]
    bag = write_bag(tmp_path / "nan", "MCAP", {"/psm_joint_telemetry": messages})
    with pytest.raises(LogDataError, match="non-finite roll position, the first the 4th") as caught:
        load_telemetry(bag)
    assert (caught.value.path, caught.value.row, caught.value.column) == (bag, 4, "roll/position")


def test_bag_stamps_out_of_order_are_an_error_naming_the_message(tmp_path):
    """A bag's header stamps are checked as a CSV's time column: the 4th message stamped before the 3rd."""
    from rcm_kin.errors import LogDataError

    order = [0, 1, 3, 2, 4, 5]
    messages = [(10**9 + k, _joint_state(Decimal(1) + Decimal(order[k]) / 400, ["roll"], [k], [1.0], [0.0]))
                for k in range(6)]
    bag = write_bag(tmp_path / "swapped", "MCAP", {"/psm_joint_telemetry": messages})
    with pytest.raises(LogDataError, match="time goes back 0.0025 s at complete message 4") as caught:
        load_telemetry(bag)
    assert (caught.value.path, caught.value.row) == (bag, 4)


def test_cli_topic_option_and_one_line_errors(two_topic_bag, tmp_path, capsys):
    assert main(["sysid", str(two_topic_bag), "--joint", "roll", "--topic", "/nope"]) == 2
    err = capsys.readouterr().err
    assert "no sensor_msgs/msg/JointState topic /nope" in err and err.endswith("; choose one with --topic\n")
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not a bag")
    assert main(["sysid", str(bad), "--joint", "roll"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and "rosbag2" in err


def test_folders_list_csv_logs_and_bags(tmp_path):
    """Folder searches (calibrate, greybox) find CSV logs and bags; a rosbag2 folder counts once."""
    for name in ("roll-step/a.csv", "roll-step/b.mcap", "roll-step/c.db3", "roll-step/notes.txt",
                 "roll-step/d/d.mcap", "roll-step/d/metadata.yaml", "roll-step/plain/x.csv", "pitch-prbs/e.db3"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text("")
    step = tmp_path / "roll-step"
    assert telemetry_files(step) == [step / "a.csv", step / "b.mcap", step / "c.db3", step / "d"]
    assert calibration_logs(tmp_path) == [step / "a.csv", step / "b.mcap", step / "c.db3", step / "d",
                                          tmp_path / "pitch-prbs" / "e.db3"]


def test_identification_folders_find_bags(measured_bags, capsys):
    """A folder of bags is searched like a folder of CSV logs by the identification's catalogue
    and by ``sysid FOLDER`` (the pose models), with the same results as the CSV log."""
    from rcm_kin.identification.log_catalog import catalog

    source, bags = measured_bags
    for bag in bags:                     # each bag is a rosbag2 folder (metadata + storage file)
        entries = catalog([bag.parent.parent], ("roll",))
        assert [(e.path, e.kind) for e in entries] == [(bag.parent, "step")]
    folder_fit = _sysid_json(bags[0].parent.parent, capsys)
    assert folder_fit["models"][0]["fit_percent"] == _sysid_json(source, capsys)["fit_percent"]


def test_a_topic_over_the_message_bound_is_refused_while_read(two_topic_bag):
    """A bag is read up to the log bound, not to memory's end (the CSV's row bound, as messages)."""
    from rcm_kin.errors import WorkLimitError
    from rcm_kin.identification.rosbag import read_joint_states

    with pytest.raises(WorkLimitError, match="more than 3 messages") as caught:
        read_joint_states(two_topic_bag, "/arm/joints", max_messages=3)
    assert caught.value.limit == 3 and caught.value.requested == 4
    t, _ = read_joint_states(two_topic_bag, "/arm/joints", max_messages=5)
    assert t.size == 4                          # all 5 read; the one without efforts left out
