"""The CRTK ``servo_cp`` stream from Python beside the same call from Rust.

Starts `penelope node --host-naming` ($PENELOPE_BIN) on a free loopback port, makes a PUMA 560
on a simulated board held by an active joint PID, then alternates rounds: the Rust client makes
CALLS calls of `RobotProxy::servo_tool` (inside the extension, `bench_servo_cp`: no Python
between the calls), and this process makes CALLS calls of `penelope.Robot.servo_cp` (a NumPy
4x4 in). Every call is timed alone: round trip p50 and p99, and the free-running calls/s
(1 / mean). Then a paced stream: `with robot.servo(rate=RATE)` for SECONDS s, its achieved rate
and overruns. Run by scripts/bench-python.
"""

from __future__ import annotations

import json
import os
import sys
import time
from typing import List

import numpy as np

import penelope
from bench_node import bench_node, puma_on_sim_board, summary

CALLS = int(os.environ.get("CALLS", "5000"))
ROUNDS = int(os.environ.get("ROUNDS", "3"))
RATE = float(os.environ.get("RATE", "500"))
SECONDS = float(os.environ.get("SECONDS", "5"))


def main() -> int:
    with bench_node() as naming:
        c = penelope.connect(naming)
        robot = puma_on_sim_board(c)
        hold = c.create("bench", "trajectory/step", "hold", pose="start")
        pid = c.create("bench", "controller/joint-pid", "pid", period_us=1000)
        assert isinstance(pid, penelope.Controller)
        pid.set_robot("slave")
        pid.set_trajectory("hold")
        hold.configure()
        pid.configure()
        pid.activate()
        deadline = time.monotonic() + 30
        while pid.status()["last"] is None:
            assert time.monotonic() < deadline, "no tick in 30 s"
            time.sleep(0.01)
        target = robot.setpoint_cp()
        flat = [float(x) for x in target.ravel()]
        rust: List[int] = []
        python: List[int] = []
        clock = time.perf_counter_ns
        for _ in range(ROUNDS):
            rust += robot._native.bench_servo_cp(flat, CALLS)
            for _ in range(CALLS):
                t = clock()
                robot.servo_cp(target)
                python.append(clock() - t)
        with robot.servo(rate=RATE) as s:
            end = time.perf_counter() + SECONDS
            while time.perf_counter() < end:
                s.servo_cp(target)
        rows = {"rust (RobotProxy::servo_tool)": summary(rust),
                "python (Robot.servo_cp, 4x4 ndarray)": summary(python)}
        print(f"servo_cp on a remote PUMA 560 held by a joint PID, over loopback, {ROUNDS} "
              f"alternating rounds of {CALLS} calls; Python {sys.version.split()[0]}, "
              f"numpy {np.__version__}")
        print(f"{'':40} {'calls/s':>9} {'p50 us':>9} {'p99 us':>9}")
        for name, r in rows.items():
            print(f"{name:40} {r['calls_per_s']:9.0f} {r['p50_us']:9.1f} {r['p99_us']:9.1f}")
        print(f"paced: robot.servo(rate={RATE:.0f}) for {SECONDS:.0f} s: {s.calls} calls, "
              f"{s.achieved_rate:.1f} Hz achieved, {s.overruns} overruns")
        print(json.dumps({"rust": rows["rust (RobotProxy::servo_tool)"],
                          "python": rows["python (Robot.servo_cp, 4x4 ndarray)"],
                          "paced": {"rate_hz": RATE, "seconds": SECONDS, "calls": s.calls,
                                    "achieved_hz": s.achieved_rate, "overruns": s.overruns}}))
        pid.deactivate()
        return 0


if __name__ == "__main__":
    sys.exit(main())
