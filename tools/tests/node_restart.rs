//! A node killed (SIGKILL: no chance to unregister) and started again at once, on another port,
//! comes back under its name: the naming service finds nothing answering at the old address
//! and replaces the stale registration, long before its lease (30 s here) would have lapsed.

use penelope_testkit::net::free_tcp_addr;
use penelope_testkit::process::{Children, Penelope};
use std::net::SocketAddr;
use std::process::Child;
use std::time::{Duration, Instant};

/// The binary under test.
const PENELOPE: Penelope = Penelope::at(env!("CARGO_BIN_EXE_penelope"));

/// The address the naming tree gives for node `phoenix`'s creator, if registered.
fn registered_at(naming: SocketAddr) -> Option<String> {
    let o = PENELOPE.ctl(naming, &["ls"]);
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    out.lines()
        .find_map(|l| l.split("node phoenix at ").nth(1))
        .map(|a| a.trim().to_string())
}

/// Waits (at most 30 s, a bound against a hang) until `phoenix` is registered at an address
/// other than `not`; returns it.
fn wait_registered(naming: SocketAddr, node: &mut Child, not: Option<&str>) -> String {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        if let Some(status) = node.try_wait().unwrap() {
            panic!("the node exited ({status}) instead of taking its name back");
        }
        if let Some(a) = registered_at(naming)
            && Some(a.as_str()) != not
        {
            return a;
        }
        assert!(Instant::now() < deadline, "the node never registered");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn a_node_killed_and_restarted_at_once_comes_back_under_its_name() {
    let naming = free_tcp_addr();
    let node_args = [
        "node",
        "--name",
        "phoenix",
        "--naming",
        &naming.to_string(),
        "--priority",
        "0",
        "--lease-ms",
        "30000",
    ];
    let mut children = Children(vec![PENELOPE.spawn(&[
        "naming",
        "--listen",
        &naming.to_string(),
    ])]);
    children.0.push(PENELOPE.spawn(&node_args));
    let first = wait_registered(naming, &mut children.0[1], None);

    // Killed: its registration stays, with most of 30 s of lease left.
    let mut old = children.0.remove(1);
    old.kill().unwrap();
    old.wait().unwrap();
    assert_eq!(registered_at(naming).as_deref(), Some(first.as_str()));

    // Started again at once (any free port: another address).
    let restarted = Instant::now();
    children.0.push(PENELOPE.spawn(&node_args));
    let second = wait_registered(naming, &mut children.0[1], Some(&first));
    let took = restarted.elapsed();
    println!("node back under its name {took:?} after its restart ({first} -> {second})");
    assert!(took < Duration::from_secs(10), "{took:?}");
    // And it serves under that name.
    let o = PENELOPE.ctl(naming, &["kinds", "phoenix"]);
    assert!(o.status.success(), "{o:?}");
}
