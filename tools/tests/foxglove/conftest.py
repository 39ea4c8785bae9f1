"""Fixtures of the tests of `penelope foxglove`: a real node (hosting its naming service) running
the demo's system, `penelope foxglove` beside it, and an independent Foxglove WebSocket client
(the `websockets` package speaking `foxglove.websocket.v1`), all on loopback.

Every process is waited for by the line it prints once it serves, never by time; every wait is
bounded. Nothing is skipped: a missing binary fails the run."""

from __future__ import annotations

import json
import os
import queue
import re
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Callable, Dict, Iterator, List, Optional

import pytest
from websockets.sync.client import connect

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "testkit" / "python"))
from penelope_ports import free_port  # noqa: E402

NODE_READY = "Ctrl-C stops the node"
FOX_READY = re.compile(r"penelope foxglove: serving (ws://\S+) ")
START_TIMEOUT_S = 60.0
REPO = Path(__file__).resolve().parents[3]
DEMO = REPO / "config" / "demo.toml"


def pytest_configure(config: pytest.Config) -> None:
    binary = os.environ.get("PENELOPE_BIN")
    if not binary or not os.access(binary, os.X_OK):
        raise pytest.UsageError(
            f"PENELOPE_BIN must name the `penelope` binary (scripts/test sets it); got {binary!r}")


class Process:
    """A child process whose standard output is read line by line on a thread."""

    def __init__(self, argv: List[str], ready: "re.Pattern[str] | str") -> None:
        self.argv = argv
        self._stderr = tempfile.TemporaryFile()
        self.proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                     stderr=self._stderr, text=True, cwd=REPO)
        self.lines: "queue.Queue[Optional[str]]" = queue.Queue()
        self.output: List[str] = []

        def pump() -> None:
            assert self.proc.stdout is not None
            for line in self.proc.stdout:
                self.lines.put(line)
            self.lines.put(None)

        threading.Thread(target=pump, daemon=True).start()
        self.match = self._wait_for(ready)

    def _wait_for(self, ready: "re.Pattern[str] | str"):
        while True:
            try:
                line = self.lines.get(timeout=START_TIMEOUT_S)
            except queue.Empty:
                self.stop()
                pytest.fail(f"{self.argv[:3]} printed no {ready!r} in {START_TIMEOUT_S} s: {self.log()}")
            if line is None:
                self.stop()
                pytest.fail(f"{self.argv[:3]} exited before it was ready: {self.log()}")
            self.output.append(line)
            if isinstance(ready, str):
                if ready in line:
                    return line
            else:
                m = ready.search(line)
                if m:
                    return m

    def log(self) -> str:
        self._stderr.seek(0)
        err = self._stderr.read().decode(errors="replace")
        return f"stdout:\n{''.join(self.output)}\nstderr:\n{err}"

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


class System:
    """A node `lab` hosting the naming service and running the demo's system, and
    `penelope foxglove` in front of it."""

    def __init__(self, binary: str, node_args: List[str], fox_args: List[str],
                 system: Optional[Path] = DEMO) -> None:
        self.binary = binary
        self.naming = f"127.0.0.1:{free_port()}"
        config = ["--config", str(system)] if system else []
        self.node = Process([binary, "node", "--name", "lab", "--host-naming", "--listen",
                             self.naming, *config, "--priority", "0", *node_args], NODE_READY)
        try:
            self.fox = Process([binary, "foxglove", "--naming", self.naming, "--listen",
                                "127.0.0.1:0", *fox_args], FOX_READY)
        except BaseException:
            self.node.stop()
            raise
        self.url = self.fox.match.group(1)

    def ctl(self, *args: str) -> subprocess.CompletedProcess:
        r = subprocess.run([self.binary, "ctl", "--naming", self.naming, *args],
                           stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, f"ctl {args}: {r.stdout}\n{r.stderr}"
        return r

    def stop(self) -> None:
        self.fox.stop()
        self.node.stop()


@pytest.fixture(scope="session")
def penelope_bin() -> str:
    return os.environ["PENELOPE_BIN"]


@pytest.fixture
def demo(penelope_bin: str) -> Iterator[System]:
    s = System(penelope_bin, [], [])
    yield s
    s.stop()


class FoxgloveClient:
    """An independent client of the Foxglove WebSocket protocol (`foxglove.websocket.v1`): the
    spec's JSON operations and little-endian binary frames, nothing of Penelope."""

    def __init__(self, url: str, subprotocols=("foxglove.websocket.v1",), sock=None) -> None:
        self.ws = connect(url, subprotocols=list(subprotocols), open_timeout=30,
                          max_size=16 * 1024 * 1024, sock=sock).__enter__()
        self.server_info: Optional[dict] = None
        self.channels: Dict[int, dict] = {}
        self.services: Dict[str, dict] = {}
        self.statuses: List[dict] = []
        self.failures: List[dict] = []
        self.responses: List[tuple] = []
        self.times: List[int] = []
        self.messages: Dict[int, List[tuple]] = {}
        self.next_sub = 1
        self.subs: Dict[int, int] = {}

    @classmethod
    def over(cls, url: str, sock) -> "FoxgloveClient":
        """A client over an already connected socket (one with a small receive buffer)."""
        return cls(url, sock=sock)

    def close(self) -> None:
        self.ws.close()

    def _take(self, m) -> None:
        if isinstance(m, str):
            j = json.loads(m)
            op = j["op"]
            if op == "serverInfo":
                self.server_info = j
            elif op == "advertise":
                for c in j["channels"]:
                    self.channels[c["id"]] = c
            elif op == "unadvertise":
                for i in j["channelIds"]:
                    self.channels.pop(i, None)
            elif op == "advertiseServices":
                for s in j["services"]:
                    self.services[s["name"]] = s
            elif op == "status":
                self.statuses.append(j)
            elif op == "serviceCallFailure":
                self.failures.append(j)
            return
        opcode = m[0]
        if opcode == 1:
            sub, t = struct.unpack_from("<IQ", m, 1)
            self.messages.setdefault(sub, []).append((t, json.loads(m[13:])))
        elif opcode == 2:
            self.times.append(struct.unpack_from("<Q", m, 1)[0])
        elif opcode == 3:
            service, call, n = struct.unpack_from("<III", m, 1)
            encoding = m[13:13 + n].decode()
            self.responses.append((service, call, encoding, json.loads(m[13 + n:])))

    def pump_until(self, done: Callable[[], bool], timeout: float, what: str) -> None:
        """Reads messages until `done()` (bounded by `timeout`)."""
        end = time.monotonic() + timeout
        while not done():
            left = end - time.monotonic()
            if left <= 0:
                pytest.fail(f"waited {timeout} s for {what}; channels "
                            f"{sorted(c['topic'] for c in self.channels.values())}, statuses {self.statuses}")
            try:
                self._take(self.ws.recv(timeout=min(left, 0.5)))
            except TimeoutError:
                pass

    def pump_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            try:
                self._take(self.ws.recv(timeout=max(0.01, end - time.monotonic())))
            except TimeoutError:
                pass

    def channel(self, topic: str) -> Optional[dict]:
        return next((c for c in self.channels.values() if c["topic"] == topic), None)

    def subscribe(self, topic: str) -> int:
        c = self.channel(topic)
        assert c is not None, topic
        sub = self.next_sub
        self.next_sub += 1
        self.subs[sub] = c["id"]
        self.ws.send(json.dumps({"op": "subscribe",
                                 "subscriptions": [{"id": sub, "channelId": c["id"]}]}))
        return sub

    def call(self, service: str, request: dict, call_id: int) -> None:
        s = self.services[service]
        payload = json.dumps(request).encode()
        self.ws.send(bytes([2]) + struct.pack("<III", s["id"], call_id, 4) + b"json" + payload)
