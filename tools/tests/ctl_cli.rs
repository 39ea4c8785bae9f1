//! `penelope ctl` end to end: a `penelope naming` and a `penelope node` run as child processes
//! on free loopback ports, and `penelope ctl` creates, configures, activates, calls, watches and
//! destroys objects through them, by script and by single verbs.

use penelope_testkit::net::{free_tcp_addr, free_udp_port};
use penelope_testkit::process::{Children, Penelope, text};
use penelope_testkit::scratch::scratch_file;
use std::net::{SocketAddr, TcpListener};
use std::path::PathBuf;
use std::process::{Command, Stdio};
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

#[test]
fn ctl_drives_a_node_through_the_naming_service() {
    let naming = free_tcp_addr();
    let node = free_tcp_addr();
    let _children = Children(vec![
        PENELOPE.spawn(&["naming", "--listen", &naming.to_string()]),
        PENELOPE.spawn(&[
            "node",
            "--name",
            "lab",
            "--listen",
            &node.to_string(),
            "--naming",
            &naming.to_string(),
            "--priority",
            "0",
        ]),
    ]);

    the_node_registers(naming);
    a_script_sets_up_a_held_puma(naming);
    single_verbs_json_and_the_tree(naming);
    crtk_verbs_move_and_refuse_a_servo_jump(naming);
    a_refusal_exits_1_and_bad_input_2(naming);
    a_script_on_standard_input_tears_down(naming);
}

/// Waits until the node is registered (bounded).
fn the_node_registers(naming: SocketAddr) {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let o = PENELOPE.ctl(naming, &["ls"]);
        if o.status.success() && text(&o).0.contains("creator") {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "the node never registered: {:?}",
            text(&o)
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Sets up a PUMA 560 on a simulated board with a joint PID holding it, by script.
fn a_script_sets_up_a_held_puma(naming: SocketAddr) {
    let setup = scratch_file(
        "ctl",
        "setup.ctl",
        &format!(
            "# a PUMA 560 held at its start pose\n\
             create lab board/sim sim0 axes=6 substep_us={SUBSTEP_US}\n\
             create lab robot/puma560 slave\n\
             call /lab/robots/slave map-joints sim0 0:0 1:1 2:2 3:3 4:4 5:5\n\
             configure lab/sim0\n\
             configure /lab/robots/slave   # comments may end a line\n\
             call lab/slave fk 0 0 0 0 0 0\n\
             call lab/slave jacobian start\n\
             create lab trajectory/step hold pose=start\n\
             create lab controller/joint-pid pid --config 'period_us = {PERIOD_US}'\n\
             call lab/pid set-robot slave\n\
             call lab/pid set-trajectory hold\n\
             configure lab/hold\n\
             configure lab/pid\n\
             \n\
             activate lab/pid\n\
             call lab/pid status\n\
             watch lab/pid --count 5\n"
        ),
    );
    let o = PENELOPE.ctl(naming, &["run", setup.to_str().unwrap()]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "stdout:\n{out}\nstderr:\n{err}");
    assert!(
        out.contains("created /lab/robots/slave (robot/puma560): unconfigured"),
        "{out}"
    );
    assert!(out.contains("/lab/robots/slave: inactive"), "{out}");
    assert!(out.contains("/lab/controllers/pid: active"), "{out}");
    assert!(out.contains("position (m):"), "{out}");
    assert!(out.contains(" vx "), "{out}");
    assert!(out.contains("loop running"), "{out}");
    let samples = out.lines().filter(|l| l.starts_with("t ")).count();
    assert_eq!(samples, 5, "{out}");
}

/// Single verbs, JSON, and the tree.
fn single_verbs_json_and_the_tree(naming: SocketAddr) {
    let o = PENELOPE.ctl(naming, &["--json", "call", "lab/slave", "gravity", "start"]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    assert_eq!(v["Joints"].as_array().map(Vec::len), Some(6), "{out}");
    let o = PENELOPE.ctl(
        naming,
        &[
            "call",
            "/lab/robots/slave",
            "ik",
            "0.4",
            "0.1",
            "0.3",
            "--json",
        ],
    );
    assert!(o.status.success(), "{:?}", text(&o));
    assert!(
        serde_json::from_slice::<serde_json::Value>(&o.stdout).unwrap()["Solutions"].is_array()
    );
    let o = PENELOPE.ctl(naming, &["ls"]);
    let (out, _) = text(&o);
    assert!(
        out.contains("slave") && out.contains("robot/puma560") && out.contains("active"),
        "{out}"
    );
    let o = PENELOPE.ctl(naming, &["kinds", "lab"]);
    assert!(
        text(&o).0.contains("controller/joint-pid"),
        "{:?}",
        text(&o)
    );
}

/// The CRTK verbs: a joint move is busy until it is over (bounded wait on the real clock), a
/// servo jump past the step limit is refused (exit 1), a bad duration is bad input (exit 2).
fn crtk_verbs_move_and_refuse_a_servo_jump(naming: SocketAddr) {
    let o = PENELOPE.ctl(naming, &["call", "lab/slave", "move-jp", "work", "2.0"]);
    assert!(o.status.success(), "{:?}", text(&o));
    let started = Instant::now();
    let deadline = started + Duration::from_secs(30);
    loop {
        let o = PENELOPE.ctl(naming, &["call", "lab/slave", "operating-state"]);
        let (out, err) = text(&o);
        assert!(o.status.success(), "{err}");
        if !out.contains("operating state: ENABLED") {
            let status = PENELOPE.ctl(naming, &["call", "lab/pid", "status"]);
            panic!("{out}\n{:?}", text(&status));
        }
        if out.contains("busy: false") {
            break;
        }
        assert!(Instant::now() < deadline, "still busy: {out}");
        std::thread::sleep(Duration::from_millis(100));
    }
    println!(
        "move-jp of 2 s: busy for {:.2} s (real clock, polled)",
        started.elapsed().as_secs_f64()
    );
    let o = PENELOPE.ctl(naming, &["call", "lab/slave", "setpoints"]);
    assert!(text(&o).0.contains("joints:"), "{:?}", text(&o));
    let o = PENELOPE.ctl(naming, &["call", "lab/slave", "servo-jp", "start"]);
    assert_eq!(o.status.code(), Some(1), "{:?}", text(&o));
    assert!(text(&o).1.contains("step limit"), "{:?}", text(&o));
    let o = PENELOPE.ctl(naming, &["call", "lab/slave", "move-jp", "start", "-1"]);
    assert_eq!(o.status.code(), Some(2), "{:?}", text(&o));
}

/// Errors: a node's refusal exits 1, bad input exits 2.
fn a_refusal_exits_1_and_bad_input_2(naming: SocketAddr) {
    let o = PENELOPE.ctl(naming, &["destroy", "lab/slave"]);
    assert_eq!(o.status.code(), Some(1), "{:?}", text(&o));
    assert!(text(&o).1.contains("in use"), "{:?}", text(&o));
    let o = PENELOPE.ctl(naming, &["call", "/lab/robots/nobody", "joint-positions"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o).1.contains("unknown name"), "{:?}", text(&o));
    let o = PENELOPE.ctl(
        naming,
        &["call", "lab/slave", "fk", "0", "nan", "0", "0", "0", "0"],
    );
    assert_eq!(o.status.code(), Some(2), "{:?}", text(&o));
    let o = PENELOPE.ctl(naming, &["call", "lab/slave", "frobnicate"]);
    assert_eq!(o.status.code(), Some(2));
    let bad = scratch_file("ctl", "bad.ctl", "ls\n# fine so far\nfrobnicate lab\nls\n");
    let o = PENELOPE.ctl(naming, &["run", bad.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).1.contains("bad.ctl:3"), "{:?}", text(&o));
    let o = PENELOPE.ctl("127.0.0.1:1".parse().unwrap(), &["ls"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        text(&o).1.contains("cannot reach the naming service"),
        "{:?}",
        text(&o)
    );
}

/// Tears down, the script from standard input; the tree is empty again but for the creator.
fn a_script_on_standard_input_tears_down(naming: SocketAddr) {
    let teardown = "deactivate lab/pid\n\
                    call lab/hold reference 0.5\n\
                    destroy lab/pid\n\
                    destroy lab/hold\n\
                    destroy /lab/robots/slave\n\
                    destroy lab/sim0\n";
    let mut child = Command::new(PENELOPE.path())
        .args(["ctl", "--naming", &naming.to_string(), "run", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    {
        use std::io::Write as _;
        child
            .stdin
            .take()
            .unwrap()
            .write_all(teardown.as_bytes())
            .unwrap();
    }
    let o = child.wait_with_output().unwrap();
    let (out, err) = text(&o);
    assert!(o.status.success(), "stdout:\n{out}\nstderr:\n{err}");
    assert!(out.contains("/lab/controllers/pid: inactive"), "{out}");
    assert!(out.contains("joint reference"), "{out}");
    assert!(out.contains("destroyed /lab/boards/sim0"), "{out}");
    let o = PENELOPE.ctl(naming, &["--json", "ls"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let paths: Vec<&str> = v["entries"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|e| e["path"].as_str())
        .collect();
    assert_eq!(paths, ["/lab", "/lab/creator"]);
}

/// A secret file for these tests, with `mode`.
fn secret_file(name: &str, mode: u32) -> PathBuf {
    use std::os::unix::fs::PermissionsExt as _;
    let path = scratch_file("ctl", name, "correct horse battery staple\n");
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).unwrap();
    path
}

#[test]
fn a_secret_file_others_may_read_is_refused_with_the_fix() {
    let file = secret_file("open.secret", 0o644);
    let out = PENELOPE.ctl(
        free_tcp_addr(),
        &["--secret-file", file.to_str().unwrap(), "ls"],
    );
    let (_, err) = text(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains(&format!("chmod 600 {}", file.display())),
        "the message must say how to fix it: {err}"
    );
}

#[test]
fn ctl_with_the_secret_sends_nothing_to_a_node_that_does_not_prove_it() {
    use penelope_protocol::net::frame::{encode, read_frame};
    use penelope_protocol::proto::{
        ClientMsg, DEFAULT_MAX_FRAME, MAGIC, PROTOCOL_VERSION, Security, ServerHello, ServerMsg,
    };
    let file = secret_file("lab.secret", 0o600);
    // An impostor naming service: it answers the hello without asking for the secret, then
    // records whatever ctl sends.
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let impostor = std::thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        let _: ClientMsg = read_frame(&mut s, DEFAULT_MAX_FRAME).unwrap();
        let hello = ServerMsg::Hello(ServerHello {
            magic: MAGIC,
            version: PROTOCOL_VERSION,
            node: "naming".into(),
            security: Security::Plain,
        });
        std::io::Write::write_all(&mut s, &encode(&hello, DEFAULT_MAX_FRAME).unwrap()).unwrap();
        let mut got = Vec::new();
        while let Ok(m) = read_frame::<_, ClientMsg>(&mut s, DEFAULT_MAX_FRAME) {
            got.push(m);
        }
        got
    });
    let out = PENELOPE.ctl(addr, &["--secret-file", file.to_str().unwrap(), "ls"]);
    let (_, err) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("did not prove the shared secret"), "{err}");
    assert_eq!(
        impostor.join().unwrap(),
        Vec::new(),
        "ctl sent something after the impostor's hello"
    );
}

/// The paper's task from a system file: a node started before its naming service brings up
/// `config/teleop.toml`, registers when the naming service appears, and `ctl` sees the FRHC,
/// the PUMA 200, the channel and both halves of the law running; the slave's telemetry
/// streams; deactivating the slave's controller stops its loop.
#[test]
fn a_node_runs_the_teleoperation_system_file() {
    let naming = free_tcp_addr();
    let node = free_tcp_addr();
    let config = concat!(env!("CARGO_MANIFEST_DIR"), "/../config/teleop.toml");
    // The node first, its naming service later: start order does not matter.
    let mut children = Children(vec![PENELOPE.spawn(&[
        "node",
        "--name",
        "lab",
        "--listen",
        &node.to_string(),
        "--naming",
        &naming.to_string(),
        "--priority",
        "0",
        "--config",
        config,
    ])]);
    children
        .0
        .push(PENELOPE.spawn(&["naming", "--listen", &naming.to_string()]));

    let deadline = Instant::now() + Duration::from_secs(30);
    let listing = loop {
        let o = PENELOPE.ctl(naming, &["ls"]);
        let (out, _) = text(&o);
        if o.status.success() && out.contains("follow") {
            break out;
        }
        assert!(
            Instant::now() < deadline,
            "the node never showed up: {:?}",
            text(&o)
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    for (name, kind) in [
        ("frhc", "robot/frhc"),
        ("puma", "robot/puma200"),
        ("link", "trajectory/teleop"),
        ("display", "controller/force-display"),
        ("follow", "controller/slave-tracking"),
        ("hand", "sensor/operator-hand"),
    ] {
        let line = listing
            .lines()
            .find(|l| l.contains(&format!(" {name} ")))
            .unwrap_or_else(|| panic!("{name} missing from\n{listing}"));
        assert!(line.contains(kind) && line.contains("active"), "{line}");
    }

    let o = PENELOPE.ctl(naming, &["watch", "lab/follow", "--count", "3"]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert_eq!(
        out.lines().filter(|l| l.contains(" q [")).count(),
        3,
        "{out}"
    );

    // Both ends of this channel are on the node: no link to watch, and ctl says why.
    let o = PENELOPE.ctl(naming, &["watch", "lab/link", "--count", "1"]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("no data-plane link"), "{err}");

    let o = PENELOPE.ctl(naming, &["deactivate", "lab/follow"]);
    assert!(o.status.success(), "{:?}", text(&o));
    let o = PENELOPE.ctl(naming, &["describe", "lab/follow"]);
    assert!(text(&o).0.contains("inactive"), "{:?}", text(&o));
}

/// `config/demo-two-nodes.toml` on two node processes (free loopback ports, data plane
/// included): `ctl watch` of the master's channel prints its link records as JSON, one per
/// line, their counters growing.
#[test]
fn ctl_watches_a_channels_link_between_two_nodes() {
    let naming = free_tcp_addr();
    let (master, slave) = (free_tcp_addr(), free_tcp_addr());
    let file = include_str!("../../config/demo-two-nodes.toml")
        .replace("127.0.0.1:7410", &format!("127.0.0.1:{}", free_udp_port()))
        .replace("127.0.0.1:7420", &format!("127.0.0.1:{}", free_udp_port()));
    let config = scratch_file("ctl", "two-nodes.toml", &file);
    let config = config.to_str().unwrap();
    let node = |name: &str, listen: SocketAddr| {
        PENELOPE.spawn(&[
            "node",
            "--name",
            name,
            "--listen",
            &listen.to_string(),
            "--naming",
            &naming.to_string(),
            "--priority",
            "0",
            "--config",
            config,
        ])
    };
    let _children = Children(vec![
        PENELOPE.spawn(&["naming", "--listen", &naming.to_string()]),
        node("master", master),
        node("slave", slave),
    ]);

    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        // The master's own channel and creator (the slave's may register first).
        let o = PENELOPE.ctl(naming, &["ls", "/master"]);
        let listed = text(&o).0;
        if o.status.success() && listed.contains(" link ") && listed.contains(" creator") {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "the master's channel never showed up: {:?}",
            text(&o)
        );
        std::thread::sleep(Duration::from_millis(100));
    }

    let o = PENELOPE.ctl(naming, &["watch", "master/link", "--count", "3", "--json"]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    let records: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect();
    assert_eq!(records.len(), 3, "{out}");
    let taken: Vec<u64> = records
        .iter()
        .map(|r| r["samples_taken"].as_u64().expect("a count"))
        .collect();
    assert!(taken.windows(2).all(|w| w[1] >= w[0]), "{taken:?}");
    for key in [
        "clock_offset_ns",
        "one_way_delay_ns",
        "jitter_ns",
        "down",
        "last_heard_ns",
    ] {
        assert!(
            records[2].get(key).is_some(),
            "{key} missing: {}",
            records[2]
        );
    }

    // And for humans, one line per record.
    let o = PENELOPE.ctl(naming, &["watch", "master/link", "--count", "2"]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert_eq!(
        out.lines().filter(|l| l.contains(" offset ")).count(),
        2,
        "{out}"
    );
}
