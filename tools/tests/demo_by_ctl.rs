//! Creation order and path do not change a run: the demo's system made object by object with
//! `penelope ctl` verbs (`config/demo.ctl`, in another order than `config/demo.toml`) on a node
//! started with the simulated clock, then moved on by `penelope ctl advance` for the demo's
//! duration, gives the telemetry of `penelope demo --sim-clock` with the same seed: the same
//! CSV files byte for byte, and the same ticks bit for bit. Another seed gives other telemetry
//! (checked over the first second), so the comparison can fail.
//!
//! The node runs in this process (as `penelope node --name lab --sim-clock` would run it, hosting
//! its naming service on loopback) so that every tick of its controllers can be recorded with
//! the recorder `penelope demo` uses; the script and the clock are driven by the `penelope`
//! binary, over the network, exactly as an operator would. Every wait is for a condition,
//! bounded by a deadline, never for a fixed time.

#[path = "../src/cmd/demo/files.rs"]
mod files;

use std::net::SocketAddr;
use std::path::Path;
use std::process::{Output, Stdio};
use std::time::{Duration, Instant};

use penelope_drivers::sim::scripts;
use penelope_runtime::objects::clock::ClockMode;
use penelope_runtime::objects::tick::TickRecord;
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_supervisor::runs::{DEMO_SYSTEM, RunOptions};
use penelope_supervisor::system::SystemFile;
use penelope_testkit::process::Penelope;
use penelope_testkit::scratch::scratch_dir;

const PENELOPE: Penelope = Penelope::at(env!("CARGO_BIN_EXE_penelope"));
const SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../config/demo.ctl");
/// The seed `config/demo.ctl` gives the wrist sensor (as `penelope demo --seed 1`).
const SEED: u64 = 1;

fn text(o: &Output) -> String {
    format!(
        "status {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn ctl(naming: SocketAddr, args: &[&str]) -> Output {
    PENELOPE
        .command()
        .arg("ctl")
        .arg("--naming")
        .arg(naming.to_string())
        // A bound against a hang, not a timing claim: an unoptimised build takes minutes to
        // step the 20 s run.
        .arg("--timeout")
        .arg("900")
        .args(args)
        .stdin(Stdio::null())
        .output()
        .unwrap()
}

/// `penelope demo --sim-clock --seed SEED --out DIR [--duration D]`: its telemetry files.
fn demo(seed: u64, dir: &Path, duration: Option<&str>) {
    let mut cmd = PENELOPE.command();
    cmd.args(["demo", "--sim-clock", "--json", "--seed", &seed.to_string()])
        .arg("--out")
        .arg(dir);
    if let Some(d) = duration {
        cmd.args(["--duration", d]);
    }
    let o = cmd.stdin(Stdio::null()).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
}

/// Every tick of both controllers of `config/demo.ctl` (master, slave), built on a
/// simulated-clock node and moved on by `ctl advance` for `duration`.
fn by_ctl(duration: Duration) -> (Vec<TickRecord>, Vec<TickRecord>) {
    let mut config = NodeConfig::new("lab", NamingChoice::Host);
    config.listen = SocketAddr::from(([127, 0, 0, 1], 0));
    config.creator.clock = ClockMode::Simulated;
    config.creator.rt.priority = None;
    let node = Node::start(config).expect("the node starts");
    let naming = node.address();

    // Ready when ctl sees the node's creator through the naming service.
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let o = ctl(naming, &["ls"]);
        if o.status.success() && String::from_utf8_lossy(&o.stdout).contains("creator") {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "the node never registered: {}",
            text(&o)
        );
        std::thread::sleep(Duration::from_millis(20));
    }

    let o = ctl(naming, &["run", SCRIPT]);
    assert!(o.status.success(), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("/lab/controllers/follow: active"), "{out}");
    assert!(out.contains("/lab/controllers/display: active"), "{out}");
    assert_eq!(
        node.creator().sim_time(),
        Some(penelope_hal::Timestamp::ZERO)
    );

    // The clock has not moved: recording now misses no tick.
    let master = node.creator().record_ticks("display", 1 << 16).unwrap();
    let slave = node.creator().record_ticks("follow", 1 << 16).unwrap();
    let by = format!("{}ms", duration.as_millis());
    let o = ctl(naming, &["advance", "lab", &by]);
    assert!(o.status.success(), "{}", text(&o));
    let expected = format!("lab: simulated clock at {:.3} s", duration.as_secs_f64());
    assert!(
        String::from_utf8_lossy(&o.stdout).contains(&expected),
        "{}",
        text(&o)
    );

    let (mut m, mut s) = (Vec::new(), Vec::new());
    master.drain_into(&mut m);
    slave.drain_into(&mut s);
    for stream in [&master, &slave] {
        assert_eq!(stream.dropped.load(std::sync::atomic::Ordering::Relaxed), 0);
    }
    node.shutdown();
    (m, s)
}

fn assert_same_ticks(what: &str, by_ctl: &[TickRecord], demo: &[TickRecord]) {
    assert_eq!(by_ctl.len(), demo.len(), "{what}: tick counts");
    for (i, (a, b)) in by_ctl.iter().zip(demo).enumerate() {
        assert!(
            a.sample == b.sample && a.truth == b.truth,
            "{what}: tick {i} differs\nby ctl: {a:?}\ndemo:   {b:?}"
        );
    }
}

#[test]
fn the_demo_built_by_ctl_verbs_on_a_sim_clock_node_gives_the_demos_telemetry() {
    let script = scripts::by_name("demo").unwrap();
    let duration = script.duration();
    // 1 kHz control on both sides ([timing] period_us = 1000).
    let ticks = duration.as_millis() as usize;

    let (master, slave) = by_ctl(duration);
    assert_eq!(master.len(), ticks, "every master tick of the run");
    assert_eq!(slave.len(), ticks, "every slave tick of the run");
    let start = slave[0].sample.time;
    assert_eq!(start, master[0].sample.time);

    // Bit for bit: the demo's run, in this process, through the same runner as `penelope demo`.
    let system = SystemFile::parse(DEMO_SYSTEM).unwrap();
    let options = RunOptions {
        seed: SEED,
        clock: ClockMode::Simulated,
        ..RunOptions::default()
    };
    let run = penelope_supervisor::runs::run(&system, &options, &mut |_| {}).unwrap();
    assert_eq!(run.dropped, (0, 0));
    assert_same_ticks("master (display)", &master, &run.master);
    assert_same_ticks("slave (follow)", &slave, &run.slave);

    // Byte for byte: `penelope demo --sim-clock`'s files against the node's ticks written by
    // the demo's own writer.
    let (ours, same, other) = (
        scratch_dir("demo-by-ctl", "ctl"),
        scratch_dir("demo-by-ctl", "demo"),
        scratch_dir("demo-by-ctl", "demo-seed2"),
    );
    files::write_telemetry(&ours.join("telemetry-master.csv"), start, &script, &master).unwrap();
    files::write_telemetry(&ours.join("telemetry-slave.csv"), start, &script, &slave).unwrap();
    demo(SEED, &same, None);
    let read = |d: &Path, f: &str| std::fs::read(d.join(f)).unwrap();
    for f in ["telemetry-master.csv", "telemetry-slave.csv"] {
        let (a, b) = (read(&ours, f), read(&same, f));
        assert_eq!(
            a.iter().filter(|&&c| c == b'\n').count(),
            ticks + 1,
            "{f}: a header and one row per tick"
        );
        assert!(
            a == b,
            "{f}: the ctl-built system's telemetry differs from the demo's"
        );
    }
    // The comparison can fail: another seed, other sensor noise, other telemetry (within the
    // first second already, so the other run is one second long: an unoptimised build is slow).
    demo(SEED + 1, &other, Some("1s"));
    let first_second = |bytes: Vec<u8>| -> Vec<String> {
        String::from_utf8(bytes)
            .unwrap()
            .lines()
            .take(1 + 1000)
            .map(str::to_string)
            .collect()
    };
    let (ours_1s, other_1s) = (
        first_second(read(&ours, "telemetry-slave.csv")),
        first_second(read(&other, "telemetry-slave.csv")),
    );
    assert_eq!(other_1s.len(), 1 + 1000, "one second of slave telemetry");
    assert_eq!(ours_1s[0], other_1s[0], "the same columns");
    assert_ne!(
        ours_1s,
        other_1s,
        "seed {} and seed {} gave the same slave telemetry",
        SEED,
        SEED + 1
    );
    for d in [ours, same, other] {
        let _ = std::fs::remove_dir_all(d);
    }
}
