"""The examples in python/examples run against a real node, as a user would run them."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from conftest import Node

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def test_dvrk_teleop_example_drives_the_slave_clutches_and_feels_the_wall(node: Node) -> None:
    run = subprocess.run(
        [sys.executable, str(EXAMPLES / "dvrk_teleop.py"), "--naming", node.naming,
         "--seconds", "4", "--rate", "200"],
        capture_output=True, text=True, timeout=300,
    )
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout.strip().splitlines()[-1])
    print(summary)
    assert summary["calls"] == 800
    # The pedal: the hand moved, the arm held (it only settled onto its last target: its lag
    # when the pedal went down).
    assert summary["hand_motion_during_clutch_mm"] > 5.0
    assert summary["slave_motion_during_clutch_mm"] < 3.0
    # Free motion tracked; the press reached the wall and its force came back to the hand.
    assert summary["worst_tracking_mm"] < 5.0
    assert summary["max_contact_force_n"] > 5.0
    assert summary["min_displayed_force_z_n"] < -2.0
    # The example removed what it made: the node is as it was.
    from penelope import connect

    with connect(node.naming) as c:
        assert not [o for o in c.objects("lab") if o["name"].startswith(("dvrk", "psm"))]
