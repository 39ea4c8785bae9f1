"""`penelope node --ros2` as a ROS 2 node over rmw_zenoh, checked by an independent client:
Zenoh's own Python binding (eclipse-zenoh) for the session, liveliness and attachments, and
`rosbags` for the ROS 2 types, their RIHS01 hashes and CDR (nothing of Penelope's decodes).

The test's Zenoh peer listens on loopback only (scouting off), where rmw_zenoh's router would;
the node connects to it. The test finds the node's liveliness tokens as `ros2 node list` and
`ros2 topic list` would, reads the CRTK topics from the keys rmw_zenoh's convention gives for
rosbags' hashes, and publishes `servo_cp` as a ROS 2 publisher would (CDR plus rmw_zenoh's
attachment): the PUMA follows. Every wait is for something to arrive, bounded."""

from __future__ import annotations

import queue
import threading
import time
from typing import Any, Dict, List, Tuple

import numpy as np
import pytest
import zenoh
from zenoh.ext import Int64, z_deserialize, z_serialize

import penelope
from conftest import Node, free_port
from test_crtk import holding_pid
from test_ros2_profile import typestore

WAIT_S = 30.0
DOMAIN = 0

# The topic set of robot `slave` (a PUMA 560 with a wrist sensor) and its ROS 2 types.
PUBLISHED = {
    "/slave/measured_js": "sensor_msgs/msg/JointState",
    "/slave/measured_cp": "geometry_msgs/msg/PoseStamped",
    "/slave/measured_cf": "geometry_msgs/msg/WrenchStamped",
    "/slave/setpoint_js": "sensor_msgs/msg/JointState",
    "/slave/operating_state": "crtk_msgs/msg/OperatingState",
    "/tf": "tf2_msgs/msg/TFMessage",
}
SUBSCRIBED = {
    "/slave/servo_jp": "sensor_msgs/msg/JointState",
    "/slave/servo_cp": "geometry_msgs/msg/PoseStamped",
    "/slave/clutch": "sensor_msgs/msg/Joy",
}


def dds_name(type_name: str) -> str:
    """rmw_zenoh's DDS-style type name: `sensor_msgs::msg::dds_::JointState_`."""
    package, kind, name = type_name.split("/")
    return f"{package}::{kind}::dds_::{name}_"


def data_key(topic: str, type_name: str, type_hash: str) -> str:
    return f"{DOMAIN}/{topic.strip('/')}/{dds_name(type_name)}/{type_hash}"


def peer(port: int) -> zenoh.Session:
    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("listen/endpoints", f'["tcp/127.0.0.1:{port}"]')
    config.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(config)


def tokens(session: zenoh.Session) -> List[str]:
    """Every liveliness token of the domain (what rmw_zenoh's graph cache starts from)."""
    out = []
    for reply in session.liveliness().get(f"@ros2_lv/{DOMAIN}/**", timeout=5.0):
        if reply.ok is not None:
            out.append(str(reply.ok.key_expr))
    return out


def parse_token(token: str) -> Dict[str, str]:
    """A token's chunks (rmw_zenoh's layout), names with `%` back to `/`."""
    parts = token.split("/")
    entity = {
        "domain": parts[1], "zid": parts[2], "node_id": parts[3], "id": parts[4],
        "kind": parts[5], "enclave": parts[6].replace("%", "/"),
        "namespace": parts[7].replace("%", "/"), "node": parts[8],
    }
    if len(parts) > 9:
        entity.update(topic=parts[9].replace("%", "/"), type=parts[10], hash=parts[11],
                      qos=parts[12])
    return entity


def attachment(sequence: int, gid: bytes) -> bytes:
    """rmw_zenoh's attachment (Jazzy): names and values in Zenoh's serialization."""
    return z_serialize(("sequence_number", Int64(sequence), "source_timestamp",
                        Int64(time.time_ns()), "source_gid", gid)).to_bytes()


@pytest.fixture
def ros2_node(penelope_bin: str) -> Any:
    port = free_port()
    session = peer(port)
    node = Node(penelope_bin, "lab", ["--ros2", "--zenoh", f"tcp/127.0.0.1:{port}"])
    yield session, node
    node.stop()
    session.close()


def wait_for(what: str, condition: Any) -> Any:
    deadline = time.monotonic() + WAIT_S
    while True:
        value = condition()
        if value:
            return value
        assert time.monotonic() < deadline, f"waited {WAIT_S} s for {what}"
        time.sleep(0.05)


def test_a_ros2_client_sees_the_node_reads_its_topics_and_drives_it_by_servo_cp(ros2_node) -> None:
    session, node = ros2_node
    store = typestore()
    assert "ros2: node /penelope_lab in domain 0" in "".join(node.output), node.output
    with penelope.connect(node.naming) as c:
        holding_pid(c, sensor=True)
        robot = c.robot("lab/slave")

        # The graph: the node, a publisher per topic of the set, a subscription per servo
        # topic, each with rosbags' RIHS01 hash of its type.
        def graph() -> Any:
            found = [parse_token(t) for t in tokens(session)]
            topics = {(e["kind"], e["topic"]): e for e in found if "topic" in e}
            wanted = [("MP", t) for t in PUBLISHED] + [("MS", t) for t in SUBSCRIBED]
            return (found, topics) if all(w in topics for w in wanted) else None

        found, topics = wait_for("the node's liveliness tokens", graph)
        nodes = [e for e in found if e["kind"] == "NN"]
        assert [(e["node"], e["namespace"], e["enclave"]) for e in nodes] == \
            [("penelope_lab", "/", "/")], nodes
        zid = nodes[0]["zid"]
        for (kind, topic), e in topics.items():
            type_name = {**PUBLISHED, **SUBSCRIBED}[topic]
            assert e["zid"] == zid and e["node"] == "penelope_lab", e
            assert e["type"] == dds_name(type_name), e
            assert e["hash"] == store.hash_rihs01(type_name), (topic, e["hash"])
            # Sensor-rate topics best effort (2) and keep-last 5; the others reliable, depth 10.
            best_effort = topic.endswith(("measured_js", "measured_cp", "measured_cf", "setpoint_js"))
            assert e["qos"] == ("2::,5:,:,:,," if best_effort and kind == "MP" else "::,10:,:,:,,"), e
        ids = [e["id"] for e in found]
        assert len(ids) == len(set(ids)), f"entity ids repeat: {ids}"
        print(f"graph: node penelope_lab (zid {zid}), {len(topics)} publishers and subscriptions")

        # The topics, from the keys rosbags' hashes give, decoded by rosbags.
        received: "queue.Queue[Tuple[str, bytes, bytes]]" = queue.Queue()
        subscribers = []
        for topic, type_name in PUBLISHED.items():
            key = data_key(topic, type_name, store.hash_rihs01(type_name))
            subscribers.append(session.declare_subscriber(
                key, lambda s, t=topic: received.put(
                    (t, s.payload.to_bytes(), s.attachment.to_bytes() if s.attachment else b""))))
        messages: Dict[str, List[Any]] = {t: [] for t in PUBLISHED}
        attachments: Dict[str, List[Tuple[int, int, bytes]]] = {t: [] for t in PUBLISHED}

        def drain(until: Any) -> None:
            deadline = time.monotonic() + WAIT_S
            while not until():
                assert time.monotonic() < deadline, {t: len(m) for t, m in messages.items()}
                try:
                    topic, payload, attached = received.get(timeout=1.0)
                except queue.Empty:
                    continue
                messages[topic].append(store.deserialize_cdr(payload, PUBLISHED[topic]))
                names = z_deserialize(tuple[str, Int64, str, Int64, str, bytes], zenoh.ZBytes(attached))
                assert names[0::2] == ("sequence_number", "source_timestamp", "source_gid"), names
                attachments[topic].append((int(names[1]), int(names[3]), names[5]))

        drain(lambda: all(len(m) >= 20 for m in messages.values()))
        js = messages["/slave/measured_js"][-1]
        assert len(js.name) == 6 and len(js.position) == 6, js
        np.testing.assert_allclose(js.position, robot.measured_js().position, atol=1e-3)
        assert messages["/slave/operating_state"][-1].state == "ENABLED"
        # The wrist sensor's constant reading (its bias of 1, 2, 3 N), in the sensor's frame.
        cf = messages["/slave/measured_cf"][-1]
        force = [cf.wrench.force.x, cf.wrench.force.y, cf.wrench.force.z]
        print(f"measured_cf: {force} N in frame {cf.header.frame_id}")
        assert cf.header.frame_id == "slave/sensor", cf.header
        np.testing.assert_allclose(np.linalg.norm(force), np.linalg.norm([1.0, 2.0, 3.0]), rtol=1e-6)
        frames = {t.child_frame_id for m in messages["/tf"] for t in m.transforms}
        assert len(frames) >= 6 and all(f.startswith("slave/") for f in frames), frames
        gaps = 0
        for topic, seen in attachments.items():
            sequence = [s for s, _, _ in seen]
            # Increasing; a gap is a message the publisher dropped under congestion (rmw_zenoh's
            # keep-last publishers drop rather than block), counted.
            assert all(b > a for a, b in zip(sequence, sequence[1:])), (topic, sequence)
            gaps += sequence[-1] - sequence[0] + 1 - len(sequence)
            assert len({g for _, _, g in seen}) == 1 and len(seen[0][2]) == 16, topic
            assert abs(seen[-1][1] - time.time_ns()) < 60e9, topic
        # The header stamps are ROS time (the Unix epoch), as other nodes' are.
        stamp = js.header.stamp.sec + js.header.stamp.nanosec * 1e-9
        assert abs(stamp - time.time()) < 60, stamp
        stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
                  for m in messages["/slave/measured_js"]]
        rate = (len(stamps) - 1) / ((stamps[-1] - stamps[0]) * 1e-9)
        print(f"measured_js: {len(stamps)} messages at {rate:.1f} Hz of tick time; "
              f"sequence numbers increasing on every topic, {gaps} gaps")
        assert 80 <= rate <= 120, rate

        # servo_cp as a ROS 2 publisher sends it: 2 cm along x in 0.5 mm steps, then the last.
        servo_token = topics[("MS", "/slave/servo_cp")]
        key = data_key("/slave/servo_cp", SUBSCRIBED["/slave/servo_cp"], servo_token["hash"])
        publisher = session.declare_publisher(key)
        gid = bytes(range(16))
        PoseStamped = store.types["geometry_msgs/msg/PoseStamped"]
        Header = store.types["std_msgs/msg/Header"]
        Time = store.types["builtin_interfaces/msg/Time"]
        Pose = store.types["geometry_msgs/msg/Pose"]
        Point = store.types["geometry_msgs/msg/Point"]
        start = messages["/slave/measured_cp"][-1].pose
        # A payload no ROS 2 publisher would send is dropped, and the node goes on.
        publisher.put(b"\x00\x01\x00\x00garbage", attachment=attachment(1, gid))
        sequence = 1

        def servo(target: Any) -> None:
            """Publishes `target`, then waits for the next measured_cp (the robot's own topic
            paces the stream: one target per reading, as a servo loop streams)."""
            nonlocal sequence
            sequence += 1
            msg = PoseStamped(
                header=Header(stamp=Time(sec=int(time.time()), nanosec=0), frame_id="slave/base"),
                pose=Pose(position=target, orientation=start.orientation))
            publisher.put(bytes(store.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped")),
                          attachment=attachment(sequence, gid))
            count = len(messages["/slave/measured_cp"])
            drain(lambda: len(messages["/slave/measured_cp"]) > count)

        for step in range(1, 41):
            target = Point(x=start.position.x + 0.0005 * step, y=start.position.y, z=start.position.z)
            servo(target)

        def arrived() -> bool:
            # The stream goes on at the last target (a stopped stream holds where the arm is).
            servo(target)
            p = messages["/slave/measured_cp"][-1].pose.position
            return max(abs(p.x - target.x), abs(p.y - target.y), abs(p.z - target.z)) < 0.5e-3

        wait_for("the PUMA at the last servo_cp target, within 0.5 mm (its measured_cp)", arrived)
        tool = robot.measured_cp()
        moved = tool[0, 3] - start.position.x
        print(f"servo_cp over ROS 2: the tool moved {moved * 1000:.2f} mm along x (commanded 20 mm)")
        assert abs(moved - 0.020) < 1e-3, moved
        for s in subscribers:
            s.undeclare()
