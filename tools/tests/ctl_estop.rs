//! `penelope ctl estop` in its three scopes against real processes on loopback: a
//! `penelope naming` and three `penelope node`s, each holding a PUMA 560 with a running joint
//! PID. `estop --all` latches every loop of every node (each node answers once its loop has
//! latched the stop); `estop NODE` one node's loops; `estop PATH` one controller.

use penelope_testkit::net::free_tcp_addr;
use penelope_testkit::process::{Children, Penelope, text};
use penelope_testkit::scratch::scratch_file;
use std::net::SocketAddr;
use std::time::{Duration, Instant};

/// The binary under test.
const PENELOPE: Penelope = Penelope::at(env!("CARGO_BIN_EXE_penelope"));

/// Control period and plant sub-step, µs: slower in unoptimised builds so a tick fits.
const PERIOD_US: u32 = if cfg!(debug_assertions) {
    10_000
} else {
    2_000
};
const SUBSTEP_US: u32 = if cfg!(debug_assertions) { 1_000 } else { 200 };

const NODES: [&str; 3] = ["east", "west", "north"];

/// The safety state of `node`'s PID loop, from its newest sample.
fn loop_state(naming: SocketAddr, node: &str) -> String {
    let o = PENELOPE.ctl(
        naming,
        &["--json", "call", &format!("{node}/pid"), "status"],
    );
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    let reply: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    reply["Status"]["last"]["state"]
        .as_str()
        .unwrap_or("")
        .to_string()
}

/// Waits until `node`'s loop shows `state`, at most 30 s (a bound against a hang).
fn wait_state(naming: SocketAddr, node: &str, states: &[&str]) {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let s = loop_state(naming, node);
        if states.contains(&s.as_str()) {
            return;
        }
        assert!(
            Instant::now() < deadline,
            "{node}/pid never showed {states:?} (last {s:?})"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn ctl_estop_all_stops_every_controller_on_three_nodes() {
    let naming = free_tcp_addr();
    let mut children = vec![PENELOPE.spawn(&["naming", "--listen", &naming.to_string()])];
    for node in NODES {
        children.push(PENELOPE.spawn(&[
            "node",
            "--name",
            node,
            "--listen",
            &free_tcp_addr().to_string(),
            "--naming",
            &naming.to_string(),
            "--priority",
            "0",
        ]));
    }
    let _children = Children(children);

    every_node_registers(naming);
    a_held_puma_on_every_node(naming);
    the_red_button_stops_every_node(naming);
    one_node_stops_only_its_loops(naming);

    // One controller, by naming path.
    let o = PENELOPE.ctl(naming, &["estop", "/north/controllers/pid"]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        out.contains("/north/controllers/pid: e-stop latched"),
        "{out}"
    );
    wait_state(naming, "north", &["estop"]);
    assert_ne!(loop_state(naming, "east"), "estop");

    // Bad input: nothing to stop named.
    let o = PENELOPE.ctl(naming, &["estop"]);
    assert_eq!(o.status.code(), Some(2), "{:?}", text(&o));
}

/// Waits until every node is registered (bounded).
fn every_node_registers(naming: SocketAddr) {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let o = PENELOPE.ctl(naming, &["ls"]);
        let listed = text(&o).0;
        if o.status.success()
            && NODES
                .iter()
                .all(|n| listed.contains(&format!("node {n} at")))
        {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "the nodes never registered: {listed}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// A PUMA 560 held at its start pose by a running PID, on every node.
fn a_held_puma_on_every_node(naming: SocketAddr) {
    for node in NODES {
        let setup = scratch_file(
            "estop",
            &format!("{node}.ctl"),
            &format!(
                "create {node} board/sim sim0 axes=6 substep_us={SUBSTEP_US}\n\
                 create {node} robot/puma560 slave\n\
                 call {node}/slave map-joints sim0 0:0 1:1 2:2 3:3 4:4 5:5\n\
                 configure {node}/sim0\n\
                 configure {node}/slave\n\
                 create {node} trajectory/step hold pose=start\n\
                 create {node} controller/joint-pid pid --config 'period_us = {PERIOD_US}'\n\
                 call {node}/pid set-robot slave\n\
                 call {node}/pid set-trajectory hold\n\
                 configure {node}/hold\n\
                 configure {node}/pid\n\
                 activate {node}/pid\n"
            ),
        );
        let o = PENELOPE.ctl(naming, &["run", setup.to_str().unwrap()]);
        assert!(o.status.success(), "{node}: {:?}", text(&o));
    }
    for node in NODES {
        wait_state(naming, node, &["running", "holding"]);
    }
}

/// The whole system's red button: every node answers that its loop latched the stop, and
/// their telemetry says so too.
fn the_red_button_stops_every_node(naming: SocketAddr) {
    let started = Instant::now();
    let o = PENELOPE.ctl(naming, &["--json", "estop", "--all"]);
    let took = started.elapsed();
    let (out, err) = text(&o);
    assert!(o.status.success(), "stdout:\n{out}\nstderr:\n{err}");
    println!("ctl estop --all over three nodes: {took:?} (process start included)");
    let reports: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect();
    assert_eq!(reports.len(), NODES.len(), "{out}");
    for node in NODES {
        let r = reports
            .iter()
            .find(|r| r["node"] == node)
            .unwrap_or_else(|| panic!("no answer from {node}: {out}"));
        assert_eq!(r["stopped"], serde_json::json!(["pid"]), "{node}: {r}");
        assert_eq!(r["pending"], serde_json::json!([]), "{node}: {r}");
    }
    // Their telemetry says so too (the node's pump publishes samples a little later).
    for node in NODES {
        wait_state(naming, node, &["estop"]);
    }
}

/// Re-armed, then one node stopped: only its loops.
fn one_node_stops_only_its_loops(naming: SocketAddr) {
    for node in NODES {
        let o = PENELOPE.ctl(naming, &["rearm", &format!("{node}/pid")]);
        assert!(o.status.success(), "{node}: {:?}", text(&o));
    }
    for node in NODES {
        wait_state(naming, node, &["running", "holding"]);
    }
    let o = PENELOPE.ctl(naming, &["estop", "west"]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        out.contains("west: e-stop latched by 1 loop(s) (pid)"),
        "{out}"
    );
    wait_state(naming, "west", &["estop"]);
    for node in ["east", "north"] {
        assert_ne!(loop_state(naming, node), "estop", "{node} was stopped too");
    }
}
