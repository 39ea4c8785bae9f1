"""Fixtures of the browser tests of `penelope web`: a real node (hosting its naming service),
`penelope web` in front of it, and a headless Chromium driven by Selenium (Debian's `chromium`
and `chromium-driver`, installed by scripts/test), all on loopback.

Every process is waited for by the line it prints once it serves, never by time; every wait is
bounded. Nothing is skipped: a missing binary, browser or driver fails the run."""

from __future__ import annotations

import os
import queue
import re
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path
from typing import Iterator, List, Optional

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "testkit" / "python"))
from penelope_ports import free_port  # noqa: E402

NODE_READY = "Ctrl-C stops the node"
WEB_READY = re.compile(r"penelope web: serving (http://\S+/)")
START_TIMEOUT_S = 60.0
CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
REPO = Path(__file__).resolve().parents[3]


def pytest_configure(config: pytest.Config) -> None:
    binary = os.environ.get("PENELOPE_BIN")
    if not binary or not os.access(binary, os.X_OK):
        raise pytest.UsageError(
            f"PENELOPE_BIN must name the `penelope` binary (scripts/test sets it); got {binary!r}")
    for tool in (CHROMIUM, CHROMEDRIVER):
        if not os.access(tool, os.X_OK):
            raise pytest.UsageError(
                f"{tool} is missing: install Debian's chromium and chromium-driver (scripts/test does)")


@pytest.fixture(scope="session")
def penelope_bin() -> str:
    return os.environ["PENELOPE_BIN"]


class Process:
    """A child process whose standard output is read line by line on a thread."""

    def __init__(self, argv: List[str], ready: "re.Pattern[str] | str") -> None:
        self.argv = argv
        self._stderr = tempfile.TemporaryFile()
        self.proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                     stderr=self._stderr, text=True)
        self.lines: "queue.Queue[Optional[str]]" = queue.Queue()
        self.output: List[str] = []

        def pump() -> None:
            assert self.proc.stdout is not None
            for line in self.proc.stdout:
                self.lines.put(line)
            self.lines.put(None)

        threading.Thread(target=pump, daemon=True).start()
        self.match = self.wait_for(ready)

    def wait_for(self, ready: "re.Pattern[str] | str") -> "re.Match[str] | str":
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
    """A node `lab` hosting the naming service, and `penelope web` in front of it."""

    def __init__(self, binary: str, prefix: List[str], listen: str, naming: str,
                 secret: Optional[Path], priority: int = 0) -> None:
        self.binary = binary
        self.naming = naming
        extra = ["--secret-file", str(secret)] if secret else []
        self.node = Process(prefix + [binary, "node", "--name", "lab", "--host-naming", "--listen",
                                      naming, "--priority", str(priority), *extra], NODE_READY)
        try:
            # An admin: the page creates and destroys objects (on a system with a secret but
            # no admin secret the node serves it as an operator).
            self.web = Process(prefix + [binary, "web", "--naming", naming, "--listen", listen,
                                         "--systems", str(REPO / "config"), "--role", "admin",
                                         *extra], WEB_READY)
        except BaseException:
            self.node.stop()
            raise
        self.url = self.web.match.group(1)

    def ctl(self, *args: str, check: bool = True) -> subprocess.CompletedProcess:
        r = subprocess.run([self.binary, "ctl", "--naming", self.naming, *args],
                           stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60)
        if check:
            assert r.returncode == 0, f"ctl {args}: {r.stdout}\n{r.stderr}"
        return r

    def stop(self) -> None:
        self.web.stop()
        self.node.stop()


@pytest.fixture
def system(penelope_bin: str) -> Iterator[System]:
    """On loopback, without a secret: the page is open to this host."""
    s = System(penelope_bin, [], "127.0.0.1:0", f"127.0.0.1:{free_port()}", None)
    yield s
    s.stop()


def make_browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--disable-gpu",
                "--no-proxy-server", "--window-size=1600,1100", "--no-first-run",
                "--disable-background-networking", "--disable-component-update",
                "--disable-sync", "--disable-default-apps",
                # The 3D view's WebGL on the CPU (no GPU here): said explicitly, as Chromium
                # no longer falls back to it by itself.
                "--enable-unsafe-swiftshader"):
        options.add_argument(arg)
    # The driver is Debian's, named explicitly: Selenium must not look for (or fetch) another.
    return webdriver.Chrome(options=options, service=Service(executable_path=CHROMEDRIVER))


@pytest.fixture
def browser() -> Iterator[object]:
    os.environ.setdefault("SE_OFFLINE", "true")
    driver = make_browser()
    driver.set_page_load_timeout(30)
    yield driver
    driver.quit()


@pytest.fixture
def secret_file(tmp_path: Path) -> Path:
    f = tmp_path / "lab.secret"
    f.write_text("correct horse battery staple\n")
    f.chmod(0o600)
    return f


class Namespace:
    """A network namespace joined to this one by a veth pair: this side `host_ip`, the
    namespace's side `ns_ip`, on a /30 of their own; nothing is routed anywhere else."""

    def __init__(self) -> None:
        if os.geteuid() != 0 or shutil.which("ip") is None:
            pytest.fail("the non-loopback test creates a network namespace: run as root with iproute2")
        tag = os.getpid() % 10000
        self.name = f"penweb{tag}"
        self.host_if = f"pwh{tag}"
        octet = os.getpid() % 250 + 1
        self.host_ip = f"10.78.{octet}.1"
        self.ns_ip = f"10.78.{octet}.2"
        self._ip("netns", "add", self.name)
        try:
            self._ip("link", "add", self.host_if, "type", "veth", "peer", "name", "eth0",
                     "netns", self.name)
            self._ip("addr", "add", f"{self.host_ip}/30", "dev", self.host_if)
            self._ip("link", "set", self.host_if, "up")
            self._ip("-n", self.name, "addr", "add", f"{self.ns_ip}/30", "dev", "eth0")
            self._ip("-n", self.name, "link", "set", "eth0", "up")
            self._ip("-n", self.name, "link", "set", "lo", "up")
        except BaseException:
            self.delete()
            raise

    @staticmethod
    def _ip(*args: str) -> None:
        r = subprocess.run(["ip", *args], capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"ip {' '.join(args)}: {r.stderr.strip()}")

    def prefix(self) -> List[str]:
        return ["ip", "netns", "exec", self.name]

    def delete(self) -> None:
        # Deleting the namespace deletes its end of the veth pair, and so the pair.
        subprocess.run(["ip", "netns", "del", self.name], capture_output=True)
        subprocess.run(["ip", "link", "del", self.host_if], capture_output=True)


@pytest.fixture
def namespace() -> Iterator[Namespace]:
    ns = Namespace()
    yield ns
    ns.delete()
