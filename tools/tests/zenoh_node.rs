//! `penelope node --zenoh ENDPOINT`, the system file's `zenoh` key and `--zenoh-config FILE`
//! (a build with `--features zenoh`), and `penelope bench zenoh` run once. Loopback only,
//! scouting off; every wait is for an answer, bounded.
#![cfg(feature = "zenoh")]

use std::io::BufRead;
use std::process::Stdio;
use std::time::{Duration, Instant};

use penelope_testkit::net::free_tcp_port;
use penelope_testkit::process::Penelope;
use penelope_testkit::scratch::scratch_dir;
use zenoh::Wait;

/// The binary under test.
const PENELOPE: Penelope = Penelope::at(env!("CARGO_BIN_EXE_penelope"));

/// A child process killed when the test ends, its stdout kept open.
struct Child(
    std::process::Child,
    Option<std::io::BufReader<std::process::ChildStdout>>,
);

impl Drop for Child {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A `--sim-clock` node `lab` hosting its naming service, running `config` with `extra`
/// arguments; returned once it says it applied the file. Its first lines are returned too.
fn sim_node(config: &std::path::Path, extra: &[&str]) -> (Child, String) {
    let listen = format!("127.0.0.1:{}", free_tcp_port());
    let child = PENELOPE
        .command()
        .args([
            "node",
            "--name",
            "lab",
            "--host-naming",
            "--listen",
            &listen,
        ])
        .args(["--sim-clock", "--priority", "0", "--config"])
        .arg(config)
        .args(extra)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut node = Child(child, None);
    let mut out = std::io::BufReader::new(node.0.stdout.take().unwrap());
    let mut said = String::new();
    let mut line = String::new();
    while !line.contains("Ctrl-C stops the node") {
        line.clear();
        let n = out.read_line(&mut line).unwrap();
        assert!(n > 0, "the node ended before applying its file: {said}");
        said.push_str(&line);
    }
    node.1 = Some(out);
    (node, said)
}

/// The test's Zenoh peer, listening on `port` on loopback only, no scouting.
fn test_peer(port: u16) -> zenoh::Session {
    let mut c = zenoh::Config::default();
    c.insert_json5("mode", r#""peer""#).unwrap();
    c.insert_json5("listen/endpoints", &format!(r#"["tcp/127.0.0.1:{port}"]"#))
        .unwrap();
    c.insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    zenoh::open(c).wait().unwrap()
}

/// The names in node `lab`'s object tree, asked until it answers (bounded).
fn object_names(peer: &zenoh::Session) -> Vec<String> {
    let give_up = Instant::now() + Duration::from_secs(20);
    loop {
        let replies = peer.get("penelope/lab/objects").wait().unwrap();
        if let Ok(reply) = replies.recv()
            && let Ok(sample) = reply.result()
        {
            let tree: serde_json::Value =
                serde_json::from_slice(&sample.payload().to_bytes()).unwrap();
            return tree
                .as_array()
                .unwrap()
                .iter()
                .filter_map(|o| o["name"].as_str().map(str::to_string))
                .collect();
        }
        assert!(Instant::now() < give_up, "node lab never answered");
    }
}

const DEMO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../config/demo.toml");

#[test]
fn a_node_started_with_zenoh_answers_its_object_tree_on_zenoh() {
    let port = free_tcp_port();
    let peer = test_peer(port);
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let (_node, said) = sim_node(DEMO.as_ref(), &["--zenoh", &endpoint]);
    assert!(said.contains("zenoh bridge: connecting to"), "{said}");
    let names = object_names(&peer);
    for name in ["frhc", "puma", "link", "follow", "display"] {
        assert!(names.iter().any(|n| n == name), "{name} in {names:?}");
    }
}

#[test]
fn the_system_files_zenoh_table_and_a_zenoh_config_file_reach_the_bridge() {
    let port = free_tcp_port();
    let peer = test_peer(port);
    let dir = scratch_dir("zenoh", "config");
    // Zenoh's own file: where to connect, scouting off as it says.
    let zenoh_file = dir.join("zenoh.json5");
    std::fs::write(
        &zenoh_file,
        format!(
            "{{ mode: \"peer\", connect: {{ endpoints: [\"tcp/127.0.0.1:{port}\"] }},\n  \
             listen: {{ endpoints: [] }}, scouting: {{ multicast: {{ enabled: false }} }} }}\n"
        ),
    )
    .unwrap();
    // The demo's `[nodes.lab]` table gets the key.
    let system = std::fs::read_to_string(DEMO).unwrap().replacen(
        "[nodes.lab]\n",
        &format!(
            "[nodes.lab]\nzenoh = {{ config = {:?} }}\n",
            zenoh_file.display().to_string()
        ),
        1,
    );
    assert!(system.contains("zenoh = { config"));
    let file = dir.join("lab.toml");
    std::fs::write(&file, system).unwrap();
    let (_node, said) = sim_node(&file, &[]);
    assert!(said.contains("zenoh bridge"), "{said}");
    assert!(object_names(&peer).iter().any(|n| n == "follow"));
}

#[test]
fn a_bad_zenoh_config_file_stops_the_node_with_the_reason() {
    let dir = scratch_dir("zenoh", "bad");
    let zenoh_file = dir.join("zenoh.json5");
    std::fs::write(&zenoh_file, "{ mode: ").unwrap();
    let out = PENELOPE
        .command()
        .args(["node", "--name", "lab", "--host-naming", "--listen"])
        .arg(format!("127.0.0.1:{}", free_tcp_port()))
        .args(["--sim-clock", "--priority", "0", "--zenoh-config"])
        .arg(&zenoh_file)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("Zenoh configuration"), "{err}");
}

#[test]
fn bench_zenoh_reports_both_transports() {
    let out = PENELOPE
        .command()
        .args(["bench", "zenoh", "--samples", "200", "--rate", "1000"])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.contains("data plane (UDP, postcard), kernel stamp"),
        "{text}"
    );
    assert!(text.contains("zenoh bridge"), "{text}");
    assert!(
        text.contains("zenoh / data plane (reader): p50 x"),
        "{text}"
    );
}
