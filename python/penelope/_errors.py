"""Exceptions: one class per kind of error, all subclasses of :class:`PenelopeError`.

A node's error carries the kind of the wire error it answered: the variant of its
``ProtocolError`` (a failure of the protocol: ``AuthFailed``, ``RateLimited``, ...) or of its
``CallError`` (a refused call: ``UnknownName``, ``BadConfig``, ...), both in
``penelope_protocol::proto``. The client's own transport failures have the kinds ``Io``,
``Frame``, ``Protocol``, ``Unauthenticated`` and ``Timeout``. The class is named as the kind,
and ``.kind`` holds it. The tests check these classes against the Rust enums
(``penelope._native.error_kinds()``).
"""

from __future__ import annotations

from typing import Dict, Type


class PenelopeError(Exception):
    """An error of a Penelope call. ``kind`` names it (a wire error's variant, or a transport
    failure's); ``str(e)`` says what went wrong."""

    kind: str = "PenelopeError"

    def __init__(self, message: str, kind: str | None = None) -> None:
        super().__init__(message)
        if kind is not None:
            self.kind = kind


# --- the node's protocol failures (the variants of ProtocolError, in their Rust order) ------------


class Malformed(PenelopeError):
    """A frame's body did not decode as the expected message."""

    kind = "Malformed"


class FrameTooLarge(PenelopeError):
    """A frame announced more bytes than the receiver accepts."""

    kind = "FrameTooLarge"


class BadMagic(PenelopeError):
    """The peer is not a Penelope peer."""

    kind = "BadMagic"


class VersionMismatch(PenelopeError):
    """The peer speaks another protocol version."""

    kind = "VersionMismatch"


class Unexpected(PenelopeError):
    """A message came out of order."""

    kind = "Unexpected"


class AuthFailed(PenelopeError):
    """The node requires the shared secret and none (or a wrong one) was given."""

    kind = "AuthFailed"


class RateLimited(PenelopeError):
    """Too many requests per second on this connection."""

    kind = "RateLimited"


class TooManyConnections(PenelopeError):
    """The node serves no more connections now."""

    kind = "TooManyConnections"


class Timeout(PenelopeError, TimeoutError):
    """No answer in time (the node's notice, or this client's own deadline)."""

    kind = "Timeout"


# --- the node's refusals of a call (the variants of CallError, in their Rust order) ---------------


class LimitReached(PenelopeError):
    """A limit on objects, subscriptions or bindings was reached."""

    kind = "LimitReached"


class UnknownKind(PenelopeError):
    """No kind of that name (see ``kinds()``)."""

    kind = "UnknownKind"


class UnknownName(PenelopeError):
    """No object, node or naming entry of that name."""

    kind = "UnknownName"


class NameTaken(PenelopeError):
    """The name is already used."""

    kind = "NameTaken"


class BadName(PenelopeError):
    """The name or path is not well formed."""

    kind = "BadName"


class BadConfig(PenelopeError):
    """The configuration (or gains) does not fit the kind."""

    kind = "BadConfig"


class BadArgument(PenelopeError, ValueError):
    """An argument is out of range, of the wrong size or not finite."""

    kind = "BadArgument"


class WrongClass(PenelopeError):
    """The object is of another class than the method's."""

    kind = "WrongClass"


class InvalidTransition(PenelopeError):
    """The lifecycle transition is not allowed from the object's state."""

    kind = "InvalidTransition"


class InUse(PenelopeError):
    """The object is needed by active objects (destroy with ``force=True``)."""

    kind = "InUse"


class NotReady(PenelopeError):
    """The object cannot do this now (not configured, not running, ...)."""

    kind = "NotReady"


class Unsupported(PenelopeError):
    """The object's kind does not support this method."""

    kind = "Unsupported"


class Device(PenelopeError):
    """A device (board, sensor, link) reported an error."""

    kind = "Device"


class NoNamingService(PenelopeError):
    """The node does not host the naming service."""

    kind = "NoNamingService"


class Remote(PenelopeError):
    """A node's own call to another node failed."""

    kind = "Remote"


class Internal(PenelopeError):
    """A bug: the node could not do what it should have."""

    kind = "Internal"


class Forbidden(PenelopeError):
    """The session's role may not do this."""

    kind = "Forbidden"


class NoLink(PenelopeError):
    """The channel has both ends on one node: no data-plane link to watch."""

    kind = "NoLink"


# --- this client's transport failures --------------------------------------------------------


class TransportError(PenelopeError, ConnectionError):
    """The socket failed or a frame could not be read or written (kinds ``Io``, ``Frame``)."""

    kind = "Io"


class ProtocolError(PenelopeError):
    """The node broke the protocol (a reply of the wrong shape)."""

    kind = "Protocol"


class Unauthenticated(PenelopeError):
    """This client holds the secret and the node did not prove it: nothing was sent."""

    kind = "Unauthenticated"


_PROTOCOL_ERRORS = (
    Malformed, FrameTooLarge, BadMagic, VersionMismatch, Unexpected, AuthFailed, RateLimited,
    TooManyConnections, Timeout,
)
_CALL_ERRORS = (
    LimitReached, UnknownKind, UnknownName, NameTaken, BadName, BadConfig, BadArgument,
    WrongClass, InvalidTransition, InUse, NotReady, Unsupported, Device, NoNamingService, Remote,
    Internal, Forbidden, NoLink,
)
_BY_KIND: Dict[str, Type[PenelopeError]] = {
    cls.kind: cls
    for cls in (*_PROTOCOL_ERRORS, *_CALL_ERRORS, TransportError, ProtocolError, Unauthenticated)
}
_BY_KIND["Frame"] = TransportError
for _cls in set(_BY_KIND.values()) | {PenelopeError}:
    _cls.__module__ = "penelope"  # shown as penelope.UnknownName, where users import it from


def _from_kind(kind: str, message: str) -> PenelopeError:
    """The exception for an error of ``kind`` (called by the extension module); a kind this
    package does not know yet (a newer node) gives a plain :class:`PenelopeError`."""
    return _BY_KIND.get(kind, PenelopeError)(message, kind)


__all__ = ["PenelopeError"] + sorted(c.__name__ for c in set(_BY_KIND.values()))
