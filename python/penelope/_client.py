"""The client and the proxies: thin Python over the Rust client (``penelope._native``), with
NumPy arrays at the edges."""

from __future__ import annotations

import math
import os
import re
import time
from dataclasses import dataclass
from types import TracebackType
from typing import (
    Any, Dict, Generic, Iterator, List, Mapping, Optional, Sequence, Tuple, Type, TypeVar,
    Union,
)

import numpy as np
import numpy.typing as npt

from . import _native
from ._errors import PenelopeError

#: A float64 NumPy array.
Array = npt.NDArray[np.float64]
#: Joint values: any sequence of floats (or a 1-D array), radians (metres for prismatic joints).
JointsLike = Union[Sequence[float], npt.ArrayLike]
#: A configuration: TOML text, or a mapping of keys to values (made into TOML).
ConfigLike = Union[str, Mapping[str, Any]]

_P = TypeVar("_P", bound="Proxy")

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")

#: The sensor kinds whose proxies are :class:`Camera`.
CAMERA_KINDS = ("sensor/sim-camera", "sensor/camera")


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        x = float(v)
        if math.isnan(x):
            return "nan"
        if math.isinf(x):
            return "inf" if x > 0 else "-inf"
        return repr(x)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write a {type(v).__name__} as a TOML value")


def _toml_key(k: str) -> str:
    return k if _BARE_KEY.match(k) else _toml_value(str(k))


def _toml(config: Optional[ConfigLike], keys: Mapping[str, Any]) -> str:
    """TOML text of ``config`` (text kept as is, a mapping written out) and ``keys``."""
    parts: List[str] = []
    if isinstance(config, str):
        if config:
            parts.append(config)
    elif config is not None:
        parts.extend(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in config.items())
    parts.extend(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in keys.items())
    return "\n".join(parts)


def _joints(q: Optional[JointsLike]) -> Optional[List[float]]:
    if q is None:
        return None
    a = np.asarray(q, dtype=np.float64)
    if a.ndim != 1:
        raise _error("BadArgument", f"joint values must be a 1-D sequence, got shape {a.shape}")
    return [float(x) for x in a]


def _pose(T: npt.ArrayLike) -> List[float]:
    t = np.asarray(T, dtype=np.float64)
    if t.shape != (4, 4):
        raise _error("BadArgument", f"T must be 4x4, got shape {t.shape}")
    return [float(x) for x in t.ravel()]


def _error(kind: str, message: str) -> Exception:
    from ._errors import _from_kind

    return _from_kind(kind, message)


class Client:
    """A client of one system, through its naming service: the naming tree, the nodes' kinds,
    create and destroy, the lifecycle verbs, and proxies of the objects. Connections to the
    nodes are opened on first use and cached; usable from several threads."""

    def __init__(self, native: _native.Client) -> None:
        self._native = native

    def __repr__(self) -> str:
        return f"penelope.Client(naming={self.naming!r})"

    # --- the connection -----------------------------------------------------------------------

    def close(self) -> None:
        """Closes every connection of this client; its proxies share them, so every later call
        through the client or a proxy of it raises :class:`Io`. The objects stay on their nodes
        (they are the nodes', not the connection's). Open :class:`Watch` subscriptions have
        connections of their own: close them apart. Idempotent."""
        self._native.close()

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` was called."""
        return self._native.closed

    def __enter__(self) -> "Client":
        return self

    def __exit__(
        self,
        exc_type: Optional[Type[BaseException]],
        exc: Optional[BaseException],
        tb: Optional[TracebackType],
    ) -> None:
        self.close()

    # --- simulated clock and recording --------------------------------------------------------

    def advance(self, node: str, seconds: float) -> float:
        """Moves the simulated clock of ``node`` (started with ``--sim-clock``) on by
        ``seconds``, stepping its active loops tick by tick; returns the clock's new time, s.
        :class:`NotReady` on a node clocked in real time."""
        return self._native.advance(node, float(seconds))

    def record(
        self, node: str, name: str, objects: Optional[Sequence[Union[str, "Proxy"]]] = None
    ) -> "Recording":
        """Starts recording on ``node`` to the new MCAP file ``name`` (a plain file name, in
        the node's recordings directory): every control tick of ``objects`` (controllers and
        linked channels, by name on that node or proxy; ``None``: all of them). Returns a
        :class:`Recording`; use it as a context manager to stop at the block's end::

            with c.record("lab", "run.mcap") as rec:
                ...
            arrays = penelope.read_recording(rec.path)
        """
        names = [o if isinstance(o, str) else o.name for o in (objects or [])]
        path, controllers, links = self._native.record_start(node, name, names)
        return Recording(self, node, path, controllers, links)

    def objects(self, node: str) -> List[Dict[str, Any]]:
        """The objects of ``node``: dicts with ``name``, ``kind``, ``class``, ``state`` and
        ``relations`` (``(relation, target)`` pairs)."""
        return self._native.objects(node)

    @property
    def naming(self) -> str:
        """The naming service's address."""
        return self._native.naming

    # --- the tree and the nodes ---------------------------------------------------------------

    def ls(self, context: str = "/") -> List[Dict[str, Any]]:
        """Every entry under ``context``, depth first, as dicts: ``path``, ``depth``, ``entry``
        (``"context"`` or ``"object"``) and, for an object, its ``node``, ``address``, ``name``,
        ``class`` and ``kind``."""
        return self._native.ls(context)

    def nodes(self) -> List[str]:
        """The names of the registered nodes."""
        return self._native.nodes()

    def estop_node(self, node: str) -> Dict[str, Any]:
        """Latches the e-stop of every loop running on ``node``, on a connection of its own
        (never behind another call, served by the node before any other work): a dict with
        ``node``, ``stopped`` (the controllers whose loops latched it before the answer) and
        ``pending`` (asked, not yet ticked)."""
        return self._native.estop_node(node)

    def estop_all(self) -> List[Dict[str, Any]]:
        """The red button: latches the e-stop of every loop on every node of the naming tree,
        the nodes asked in parallel. One dict per node as :meth:`estop_node` returns; a node that
        could not be reached has an ``error`` message (raise or retry: it is not stopped)."""
        return self._native.estop_all()

    def kinds(self, node: Optional[str] = None) -> List[Dict[str, str]]:
        """The kinds ``node`` can create (every node's when ``None``), as dicts: ``kind``,
        ``class``, ``summary`` and ``config`` (its keys, with units and defaults)."""
        return self._native.kinds(node)

    def create(
        self, node: str, kind: str, name: str, config: Optional[ConfigLike] = None, **keys: Any
    ) -> "Proxy":
        """Makes an object of ``kind`` (``"robot/puma560"``) named ``name`` on ``node``,
        configured by ``config`` (TOML text or a mapping) and ``keys``; returns its proxy (a
        :class:`Robot`, :class:`Sensor`, :class:`Controller` or :class:`Object`). It starts
        ``unconfigured``. The proxy owns the object: used as a context manager, it destroys
        the object at the block's end (see :meth:`Proxy.__exit__`).

        Raises :class:`UnknownKind`, :class:`NameTaken`, :class:`BadName`, :class:`BadConfig`,
        :class:`LimitReached`."""
        path = self._native.create(node, kind, name, _toml(config, keys))
        proxy = self.proxy(path)
        proxy._owned = True
        return proxy

    def destroy(self, obj: Union[str, "Proxy"], force: bool = False) -> None:
        """Removes the object (a proxy, a naming path or ``NODE/NAME``). Refused with
        :class:`InUse` while an active object uses it, unless ``force``."""
        self._native.destroy(_spec(obj), force)

    def locate(self, obj: Union[str, "Proxy"]) -> Dict[str, str]:
        """What the naming service says of the object: ``node``, ``address``, ``name``,
        ``class``, ``kind``."""
        return self._native.locate(_spec(obj))

    # --- lifecycle ----------------------------------------------------------------------------

    def configure(self, obj: Union[str, "Proxy"]) -> Dict[str, Any]:
        """``unconfigured -> inactive``; returns the object's new description."""
        return self._native.transition(_spec(obj), "configure")

    def activate(self, obj: Union[str, "Proxy"]) -> Dict[str, Any]:
        """``inactive -> active`` (a controller starts its loop)."""
        return self._native.transition(_spec(obj), "activate")

    def deactivate(self, obj: Union[str, "Proxy"]) -> Dict[str, Any]:
        """``active -> inactive`` (a controller stops its loop safely)."""
        return self._native.transition(_spec(obj), "deactivate")

    def cleanup(self, obj: Union[str, "Proxy"]) -> Dict[str, Any]:
        """``inactive -> unconfigured``."""
        return self._native.transition(_spec(obj), "cleanup")

    def describe(self, obj: Union[str, "Proxy"]) -> Dict[str, Any]:
        """The object's ``name``, ``kind``, ``class``, ``state`` and ``relations``."""
        return self.object(_spec(obj)).describe()

    # --- proxies ------------------------------------------------------------------------------

    def proxy(self, path: str) -> "Proxy":
        """The proxy of the object at ``path``, of the class its naming entry says."""
        where = self._native.locate(path)
        cls = where["class"]
        if cls == "robot":
            return self.robot(path)
        if cls == "sensor" and where["kind"] in CAMERA_KINDS:
            return self.camera(path)
        if cls == "sensor":
            return self.sensor(path)
        if cls == "controller":
            return self.controller(path)
        if cls == "board":
            return self.board(path)
        if cls == "trajectory":
            return self.trajectory(path)
        return self.object(path)

    def robot(self, path: str) -> "Robot":
        """The robot at ``path`` (a naming path or ``NODE/NAME``); :class:`WrongClass` if it is
        not a robot."""
        return Robot(self, self._native.robot(path))

    def sensor(self, path: str) -> "Sensor":
        """The sensor at ``path``."""
        return Sensor(self, self._native.sensor(path))

    def camera(self, path: str) -> "Camera":
        """The camera (``sensor/sim-camera``, ``sensor/camera``) at ``path``, for its frames."""
        return Camera(self, self._native.sensor(path))

    def controller(self, path: str) -> "Controller":
        """The controller at ``path``."""
        return Controller(self, self._native.controller(path))

    def board(self, path: str) -> "Board":
        """The board at ``path``."""
        return Board(self, self._native.board(path))

    def trajectory(self, path: str) -> "Trajectory":
        """The trajectory at ``path``."""
        return Trajectory(self, self._native.trajectory(path))

    def link(self, path: str) -> "Link":
        """The teleop channel (a ``trajectory/teleop``) at ``path``, for its link statistics
        when its other end is on another node."""
        return Link(self, self._native.trajectory(path))

    def object(self, path: str) -> "Object":
        """The object at ``path``, whatever its class (lifecycle and description)."""
        return Object(self, self._native.object(path))

    def watch(
        self, obj: Union[str, "Proxy"], decimation: int = 1, count: Optional[int] = None
    ) -> "Watch":
        """The telemetry of a controller (or of the robot an active controller drives): see
        :func:`watch`."""
        return Watch(self._native.watch(_spec(obj), decimation, count))


def _spec(obj: Union[str, "Proxy"]) -> str:
    return obj if isinstance(obj, str) else obj.path


class Proxy:
    """What every remote object answers: its path, description and lifecycle."""

    _native: _native._Lifecycle

    def __init__(self, client: Client, native: Any) -> None:
        self._client = client
        self._native = native
        self._owned = False

    def __enter__(self: _P) -> _P:
        return self

    def __exit__(
        self,
        exc_type: Optional[Type[BaseException]],
        exc: Optional[BaseException],
        tb: Optional[TracebackType],
    ) -> None:
        """A proxy that made its object (:meth:`Client.create`) destroys it: an active
        controller deactivated first (its loop stops safely), then destroyed without ``force``, so an
        active object that still uses it makes this raise :class:`InUse` rather than be stopped
        behind the caller's back (nest the ``with`` blocks in creation order). A proxy of an
        object it did not make leaves the object alone: the object is the node's, and others
        may use it."""
        if not self._owned:
            return
        self._owned = False
        info = self.describe()
        # (Other classes are active while an active controller uses them: not deactivated.)
        if info["class"] == "controller" and info["state"] == "active":
            self.deactivate()
        self._client.destroy(self)

    @property
    def owned(self) -> bool:
        """Whether this proxy made its object (and destroys it when used as a context
        manager)."""
        return self._owned

    @property
    def name(self) -> str:
        """The object's name on its node (the last part of its path)."""
        return self.path.rsplit("/", 1)[-1]

    @property
    def node(self) -> str:
        """The name of the node hosting the object."""
        return self.path.split("/")[1]

    def __repr__(self) -> str:
        return f"penelope.{type(self).__name__}({self.path!r})"

    @property
    def client(self) -> Client:
        """The client this proxy calls through."""
        return self._client

    @property
    def path(self) -> str:
        """The object's naming path, ``/<node>/<class context>/<name>``."""
        return self._native.path

    def describe(self) -> Dict[str, Any]:
        """The object's ``name``, ``kind``, ``class``, ``state`` and ``relations``."""
        return self._native.describe()

    @property
    def state(self) -> str:
        """The lifecycle state now (``unconfigured``, ``inactive``, ``active``, ...)."""
        return str(self.describe()["state"])

    def configure(self) -> Dict[str, Any]:
        """``unconfigured -> inactive``: checks the relations and builds the object."""
        return self._native.transition("configure")

    def activate(self) -> Dict[str, Any]:
        """``inactive -> active``."""
        return self._native.transition("activate")

    def deactivate(self) -> Dict[str, Any]:
        """``active -> inactive``."""
        return self._native.transition("deactivate")

    def cleanup(self) -> Dict[str, Any]:
        """``inactive -> unconfigured``."""
        return self._native.transition("cleanup")

    def shutdown(self) -> Dict[str, Any]:
        """Any state but ``finalized`` ``-> finalized``."""
        return self._native.transition("shutdown")

    def reset(self) -> Dict[str, Any]:
        """``error -> unconfigured``: the explicit re-arm after a fault."""
        return self._native.transition("reset")


class Object(Proxy):
    """An object of any class: its lifecycle and description only."""


class Robot(Proxy):
    """A remote robot (manipulator or joystick), read like the Rust ``RobotProxy``. Joint
    arguments ``q`` default to the measured positions."""

    _native: _native.Robot
    #: The active controller found driving this robot (looked for again when it stops).
    _driver: Optional["Controller"] = None

    def joint_count(self) -> int:
        """Number of joints."""
        return self._native.joint_count()

    def fk(self, q: Optional[JointsLike] = None) -> Array:
        """Forward kinematics: the tool pose in the base frame at ``q``, as the 4x4
        homogeneous transform (metres; the rotation's columns are the versors n, o, a)."""
        return np.array(self._native.fk(_joints(q)), dtype=np.float64).reshape(4, 4)

    def jacobian(self, q: Optional[JointsLike] = None, frame: str = "base") -> Array:
        """The geometric Jacobian at ``q``, 6xN, rows ``[v; ω]``, in the ``"base"`` frame or
        the ``"tool"`` frame (the base-frame one rotated by the tool orientation at the same
        ``q``; with ``q=None`` the measured positions are read once and used for both)."""
        if frame not in ("base", "tool"):
            raise _error("BadArgument", f'frame must be "base" or "tool", got {frame!r}')
        qq = _joints(q)
        if frame == "tool" and qq is None:
            qq = self._native.joint_positions()
        flat, n = self._native.jacobian(qq)
        j = np.array(flat, dtype=np.float64).reshape(6, n)
        if frame == "tool":
            r = self.fk(qq)[:3, :3]
            j = np.vstack((r.T @ j[:3], r.T @ j[3:]))
        return j

    def ik(self, T: npt.ArrayLike) -> List[Array]:
        """Inverse kinematics: every branch (joint vectors) reaching the 4x4 homogeneous
        transform ``T`` within the joint limits; possibly none. :class:`BadArgument` for a
        non-orthonormal rotation or a last row other than ``0 0 0 1``."""
        return [np.array(q, dtype=np.float64) for q in self._native.ik(_pose(T))]

    def joint_positions(self) -> Array:
        """Measured joint positions, rad."""
        return np.array(self._native.joint_positions(), dtype=np.float64)

    def joint_velocities(self) -> Array:
        """Measured joint velocities, rad/s."""
        return np.array(self._native.joint_velocities(), dtype=np.float64)

    def gravity(self, q: Optional[JointsLike] = None) -> Array:
        """Joint torques (N·m) that hold the arm still at ``q`` against gravity."""
        return np.array(self._native.gravity(_joints(q)), dtype=np.float64)

    def tool_wrench(self) -> Array:
        """The wrench at the tool from the robot's bound force sensor, ``[fx, fy, fz, tx, ty,
        tz]`` (N, N·m) in the base frame. :class:`NotReady` without a sensor."""
        return np.array(self._native.tool_wrench(), dtype=np.float64)

    # --- CRTK names ---------------------------------------------------------------------------

    def _driving_controller(self) -> Optional["Controller"]:
        """The active controller whose ``robot`` relation is this robot, on its node."""
        if self._driver is not None:
            return self._driver
        for o in self._client.objects(self.node):
            if (o["class"] == "controller" and o["state"] == "active"
                    and ("robot", self.name) in [tuple(r) for r in o["relations"]]):
                self._driver = self._client.controller(f"/{self.node}/controllers/{o['name']}")
                return self._driver
        return None

    def measured_js(self) -> "JointState":
        """CRTK ``measured_js``: the measured joint state. When an active controller drives
        the robot, its newest tick, read at once (positions, velocities and efforts of one
        instant, ``time`` the loop's clock in s); otherwise the robot's own reads of
        positions and velocities (two calls), ``effort`` zeros (no loop commands a torque) and
        ``time`` ``None``."""
        driver = self._driving_controller()
        if driver is not None:
            try:
                status = driver._native.status()
            except PenelopeError:  # the controller went away: look again next time
                self._driver = None
                status = None
            last = None if status is None else status["last"]
            if status is not None and status["running"] and last is not None:
                return JointState(
                    position=np.array(last["q"], dtype=np.float64),
                    velocity=np.array(last["qd"], dtype=np.float64),
                    effort=np.array(last["effort"], dtype=np.float64),
                    time=last["time_ns"] * 1e-9,
                )
            self._driver = None
        q = self.joint_positions()
        return JointState(
            position=q, velocity=self.joint_velocities(), effort=np.zeros_like(q), time=None
        )

    def measured_cp(self) -> Array:
        """CRTK ``measured_cp``: the tool pose at the measured joints, the 4x4 homogeneous
        transform in the base frame (m)."""
        return self.fk()

    def measured_cf(self) -> Array:
        """CRTK ``measured_cf``: the wrench at the tool from the bound force sensor, the
        6-vector ``[fx, fy, fz, tx, ty, tz]`` (N, N·m) in the base frame."""
        return self.tool_wrench()

    def setpoints(self) -> "Setpoints":
        """The reference the robot's active controller follows now, with the loop's time:
        see :class:`Setpoints`. :class:`NotReady` without an active controller or before its
        first tick."""
        time_ns, joints, pose = self._native.setpoints()
        return Setpoints(
            position=None if joints is None else np.array(joints, dtype=np.float64),
            pose=None if pose is None else np.array(pose, dtype=np.float64).reshape(4, 4),
            time=time_ns * 1e-9,
        )

    def setpoint_js(self) -> Array:
        """CRTK ``setpoint_js``: the joint reference the active controller follows, rad.
        :class:`NotReady` when it follows a tool pose only (see :meth:`setpoint_cp`)."""
        s = self.setpoints()
        if s.position is None:
            raise _error("NotReady", "the active controller follows a tool pose, not joints")
        return s.position

    def setpoint_cp(self) -> Array:
        """CRTK ``setpoint_cp``: the tool pose the active controller follows (4x4, base
        frame; forward kinematics of the joint reference for a joint law)."""
        s = self.setpoints()
        if s.pose is None:
            raise _error("NotReady", "the active controller's reference has no tool pose")
        return s.pose

    def operating_state(self) -> "OperatingState":
        """CRTK ``operating_state``: see :class:`OperatingState`."""
        state, is_homed, is_busy = self._native.operating_state()
        return OperatingState(state=state, is_homed=is_homed, is_busy=is_busy)

    def move_jp(self, q: JointsLike, duration: float) -> "Move":
        """CRTK ``move_jp``: moves to the joint positions ``q`` (rad, one per joint) in
        ``duration`` s along a smooth trajectory from the active controller's reference;
        returns at once with a :class:`Move` (call :meth:`Move.wait`). :class:`BadArgument`
        for a wrong joint count, a non-finite value, a target outside the joint limits or a
        duration outside (0, 3600] s; :class:`NotReady` without an active controller that
        follows joints."""
        qq = _joints(q)
        assert qq is not None
        self._native.move_jp(qq, float(duration))
        return Move(self, float(duration))

    def move_cp(self, T: npt.ArrayLike, duration: float) -> "Move":
        """CRTK ``move_cp``: as :meth:`move_jp` to the 4x4 tool pose ``T`` (base frame; the
        inverse-kinematics branch nearest the current reference). :class:`BadArgument` for an
        unreachable pose."""
        self._native.move_cp(_pose(T), float(duration))
        return Move(self, float(duration))

    def servo_jp(self, q: JointsLike) -> None:
        """CRTK ``servo_jp``: the newest joint target of a stream; the active controller's
        reference jumps to it (no interpolation). Send one every control period or so: past
        the controller's reference watchdog the loop holds. :class:`BadArgument` as
        :meth:`move_jp`, and for a target farther than the servo step limit from the current
        reference."""
        qq = _joints(q)
        assert qq is not None
        self._native.servo_jp(qq)

    def servo_cp(self, T: npt.ArrayLike) -> None:
        """CRTK ``servo_cp``: as :meth:`servo_jp` to the 4x4 tool pose ``T`` (base frame)."""
        self._native.servo_cp(_pose(T))

    def servo(self, rate: float = 500.0) -> "ServoLoop":
        """A rate-paced loop for streaming targets: each ``servo_cp`` / ``servo_jp`` through
        it sends, then sleeps until the next period. See :class:`ServoLoop`::

            with robot.servo(rate=500) as s:
                for T in poses:
                    s.servo_cp(T)
            print(s.achieved_rate, s.overruns)
        """
        return ServoLoop(self, rate)

    def map_joints(self, board: str, mapping: Union[Mapping[int, int], Sequence[Sequence[int]]]) -> None:
        """Maps joints to the axes of ``board`` (a board's name on the same node):
        ``{joint: axis}`` or ``[(joint, axis), ...]``."""
        pairs = mapping.items() if isinstance(mapping, Mapping) else mapping
        self._native.map_joints(board, [(int(j), int(a)) for j, a in pairs])

    def watch(self, decimation: int = 1, count: Optional[int] = None) -> "Watch":
        """The telemetry of the controller driving this robot: see :func:`watch`."""
        return watch(self, decimation, count)


@dataclass(frozen=True)
class JointState:
    """A measured joint state (CRTK ``measured_js``)."""

    #: Joint positions, rad (m for prismatic joints).
    position: Array
    #: Joint velocities, rad/s.
    velocity: Array
    #: Joint efforts the loop commanded, N·m.
    effort: Array
    #: The loop's time of the tick, s (``None`` when no loop drives the robot).
    time: Optional[float]


@dataclass(frozen=True)
class Setpoints:
    """The reference a robot's active controller follows (CRTK ``setpoint_js`` and
    ``setpoint_cp``)."""

    #: Joint reference, rad (``None`` when the controller follows a tool pose only).
    position: Optional[Array]
    #: Tool pose reference, 4x4 in the base frame (``None`` when there is none).
    pose: Optional[Array]
    #: The loop's time of the sample it was read from, s.
    time: float


@dataclass(frozen=True)
class OperatingState:
    """CRTK's operating state of a robot."""

    #: ``"DISABLED"`` (no active controller), ``"ENABLED"`` (running), ``"PAUSED"`` (holding:
    #: a stale reference, a clutch) or ``"FAULT"`` (a latched fault or e-stop).
    state: str
    #: Whether the joints' positions are known (simulated: always).
    is_homed: bool
    #: Whether a ``move_jp`` / ``move_cp`` is under way.
    is_busy: bool


class RobotFault(PenelopeError):
    """A robot went to ``FAULT`` (a latched fault or e-stop), or the loop its motion was
    queued on failed and was stopped, while :meth:`Move.wait` waited for the motion. Raised by
    this client, not sent by a node."""

    kind = "RobotFault"


class Move:
    """A motion under way (:meth:`Robot.move_jp`, :meth:`Robot.move_cp`)."""

    #: Added to the motion's duration to bound :meth:`wait` by default, s: the node's loop and
    #: this client's polling on a loaded machine.
    MARGIN_S = 10.0

    def __init__(self, robot: Robot, duration: float) -> None:
        self.robot = robot
        #: The motion's duration, s.
        self.duration = duration
        self._started = time.monotonic()
        # The loop the move was queued on: when the robot ends up with none, its status says
        # whether it failed under the move (unknown if the node cannot list it now).
        self._driver: Optional[Controller] = None
        try:
            self._driver = robot._driving_controller()
        except PenelopeError:
            pass

    def wait(self, timeout: Optional[float] = None, poll: float = 0.005) -> "Move":
        """Waits until the robot is no longer busy with the motion (polling
        :meth:`Robot.operating_state` every ``poll`` s on the real clock), at most ``timeout``
        s (default: the duration plus :attr:`MARGIN_S`, counted from the start); returns
        ``self``. :class:`Timeout` past the bound; :class:`RobotFault` if the robot faults,
        or if the loop the move was queued on failed and was stopped (the robot then has no
        active controller: ``DISABLED``, not busy). On a node with a simulated clock the
        motion advances only as the clock does: advance it (:meth:`Client.advance`) before
        waiting."""
        bound = self.duration + self.MARGIN_S if timeout is None else timeout
        deadline = self._started + bound
        while True:
            state = self.robot.operating_state()
            if state.state == "FAULT":
                raise RobotFault(f"{self.robot.path} went to FAULT during its move", "RobotFault")
            if not state.is_busy:
                if state.state == "DISABLED":
                    self._raise_if_its_loop_failed()
                return self
            if time.monotonic() > deadline:
                raise _error("Timeout", f"{self.robot.path} still busy after {bound:.1f} s")
            time.sleep(poll)

    def _raise_if_its_loop_failed(self) -> None:
        """:class:`RobotFault` when the controller the move was queued on is in ``error``: its
        loop failed and the node stopped it (a loop deactivated on purpose is no fault)."""
        if self._driver is None:
            return
        try:
            status = self._driver._native.status()
        except PenelopeError:  # destroyed meanwhile: nothing says it failed
            return
        if status["state"] != "error":
            return
        last = status["last"]
        cause = "" if last is None or last["fault"] is None else f" ({last['fault']})"
        raise RobotFault(
            f"{self.robot.path}: its controller {self._driver.path} failed during its move{cause}",
            "RobotFault",
        )


class ServoLoop:
    """A rate-paced stream of servo targets (:meth:`Robot.servo`): each :meth:`servo_cp` /
    :meth:`servo_jp` sends its target and then sleeps until the next period of an absolute
    schedule (``start + k / rate``), so the pace does not drift with the calls' own time. A
    call that ends past its period's end is an overrun: counted, and the schedule restarts
    from now (no burst of catch-up calls). The loop holds nothing on the node: when the stream
    stops, the controller's reference watchdog holds the robot."""

    def __init__(self, robot: Robot, rate: float) -> None:
        if not (math.isfinite(rate) and 0.0 < rate <= 10_000.0):
            raise _error("BadArgument", f"rate must be in (0, 10000] Hz, got {rate}")
        self.robot = robot
        #: The asked rate, Hz.
        self.rate = float(rate)
        #: The period, s.
        self.period = 1.0 / self.rate
        #: Targets sent.
        self.calls = 0
        #: Periods overrun (a call, with the sleep before it, that ended past its period).
        self.overruns = 0
        self._start: Optional[float] = None
        self._next = 0.0
        self._end: Optional[float] = None

    def __enter__(self) -> "ServoLoop":
        self._start = time.perf_counter()
        self._next = self._start + self.period
        return self

    def __exit__(
        self,
        exc_type: Optional[Type[BaseException]],
        exc: Optional[BaseException],
        tb: Optional[TracebackType],
    ) -> None:
        self._end = time.perf_counter()

    @property
    def elapsed(self) -> float:
        """Seconds since the loop started (until it ended, once it has)."""
        if self._start is None:
            return 0.0
        end = self._end if self._end is not None else time.perf_counter()
        return end - self._start

    @property
    def achieved_rate(self) -> float:
        """Targets sent per second of the loop."""
        e = self.elapsed
        return self.calls / e if e > 0 else 0.0

    def _pace(self) -> None:
        if self._start is None:
            self.__enter__()
        self.calls += 1
        now = time.perf_counter()
        if now > self._next:
            self.overruns += 1
            self._next = now + self.period
            return
        time.sleep(self._next - now)
        self._next += self.period

    def servo_cp(self, T: npt.ArrayLike) -> None:
        """Sends the tool-pose target ``T`` (:meth:`Robot.servo_cp`), then sleeps to the next
        period."""
        self.robot.servo_cp(T)
        self._pace()

    def servo_jp(self, q: JointsLike) -> None:
        """Sends the joint target ``q`` (:meth:`Robot.servo_jp`), then sleeps to the next
        period."""
        self.robot.servo_jp(q)
        self._pace()


class Board(Proxy):
    """A remote board: encoders and amplifiers."""

    _native: _native.Board

    def axis_count(self) -> int:
        """Number of axes."""
        return self._native.axis_count()

    def read_encoders(self) -> "npt.NDArray[np.int64]":
        """Encoder positions of every axis, counts."""
        return np.array(self._native.read_encoders(), dtype=np.int64)

    def amplifiers_enabled(self) -> bool:
        """Whether the amplifiers are enabled (the board's word, not a measurement of the
        power stage)."""
        return self._native.amplifiers_enabled()

    def rearm(self) -> None:
        """Asks the board to leave a fault it latched itself, once the cause is gone
        (:class:`NotReady` while a loop drives it: re-arm its controller instead)."""
        self._native.rearm()


class Trajectory(Proxy):
    """A remote trajectory."""

    _native: _native.Trajectory

    def reference(self, t: float) -> Dict[str, Any]:
        """The reference at ``t`` s after the start: a dict with ``type`` and, for
        ``"joint"``, ``q`` and ``qd`` (arrays); for ``"cartesian"``, ``pose`` (4x4); for
        ``"wrench"``, ``force`` and ``torque`` (base frame)."""
        r = self._native.reference(float(t))
        for k in ("q", "qd", "force", "torque"):
            if k in r:
                r[k] = np.array(r[k], dtype=np.float64)
        if "pose" in r:
            r["pose"] = np.array(r["pose"], dtype=np.float64).reshape(4, 4)
        return r

    def duration(self) -> Optional[float]:
        """The total duration, s (``None`` for an endless trajectory)."""
        return self._native.duration()


class Link(Trajectory):
    """A teleop channel (``trajectory/teleop``) whose other end is on another node: its link
    statistics."""

    def statistics(self) -> Dict[str, Any]:
        """The newest link statistics (one record of :meth:`watch`): ``down``, ``losses``,
        ``restorations``, ``samples_taken``/``dropped``/``missed``, ``refused``, the clock
        ``clock_offset_ns``, ``round_trip_ns``, ``one_way_delay_ns``, ``jitter_ns``,
        ``heartbeat_loss``, ``trips`` and ``trip_p50_ns``/``p99``/``max`` (``None`` while not
        estimated). :class:`NoLink` for a channel with both ends on one node."""
        with self.watch(count=1) as w:
            return next(w)

    def watch(self, decimation: int = 1, count: Optional[int] = None) -> "LinkWatch":
        """The link statistics as they come, one record every 100 ms times ``decimation``."""
        return LinkWatch(self._client._native.watch_link(self.path, decimation, count))


class Sensor(Proxy):
    """A remote force/torque sensor."""

    _native: _native.Sensor

    def read(self) -> Array:
        """The newest reading, ``[fx, fy, fz, tx, ty, tz]`` (N, N·m) in the sensor frame."""
        return np.array(self._native.read(), dtype=np.float64)

    def bias(self) -> None:
        """Takes the current reading as the zero."""
        self._native.bias()


class Camera(Sensor):
    """A camera (``sensor/sim-camera``, ``sensor/camera``): its frames, each stamped with its
    capture instant on the system's common clock."""

    def watch(self, decimation: int = 1, count: Optional[int] = None) -> "FrameWatch":
        """The frames as they come, one in ``decimation``: see :class:`FrameWatch`."""
        return FrameWatch(self._client._native.watch_camera(self.path, decimation, count))


class Controller(Proxy):
    """A remote controller."""

    _native: _native.Controller

    def set_gains(self, gains: Optional[ConfigLike] = None, **keys: Any) -> None:
        """Replaces gains at run time: TOML text, a mapping, or keywords with the kind's keys,
        such as ``set_gains(kp=[100, 100, 100, 10, 10, 10])``. :class:`BadConfig` for unknown
        keys or bad values."""
        self._native.set_gains(_toml(gains, keys))

    def set_robot(self, robot: str) -> None:
        """Relates the controller to the robot named ``robot`` on its node."""
        self._native.set_robot(robot)

    def set_trajectory(self, trajectory: str) -> None:
        """Relates the controller to the trajectory named ``trajectory`` on its node."""
        self._native.set_trajectory(trajectory)

    def set_sensor(self, sensor: Union[str, "Sensor"]) -> None:
        """Relates the controller to a force sensor: a name on its node, the naming path of a
        sensor on another node, or a proxy."""
        if not isinstance(sensor, str):
            sensor = sensor.name if sensor.node == self.node else sensor.path
        self._native.set_sensor(sensor)

    def status(self) -> Dict[str, Any]:
        """The loop's ``state``, ``running``, ``ticks``, ``overruns``, ``telemetry_dropped``
        and ``last`` sample (a telemetry dict as :func:`watch` yields, or ``None``)."""
        s = self._native.status()
        if s["last"] is not None:
            s["last"] = _sample(s["last"])
        return s

    def estop(self) -> None:
        """Latches the emergency stop of the running loop."""
        self._native.estop()

    def rearm(self) -> None:
        """Clears a latched fault or e-stop and activates again from the measured state."""
        self._native.rearm()

    def watch(self, decimation: int = 1, count: Optional[int] = None) -> "Watch":
        """This controller's telemetry: see :func:`watch`."""
        return watch(self, decimation, count)


_VECTORS = (
    "q", "qd", "effort", "tool_position", "force", "torque", "commanded_force", "commanded_torque",
)


def _sample(d: Dict[str, Any]) -> Dict[str, Any]:
    for k in _VECTORS:
        d[k] = np.array(d[k], dtype=np.float64)
    return d


_N = TypeVar("_N", _native.Watch, _native.LinkWatch, _native.FrameWatch)
_W = TypeVar("_W", bound="_Subscription[Any]")


class _Subscription(Iterator[Dict[str, Any]], Generic[_N]):
    """What every subscription iterator shares: its native stream, its path, the records the
    node dropped, and unsubscribing (:meth:`close`, or the end of a ``with`` block)."""

    def __init__(self, native: _N) -> None:
        self._native: _N = native

    @property
    def path(self) -> str:
        """The watched object's naming path."""
        return self._native.path

    @property
    def dropped(self) -> int:
        """What the node dropped because this side read too slowly."""
        return self._native.dropped

    def __iter__(self: _W) -> _W:
        return self

    def __next__(self) -> Dict[str, Any]:
        return next(self._native)

    def close(self) -> None:
        """Unsubscribes and closes the connection."""
        self._native.close()

    def __enter__(self: _W) -> _W:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Watch(_Subscription[_native.Watch]):
    """An iterator of telemetry samples on a connection of its own. Each sample is a dict:
    ``time_ns`` and ``seq`` (ints), the arrays ``q``, ``qd`` (rad, rad/s), ``effort`` (N·m),
    ``tool_position`` (m), ``force`` (N) and ``torque`` (N·m, base frame), ``state`` and
    ``fault`` (strings, ``fault`` ``None`` when clear), ``commanded_force`` and
    ``commanded_torque`` (the wrench the loop commanded after its caps: a master's displayed
    force), ``clutch`` (bool, ``None`` when no hand holds the robot) and ``port_energy`` and
    ``channel_energy`` (J, ``None`` for laws without those observers). Each wait is bounded by
    the client's timeout (:class:`Timeout`). Use as a context manager, or call :meth:`close`,
    to unsubscribe at once; :attr:`dropped` counts the batches the node dropped."""

    def __next__(self) -> Dict[str, Any]:
        return _sample(next(self._native))


class LinkWatch(_Subscription[_native.LinkWatch]):
    """An iterator of a channel's link statistics (dicts, see :meth:`Link.statistics`) on a
    connection of its own; a context manager that unsubscribes."""


class FrameWatch(_Subscription[_native.FrameWatch]):
    """An iterator of a camera's frames on a connection of its own; a context manager that
    unsubscribes. Each frame is a dict: ``seq`` (the camera's frame number), ``capture_ns``
    (the middle of its exposure), ``ready_ns`` (read out on the camera's node), ``sent_ns``
    (handed to this subscription), all ns on the common clock; ``encoding`` (``"jpeg"``),
    ``data`` (the encoded image, bytes) and ``model``: ``frame_id``, ``width``, ``height``,
    ``fx``, ``fy``, ``cx``, ``cy`` (px), ``pose_in_robot_base`` (4x4 array, or ``None``) and
    ``robot`` (the robot it watches, or ``None``). The node keeps a few frames per subscriber
    and drops the oldest when this side reads too slowly (:attr:`dropped`)."""

    def __next__(self) -> Dict[str, Any]:
        f = next(self._native)
        pose = f["model"]["pose_in_robot_base"]
        if pose is not None:
            f["model"]["pose_in_robot_base"] = np.array(pose, dtype=np.float64).reshape(4, 4)
        return f


class Recording:
    """A recording under way on one node (:meth:`Client.record`). As a context manager it
    stops at the block's end (even on an exception); :attr:`ticks` is then known."""

    def __init__(
        self, client: Client, node: str, path: str, controllers: List[str], links: List[str]
    ) -> None:
        self._client = client
        #: The node recording.
        self.node = node
        #: The file's path on the node's host.
        self.path = path
        #: The controllers recorded.
        self.controllers = controllers
        #: The linked channels recorded.
        self.links = links
        #: Control ticks written (``None`` until stopped).
        self.ticks: Optional[int] = None

    def __repr__(self) -> str:
        return f"penelope.Recording({self.node!r}, {self.path!r})"

    def stop(self) -> int:
        """Ends the recording (once; later calls return the same count): the ticks
        written."""
        if self.ticks is None:
            path, ticks = self._client._native.record_stop(self.node)
            self.path, self.ticks = path, ticks
        return self.ticks

    def __enter__(self) -> "Recording":
        return self

    def __exit__(
        self,
        exc_type: Optional[Type[BaseException]],
        exc: Optional[BaseException],
        tb: Optional[TracebackType],
    ) -> None:
        self.stop()


def connect(
    naming: str = "127.0.0.1:7300",
    secret_file: Optional[Union[str, "os.PathLike[str]"]] = None,
    *,
    name: str = "penelope-python",
    timeout: float = 5.0,
    admin_secret_file: Optional[Union[str, "os.PathLike[str]"]] = None,
) -> Client:
    """Connects to the naming service at ``naming`` (``HOST:PORT``) at once, so that an
    unreachable or refusing service is reported here.

    ``secret_file``: the system's shared secret (readable by its owner only, as for
    ``penelope node``); with it, every connection proves the secret and is encrypted, and a
    node that does not prove it is refused (:class:`Unauthenticated`). A node that requires the
    secret refuses a client without it (:class:`AuthFailed`). ``timeout`` (s) bounds the
    connection and every call.

    The client speaks as the most its files prove: an administrator (create and destroy
    objects) with ``admin_secret_file`` or on a system without a secret (loopback only, where
    roles are taken on trust); an operator (run objects, record, but not create or destroy)
    with ``secret_file`` alone."""
    path = None if secret_file is None else os.fspath(secret_file)
    admin = None if admin_secret_file is None else os.fspath(admin_secret_file)
    return Client(_native.Client.connect(naming, path, name, timeout, admin))


def watch(
    obj: Union[Robot, Controller], decimation: int = 1, count: Optional[int] = None
) -> Watch:
    """The telemetry of ``obj`` (a controller, or a robot an active controller drives): an
    iterator of samples, one control tick in ``decimation``, ending after ``count`` samples
    (never when ``None``). See :class:`Watch`."""
    return obj.client.watch(obj, decimation, count)
