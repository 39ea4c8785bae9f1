"""Penelope's Python client: the Rust client (``penelope_supervisor::client``) behind PyO3,
so that the protocol has one implementation.

    import penelope

    c = penelope.connect("127.0.0.1:7300")
    robot = c.create("lab", "robot/puma560", "slave")
    print(robot.fk([0, 0.5, -3.1, 0, 0.6, 0]))   # the 4x4 tool pose, a NumPy array

Errors are exceptions of the class named by the wire error's kind (:class:`UnknownName`,
:class:`BadConfig`, :class:`AuthFailed`, ...), all subclasses of :class:`PenelopeError`.
"""

from ._client import (
    Array,
    Client,
    Controller,
    Object,
    Proxy,
    Robot,
    Sensor,
    Watch,
    connect,
    watch,
)
from ._errors import *  # noqa: F401,F403  (one class per kind of error)
from ._errors import PenelopeError, __all__ as _error_names
from ._native import __version__

__all__ = [
    "Array",
    "Client",
    "Controller",
    "Object",
    "Proxy",
    "Robot",
    "Sensor",
    "Watch",
    "connect",
    "watch",
    "PenelopeError",
    "__version__",
] + [n for n in _error_names if n != "PenelopeError"]
