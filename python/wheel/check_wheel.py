"""The wheel, installed into a fresh virtual environment with no Rust toolchain on PATH, imports
and talks to a real node. Run by scripts/test with that environment's interpreter:

    PENELOPE_BIN=target/release/penelope <venv>/bin/python python/wheel/check_wheel.py

Checks: no `cargo` or `rustc` on PATH; `penelope` is imported from this environment's
site-packages (the wheel), not from the source tree; its compiled module is there; a node
started from $PENELOPE_BIN answers the client (the nodes, a robot's forward kinematics equal to
the command line's to 1e-12). Exits non-zero with the reason on any failure."""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import sysconfig
from pathlib import Path

READY = "Ctrl-C stops the node"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def main() -> int:
    for tool in ("cargo", "rustc"):
        assert shutil.which(tool) is None, f"{tool} is on PATH: {shutil.which(tool)}"
    # Not from the source tree: run from elsewhere, with the source tree off sys.path.
    here = Path(__file__).resolve().parent.parent
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() not in (here, here / "wheel")]
    import numpy as np

    import penelope

    site = Path(sysconfig.get_paths()["purelib"]).resolve()
    where = Path(penelope.__file__).resolve()
    assert site in where.parents, f"penelope imported from {where}, not from {site}"
    native = Path(penelope._native.__file__).resolve()
    assert site in native.parents, native
    binary = os.environ["PENELOPE_BIN"]
    naming = f"127.0.0.1:{free_port()}"
    node = subprocess.Popen(
        [binary, "node", "--name", "lab", "--host-naming", "--listen", naming, "--priority", "0"],
        stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, text=True,
    )
    try:
        assert node.stdout is not None
        for line in node.stdout:  # the readiness line, no fixed sleep
            if READY in line:
                break
        else:
            raise AssertionError("the node exited before it was ready")
        q = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]
        with penelope.connect(naming) as c:
            assert c.nodes() == ["lab"]
            with c.create("lab", "robot/puma560", "slave") as robot:
                assert isinstance(robot, penelope.Robot)
                t = robot.fk(q)
        cli = subprocess.run(
            [binary, "kin", "puma560", "fk", "--q", ",".join(map(repr, q)), "--json"],
            check=True, capture_output=True, text=True,
        ).stdout
        np.testing.assert_allclose(t, np.array(json.loads(cli)["T"]), rtol=0, atol=1e-12)
    finally:
        node.terminate()
        node.wait(timeout=10)
    print(f"the wheel's penelope {penelope.__version__} from {where.parent}: talks to a node, "
          "no Rust toolchain on PATH")
    return 0


if __name__ == "__main__":
    sys.exit(main())
