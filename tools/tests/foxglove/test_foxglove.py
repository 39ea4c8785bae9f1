"""`penelope foxglove` beside a running demo node, against an independent Foxglove WebSocket
client (`conftest.FoxgloveClient`: the `websockets` package and the protocol's spec, nothing of
Penelope): server info, channel advertisements with their schema names, subscriptions, a live
stream whose arm moves, the server's time (the simulated clock's on a simulated node), and the
e-stop as a service that latches every loop's e-stop."""

from __future__ import annotations

import json
import subprocess
import time

import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from conftest import FoxgloveClient, System

WAIT_S = 60.0
WINDOW_S = 5.0
SLAVE = "/controllers/follow"       # the demo's slave controller (puma)
MASTER = "/controllers/display"     # its master controller (frhc)


@pytest.fixture
def client(demo: System):
    c = FoxgloveClient(demo.url)
    yield c
    c.close()


def spread(values) -> float:
    return max(values) - min(values)


def test_server_info_advertisements_and_a_live_stream_whose_arm_moves(demo: System, client):
    assert client.ws.subprotocol == "foxglove.websocket.v1"
    client.pump_until(lambda: client.server_info is not None, WAIT_S, "serverInfo")
    assert "time" in client.server_info["capabilities"]
    assert "services" in client.server_info["capabilities"]
    assert client.server_info["supportedEncodings"] == ["json"]
    client.pump_until(lambda: client.channel(SLAVE) and client.channel(MASTER), WAIT_S,
                      "the demo's controllers advertised")
    for c in client.channels.values():
        assert c["encoding"] == "json" and c["schemaEncoding"] == "jsonschema", c
        json.loads(c["schema"])
    assert client.channel(SLAVE)["schemaName"] == "penelope.Tick"
    assert client.channel("/penelope/gateway")["schemaName"] == "penelope.GatewayStats"

    sub = client.subscribe(SLAVE)
    client.pump_until(lambda: client.messages.get(sub), WAIT_S, "the first tick")
    start = len(client.messages[sub])
    client.pump_for(WINDOW_S)
    window = client.messages[sub][start:]
    print(f"{SLAVE}: {len(window)} messages in {WINDOW_S} s (rate 100/s)")
    assert len(window) >= 20
    # Not above the rate (100 per second), allowing for the window's edges.
    assert len(window) <= 100 * WINDOW_S * 1.2
    stamps = [t for t, _ in window]
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps), "times go forward"
    # Message time is the tick's on the common clock: this node hosts the naming service.
    assert all(t == m["sample"]["time"] for t, m in window)
    moved = max(spread([m["sample"]["q"][j] for _, m in window]) for j in range(6))
    print(f"the slave's joints moved by up to {moved:.4f} rad in the window")
    assert moved > 1e-3
    # The server's time follows the messages'.
    assert client.times and client.times[-1] >= stamps[0]


def test_the_estop_service_latches_every_loop(demo: System, client):
    client.pump_until(lambda: "/penelope/estop" in client.services and client.channel(SLAVE),
                      WAIT_S, "the e-stop service and the slave's channel")
    service = client.services["/penelope/estop"]
    assert service["type"] == "penelope.EStop"
    assert service["request"]["encoding"] == "json"
    sub = client.subscribe(SLAVE)
    client.pump_until(lambda: client.messages.get(sub), WAIT_S, "the first tick")
    assert client.messages[sub][-1][1]["sample"]["state"] != "estop"
    client.call("/penelope/estop", {}, call_id=7)
    client.pump_until(lambda: client.responses or client.failures, WAIT_S, "the e-stop's answer")
    assert not client.failures, client.failures
    service_id, call_id, encoding, reply = client.responses[0]
    assert (service_id, call_id, encoding) == (service["id"], 7, "json")
    stopped = [c for n in reply["nodes"] for c in n["stopped"] + n.get("pending", [])]
    assert "follow" in stopped and "display" in stopped, reply
    client.pump_until(lambda: client.messages[sub][-1][1]["sample"]["state"] == "estop", WAIT_S,
                      "a tick of the latched e-stop")


def test_without_the_estop_service_a_call_fails_and_nothing_stops(penelope_bin: str):
    system = System(penelope_bin, [], ["--no-estop"])
    try:
        c = FoxgloveClient(system.url)
        try:
            c.pump_until(lambda: c.server_info is not None and c.channel(SLAVE), WAIT_S,
                         "serverInfo and the slave's channel")
            assert "services" not in c.server_info["capabilities"]
            assert not c.services
            sub = c.subscribe(SLAVE)
            c.ws.send(bytes([2]) + (1).to_bytes(4, "little") + (3).to_bytes(4, "little")
                      + (4).to_bytes(4, "little") + b"json{}")
            c.pump_until(lambda: c.failures, WAIT_S, "the refusal")
            assert c.failures[0]["callId"] == 3
            c.pump_until(lambda: len(c.messages.get(sub, [])) >= 10, WAIT_S, "ticks")
            assert all(m["sample"]["state"] != "estop" for _, m in c.messages[sub])
        finally:
            c.close()
    finally:
        system.stop()


def test_on_a_simulated_clock_messages_carry_the_simulated_time(penelope_bin: str):
    system = System(penelope_bin, ["--sim-clock"], [])
    try:
        c = FoxgloveClient(system.url, subprotocols=("foxglove.sdk.v1",))
        try:
            assert c.ws.subprotocol == "foxglove.sdk.v1"
            c.pump_until(lambda: c.channel(SLAVE), WAIT_S, "the slave's channel")
            sub = c.subscribe(SLAVE)
            # The clock stands still until moved: the ticks come with `advance`.
            system.ctl("advance", "lab", "1s")
            c.pump_until(lambda: len(c.messages.get(sub, [])) >= 20, WAIT_S, "the ticks of 1 s")
            stamps = [t for t, _ in c.messages[sub]]
            print(f"{len(stamps)} messages of 1 simulated second, first {stamps[0]} ns, "
                  f"last {stamps[-1]} ns")
            assert 0 <= stamps[0] and stamps[-1] <= 1_000_000_000
            c.pump_until(lambda: c.times, WAIT_S, "the server's time")
            assert max(c.times) <= 1_000_000_000
        finally:
            c.close()
    finally:
        system.stop()


def test_a_client_must_offer_the_protocol_and_a_foreign_page_is_refused(demo: System):
    with pytest.raises(InvalidStatus) as e:
        connect(demo.url, subprotocols=["some.other.v1"], open_timeout=30)
    assert e.value.response.status_code == 400
    with pytest.raises(InvalidStatus) as e:
        connect(demo.url, subprotocols=["foxglove.websocket.v1"], open_timeout=30,
                origin="https://evil.example")
    assert e.value.response.status_code == 403
    # A page of Foxglove's app is let in.
    with connect(demo.url, subprotocols=["foxglove.websocket.v1"], open_timeout=30,
                 origin="https://app.foxglove.dev") as ws:
        assert json.loads(ws.recv(timeout=30))["op"] == "serverInfo"


def test_a_listen_address_beyond_loopback_is_refused(penelope_bin: str):
    r = subprocess.run([penelope_bin, "foxglove", "--listen", "0.0.0.0:0"], stdin=subprocess.DEVNULL,
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2, r
    assert "loopback only" in r.stderr and "ssh -L" in r.stderr, r.stderr
