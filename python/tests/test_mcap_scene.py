"""The 3D scene in `penelope demo`'s run.mcap, checked by independent means.

- The file is read with the official `mcap` reader (Foxglove's).
- Every `/tf` (foxglove.FrameTransforms) and `/scene` (foxglove.SceneUpdate) message is
  validated with `jsonschema` against Foxglove's published JSON Schemas taken from the
  `@foxglove/schemas` npm package (scripts/test fetches it and names the directory in
  $FOXGLOVE_SCHEMAS_DIR), not against the copy the file carries; that copy must equal them.
- Every link transform of every `/tf` message is checked against `penelope kin ROBOT fk --json`
  (every link frame; the tool frame is also its `T`) at the joint angles of the controller tick
  with the same time, and against forward kinematics done here, in Python, on the robot's
  description parsed by `urdf_parser_py` (an independent URDF parser from PyPI).
- The contact shape drawn for the slave is the demo's wall (config/demo.toml), the top face of
  its slab on the wall's plane; the force arrows point along the recorded wrenches.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
from collections import defaultdict
from pathlib import Path

import jsonschema
import pytest
from mcap.reader import make_reader
from urdf_parser_py.urdf import URDF

DURATION_S = 2
SCENE_PERIOD_NS = 10_000_000  # the default scene rate: 100 Hz of tick time
# config/demo.toml: which controller's ticks carry which robot's joints, and the slave's wall.
CONTROLLER_OF = {"frhc": "/controllers/display", "puma": "/controllers/follow"}
WALL_POINT = (0.350868, 0.127, 0.2902)
WALL_NORMAL = (0.0, 0.0, 1.0)
SENSOR_MOUNT = (0.0, 0.0, 0.02)
TOLERANCE = 1e-9


def foxglove_schema(name: str) -> dict:
    directory = os.environ.get("FOXGLOVE_SCHEMAS_DIR")
    if not directory:
        pytest.fail(
            "FOXGLOVE_SCHEMAS_DIR must name the JSON Schemas of the @foxglove/schemas npm "
            "package (scripts/test fetches them)"
        )
    path = Path(directory) / f"{name}.json"
    if not path.is_file():
        pytest.fail(f"{path} is missing: the @foxglove/schemas package was not fetched")
    return json.loads(path.read_text())


# --- small rigid-body algebra (4x4 lists) ---------------------------------------------------


def matmul(a: list, b: list) -> list:
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def from_quaternion(t: dict, q: dict) -> list:
    x, y, z, w = q["x"], q["y"], q["z"], q["w"]
    return [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w), t["x"]],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w), t["y"]],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y), t["z"]],
        [0.0, 0.0, 0.0, 1.0],
    ]


def from_xyz_rpy(xyz, rpy) -> list:
    """URDF's origin: R = Rz(yaw) Ry(pitch) Rx(roll), then the translation."""
    xyz = xyz or [0.0, 0.0, 0.0]
    r, p, y = rpy or [0.0, 0.0, 0.0]
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr, xyz[0]],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr, xyz[1]],
        [-sp, cp * sr, cp * cr, xyz[2]],
        [0.0, 0.0, 0.0, 1.0],
    ]


def about_axis(axis, angle: float) -> list:
    n = math.sqrt(sum(a * a for a in axis))
    x, y, z = (a / n for a in axis)
    c, s, C = math.cos(angle), math.sin(angle), 1 - math.cos(angle)
    return [
        [c + x * x * C, x * y * C - z * s, x * z * C + y * s, 0.0],
        [y * x * C + z * s, c + y * y * C, y * z * C - x * s, 0.0],
        [z * x * C - y * s, z * y * C + x * s, c + z * z * C, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]


def along_axis(axis, d: float) -> list:
    n = math.sqrt(sum(a * a for a in axis))
    return [
        [1.0, 0.0, 0.0, axis[0] / n * d],
        [0.0, 1.0, 0.0, axis[1] / n * d],
        [0.0, 0.0, 1.0, axis[2] / n * d],
        [0.0, 0.0, 0.0, 1.0],
    ]


def urdf_link_frames(robot: URDF, q: list) -> dict:
    """Every link's frame in the root link's at joint values `q` (the moving joints in file
    order), by walking the URDF's joints."""
    moving = [j.name for j in robot.joints if j.type != "fixed"]
    frames = {robot.get_root(): [[float(i == j) for j in range(4)] for i in range(4)]}
    pending = list(robot.joints)
    while pending:
        for joint in list(pending):
            if joint.parent not in frames:
                continue
            origin = joint.origin
            t = matmul(frames[joint.parent], from_xyz_rpy(origin.xyz if origin else None,
                                                         origin.rpy if origin else None))
            if joint.type in ("revolute", "continuous"):
                t = matmul(t, about_axis(joint.axis, q[moving.index(joint.name)]))
            elif joint.type == "prismatic":
                t = matmul(t, along_axis(joint.axis, q[moving.index(joint.name)]))
            frames[joint.child] = t
            pending.remove(joint)
    return frames


def max_difference(a: list, b: list) -> float:
    return max(abs(a[i][j] - b[i][j]) for i in range(4) for j in range(4))


def test_the_demos_recording_draws_every_link_where_the_kinematics_puts_it(
    penelope_bin: str, tmp_path: Path
) -> None:
    out = tmp_path / "demo"
    run = subprocess.run(
        [penelope_bin, "demo", "--sim-clock", "--duration", f"{DURATION_S}s", "--json",
         "--out", str(out)],
        capture_output=True, text=True, timeout=300,
    )
    assert run.returncode == 0, run.stderr

    validators = {
        name: jsonschema.Draft202012Validator(foxglove_schema(name.split(".")[1]))
        for name in ("foxglove.FrameTransforms", "foxglove.SceneUpdate")
    }
    ticks: dict[str, dict[int, list]] = defaultdict(dict)
    descriptions: dict[str, dict] = {}
    tf: list[tuple[int, dict]] = []
    scenes: list[tuple[int, dict]] = []
    with (out / "run.mcap").open("rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            value = json.loads(message.data)
            if channel.topic in ("/tf", "/scene"):
                # The schema the file carries is Foxglove's, unchanged.
                assert json.loads(schema.data) == foxglove_schema(schema.name.split(".")[1])
                validators[schema.name].validate(value)
                (tf if channel.topic == "/tf" else scenes).append((message.log_time, value))
            elif channel.topic.startswith("/robot_description/"):
                assert schema.name == "penelope.RobotDescription"
                descriptions[value["robot"]] = value
            elif channel.topic.startswith("/controllers/"):
                ticks[channel.topic][message.log_time] = value["sample"]

    # One description per robot; each parses as URDF and names the frames.
    assert sorted(descriptions) == sorted(CONTROLLER_OF)
    urdfs = {}
    for name, d in descriptions.items():
        robot = URDF.from_xml_string(d["urdf"])
        assert [link.name for link in robot.links] == d["frames"], name
        assert robot.get_root() == d["frames"][0]
        urdfs[name] = robot

    # 100 Hz of tick time for each robot over the run.
    per_robot = defaultdict(list)
    for time, message in tf:
        robot = message["transforms"][0]["child_frame_id"].split("/")[0]
        per_robot[robot].append(time)
    expected = DURATION_S * 1_000_000_000 // SCENE_PERIOD_NS
    for robot, times in per_robot.items():
        assert len(times) == expected, robot
        assert all(b - a == SCENE_PERIOD_NS for a, b in zip(times, times[1:])), robot

    # Every link of every /tf message against `penelope kin ROBOT fk` and the URDF's own
    # kinematics at the tick's joints.
    kin_calls = 0
    worst = 0.0
    tool_in_base: dict = {}
    sensor_in_base: dict = {}
    for time, message in tf:
        transforms = message["transforms"]
        robot = transforms[0]["child_frame_id"].split("/")[0]
        d = descriptions[robot]
        root = f"{robot}/{d['frames'][0]}"
        assert transforms[0]["parent_frame_id"] == "world"
        assert transforms[0]["child_frame_id"] == root
        placement = transforms[0]["translation"]
        assert placement["x"] == 0.0 and placement["z"] == 0.0
        assert placement["y"] in (0.0, 1.0), "robots stand 1 m apart along y"
        sample = ticks[CONTROLLER_OF[robot]][time]
        stamp = transforms[0]["timestamp"]
        assert stamp["sec"] * 1_000_000_000 + stamp["nsec"] == time
        urdf = urdfs[robot]
        n = sum(1 for j in urdf.joints if j.type != "fixed")
        q = sample["q"][:n]
        kin = subprocess.run(
            [penelope_bin, "kin", urdf.name, "fk", "--json", "--q", ",".join(repr(x) for x in q)],
            capture_output=True, text=True, timeout=60,
        )
        assert kin.returncode == 0, kin.stderr
        kin_calls += 1
        fk = json.loads(kin.stdout)
        by_kin = {link["frame"]: link["T"] for link in fk["links"]}
        assert max_difference(by_kin[d["frames"][-1]], fk["T"]) < TOLERANCE
        by_urdf = urdf_link_frames(urdf, q)
        drawn = {f"{robot}/{d['frames'][0]}"}
        tool = f"{robot}/{d['frames'][-1]}"
        for t in transforms[1:]:
            pose = from_quaternion(t["translation"], t["rotation"])
            if t["child_frame_id"] == f"{robot}/sensor":
                # The wrist sensor's mount below the tool (config/demo.toml: 2 cm along z).
                assert robot == "puma" and t["parent_frame_id"] == tool
                assert max_difference(pose, from_xyz_rpy(SENSOR_MOUNT, None)) < TOLERANCE
                sensor_in_base[time] = matmul(tool_in_base[(robot, time)], pose)
                continue
            assert t["parent_frame_id"] == root
            frame = t["child_frame_id"].split("/", 1)[1]
            drawn.add(t["child_frame_id"])
            worst = max(worst, max_difference(pose, by_kin[frame]),
                        max_difference(pose, by_urdf[frame]))
            if t["child_frame_id"] == tool:
                tool_in_base[(robot, time)] = pose
        assert drawn == {f"{robot}/{f}" for f in d["frames"]}, "every link, once"
    print(f"checked {len(tf)} /tf messages ({kin_calls} kin fk calls); worst difference {worst:.3e}")
    assert worst < TOLERANCE

    # The slave's wall: a slab whose top face lies on the demo's plane, in the slave's root.
    # The force arrows point along the wrenches of their ticks.
    arrows = 0
    for time, update in scenes:
        for entity in update["entities"]:
            robot, what = entity["id"].split("/", 1)
            if what.startswith("contact"):
                assert robot == "puma"
                assert entity["frame_id"] == "puma/base_link"
                cube = entity["cubes"][0]
                p, qn = cube["pose"]["position"], cube["pose"]["orientation"]
                r = from_quaternion({"x": 0, "y": 0, "z": 0}, qn)
                up = [r[i][2] for i in range(3)]
                assert max(abs(u - n) for u, n in zip(up, WALL_NORMAL)) < 1e-9
                top = [p[k] + up[i] * cube["size"]["z"] / 2 for i, k in enumerate("xyz")]
                assert max(abs(a - b) for a, b in zip(top, WALL_POINT)) < 1e-9
            for arrow in entity["arrows"]:
                arrows += 1
                sample = ticks[CONTROLLER_OF[robot]][time]
                wrench = sample["wrench" if what == "sensed_wrench" else "commanded_wrench"]
                force = wrench["force"]
                # The arrow (its +x) is the force: its direction, turned into the frame it is
                # drawn in, and its length, 1 cm per newton.
                if what == "sensed_wrench":
                    assert entity["frame_id"] == f"{robot}/sensor"
                    frame = sensor_in_base[time]
                else:
                    assert entity["frame_id"] == f"{robot}/tool"
                    frame = tool_in_base[(robot, time)]
                if wrench["frame"] == "Base":
                    in_base = force
                elif wrench["frame"] == "Sensor":
                    in_base = [sum(sensor_in_base[time][i][k] * force[k] for k in range(3))
                               for i in range(3)]
                else:
                    pytest.fail(f"a wrench in frame {wrench['frame']} in the demo")
                magnitude = math.sqrt(sum(x * x for x in force))
                r = from_quaternion({"x": 0, "y": 0, "z": 0}, arrow["pose"]["orientation"])
                along = [sum(frame[i][k] * r[k][0] for k in range(3)) for i in range(3)]
                assert max(abs(a - f / magnitude) for a, f in zip(along, in_base)) < 1e-9
                length = arrow["shaft_length"] + arrow["head_length"]
                assert abs(length - 0.01 * magnitude) < 1e-9
    assert arrows > 0, "the sensed wrench and the displayed force are drawn"
