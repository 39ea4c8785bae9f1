//! `penelope node` recording in the ROS 2 profile: the system file's `record_profile = "ros2"`
//! and `--record-profile`, which overrides it; the file read back with the `mcap` crate and
//! its messages decoded with `penelope-ros2-msgs`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use penelope_ros2_msgs::{JointState, OperatingState, RosMessage};
use penelope_testkit::process::Penelope;

const PENELOPE: Penelope = Penelope::at(env!("CARGO_BIN_EXE_penelope"));

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("penelope-ros2rec-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A child process, killed when the test ends.
struct Child(std::process::Child);

impl Drop for Child {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Runs a `--sim-clock` node on `config` (with `extra` arguments) for 500 ms of simulated
/// time, then stops it with SIGINT.
fn record_half_a_second(config: &Path, extra: &[&str]) {
    use std::io::BufRead;
    let listen = penelope_testkit::net::free_tcp_addr();
    let mut node = Child(
        PENELOPE
            .command()
            .args(["node", "--name", "lab", "--host-naming", "--listen"])
            .arg(listen.to_string())
            .args(["--sim-clock", "--priority", "0", "--config"])
            .arg(config)
            .args(extra)
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap(),
    );
    let mut out = std::io::BufReader::new(node.0.stdout.take().unwrap());
    let mut line = String::new();
    while !line.contains("Ctrl-C stops the node") {
        line.clear();
        assert!(
            out.read_line(&mut line).unwrap() > 0,
            "the node ended early"
        );
    }
    let advance = PENELOPE
        .command()
        .args(["ctl", "--naming", &listen.to_string(), "--timeout", "300"])
        .args(["advance", "lab", "500ms"])
        .stdin(std::process::Stdio::null())
        .output()
        .unwrap();
    assert!(
        advance.status.success(),
        "{}",
        String::from_utf8_lossy(&advance.stderr)
    );
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(node.0.id() as i32),
        nix::sys::signal::Signal::SIGINT,
    )
    .unwrap();
    // Drain what it prints so it never blocks on a full pipe while finishing.
    let _ = std::io::Read::read_to_string(&mut out, &mut String::new());
    assert!(node.0.wait().unwrap().success(), "the node stops cleanly");
}

/// Messages by topic: (schema name, data).
type ByTopic = BTreeMap<String, Vec<(String, Vec<u8>)>>;

/// The file's profile and its messages by topic.
fn read(path: &Path) -> (String, ByTopic) {
    let bytes = std::fs::read(path).unwrap();
    let profile = mcap::read::LinearReader::new(&bytes)
        .unwrap()
        .find_map(|r| match r {
            Ok(mcap::records::Record::Header(h)) => Some(h.profile),
            _ => None,
        })
        .unwrap();
    let mut by_topic = ByTopic::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m
            .channel
            .schema
            .as_ref()
            .map_or(String::new(), |s| s.name.clone());
        by_topic
            .entry(m.channel.topic.clone())
            .or_default()
            .push((schema, m.data.to_vec()));
    }
    (profile, by_topic)
}

#[test]
fn a_node_records_the_ros2_topic_set_when_its_file_or_flag_says_so() {
    let dir = scratch("node");
    let file = dir.join("lab-ros2.mcap");
    let demo = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../config/demo.toml"))
        .unwrap();
    let text = demo.replacen(
        "[nodes.lab]\n",
        &format!(
            "[nodes.lab]\nrecord = {:?}\nrecord_profile = \"ros2\"\n",
            file.to_str().unwrap()
        ),
        1,
    );
    assert_ne!(text, demo);
    let config = dir.join("system.toml");
    std::fs::write(&config, text).unwrap();

    record_half_a_second(&config, &[]);
    let (profile, by_topic) = read(&file);
    assert_eq!(profile, "ros2");
    // 500 ms of ticks at the default 100 Hz: about 50 of each robot's messages (and those of
    // the deactivation).
    let js = &by_topic["/puma/measured_js"];
    println!("/puma/measured_js: {} messages", js.len());
    assert!((50..=60).contains(&js.len()), "{}", js.len());
    for (schema, data) in js {
        assert_eq!(schema, JointState::TYPE_NAME);
        let state = JointState::decode_cdr(data).unwrap();
        assert_eq!(state.name.len(), 6);
        assert_eq!(state.position.len(), 6);
    }
    let states: Vec<String> = by_topic["/frhc/operating_state"]
        .iter()
        .map(|(_, d)| OperatingState::decode_cdr(d).unwrap().state)
        .collect();
    assert!(states.iter().any(|s| s == "ENABLED"), "{states:?}");
    for topic in ["/frhc/measured_cp", "/puma/measured_cf", "/tf"] {
        assert!(by_topic.contains_key(topic), "{topic}");
    }
    assert!(!by_topic.contains_key("/controllers/follow"));

    // `--record-profile penelope` overrides the file.
    std::fs::remove_file(&file).unwrap();
    record_half_a_second(&config, &["--record-profile", "penelope"]);
    let (profile, by_topic) = read(&file);
    assert_eq!(profile, "penelope");
    assert!(by_topic.contains_key("/controllers/follow"));
    let _ = std::fs::remove_dir_all(dir);
}
