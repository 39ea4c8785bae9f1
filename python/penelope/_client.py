"""The client and the proxies: thin Python over the Rust client (``penelope._native``), with
NumPy arrays at the edges."""

from __future__ import annotations

import math
import os
import re
from typing import Any, Dict, Iterator, List, Mapping, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

from . import _native

#: A float64 NumPy array.
Array = npt.NDArray[np.float64]
#: Joint values: any sequence of floats (or a 1-D array), radians (metres for prismatic joints).
JointsLike = Union[Sequence[float], npt.ArrayLike]
#: A configuration: TOML text, or a mapping of keys to values (made into TOML).
ConfigLike = Union[str, Mapping[str, Any]]

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


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
        ``unconfigured``.

        Raises :class:`UnknownKind`, :class:`NameTaken`, :class:`BadName`, :class:`BadConfig`,
        :class:`LimitReached`."""
        path = self._native.create(node, kind, name, _toml(config, keys))
        return self.proxy(path)

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
        cls = self._native.locate(path)["class"]
        if cls == "robot":
            return self.robot(path)
        if cls == "sensor":
            return self.sensor(path)
        if cls == "controller":
            return self.controller(path)
        return self.object(path)

    def robot(self, path: str) -> "Robot":
        """The robot at ``path`` (a naming path or ``NODE/NAME``); :class:`WrongClass` if it is
        not a robot."""
        return Robot(self, self._native.robot(path))

    def sensor(self, path: str) -> "Sensor":
        """The sensor at ``path``."""
        return Sensor(self, self._native.sensor(path))

    def controller(self, path: str) -> "Controller":
        """The controller at ``path``."""
        return Controller(self, self._native.controller(path))

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
        t = np.asarray(T, dtype=np.float64)
        if t.shape != (4, 4):
            raise _error("BadArgument", f"T must be 4x4, got shape {t.shape}")
        return [np.array(q, dtype=np.float64) for q in self._native.ik(t.ravel().tolist())]

    def joint_positions(self) -> Array:
        """Measured joint positions, rad."""
        return np.array(self._native.joint_positions(), dtype=np.float64)

    def joint_velocities(self) -> Array:
        """Measured joint velocities, rad/s."""
        return np.array(self._native.joint_velocities(), dtype=np.float64)

    def gravity(self, q: Optional[JointsLike] = None) -> Array:
        """Joint torques (N·m) that hold the arm still at ``q`` against gravity."""
        return np.array(self._native.gravity(_joints(q)), dtype=np.float64)

    def map_joints(self, board: str, mapping: Union[Mapping[int, int], Sequence[Sequence[int]]]) -> None:
        """Maps joints to the axes of ``board`` (a board's name on the same node):
        ``{joint: axis}`` or ``[(joint, axis), ...]``."""
        pairs = mapping.items() if isinstance(mapping, Mapping) else mapping
        self._native.map_joints(board, [(int(j), int(a)) for j, a in pairs])

    def watch(self, decimation: int = 1, count: Optional[int] = None) -> "Watch":
        """The telemetry of the controller driving this robot: see :func:`watch`."""
        return watch(self, decimation, count)


class Sensor(Proxy):
    """A remote force/torque sensor."""

    _native: _native.Sensor

    def read(self) -> Array:
        """The newest reading, ``[fx, fy, fz, tx, ty, tz]`` (N, N·m) in the sensor frame."""
        return np.array(self._native.read(), dtype=np.float64)

    def bias(self) -> None:
        """Takes the current reading as the zero."""
        self._native.bias()


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


class Watch(Iterator[Dict[str, Any]]):
    """An iterator of telemetry samples on a connection of its own. Each sample is a dict:
    ``time_ns`` and ``seq`` (ints), the arrays ``q``, ``qd`` (rad, rad/s), ``effort`` (N·m),
    ``tool_position`` (m), ``force`` (N) and ``torque`` (N·m, base frame), ``state`` and
    ``fault`` (strings, ``fault`` ``None`` when clear), ``commanded_force`` and
    ``commanded_torque`` (the wrench the loop commanded after its caps: a master's displayed
    force), ``clutch`` (bool, ``None`` when no hand holds the robot) and ``port_energy`` and
    ``channel_energy`` (J, ``None`` for laws without those observers). Each wait is bounded by the client's
    timeout (:class:`Timeout`). Use as a context manager, or call :meth:`close`, to
    unsubscribe at once."""

    def __init__(self, native: _native.Watch) -> None:
        self._native = native

    @property
    def path(self) -> str:
        """The watched object's naming path."""
        return self._native.path

    @property
    def dropped(self) -> int:
        """Batches the node dropped because this side read too slowly."""
        return self._native.dropped

    def __iter__(self) -> "Watch":
        return self

    def __next__(self) -> Dict[str, Any]:
        return _sample(next(self._native))

    def close(self) -> None:
        """Unsubscribes and closes the connection."""
        self._native.close()

    def __enter__(self) -> "Watch":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


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
