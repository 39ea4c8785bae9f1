"""Fixtures: a real `penelope node` (hosting its naming service) on a free loopback port,
started from the binary named by $PENELOPE_BIN, ready when it prints its readiness line,
stopped when the test ends.

Nothing is skipped: without $PENELOPE_BIN (or with a binary that does not start) the run
fails."""

from __future__ import annotations

import os
import queue
import sys
import subprocess
import tempfile
import threading
from pathlib import Path
from typing import Iterator, List, Optional

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "testkit" / "python"))
from penelope_ports import free_port  # noqa: E402

READY = "Ctrl-C stops the node"
START_TIMEOUT_S = 60.0


def pytest_configure(config: pytest.Config) -> None:
    binary = os.environ.get("PENELOPE_BIN")
    if not binary or not os.access(binary, os.X_OK):
        raise pytest.UsageError(
            "PENELOPE_BIN must name the `penelope` binary (scripts/test sets it after "
            f"building it); got {binary!r}"
        )


@pytest.fixture(scope="session")
def penelope_bin() -> str:
    return os.environ["PENELOPE_BIN"]


class Node:
    """A `penelope node --host-naming` child process; `naming` is its address."""

    def __init__(self, binary: str, name: str, extra: List[str],
                 naming: Optional[str] = None) -> None:
        # Hosting the naming service, or (given `naming`) registering in another node's.
        self.naming = naming or f"127.0.0.1:{free_port()}"
        self._stderr = tempfile.TemporaryFile()
        where = (["--naming", naming, "--listen", f"127.0.0.1:{free_port()}"] if naming
                 else ["--host-naming", "--listen", self.naming])
        self.proc = subprocess.Popen(
            [binary, "node", "--name", name, *where, "--priority", "0", *extra],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=self._stderr,
            text=True,
        )
        lines: "queue.Queue[Optional[str]]" = queue.Queue()
        self.output: List[str] = []

        def pump() -> None:
            assert self.proc.stdout is not None
            for line in self.proc.stdout:
                lines.put(line)
            lines.put(None)

        threading.Thread(target=pump, daemon=True).start()
        # Wait for the readiness line (no fixed sleep): the node prints it once it serves.
        while True:
            try:
                line = lines.get(timeout=START_TIMEOUT_S)
            except queue.Empty:
                log = self.log()
                self.stop()
                pytest.fail(f"the node printed no {READY!r} in {START_TIMEOUT_S} s: {log}")
            if line is None:
                log = self.log()
                self.stop()
                pytest.fail(f"the node exited before it was ready: {log}")
            self.output.append(line)
            if READY in line:
                break

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
        self._stderr.close()


@pytest.fixture
def node(penelope_bin: str) -> Iterator[Node]:
    """A node `lab` without a secret (loopback only)."""
    n = Node(penelope_bin, "lab", [])
    yield n
    n.stop()


@pytest.fixture
def secret_file(tmp_path: Path) -> Path:
    """A shared secret, readable by its owner only."""
    f = tmp_path / "lab.secret"
    f.write_text("correct horse battery staple\n")
    f.chmod(0o600)
    return f


@pytest.fixture
def admin_secret_file(tmp_path: Path) -> Path:
    """The administrators' secret (creating and destroying objects needs it)."""
    f = tmp_path / "admin.secret"
    f.write_text("7d1e4f0a9c2b5e8d3f6a1c4e7b0d2f5a\n")
    f.chmod(0o600)
    return f


@pytest.fixture
def secure_node(penelope_bin: str, secret_file: Path, admin_secret_file: Path) -> Iterator[Node]:
    """A node `lab` that requires the secret, and the admin secret to create objects."""
    n = Node(penelope_bin, "lab", ["--secret-file", str(secret_file),
                                   "--admin-secret-file", str(admin_secret_file)])
    yield n
    n.stop()
