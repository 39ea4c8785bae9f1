"""A dVRK-style teleoperation loop on the CRTK verbs: an operator's hand pose (a scripted
master tool manipulator here) drives a simulated PUMA 560 (the patient-side arm) through
``servo_cp`` at a fixed rate; a foot-pedal clutch lets the hand move without the arm and
re-anchors the mapping on release; the arm's wrist wrench comes back through ``measured_cf``
as the force the master would display.

    python python/examples/dvrk_teleop.py --naming 127.0.0.1:7300 [--node lab] [--seconds 4]

It makes its own slave on ``--node`` (a simulated board, the PUMA 560, a joint PID holding it,
and a virtual wrist sensor probing a wall 1 cm below the tool) and removes it at the end (the
proxies are context managers that own what they created). The hand moves in a slow figure,
clutches from 1.0 to 1.5 s (the hand keeps moving, the arm holds), then presses down 2 cm into
the wall. It prints one JSON line: the servo rate achieved, overruns, the tracking error, the
arm's and the hand's motion during the clutch, and the largest contact force.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import Dict, List

import numpy as np

import penelope

#: The hand's scripted clutch (foot pedal) window, s.
CLUTCH = (1.0, 1.5)
#: Slave motion per unit of hand motion.
SCALE = 0.5
#: The master's displayed force per unit of the slave's sensed force.
FORCE_GAIN = 0.5
#: The slave's joint PID: stiffer than the defaults, with an integral term against friction.
PID_GAINS: Dict[str, List[float]] = {
    "kp": [3600.0, 6400.0, 3600.0, 400.0, 400.0, 400.0],
    "kd": [40.0, 40.0, 40.0, 10.0, 10.0, 10.0],
    "ki": [8000.0, 8000.0, 8000.0, 800.0, 800.0, 800.0],
    "integral_limit": [30.0, 30.0, 30.0, 3.0, 3.0, 3.0],
}


def hand_position(t: float, seconds: float) -> np.ndarray:
    """The operator's hand position at ``t``, m, relative to where it started: a slow figure
    in x-y, and from 40% of the run a press down of 4 cm (2 cm at the slave, with SCALE)."""
    press = min(max((t / seconds - 0.4) / 0.3, 0.0), 1.0)
    return np.array([
        0.02 * math.sin(2 * math.pi * t / 4.0),
        0.01 * (1 - math.cos(2 * math.pi * t / 4.0)),
        -0.04 * press,
    ])


def run(c: penelope.Client, node: str, seconds: float, rate: float) -> Dict[str, float]:
    with c.create(node, "board/sim", "dvrk-board", axes=6, substep_us=200) as board, \
            c.create(node, "robot/puma560", "psm") as psm:
        assert isinstance(psm, penelope.Robot)
        psm.map_joints(board.name, {j: j for j in range(6)})
        board.configure()
        psm.configure()
        start = psm.measured_cp()
        wall_z = float(start[2, 3]) - 0.01
        with c.create(node, "trajectory/step", "dvrk-hold", pose="start") as hold, \
                c.create(node, "sensor/virtual", "dvrk-wrist",
                         shapes=[{"kind": "plane", "point": [0.0, 0.0, wall_z],
                                  "normal": [0.0, 0.0, 1.0], "stiffness": 2000.0,
                                  "damping": 10.0}]) as wrist, \
                c.create(node, "controller/joint-pid", "dvrk-pid", PID_GAINS,
                         period_us=1000) as pid:
            assert isinstance(pid, penelope.Controller)
            pid.set_robot(psm.name)
            pid.set_trajectory(hold.name)
            pid.set_sensor(wrist.name)
            hold.configure()
            wrist.configure()
            pid.configure()
            pid.activate()
            deadline = time.monotonic() + 30.0
            while pid.status()["last"] is None:  # its first tick: a setpoint to start from
                if time.monotonic() > deadline:
                    raise TimeoutError("the slave's loop did not tick in 30 s")
                time.sleep(0.01)
            return teleoperate(psm, seconds, rate)


def teleoperate(psm: penelope.Robot, seconds: float, rate: float) -> Dict[str, float]:
    slave_anchor = psm.setpoint_cp()
    hand_anchor = hand_position(0.0, seconds)
    target = slave_anchor.copy()
    clutched = False
    worst_tracking = 0.0
    max_force = 0.0
    displayed: List[float] = []
    slave_at_clutch = hand_at_clutch = np.zeros(3)
    slave_clutch_motion = hand_clutch_motion = 0.0
    steps = int(seconds * rate)
    with psm.servo(rate=rate) as s:
        for k in range(steps):
            t = k / rate
            hand = hand_position(t, seconds)
            pedal = CLUTCH[0] <= t < CLUTCH[1]
            if pedal and not clutched:  # pressed: the arm holds where it is
                clutched = True
                slave_at_clutch, hand_at_clutch = target[:3, 3].copy(), hand
            if not pedal and clutched:  # released: re-anchor, no jump
                clutched = False
                slave_anchor, hand_anchor = target.copy(), hand
                slave_clutch_motion = float(np.linalg.norm(
                    psm.measured_cp()[:3, 3] - slave_at_clutch))
                hand_clutch_motion = float(np.linalg.norm(hand - hand_at_clutch))
            if not clutched:
                target = slave_anchor.copy()
                target[:3, 3] += SCALE * (hand - hand_anchor)
            s.servo_cp(target)
            if k % 20 == 19:  # the force back to the hand, and a look at the tracking
                try:
                    f = psm.measured_cf()
                except penelope.NotReady:  # the sensor feed's first sample is not in yet
                    continue
                displayed.append(float(-FORCE_GAIN * f[2]))
                max_force = max(max_force, float(np.linalg.norm(f[:3])))
                if target[2, 3] > slave_anchor[2, 3] - 0.005:  # before the wall
                    err = np.linalg.norm(psm.measured_cp()[:3, 3] - target[:3, 3])
                    worst_tracking = max(worst_tracking, float(err))
    return {
        "calls": s.calls,
        "rate_hz": rate,
        "achieved_rate_hz": s.achieved_rate,
        "overruns": s.overruns,
        "worst_tracking_mm": worst_tracking * 1e3,
        "slave_motion_during_clutch_mm": slave_clutch_motion * 1e3,
        "hand_motion_during_clutch_mm": hand_clutch_motion * 1e3,
        "max_contact_force_n": max_force,
        "min_displayed_force_z_n": min(displayed) if displayed else 0.0,
    }


def main(argv: List[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--naming", default="127.0.0.1:7300", help="the naming service, HOST:PORT")
    p.add_argument("--node", default="lab", help="the node to make the slave on")
    p.add_argument("--seconds", type=float, default=4.0, help="how long the hand moves")
    p.add_argument("--rate", type=float, default=200.0, help="servo_cp rate, Hz")
    a = p.parse_args(argv)
    with penelope.connect(a.naming) as c:
        summary = run(c, a.node, a.seconds, a.rate)
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
