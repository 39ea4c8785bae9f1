"""The Python client against a real node: connect, the tree, create a PUMA 560 on a simulated
board, fk equal to `penelope kin puma560 fk` to 1e-12, the other robot calls, telemetry,
errors of the right kind, and authentication with a secret file."""

from __future__ import annotations

import json
import subprocess
import time
from pathlib import Path
from typing import List

import numpy as np
import pytest

import penelope

# Control period, µs (release builds: a tick fits easily).
PERIOD_US = 2000

CONFIGURATIONS: List[List[float]] = [
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.1, 0.2, 0.3, 0.4, 0.5, 0.6],
    [0.0, 0.7853981633974483, -3.141592653589793, 0.0, 0.7853981633974483, 0.0],
    [-1.2, 0.35, -2.5, 1.9, -0.8, 2.7],
    [2.9, -0.6, 0.9, -2.2, 1.3, -3.0],
]


def puma(c: penelope.Client) -> penelope.Robot:
    """A PUMA 560 on a simulated six-axis board, both configured."""
    board = c.create("lab", "board/sim", "sim0", axes=6, substep_us=200)
    robot = c.create("lab", "robot/puma560", "slave")
    assert isinstance(robot, penelope.Robot)
    robot.map_joints("sim0", {j: j for j in range(6)})
    c.configure(board)
    assert robot.configure()["state"] == "inactive"
    return robot


def cli_fk(binary: str, q: List[float]) -> np.ndarray:
    out = subprocess.run(
        [binary, "kin", "puma560", "fk", "--q", ",".join(repr(x) for x in q), "--json"],
        check=True, capture_output=True, text=True,
    ).stdout
    return np.array(json.loads(out)["T"], dtype=np.float64)


def test_connect_lists_the_node_and_its_kinds(node) -> None:
    c = penelope.connect(node.naming)
    assert c.nodes() == ["lab"]
    paths = [e["path"] for e in c.ls()]
    assert "/lab/creator" in paths
    kinds = [k["kind"] for k in c.kinds()]
    assert "robot/puma560" in kinds and "board/sim" in kinds
    assert all(k["class"] for k in c.kinds("lab"))


def test_fk_equals_the_command_line_to_1e_12(node, penelope_bin) -> None:
    c = penelope.connect(node.naming)
    robot = puma(c)
    assert robot.path == "/lab/robots/slave"
    assert robot.joint_count() == 6
    for q in CONFIGURATIONS:
        t = robot.fk(q)
        assert t.shape == (4, 4) and t.dtype == np.float64
        np.testing.assert_allclose(t, cli_fk(penelope_bin, q), rtol=0, atol=1e-12)
    # fk() at the measured positions is fk at joint_positions().
    q = robot.joint_positions()
    assert q.shape == (6,)
    np.testing.assert_allclose(robot.fk(), robot.fk(q), rtol=0, atol=1e-12)


def test_jacobian_ik_and_gravity(node) -> None:
    c = penelope.connect(node.naming)
    robot = puma(c)
    q = np.array(CONFIGURATIONS[1])
    j = robot.jacobian(q)
    assert j.shape == (6, 6)
    # The linear rows are the derivative of fk's position (central differences).
    h = 1e-6
    for k in range(6):
        dq = np.zeros(6)
        dq[k] = h
        dp = (robot.fk(q + dq)[:3, 3] - robot.fk(q - dq)[:3, 3]) / (2 * h)
        np.testing.assert_allclose(j[:3, k], dp, atol=1e-6)
    r = robot.fk(q)[:3, :3]
    jt = robot.jacobian(q, frame="tool")
    np.testing.assert_allclose(jt[:3], r.T @ j[:3], atol=1e-12)
    with pytest.raises(penelope.BadArgument):
        robot.jacobian(q, frame="flange")
    # Every branch of ik reaches the pose, and one of them is q.
    t = robot.fk(q)
    branches = robot.ik(t)
    assert branches
    for b in branches:
        np.testing.assert_allclose(robot.fk(b), t, atol=1e-9)
    assert any(np.allclose(b, q, atol=1e-9) for b in branches)
    g = robot.gravity(q)
    assert g.shape == (6,) and np.all(np.isfinite(g))
    with pytest.raises(penelope.BadArgument) as e:
        robot.ik(np.diag([2.0, 1.0, 1.0, 1.0]))
    assert e.value.kind == "BadArgument"


def test_watch_yields_telemetry_samples(node) -> None:
    c = penelope.connect(node.naming)
    robot = puma(c)
    hold = c.create("lab", "trajectory/step", "hold", pose="start")
    pid = c.create("lab", "controller/joint-pid", "pid", period_us=PERIOD_US)
    assert isinstance(pid, penelope.Controller)
    pid.set_robot("slave")
    pid.set_trajectory("hold")
    hold.configure()
    pid.configure()
    assert pid.activate()["state"] == "active"
    samples = list(penelope.watch(pid, decimation=5, count=5))
    assert len(samples) == 5
    for s in samples:
        assert s["q"].shape == (6,) and s["q"].dtype == np.float64
        assert s["tool_position"].shape == (3,)
        assert s["force"].shape == (3,) and s["torque"].shape == (3,)
        assert isinstance(s["seq"], int) and isinstance(s["state"], str)
        # A joint PID commands no wrench, no hand holds the robot, the law has no observers.
        assert s["commanded_force"].shape == (3,) and not s["commanded_force"].any()
        assert s["clutch"] is None and s["port_energy"] is None and s["channel_energy"] is None
    seqs = [s["seq"] for s in samples]
    assert seqs == sorted(seqs) and len(set(seqs)) == 5
    # A robot driven by an active controller streams the same loop.
    with robot.watch(count=2) as w:
        assert w.path == "/lab/robots/slave"
        assert len(list(w)) == 2
    status = pid.status()
    assert status["running"] and status["ticks"] > 0
    assert status["last"]["q"].shape == (6,)
    pid.set_gains(kp=[100, 100, 100, 10, 10, 10])
    with pytest.raises(penelope.BadConfig) as e:
        pid.set_gains(no_such_gain=1.0)
    assert e.value.kind == "BadConfig"
    with pytest.raises(penelope.InUse):
        c.destroy(robot)
    c.deactivate(pid)
    c.destroy("lab/pid")
    c.destroy(robot, force=True)


def running_pid(c: penelope.Client) -> penelope.Controller:
    """A joint PID holding the PUMA 560 at its start pose, active."""
    puma(c)
    hold = c.create("lab", "trajectory/step", "hold", pose="start")
    pid = c.create("lab", "controller/joint-pid", "pid", period_us=PERIOD_US)
    assert isinstance(pid, penelope.Controller)
    pid.set_robot("slave")
    pid.set_trajectory("hold")
    hold.configure()
    pid.configure()
    assert pid.activate()["state"] == "active"
    return pid


def wait_state(pid: penelope.Controller, *states: str) -> None:
    """Waits (at most 10 s, a bound against a hang) until the loop's newest published sample
    shows one of ``states`` (the node publishes samples a little after the ticks)."""
    deadline = time.monotonic() + 10.0
    while True:
        last = pid.status()["last"]
        if last is not None and last["state"] in states:
            return
        if time.monotonic() > deadline:
            pytest.fail(f"the loop never showed {states}: {pid.status()}")
        time.sleep(0.01)


def test_a_cameras_frames_are_jpegs_stamped_on_the_common_clock_beside_the_telemetry(
    node,
) -> None:
    c = penelope.connect(node.naming)
    pid = running_pid(c)
    cam = c.create(
        "lab", "sensor/sim-camera", "cam", robot="slave", eye=[1.5, -1.0, 1.0],
        target=[0.0, 0.0, 0.5], up=[0.0, 0.0, 1.0], width=160, height=120, rate_hz=30.0,
    )
    assert isinstance(cam, penelope.Camera)
    cam.configure()
    with cam.watch(count=3) as w:
        assert w.path == "/lab/sensors/cam"
        frames = list(w)
    assert len(frames) == 3
    seqs = [f["seq"] for f in frames]
    assert seqs == sorted(seqs) and len(set(seqs)) == 3
    for f in frames:
        assert f["encoding"] == "jpeg" and f["data"][:2] == b"\xff\xd8"
        assert f["capture_ns"] < f["ready_ns"] <= f["sent_ns"]
        m = f["model"]
        assert (m["width"], m["height"], m["robot"]) == (160, 120, "slave")
        assert m["pose_in_robot_base"].shape == (4, 4)
        # The optical axis (the pose's z) looks from the eye toward the target.
        z = m["pose_in_robot_base"][:3, 2]
        toward = np.array([0.0, 0.0, 0.5]) - np.array([1.5, -1.0, 1.0])
        assert np.dot(z, toward / np.linalg.norm(toward)) > 0.999
    # One clock: this node serves the naming service, so its ticks and the frames' capture
    # instants are both its monotonic clock; the newest frame was captured within a second
    # of the loop's newest tick.
    tick_ns = pid.status()["last"]["time_ns"]
    assert abs(tick_ns - frames[-1]["capture_ns"]) < 1_000_000_000
    with pytest.raises(penelope.BadArgument):
        cam.watch(decimation=0)


def test_estop_of_a_node_and_of_everything_latches_the_running_loop(node) -> None:
    c = penelope.connect(node.naming)
    pid = running_pid(c)
    wait_state(pid, "running", "holding")
    # The node's red button: the loop latched its e-stop before the answer came back.
    report = c.estop_node("lab")
    assert report == {"node": "lab", "stopped": ["pid"], "pending": []}, report
    wait_state(pid, "estop")
    # Re-armed, it runs again; then the whole system's button stops it again.
    pid.rearm()
    wait_state(pid, "running", "holding")
    everything = c.estop_all()
    assert everything == [{"node": "lab", "stopped": ["pid"], "pending": []}], everything
    wait_state(pid, "estop")
    with pytest.raises(penelope.UnknownName):
        c.estop_node("no-such-node")
    c.deactivate(pid)


def test_errors_carry_the_wire_error_kind(node) -> None:
    c = penelope.connect(node.naming)
    with pytest.raises(penelope.UnknownName) as e:
        c.robot("lab/no-such-robot")
    assert e.value.kind == "UnknownName"
    assert isinstance(e.value, penelope.PenelopeError)
    with pytest.raises(penelope.UnknownName):
        c.robot("/no-such-node/robots/slave")
    with pytest.raises(penelope.BadName) as e:
        c.create("lab", "robot/puma560", "bad name!")
    assert e.value.kind == "BadName"
    with pytest.raises(penelope.UnknownKind):
        c.create("lab", "robot/no-such-kind", "x")
    with pytest.raises(penelope.BadConfig):
        c.create("lab", "board/sim", "b", axes="six")
    c.create("lab", "board/sim", "sim0")
    with pytest.raises(penelope.NameTaken):
        c.create("lab", "board/sim", "sim0")
    with pytest.raises(penelope.WrongClass) as e:
        c.robot("lab/sim0")
    assert e.value.kind == "WrongClass"
    robot = c.create("lab", "robot/puma560", "slave")
    with pytest.raises(penelope.InvalidTransition):
        robot.cleanup()
    with pytest.raises(penelope.BadArgument):
        robot.fk([float("nan")] * 6)


def test_the_secret_file_authenticates_and_its_absence_is_refused(secure_node, secret_file: Path,
                                                                  admin_secret_file: Path,
                                                                  tmp_path: Path) -> None:
    # The shared secret alone makes an operator: it may not create.
    operator = penelope.connect(secure_node.naming, secret_file=secret_file)
    assert operator.nodes() == ["lab"]
    with pytest.raises(penelope.PenelopeError) as e:
        operator.create("lab", "board/sim", "sim0")
    assert e.value.kind == "Forbidden"
    c = penelope.connect(secure_node.naming, secret_file=secret_file,
                         admin_secret_file=admin_secret_file)
    robot = puma(c)
    assert robot.fk(CONFIGURATIONS[1]).shape == (4, 4)
    with pytest.raises(penelope.AuthFailed) as e:
        penelope.connect(secure_node.naming)
    assert e.value.kind == "AuthFailed"
    wrong = tmp_path / "wrong.secret"
    wrong.write_text("not the secret\n")
    wrong.chmod(0o600)
    with pytest.raises(penelope.PenelopeError) as e:
        penelope.connect(secure_node.naming, secret_file=wrong)
    assert e.value.kind in ("AuthFailed", "Unauthenticated")
    # A secret others may read is refused before anything is sent, with the fix.
    wrong.chmod(0o644)
    with pytest.raises(PermissionError, match="chmod 600"):
        penelope.connect(secure_node.naming, secret_file=wrong)


def test_every_wire_error_kind_has_its_class() -> None:
    # The variants of ProtocolError and CallError, as the Rust enums list them (read from their
    # own Deserialize by the extension): one class per variant, in the same two groups and
    # order, and no class for a variant that is gone.
    protocol, call = penelope._native.error_kinds()
    assert "AuthFailed" in protocol and "UnknownName" in call and "NoLink" in call
    assert [c.kind for c in penelope._errors._PROTOCOL_ERRORS] == list(protocol)
    assert [c.kind for c in penelope._errors._CALL_ERRORS] == list(call)
    for v in (*protocol, *call):
        cls = getattr(penelope, v, None)
        assert isinstance(cls, type) and issubclass(cls, penelope.PenelopeError), v
        assert cls.kind == v
    # A kind this package does not know (a newer node's) is still a PenelopeError with it.
    e = penelope._errors._from_kind("SomethingNew", "a newer node's error")
    assert type(e) is penelope.PenelopeError and e.kind == "SomethingNew"
