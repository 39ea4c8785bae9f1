"""Recordings in the ROS 2 profile and Penelope's ROS 2 messages, checked by independent means:
`rosbags` (a pure-Python ROS 1/2 bag library with its own message definitions, CDR codec and
RIHS01 computation), the official `mcap` reader and `mcap-ros2-support`'s decoder.

- Every message type Penelope encodes (one sample each, `ros2-msgs/tests/data/samples.jsonl`,
  which a Rust test keeps equal to what the encoder writes): rosbags decodes our CDR to the
  values written below, re-encodes them to the same bytes, computes the same RIHS01 hash from
  its own definitions, and parses our schema text to the same fields.
- `penelope demo --record-profile ros2`: run-ros2.mcap has profile `ros2`, `ros2msg` schemas
  named by ROS type, `cdr` channels with their type hashes; rosbags' AnyReader opens the bare
  .mcap and decodes EVERY message, and so does mcap-ros2-support's decoder; the counts agree (each robot's topics once per 10 ms of the
  run, /tf once per robot); measured_js and measured_cp are the ticks the demo's CSV files
  hold at the same instants, and the arms move as the operator's script moves them; run.mcap
  is still the Penelope profile.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

ROOT = Path(__file__).resolve().parents[2]
SAMPLES = ROOT / "ros2-msgs" / "tests" / "data" / "samples.jsonl"

# crtk_msgs/msg/OperatingState as the CRTK repository defines it (ROS 2 branch), not ours.
CRTK_OPERATING_STATE = (
    "std_msgs/Header header\nstring state\nbool is_homed\nbool is_busy\n"
)

DURATION_S = 8
SCENE_PERIOD_NS = 10_000_000  # the recording's default rate, 100 Hz of tick time


def typestore() -> Any:
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg(CRTK_OPERATING_STATE, "crtk_msgs/msg/OperatingState"))
    return store


def plain(value: Any) -> Any:
    """A rosbags message as dicts, lists and numbers."""
    if dataclasses.is_dataclass(value):
        return {
            f.name: plain(getattr(value, f.name))
            for f in dataclasses.fields(value)
            # not rosbags' `__msgtype__` nor a constant (ROS field names are lower case)
            if not f.name.startswith("__") and not f.name.isupper()
        }
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, list):
        return [plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def header(sec: int, nanosec: int, frame: str) -> dict:
    return {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": frame}


def v3(x: float, y: float, z: float) -> dict:
    return {"x": x, "y": y, "z": z}


def q(x: float, y: float, z: float, w: float) -> dict:
    return {"x": x, "y": y, "z": z, "w": w}


WORLD_TO_BASE = {
    "header": header(11, 12, "world"),
    "child_frame_id": "puma/base_link",
    "transform": {"translation": v3(0.0, 1.0, 0.0), "rotation": q(0.0, 0.0, 0.6, 0.8)},
}
LINK_WARN = {
    "level": 1,
    "name": "link: link",
    "message": "up; lost 1 times, restored 1 times",
    "hardware_id": "",
    "values": [
        {"key": "round_trip_ns", "value": "250000"},
        {"key": "clock_offset_ns", "value": ""},
    ],
}

# The values ros2-msgs/tests/samples.rs encodes, by type.
EXPECTED = {
    "builtin_interfaces/msg/Time": {"sec": 1_700_000_000, "nanosec": 123_456_789},
    "std_msgs/msg/Header": header(5, 6, "puma/base_link"),
    "geometry_msgs/msg/Point": v3(1.5, -2.25, 3.125),
    "geometry_msgs/msg/Quaternion": q(0.5, -0.5, 0.5, 0.5),
    "geometry_msgs/msg/Vector3": v3(0.1, 0.2, 0.3),
    "geometry_msgs/msg/Pose": {"position": v3(1.0, 2.0, 3.0), "orientation": q(0, 0, 0, 1)},
    "geometry_msgs/msg/PoseStamped": {
        "header": header(7, 8, "world"),
        "pose": {"position": v3(0.4, 0.5, 0.6), "orientation": q(0.0, 0.0, 1.0, 0.0)},
    },
    "geometry_msgs/msg/Wrench": {"force": v3(1, 2, 3), "torque": v3(-1, -2, -3)},
    "geometry_msgs/msg/WrenchStamped": {
        "header": header(9, 10, "puma/sensor"),
        "wrench": {"force": v3(0.5, 0.0, -9.81), "torque": v3(0.01, 0.02, 0.03)},
    },
    "geometry_msgs/msg/Transform": {"translation": v3(1, 0, 0), "rotation": q(0, 0, 0, 1)},
    "geometry_msgs/msg/TransformStamped": WORLD_TO_BASE,
    "sensor_msgs/msg/JointState": {
        "header": header(13, 14, ""),
        "name": ["j1", "j2", "joint_three"],
        "position": [0.1, -0.2, 0.3],
        "velocity": [1.0, 2.0, 3.0],
        "effort": [],
    },
    "sensor_msgs/msg/Joy": {
        "header": header(15, 16, "pedals"),
        "axes": [0.5, -1.0],
        "buttons": [0, 1, 1],
    },
    "sensor_msgs/msg/CompressedImage": {
        "header": header(23, 24, "camera_optical"),
        "format": "jpeg",
        "data": [0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x10, 0xFF, 0xD9],
    },
    "sensor_msgs/msg/RegionOfInterest": {
        "x_offset": 1, "y_offset": 2, "height": 3, "width": 4, "do_rectify": True,
    },
    "sensor_msgs/msg/CameraInfo": {
        "header": header(25, 26, "camera_optical"),
        "height": 480,
        "width": 640,
        "distortion_model": "plumb_bob",
        "d": [0.0] * 5,
        "k": [500.0, 0.0, 320.5, 0.0, 510.0, 240.25, 0.0, 0.0, 1.0],
        "r": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        "p": [500.0, 0.0, 320.5, 0.0, 0.0, 510.0, 240.25, 0.0, 0.0, 0.0, 1.0, 0.0],
        "binning_x": 0,
        "binning_y": 0,
        "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0, "do_rectify": False},
    },
    "tf2_msgs/msg/TFMessage": {
        "transforms": [
            WORLD_TO_BASE,
            {
                "header": header(17, 18, "puma/base_link"),
                "child_frame_id": "puma/link1",
                "transform": {
                    "translation": v3(0.0, 0.0, 0.5),
                    "rotation": q(0.6, 0.0, 0.0, 0.8),
                },
            },
        ]
    },
    "diagnostic_msgs/msg/KeyValue": {"key": "lost", "value": "3"},
    "diagnostic_msgs/msg/DiagnosticStatus": LINK_WARN,
    "diagnostic_msgs/msg/DiagnosticArray": {
        "header": header(19, 20, ""),
        "status": [
            LINK_WARN,
            {"level": 2, "name": "b: link", "message": "down", "hardware_id": "hw", "values": []},
        ],
    },
    "crtk_msgs/msg/OperatingState": {
        "header": header(21, 22, ""),
        "state": "ENABLED",
        "is_homed": True,
        "is_busy": False,
    },
}


def schema_sections(type_name: str, schema: str) -> dict[str, str]:
    """An MCAP `ros2msg` schema split into its types' texts."""
    separator = "=" * 80 + "\n"
    parts = schema.split(separator)
    sections = {type_name: parts[0]}
    for part in parts[1:]:
        first, _, text = part.partition("\n")
        assert first.startswith("MSG: "), first
        sections[first[len("MSG: "):]] = text
    return sections


def field_shapes(fields: list) -> list:
    return [(name, repr(desc)) for name, desc in fields]


def test_every_message_type_matches_rosbags_values_bytes_hash_and_fields() -> None:
    store = typestore()
    lines = [json.loads(line) for line in SAMPLES.read_text().splitlines()]
    assert {line["type"] for line in lines} == set(EXPECTED), "one sample per type"
    for line in lines:
        type_name = line["type"]
        ours = bytes.fromhex(line["cdr"])
        decoded = store.deserialize_cdr(ours, type_name)
        assert plain(decoded) == EXPECTED[type_name], type_name
        assert bytes(store.serialize_cdr(decoded, type_name)) == ours, (
            f"{type_name}: rosbags encodes these values to other bytes"
        )
        assert line["hash"] == store.hash_rihs01(type_name), type_name
        # Our schema text parses to the fields rosbags' own definitions have.
        for name, text in schema_sections(type_name, line["schema"]).items():
            parsed = get_types_from_msg(text, name)
            assert field_shapes(parsed[name][1]) == field_shapes(store.fielddefs[name][1]), name


def run_demo(penelope_bin: str, out: Path) -> None:
    run = subprocess.run(
        [penelope_bin, "demo", "--sim-clock", "--duration", f"{DURATION_S}s", "--json",
         "--record-profile", "ros2", "--out", str(out)],
        capture_output=True, text=True, timeout=600,
    )
    assert run.returncode == 0, run.stderr


def csv_rows(path: Path) -> tuple[list[str], np.ndarray]:
    lines = path.read_text().splitlines()
    names = lines[0].split(",")
    wanted = [i for i, n in enumerate(names) if n.startswith(("time_s", "q_rad", "tool_m_"))]
    rows = np.array([[float(line.split(",")[i]) for i in wanted] for line in lines[1:]])
    return [names[i] for i in wanted], rows


@pytest.fixture(scope="module")
def demo(penelope_bin: str, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("demo-ros2")
    run_demo(penelope_bin, out)
    return out


def test_the_demos_ros2_recording_has_what_ros2_bag_needs(demo: Path) -> None:
    store = typestore()
    with (demo / "run.mcap").open("rb") as f:
        assert make_reader(f).get_header().profile == "penelope", "run.mcap as always"
    with (demo / "run-ros2.mcap").open("rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert summary is not None
        for channel in summary.channels.values():
            schema = summary.schemas[channel.schema_id]
            assert schema.encoding == "ros2msg", channel.topic
            assert channel.message_encoding == "cdr", channel.topic
            assert "/msg/" in schema.name, schema.name
            assert channel.metadata["topic_type_hash"] == store.hash_rihs01(schema.name)
            assert channel.metadata["offered_qos_profiles"].startswith("- history:")
        counted = sum(summary.statistics.channel_message_counts.values())
    # mcap-ros2-support's decoder (a second, independent one) reads every message from the
    # schemas in the file alone.
    with (demo / "run-ros2.mcap").open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        decoded = 0
        for _schema, channel, _message, ros_msg in reader.iter_decoded_messages():
            if channel.topic.endswith("/measured_js"):
                assert len(ros_msg.name) == len(ros_msg.position) > 0
            decoded += 1
    assert decoded == counted > 0


def test_every_message_of_the_demos_ros2_recording_decodes_and_the_arms_move(
    demo: Path,
) -> None:
    messages: dict[str, list[tuple[int, Any]]] = defaultdict(list)
    with AnyReader([demo / "run-ros2.mcap"]) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        for connection, log_time, raw in reader.messages():
            messages[connection.topic].append(
                (log_time, reader.deserialize(raw, connection.msgtype))
            )
    total = sum(len(v) for v in messages.values())
    print(f"decoded {total} messages on {len(messages)} topics")
    robots = ("frhc", "puma")  # config/demo.toml's master and slave
    expected_topics = {"/tf"}
    for robot in robots:
        for topic in ("measured_js", "measured_cp", "setpoint_js", "operating_state"):
            expected_topics.add(f"/{robot}/{topic}")
    expected_topics.add("/puma/measured_cf")  # the slave's wrist sensor; the master has none
    assert set(messages) == expected_topics
    assert types["/puma/measured_cf"] == "geometry_msgs/msg/WrenchStamped"
    assert types["/frhc/operating_state"] == "crtk_msgs/msg/OperatingState"

    # Counts: each robot's topics once per 10 ms of the run, /tf once per robot as well.
    per_robot = DURATION_S * 1_000_000_000 // SCENE_PERIOD_NS
    for topic, listed in messages.items():
        if topic == "/tf":
            assert len(listed) == 2 * per_robot, topic
            continue
        assert len(listed) == per_robot, (topic, len(listed))
        times = [t for t, _ in listed]
        assert all(b - a == SCENE_PERIOD_NS for a, b in zip(times, times[1:])), topic
        for log_time, message in listed:
            stamp = message.header.stamp
            assert stamp.sec * 1_000_000_000 + stamp.nanosec == log_time, topic

    # measured_js and measured_cp are the ticks the CSV files hold at those instants (every
    # tenth row of a 1 kHz loop); and the arms move as the operator's script moves them.
    for robot, csv in (("frhc", "telemetry-master.csv"), ("puma", "telemetry-slave.csv")):
        names, rows = csv_rows(demo / csv)
        q_columns = [i for i, n in enumerate(names) if n.startswith("q_rad")]
        tool_columns = [names.index(f"tool_m_{a}") for a in "xyz"]
        joints = messages[f"/{robot}/measured_js"]
        poses = messages[f"/{robot}/measured_cp"]
        assert len(joints[0][1].name) == len(q_columns)
        for k, ((_, js), (_, cp)) in enumerate(zip(joints, poses)):
            row = rows[10 * k]
            assert np.allclose(js.position, row[q_columns], atol=1e-8), (robot, k)
            p = cp.pose.position
            assert np.allclose([p.x, p.y, p.z], row[tool_columns], atol=1e-6), (robot, k)
        positions = np.array([js.position for _, js in joints])
        travel = np.ptp(positions, axis=0).max()
        tool = np.array([[cp.pose.position.x, cp.pose.position.y, cp.pose.position.z]
                         for _, cp in poses])
        reach = np.linalg.norm(tool - tool[0], axis=1).max()
        print(f"{robot}: joints travel up to {travel:.4f} rad, tool up to {reach * 1e3:.1f} mm")
        assert travel > 0.01 and reach > 0.01, f"{robot} does not move"
        states = {m.state for _, m in messages[f"/{robot}/operating_state"]}
        assert "ENABLED" in states, states

    # /tf: world -> each robot's root, then its links, the slave's sensor below its tool.
    children = {t.child_frame_id for _, tf in messages["/tf"] for t in tf.transforms}
    assert "puma/sensor" in children
    assert any(c.startswith("frhc/") for c in children)
    roots = {t.header.frame_id for _, tf in messages["/tf"] for t in tf.transforms[:1]}
    assert roots == {"world"}
    frames = {m.header.frame_id for _, m in messages["/puma/measured_cf"]}
    assert frames == {"puma/sensor"}
