"""What the Python benchmarks share: a `penelope node --host-naming` ($PENELOPE_BIN) on a free
loopback port, ready when it prints its readiness line (no fixed sleep) and stopped at the end;
a PUMA 560 on a simulated board; and the statistics of calls timed one by one."""

from __future__ import annotations

import os
import socket
import statistics
import subprocess
from contextlib import contextmanager
from typing import Dict, Iterator, List

import penelope

#: What the node prints once it serves.
READY = "Ctrl-C stops the node"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


@contextmanager
def bench_node() -> Iterator[str]:
    """A node named `bench` hosting the naming service; yields the naming service's address.
    RuntimeError if the node exits before it is ready."""
    naming = f"127.0.0.1:{free_port()}"
    node = subprocess.Popen(
        [os.environ["PENELOPE_BIN"], "node", "--name", "bench", "--host-naming", "--listen",
         naming, "--priority", "0"],
        stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, text=True,
    )
    try:
        assert node.stdout is not None
        for line in node.stdout:
            if READY in line:
                break
        else:
            raise RuntimeError("the node exited before it was ready")
        yield naming
    finally:
        node.terminate()
        node.wait(timeout=10)


def puma_on_sim_board(c: penelope.Client) -> penelope.Robot:
    """A PUMA 560 `slave` on a simulated six-axis board `sim0` of node `bench`, both
    configured."""
    board = c.create("bench", "board/sim", "sim0", axes=6)
    robot = c.create("bench", "robot/puma560", "slave")
    assert isinstance(robot, penelope.Robot)
    robot.map_joints("sim0", {j: j for j in range(6)})
    board.configure()
    robot.configure()
    return robot


def summary(ns: List[int]) -> Dict[str, float]:
    """Calls timed one by one (ns): their count, the free-running calls/s (1 / mean), and the
    mean, p50 and p99 in µs."""
    ns = sorted(ns)
    mean = statistics.fmean(ns)
    return {
        "calls": len(ns),
        "calls_per_s": 1e9 / mean,
        "mean_us": mean / 1e3,
        "p50_us": ns[(len(ns) - 1) // 2] / 1e3,
        "p99_us": ns[round((len(ns) - 1) * 0.99)] / 1e3,
    }
