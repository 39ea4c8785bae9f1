"""`penelope foxglove` beside a running demo node, against an independent Foxglove WebSocket
client (`conftest.FoxgloveClient`: the `websockets` package and the protocol's spec, nothing of
Penelope): server info, channel advertisements with their schema names, subscriptions, a live
stream whose arm moves, the server's time (the simulated clock's on a simulated node), and the
e-stop as a service that latches every loop's e-stop."""

from __future__ import annotations

import json
import subprocess
import time
import xml.etree.ElementTree as ET

import jsonschema
import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from conftest import DEMO, FOX_READY, FoxgloveClient, Process, System, free_port

WAIT_S = 60.0
WINDOW_S = 5.0
SLAVE = "/controllers/follow"       # the demo's slave controller (puma)
MASTER = "/controllers/display"     # its master controller (frhc)
WELL_KNOWN = {"/tf": "foxglove.FrameTransforms", "/scene": "foxglove.SceneUpdate",
              "/robot_description/puma": "penelope.RobotDescription",
              "/robot_description/frhc": "penelope.RobotDescription"}


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
    client.pump_until(lambda: all(client.channel(t) for t in [SLAVE, MASTER, *WELL_KNOWN]),
                      WAIT_S, "the demo's robots and controllers advertised")
    for c in client.channels.values():
        assert c["encoding"] == "json" and c["schemaEncoding"] == "jsonschema", c
        json.loads(c["schema"])
    for topic, name in WELL_KNOWN.items():
        assert client.channel(topic)["schemaName"] == name, topic
    assert client.channel(SLAVE)["schemaName"] == "penelope.Tick"
    assert client.channel("/penelope/gateway")["schemaName"] == "penelope.GatewayStats"

    # The description: latched, so it comes at once; its URDF parses and names the frames.
    description = client.subscribe("/robot_description/puma")
    client.pump_until(lambda: client.messages.get(description), WAIT_S, "the puma's description")
    d = client.messages[description][0][1]
    assert d["robot"] == "puma"
    links = {link.get("name") for link in ET.fromstring(d["urdf"]).iter("link")}
    assert set(d["frames"]) <= links, (d["frames"], links)

    tf = client.subscribe("/tf")
    scene = client.subscribe("/scene")
    ticks = client.subscribe(SLAVE)
    client.pump_until(lambda: client.messages.get(tf) and client.messages.get(ticks), WAIT_S,
                      "the first transforms and ticks")
    start = {s: len(client.messages[s]) for s in (tf, ticks)}
    client.pump_for(WINDOW_S)
    window = client.messages[tf][start[tf]:]
    puma = [(t, m) for t, m in window
            if m["transforms"] and m["transforms"][0]["child_frame_id"].startswith("puma/")]
    print(f"/tf: {len(window)} messages in {WINDOW_S} s, {len(puma)} of the puma "
          f"(rate 100/s per robot)")
    assert len(puma) >= 20
    assert len(puma) <= 100 * WINDOW_S * 1.2, "not above the rate"
    stamps = [t for t, _ in puma]
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps), "times go forward"
    # Every transform is the well-known schema's, as advertised.
    tf_schema = json.loads(client.channel("/tf")["schema"])
    for _, m in puma[:5] + puma[-5:]:
        jsonschema.validate(m, tf_schema)
    first = puma[0][1]["transforms"]
    assert first[0]["parent_frame_id"] == "world"
    assert [x["child_frame_id"] for x in first] == [f"puma/{f}" for f in d["frames"]]
    assert all(x["parent_frame_id"] == f"puma/{d['frames'][0]}" for x in first[1:])
    # The arm moves: the tool frame's translation changes over the window.
    tool = [m["transforms"][-1]["translation"] for _, m in puma]
    moved = max(max(p[k] for p in tool) - min(p[k] for p in tool) for k in "xyz")
    print(f"the puma's tool frame moved by up to {moved * 1000:.1f} mm in the window")
    assert moved > 1e-3
    # Message time is the tick's on the common clock (this node hosts the naming service).
    tick_times = {m["sample"]["time"] for _, m in client.messages[ticks]}
    assert sum(t in tick_times for t in stamps) >= len(stamps) - 2
    # The scene: the wall of the puma's world and its sensed wrench, valid SceneUpdates.
    scene_schema = json.loads(client.channel("/scene")["schema"])
    updates = [m for _, m in client.messages[scene]]
    assert updates
    for m in updates[:3] + updates[-3:]:
        jsonschema.validate(m, scene_schema)
    ids = {e["id"] for m in updates for e in m["entities"]}
    assert "puma/contact0" in ids and "puma/sensed_wrench" in ids, ids
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


def test_a_client_that_does_not_read_loses_messages_counted_and_holds_up_no_one(demo: System):
    """A client with a tiny receive buffer subscribes to `/tf` and never reads: the server's
    queue for it fills and its messages are dropped and counted, while another client gets the
    full rate and the node's subscriptions lose nothing."""
    import socket
    from urllib.parse import urlparse

    url = urlparse(demo.url)
    raw = socket.socket()
    raw.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    raw.connect((url.hostname, url.port))
    slow = FoxgloveClient.over(demo.url, raw)
    watcher = FoxgloveClient(demo.url)
    try:
        slow.pump_until(lambda: slow.channel("/tf"), WAIT_S, "/tf advertised to the slow client")
        slow.subscribe("/tf")
        watcher.pump_until(lambda: watcher.channel("/tf") and watcher.channel("/penelope/gateway"),
                           WAIT_S, "/tf advertised")
        tf = watcher.subscribe("/tf")
        stats = watcher.subscribe("/penelope/gateway")

        def slow_dropped() -> int:
            reports = watcher.messages.get(stats, [])
            if not reports:
                return 0
            clients = reports[-1][1]["clients"]
            return max((c["dropped"] for c in clients if c["subscriptions"] == 1), default=0)

        # The kernel's socket buffers fill first (the server's may grow to megabytes): a
        # generous bound, for a busy machine.
        watcher.pump_until(lambda: slow_dropped() > 0, 3 * WAIT_S,
                           "the slow client's drops reported")
        start = len(watcher.messages[tf])
        watcher.pump_for(WINDOW_S)
        got = len(watcher.messages[tf]) - start
        last = watcher.messages[stats][-1][1]
        print(f"while a client did not read: the other got {got} /tf messages in {WINDOW_S} s; "
              f"the slow one's dropped {slow_dropped()}; streams {last['streams']}")
        # The other client lost nothing, and no subscription to the node fell behind (the
        # rate itself is the machine's to give: two robots at 100/s each on an idle one).
        assert got >= 20
        assert all(s["node_dropped"] == 0 for s in last["streams"])
        mine = [c for c in last["clients"] if c["subscriptions"] == 2]
        assert mine and mine[0]["dropped"] == 0
        # Once it reads, the slow client finds it was told (a status Foxglove shows).
        slow.pump_until(lambda: any("reads too slowly" in st["message"] for st in slow.statuses),
                        WAIT_S, "the slow client's notice")
    finally:
        watcher.close()
        slow.close()


def test_objects_made_later_appear_and_a_controller_bound_later_draws_its_robot(penelope_bin: str):
    """A node with no objects: the gateway finds a robot and a controller made with `ctl`
    after it started, and the controller's robot once it is bound to it (after the gateway
    already follows the controller)."""
    system = System(penelope_bin, [], [], system=None)
    try:
        c = FoxgloveClient(system.url)
        try:
            c.pump_until(lambda: c.server_info is not None, WAIT_S, "serverInfo")
            for line in ["create lab board/sim sim0 axes=6",
                         "create lab robot/puma560 slave",
                         "call /lab/robots/slave map-joints sim0 0:0 1:1 2:2 3:3 4:4 5:5",
                         "configure lab/sim0", "configure lab/slave",
                         "create lab trajectory/step hold pose=start",
                         "create lab controller/joint-pid pid period_us=2000"]:
                system.ctl(*line.split())
            c.pump_until(lambda: c.channel("/controllers/pid")
                         and c.channel("/robot_description/slave"), WAIT_S,
                         "the new controller and robot advertised")
            tf = c.subscribe("/tf")
            for line in ["call lab/pid set-robot slave", "call lab/pid set-trajectory hold",
                         "configure lab/hold", "configure lab/pid", "activate lab/pid"]:
                system.ctl(*line.split())
            c.pump_until(lambda: any(m["transforms"][0]["child_frame_id"] == "slave/base_link"
                                     for _, m in c.messages.get(tf, [])),
                         WAIT_S, "the bound robot's transforms")
        finally:
            c.close()
    finally:
        system.stop()


def test_a_node_beside_the_naming_service_is_put_on_the_common_clock(penelope_bin: str):
    """The naming service runs alone; the node is another process: the gateway estimates the
    node's offset to the naming host's clock (`Call::Time` exchanges) and adds it. Both are this
    host's monotonic clock, so the offset found is the estimate's error."""
    naming = f"127.0.0.1:{free_port()}"
    service = Process([penelope_bin, "naming", "--listen", naming], "Ctrl-C stops it")
    node = fox = None
    try:
        node = Process([penelope_bin, "node", "--name", "lab", "--naming", naming, "--config",
                        str(DEMO), "--priority", "0"], "Ctrl-C stops the node")
        fox = Process([penelope_bin, "foxglove", "--naming", naming, "--listen", "127.0.0.1:0"],
                      FOX_READY)
        c = FoxgloveClient(fox.match.group(1))
        try:
            c.pump_until(lambda: c.channel(SLAVE) and c.channel("/penelope/gateway"), WAIT_S,
                         "the slave's channel")
            ticks = c.subscribe(SLAVE)
            stats = c.subscribe("/penelope/gateway")

            def follow_clock():
                for _, m in c.messages.get(stats, []):
                    for stream in m["streams"]:
                        if stream["topic"] == SLAVE and stream["clock"] != "unknown":
                            return stream["clock"]
                return None

            c.pump_until(lambda: len(c.messages.get(ticks, [])) >= 20 and follow_clock(),
                         WAIT_S, "ticks and the stream's clock")
            assert follow_clock() == "offset"
            offsets = [t - m["sample"]["time"] for t, m in c.messages[ticks]]
            print(f"common less node clock as estimated: {min(offsets)} .. {max(offsets)} ns "
                  f"(the same host: the estimate's error)")
            assert all(abs(o) < 5_000_000 for o in offsets)
        finally:
            c.close()
    finally:
        for p in (fox, node, service):
            if p is not None:
                p.stop()


def test_a_channel_linked_across_nodes_streams_its_link_statistics(penelope_bin: str):
    """The demo split over two nodes (`config/demo-two-nodes.toml`): each end of the channel
    `link` streams its link's statistics, on `/links/link` and `/links/link@<node>`."""
    two = DEMO.parent / "demo-two-nodes.toml"
    naming = f"127.0.0.1:{free_port()}"
    master = slave = fox = None
    try:
        master = Process([penelope_bin, "node", "--name", "master", "--host-naming", "--listen",
                          naming, "--config", str(two), "--priority", "0"], "Ctrl-C stops the node")
        slave = Process([penelope_bin, "node", "--name", "slave", "--naming", naming, "--config",
                         str(two), "--priority", "0"], "Ctrl-C stops the node")
        fox = Process([penelope_bin, "foxglove", "--naming", naming, "--listen", "127.0.0.1:0"],
                      FOX_READY)
        c = FoxgloveClient(fox.match.group(1))
        try:
            topics = lambda: sorted(ch["topic"] for ch in c.channels.values()
                                    if ch["topic"].startswith("/links/"))
            c.pump_until(lambda: len(topics()) == 2, WAIT_S, "both ends' link channels")
            assert all(c.channel(t)["schemaName"] == "penelope.LinkStats" for t in topics())
            subs = [c.subscribe(t) for t in topics()]
            c.pump_until(lambda: all(len(c.messages.get(s, [])) >= 3 for s in subs), WAIT_S,
                         "link records from both ends")
            schema = json.loads(c.channel(topics()[0])["schema"])
            for s in subs:
                last = c.messages[s][-1][1]
                jsonschema.validate(last, schema)
                assert last["down"] is False, last
                assert last["samples_taken"] > 0, last
            print("link ends:", [(t, c.messages[s][-1][1]["round_trip_ns"])
                                 for t, s in zip(topics(), subs)])
        finally:
            c.close()
    finally:
        for p in (fox, slave, master):
            if p is not None:
                p.stop()
