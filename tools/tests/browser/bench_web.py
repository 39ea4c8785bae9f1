"""`scripts/bench-web`: how many browsers can watch one node's loop live, at the page's full
decimated rate, without the loop overrunning; and how long the page takes to load.

A node runs a joint PID on a simulated PUMA 560 at 1 kHz (the default period), `penelope web`
serves it on loopback, and headless Chromium windows (one browser process, one window each,
every one drawing its plots) watch the loop. For each count of windows the loop's overrun
counter is read before and after a measuring window of SECONDS; each window's received samples
give its rate (the page asks for one tick in 10: 100 samples/s).

Environment: WINDOWS (counts, default "0 1 2 4 8"), SECONDS (default 10), PRIORITY (the node's
SCHED_FIFO priority, default 0: normal scheduling), LOADS (page loads timed, default 10)."""

from __future__ import annotations

import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from conftest import System, free_port, make_browser  # noqa: E402

PERIOD_US = 1000
SETUP = f"""\
create lab board/sim sim0 axes=6
create lab robot/puma560 slave
call /lab/robots/slave map-joints sim0 0:0 1:1 2:2 3:3 4:4 5:5
configure lab/sim0
configure lab/slave
create lab trajectory/step hold pose=start
create lab controller/joint-pid pid period_us={PERIOD_US}
call lab/pid set-robot slave
call lab/pid set-trajectory hold
configure lab/hold
configure lab/pid
activate lab/pid
"""
BOUND_S = 60.0


def status(system: System) -> dict:
    r = system.ctl("--json", "call", "lab/pid", "status")
    return json.loads(r.stdout)["Status"]


def until(check, what: str) -> None:
    """Waits (bounded) for `check()`; readiness, not time."""
    end = time.monotonic() + BOUND_S
    while not check():
        if time.monotonic() > end:
            raise SystemExit(f"waited {BOUND_S} s for {what}")
        time.sleep(0.05)


def page_loads(driver, url: str, loads: int) -> None:
    usable, loaded = [], []
    for _ in range(loads):
        driver.get("about:blank")
        driver.get(url)
        until(lambda: driver.execute_script("return document.body.dataset.treeLoaded"), "the tree")
        usable.append(float(driver.execute_script("return document.body.dataset.treeLoadedMs")))
        loaded.append(driver.execute_script(
            "const n = performance.getEntriesByType('navigation')[0]; return n.loadEventEnd;"))
    print(f"page load over {loads} loads (ms): load event median {statistics.median(loaded):.1f} "
          f"max {max(loaded):.1f}; tree shown (page usable) median {statistics.median(usable):.1f} "
          f"max {max(usable):.1f}")


def main() -> None:
    binary = os.environ["PENELOPE_BIN"]
    counts = [int(w) for w in os.environ.get("WINDOWS", "0 1 2 4 8").split()]
    seconds = float(os.environ.get("SECONDS_PER_COUNT", os.environ.get("SECONDS", "10")))
    priority = int(os.environ.get("PRIORITY", "0"))
    loads = int(os.environ.get("LOADS", "10"))
    system = System(binary, [], "127.0.0.1:0", f"127.0.0.1:{free_port()}", None, priority)
    driver = None
    try:
        with tempfile.NamedTemporaryFile("w", suffix=".ctl", delete=False) as f:
            f.write(SETUP)
        system.ctl("run", f.name)
        os.unlink(f.name)
        driver = make_browser()
        page_loads(driver, system.url, loads)
        print(f"loop: joint PID at {1e6 / PERIOD_US:.0f} Hz, node priority {priority}; "
              f"each window: one tick in 10, {seconds:.0f} s measured per count")
        print(f"{'windows':>7} {'overruns':>8} {'ticks':>7} {'tel. dropped':>12} "
              f"{'samples/s per window (min..max)':>32}")
        handles = [driver.current_window_handle]
        opened = 0
        for count in counts:
            while opened < count:
                if opened > 0:
                    driver.switch_to.new_window("window")
                    handles.append(driver.current_window_handle)
                driver.get(system.url)
                until(lambda: driver.execute_script("return document.body.dataset.treeLoaded"), "the tree")
                driver.execute_script("select('/lab/controllers/pid'); watch('/lab/controllers/pid');")
                until(lambda: int(driver.execute_script(
                    "return document.getElementById('live').dataset.samples")) > 0, "samples")
                opened += 1
            watching = handles[:opened] if opened else []

            def samples() -> list:
                out = []
                for h in watching:
                    driver.switch_to.window(h)
                    out.append(int(driver.execute_script(
                        "return document.getElementById('live').dataset.samples")))
                return out

            s0, before, t0 = samples(), status(system), time.monotonic()
            time.sleep(seconds)  # the measuring window itself
            s1, after, t1 = samples(), status(system), time.monotonic()
            rates = [(b - a) / (t1 - t0) for a, b in zip(s0, s1)]
            span = f"{min(rates):.1f}..{max(rates):.1f}" if rates else "-"
            print(f"{count:>7} {after['overruns'] - before['overruns']:>8} "
                  f"{after['ticks'] - before['ticks']:>7} "
                  f"{after['telemetry_dropped'] - before['telemetry_dropped']:>12} {span:>32}",
                  flush=True)
    finally:
        if driver is not None:
            driver.quit()
        system.stop()


if __name__ == "__main__":
    main()
