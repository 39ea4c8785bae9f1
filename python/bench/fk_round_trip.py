"""The round trip of `fk` on a remote robot from Python beside the same call from Rust.

Starts `penelope node --host-naming` ($PENELOPE_BIN) on a free loopback port, makes a PUMA 560
on a simulated board, then alternates rounds: the Rust example `fk_round_trip`
($PENELOPE_FK_RUST) makes CALLS calls of `RobotProxy::forward_kinematics`, and this process
makes CALLS calls of `penelope.Robot.fk` (the NumPy 4x4 result) and of the extension's own
`fk` (a flat list: the Python/PyO3 crossing without NumPy). Every call is timed alone; the
report gives mean, p50 and p99 per way and their ratios to Rust. Run by scripts/bench-python.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
from typing import Callable, Dict, List

import penelope
from bench_node import bench_node, puma_on_sim_board, summary

CALLS = int(os.environ.get("CALLS", "5000"))
ROUNDS = int(os.environ.get("ROUNDS", "3"))
Q = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]


def time_calls(call: Callable[[], object], n: int) -> List[int]:
    for _ in range(min(n, 200)):
        call()
    ns = []
    clock = time.perf_counter_ns
    for _ in range(n):
        t = clock()
        call()
        ns.append(clock() - t)
    return ns


def main() -> int:
    rust = os.environ["PENELOPE_FK_RUST"]
    with bench_node() as naming:
        c = penelope.connect(naming)
        robot = puma_on_sim_board(c)
        native = robot._native  # the extension's proxy: fk as a flat list
        runs: Dict[str, List[int]] = {"python": [], "python-list": []}
        rust_runs: List[Dict[str, float]] = []
        for _ in range(ROUNDS):
            out = subprocess.run([rust, naming, robot.path, str(CALLS)], check=True,
                                 capture_output=True, text=True).stdout
            rust_runs.append(json.loads(out))
            runs["python"] += time_calls(lambda: robot.fk(Q), CALLS)
            runs["python-list"] += time_calls(lambda: native.fk(Q), CALLS)
        r = {
            "calls": sum(x["calls"] for x in rust_runs),
            # The Rust runs' statistics, averaged over the rounds (each round CALLS calls).
            "mean_us": statistics.fmean(x["mean_ns"] for x in rust_runs) / 1e3,
            "p50_us": statistics.fmean(x["p50_ns"] for x in rust_runs) / 1e3,
            "p99_us": statistics.fmean(x["p99_ns"] for x in rust_runs) / 1e3,
        }
        rows = {"rust (RobotProxy::forward_kinematics)": r,
                "python (Robot.fk -> 4x4 ndarray)": summary(runs["python"]),
                "python (_native fk -> list)": summary(runs["python-list"])}
        print(f"fk on a remote PUMA 560 over loopback, {ROUNDS} alternating rounds of "
              f"{CALLS} calls; Python {sys.version.split()[0]}, numpy {penelope._client.np.__version__}")
        print(f"{'':40} {'mean us':>9} {'p50 us':>9} {'p99 us':>9}   ratio to rust (mean, p50, p99)")
        for name, s in rows.items():
            ratio = "" if s is r else (f"{s['mean_us'] / r['mean_us']:.2f}, "
                                       f"{s['p50_us'] / r['p50_us']:.2f}, "
                                       f"{s['p99_us'] / r['p99_us']:.2f}")
            print(f"{name:40} {s['mean_us']:9.1f} {s['p50_us']:9.1f} {s['p99_us']:9.1f}   {ratio}")
        print(json.dumps({"rust": r, "python": rows["python (Robot.fk -> 4x4 ndarray)"],
                          "python_list": rows["python (_native fk -> list)"]}))
        return 0


if __name__ == "__main__":
    sys.exit(main())
