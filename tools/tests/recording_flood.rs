//! A recording made while a node is flooded by slow readers: sixteen `penelope ctl watch`
//! subscribers at full rate (decimation 1) whose output nobody reads, so that each blocks on
//! its full stdout pipe and stops reading its socket, and the node's sends to it back up.
//!
//! Asserted (each could fail): every control tick of the window is in the file or counted as
//! dropped by the recorder, and the count matches the gaps exactly; the loops' telemetry rings
//! never overflowed (`telemetry_dropped` 0: the pump that feeds the recorder and the watchers
//! was never held up by a slow client for longer than the ring's 4,096 ticks — the window is
//! 30,000); no overrun (`overruns` 0); the flood did reach the node (its sends to the watchers
//! backed up: `ss` shows bytes queued on their connections); and the node still answers.
//!
//! On the simulated clock, so that the window is exactly 6,000 ticks of each controller and
//! the result does not depend on this machine's load; the real-time figures are in the
//! recording throughput bench (`penelope bench record`).

use penelope_testkit::process::Penelope;
use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::path::Path;
use std::process::{ChildStderr, ChildStdout, Command, Output, Stdio};

/// The binary under test.
const PENELOPE: Penelope = Penelope::at(env!("CARGO_BIN_EXE_penelope"));

/// A child process, killed when the test ends.
struct Child(std::process::Child);

impl Drop for Child {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A `--sim-clock` node running the demo's system file on a free loopback port, returned once
/// it says the file is applied; with its stdout reader, kept open for the node's life.
fn sim_node(
    records: &Path,
) -> (
    SocketAddr,
    Child,
    std::io::BufReader<std::process::ChildStdout>,
) {
    let listen = penelope_testkit::net::free_tcp_addr();
    let config = Path::new(env!("CARGO_MANIFEST_DIR")).join("../config/demo.toml");
    let mut child = Child(
        PENELOPE
            .command()
            .args(["node", "--name", "lab", "--host-naming", "--listen"])
            .arg(listen.to_string())
            .args(["--sim-clock", "--priority", "0", "--config"])
            .arg(config)
            .arg("--records")
            .arg(records)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let mut out = std::io::BufReader::new(child.0.stdout.take().unwrap());
    let mut line = String::new();
    while !line.contains("Ctrl-C stops the node") {
        line.clear();
        assert!(out.read_line(&mut line).unwrap() > 0, "the node ended");
    }
    (listen, child, out)
}

fn ctl(naming: SocketAddr, args: &[&str]) -> Output {
    PENELOPE
        .command()
        .args(["ctl", "--naming", &naming.to_string(), "--timeout", "300"])
        .args(args)
        .stdin(Stdio::null())
        .output()
        .unwrap()
}

fn ok(o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap_or_default()
}

const WATCHERS: usize = 16;
const WINDOW_TICKS: u64 = 30_000;

#[test]
fn a_recording_under_a_flood_of_slow_readers_loses_nothing_uncounted_and_no_loop_suffers() {
    let dir = std::env::temp_dir().join(format!("penelope-flood-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("flood.mcap");
    let (naming, _node, _out) = sim_node(&dir);
    ok(&ctl(naming, &["advance", "lab", "10ms"]));

    let mut watchers = slow_readers(naming);
    // Samples flow only while the clock moves: once it has, every watcher prints (its first
    // line blocks only until the pump has delivered that advance's records).
    ok(&ctl(naming, &["advance", "lab", "10ms"]));
    for (i, (_, stdout, _)) in watchers.iter_mut().enumerate() {
        let mut line = String::new();
        std::io::BufReader::new(&mut *stdout)
            .read_line(&mut line)
            .unwrap();
        assert!(
            line.contains("seq"),
            "watcher {i} printed a record: {line:?}"
        );
    }

    // A client names the file; the node makes it in its recordings directory.
    ok(&ctl(
        naming,
        &["record", "start", "lab", "flood.mcap", "--json"],
    ));
    let before: Vec<u64> = ["display", "follow"]
        .iter()
        .map(|c| status(naming, c)["ticks"].as_u64().unwrap())
        .collect();
    for _ in 0..(WINDOW_TICKS / 500) {
        ok(&ctl(naming, &["advance", "lab", "500ms"]));
    }
    let stopped = ok(&ctl(naming, &["record", "stop", "lab", "--json"]));
    let backed_up = queued_connections(naming.port());
    assert!(
        backed_up >= WATCHERS / 2,
        "the flood reached the node: {backed_up} of its connections have bytes queued"
    );

    // The loops: no overrun, no telemetry lost to a full ring.
    for (i, c) in ["display", "follow"].into_iter().enumerate() {
        let st = status(naming, c);
        assert_eq!(st["overruns"], 0, "{c}: {st}");
        assert_eq!(st["telemetry_dropped"], 0, "{c}: {st}");
        assert_eq!(st["running"], true, "{c}: {st}");
        assert_eq!(
            st["ticks"].as_u64().unwrap() - before[i],
            WINDOW_TICKS,
            "{c}: the window's ticks"
        );
    }

    every_tick_recorded_or_counted(&file, &stopped);
    // The node still answers while the watchers hang.
    assert!(ctl(naming, &["ls"]).status.success());
    drop(watchers);
    let _ = std::fs::remove_dir_all(dir);
}

/// The slow readers, subscribed one at a time (the node bounds handshakes per address, and
/// a burst of sixteen from loopback would evict some): each is ready once it says on stderr
/// that the node acknowledged its subscription. From then on nobody reads its stdout.
fn slow_readers(naming: SocketAddr) -> Vec<(Child, ChildStdout, BufReader<ChildStderr>)> {
    let mut watchers = Vec::new();
    for i in 0..WATCHERS {
        let controller = if i % 2 == 0 { "display" } else { "follow" };
        let mut w = Child(
            PENELOPE
                .command()
                .args(["ctl", "--naming", &naming.to_string(), "--timeout", "300"])
                .args(["watch", &format!("/lab/controllers/{controller}")])
                .args(["--decimation", "1", "--json"])
                .stdin(Stdio::null())
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap(),
        );
        // Kept open, so that nothing it says later meets a closed pipe.
        let mut stderr = std::io::BufReader::new(w.0.stderr.take().unwrap());
        let mut said = String::new();
        stderr.read_line(&mut said).unwrap();
        assert!(said.starts_with("watching "), "watcher {i}: {said:?}");
        let stdout = w.0.stdout.take().unwrap();
        watchers.push((w, stdout, stderr));
    }
    watchers
}

/// The recording: every tick is there or counted as dropped, and the count is exact (the
/// ticks `stopped` reports written).
fn every_tick_recorded_or_counted(file: &Path, stopped: &serde_json::Value) {
    let r = penelope_runtime::objects::recording::read_recording(file).unwrap();
    let mut written = 0;
    for c in ["display", "follow"] {
        let ticks = &r.controllers[c];
        let dropped = r.dropped.get(c).copied().unwrap_or(0);
        let gaps: u64 = ticks
            .windows(2)
            .map(|w| {
                assert!(w[1].sample.seq > w[0].sample.seq, "{c}: in order");
                w[1].sample.seq - w[0].sample.seq - 1
            })
            .sum();
        assert_eq!(gaps, dropped, "{c}: every lost tick counted");
        assert!(
            ticks.len() as u64 + dropped >= WINDOW_TICKS,
            "{c}: {} written + {dropped} dropped",
            ticks.len()
        );
        written += ticks.len() as u64;
    }
    assert_eq!(stopped["ticks"].as_u64(), Some(written), "{stopped}");
}

/// The node's connections (local port `port`) with bytes queued to send, as `ss` (iproute2)
/// reports them.
fn queued_connections(port: u16) -> usize {
    let o = Command::new("ss")
        .args([
            "-tnH",
            "state",
            "established",
            &format!("( sport = :{port} )"),
        ])
        .output()
        .expect("ss (iproute2) runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .filter(|l| {
            // Recv-Q Send-Q Local Peer
            l.split_whitespace()
                .nth(1)
                .and_then(|q| q.parse::<u64>().ok())
                .is_some_and(|q| q > 0)
        })
        .count()
}

fn status(naming: SocketAddr, controller: &str) -> serde_json::Value {
    let v = ok(&ctl(
        naming,
        &[
            "call",
            &format!("/lab/controllers/{controller}"),
            "status",
            "--json",
        ],
    ));
    // The reply as the protocol defines it: `{"Status": {...}}`.
    v.get("Status").cloned().unwrap_or(v)
}
