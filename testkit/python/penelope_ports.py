"""Free loopback ports for the Python tests (python/tests, tools/tests/foxglove,
tools/tests/browser), as `penelope_testkit::net` hands them out to the Rust tests.

A port the kernel picks for a socket bound to port 0 comes from its ephemeral range, where every
other socket on the machine that binds port 0 or connects out draws its own: on a busy machine
one of them can take the port between the test finding it free and the node binding it. The
ports handed out here lie below that range."""

from __future__ import annotations

import itertools
import os
import socket


def _ephemeral_low() -> int:
    try:
        with open("/proc/sys/net/ipv4/ip_local_port_range") as f:
            return int(f.read().split()[0])
    except (OSError, ValueError, IndexError):
        return 32768


# Ports handed out lie below the kernel's ephemeral range, which it never gives to a socket
# binding port 0 or connecting out: a port found free here cannot be taken by such a socket
# before the node binds it. A counter (spread by process id) never hands one out twice.
_LOWEST = 10_000
_SPAN = max(_ephemeral_low(), _LOWEST + 1024) - _LOWEST
_next_port = itertools.count((os.getpid() * 7919) % _SPAN)


def free_port() -> int:
    """A loopback TCP port nobody listens on (now), below the ephemeral range."""
    for _ in range(1000):
        port = _LOWEST + next(_next_port) % _SPAN
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    raise RuntimeError("no free loopback port in 1000 tries")
