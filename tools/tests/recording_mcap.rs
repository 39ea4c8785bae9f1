//! `penelope demo`'s `run.mcap` read back with the `mcap` crate against the run's CSV files,
//! and `penelope recording info` on it; `penelope node --record FILE` on the simulated clock, read back.

use penelope_testkit::process::Penelope;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The binary under test.
const PENELOPE: Penelope = Penelope::at(env!("CARGO_BIN_EXE_penelope"));

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("penelope-mcap-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// A CSV file's rows, each as column name to text.
fn csv_rows(path: &Path) -> Vec<BTreeMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    lines
        .map(|l| {
            header
                .iter()
                .zip(l.split(','))
                .map(|(h, v)| (h.to_string(), v.to_string()))
                .collect()
        })
        .collect()
}

fn num(row: &BTreeMap<String, String>, column: &str) -> f64 {
    row[column].parse().unwrap()
}

struct Message {
    log_time: u64,
    value: serde_json::Value,
}

#[test]
fn the_demo_writes_run_mcap_with_every_tick_of_its_csv_files_and_replay_lists_it() {
    let out = scratch("demo");
    let status = PENELOPE
        .command()
        .args(["demo", "--sim-clock", "--duration", "3s", "--json", "--out"])
        .arg(&out)
        .output()
        .expect("penelope runs");
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    let bytes = std::fs::read(out.join("run.mcap")).expect("run.mcap written");

    let topics = channels_with_json_schemas(&bytes);
    let by_topic = messages_by_topic(&bytes);
    the_ticks_are_the_csv_rows(&by_topic, &out);
    // What the recorder lost, per controller.
    let recorder = &by_topic["/recorder"];
    assert_eq!(recorder.len(), 2);
    for r in recorder {
        assert_eq!(r.value["dropped"], 0, "{}", r.value);
    }
    // The first ticks' safety state is an event.
    assert!(by_topic["/safety"].len() >= 2);

    recording_info_says_the_same(&out, &topics, &by_topic);
    let _ = std::fs::remove_dir_all(out);
}

/// Channels: each with a JSON Schema, JSON messages; the controllers', the safety events' and
/// the recorder's. Returns each topic's schema name.
fn channels_with_json_schemas(bytes: &[u8]) -> BTreeMap<String, String> {
    let summary = mcap::Summary::read(bytes)
        .unwrap()
        .expect("a summary section");
    let mut topics = BTreeMap::new();
    for c in summary.channels.values() {
        let schema = c
            .schema
            .as_ref()
            .unwrap_or_else(|| panic!("{} has a schema", c.topic));
        assert_eq!(schema.encoding, "jsonschema", "{}", c.topic);
        let parsed: serde_json::Value =
            serde_json::from_slice(&schema.data).expect("schema is JSON");
        assert_eq!(parsed["type"], "object", "{}", c.topic);
        assert_eq!(c.message_encoding, "json", "{}", c.topic);
        topics.insert(c.topic.clone(), schema.name.clone());
    }
    assert_eq!(topics["/controllers/display"], "penelope.Tick");
    assert_eq!(topics["/controllers/follow"], "penelope.Tick");
    assert_eq!(topics["/safety"], "penelope.SafetyEvent");
    assert_eq!(topics["/recorder"], "penelope.RecorderDropped");

    topics
}

/// Every message of the file, JSON, by topic.
fn messages_by_topic(bytes: &[u8]) -> BTreeMap<String, Vec<Message>> {
    let mut by_topic: BTreeMap<String, Vec<Message>> = BTreeMap::new();
    for m in mcap::MessageStream::new(bytes).unwrap() {
        let m = m.unwrap();
        let value = serde_json::from_slice(&m.data).expect("messages are JSON");
        by_topic
            .entry(m.channel.topic.clone())
            .or_default()
            .push(Message {
                log_time: m.log_time,
                value,
            });
    }

    by_topic
}

/// One message per tick row of the CSV files in `out`, with the same time, state, joints,
/// efforts, tool position and true force, over the same 3 s span.
fn the_ticks_are_the_csv_rows(by_topic: &BTreeMap<String, Vec<Message>>, out: &Path) {
    let master_csv = csv_rows(&out.join("telemetry-master.csv"));
    let slave_csv = csv_rows(&out.join("telemetry-slave.csv"));
    assert!(
        master_csv.len() > 2500,
        "3 s at 1 kHz: {}",
        master_csv.len()
    );
    let run_start = by_topic["/controllers/display"][0].log_time;
    for (topic, rows) in [
        ("/controllers/display", &master_csv),
        ("/controllers/follow", &slave_csv),
    ] {
        let messages = &by_topic[topic];
        assert_eq!(
            messages.len(),
            rows.len(),
            "{topic}: one message per CSV tick row"
        );
        for (m, row) in [
            (&messages[0], &rows[0]),
            (&messages[messages.len() - 1], &rows[rows.len() - 1]),
        ] {
            // The time on the node's clock: the CSV's is since the run's start.
            let since = (m.log_time - run_start) as f64 * 1e-9;
            assert!(
                (since - num(row, "time_s")).abs() < 1e-6,
                "{topic}: time {since}"
            );
            assert_eq!(m.value["sample"]["time"].as_u64(), Some(m.log_time));
            assert_eq!(
                m.value["sample"]["state"].as_str().unwrap().to_lowercase(),
                row["state"]
            );
            for j in 0..6 {
                let q = m.value["sample"]["q"][j].as_f64().unwrap();
                let csv = num(row, &format!("q_rad{}", j + 1));
                assert!((q - csv).abs() < 1e-8, "{topic} q{j}: {q} vs {csv}");
                let e = m.value["sample"]["effort"][j].as_f64().unwrap();
                let csv = num(row, &format!("effort_nm{}", j + 1));
                assert!((e - csv).abs() < 1e-8, "{topic} effort{j}: {e} vs {csv}");
            }
            for (axis, key) in [(0, "tool_m_x"), (1, "tool_m_y"), (2, "tool_m_z")] {
                let v = m.value["sample"]["tool_position"][axis].as_f64().unwrap();
                assert!((v - num(row, key)).abs() < 1e-8, "{topic} {key}");
            }
            let truth = m.value["truth"]["base_wrench"]["force"][2]
                .as_f64()
                .unwrap();
            assert!(
                (truth - num(row, "true_force_n_z")).abs() < 1e-8,
                "{topic} truth"
            );
        }
    }
    // The span of the run: the CSV's last tick less its first.
    let last = |t: &str| by_topic[t].last().unwrap().log_time;
    let span = (last("/controllers/display").max(last("/controllers/follow")) - run_start) as f64;
    let csv_span = num(&master_csv[master_csv.len() - 1], "time_s")
        .max(num(&slave_csv[slave_csv.len() - 1], "time_s"));
    assert!(
        (span * 1e-9 - csv_span).abs() < 1e-6,
        "span {span} ns vs {csv_span} s"
    );
    assert!((csv_span - 3.0).abs() < 0.01, "the run's 3 s: {csv_span}");
}

/// `penelope recording info` says the same: the channels, their message counts and schemas,
/// and the run's start, end and duration; in text too.
fn recording_info_says_the_same(
    out: &Path,
    topics: &BTreeMap<String, String>,
    by_topic: &BTreeMap<String, Vec<Message>>,
) {
    let replay = PENELOPE
        .command()
        .args(["recording", "info"])
        .arg(out.join("run.mcap"))
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        replay.status.success(),
        "{}",
        String::from_utf8_lossy(&replay.stderr)
    );
    let listed: serde_json::Value = serde_json::from_slice(&replay.stdout).unwrap();
    let channels = listed["channels"].as_array().unwrap();
    assert_eq!(channels.len(), topics.len());
    for c in channels {
        let topic = c["topic"].as_str().unwrap();
        assert_eq!(
            c["messages"].as_u64().unwrap() as usize,
            by_topic.get(topic).map_or(0, Vec::len),
            "{topic}"
        );
        assert_eq!(c["schema"].as_str().unwrap(), topics[topic]);
    }
    let all = by_topic.values().flatten();
    let (start, end) = (
        all.clone().map(|m| m.log_time).min().unwrap(),
        all.map(|m| m.log_time).max().unwrap(),
    );
    assert_eq!(listed["start_ns"].as_u64(), Some(start));
    assert_eq!(listed["end_ns"].as_u64(), Some(end));
    assert_eq!(listed["duration_ns"].as_u64(), Some(end - start));
    let text = PENELOPE
        .command()
        .args(["recording", "info"])
        .arg(out.join("run.mcap"))
        .output()
        .unwrap();
    let text = String::from_utf8(text.stdout).unwrap();
    assert!(
        text.contains("/controllers/follow") && text.contains("penelope.Tick"),
        "{text}"
    );
}

#[test]
fn replay_of_a_missing_or_foreign_file_exits_with_code_two() {
    let dir = scratch("bad");
    std::fs::create_dir_all(&dir).unwrap();
    let foreign = dir.join("not.mcap");
    std::fs::write(&foreign, "time_s,q\n0,1\n").unwrap();
    for file in [dir.join("missing.mcap"), foreign] {
        let out = PENELOPE
            .command()
            .args(["recording", "info"])
            .arg(&file)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{}", file.display());
        assert!(String::from_utf8_lossy(&out.stderr).contains("error:"));
    }
    let _ = std::fs::remove_dir_all(dir);
}

/// A child process, killed when the test ends, passed or failed; with its stdout reader, kept
/// open so that the node never writes into a closed pipe.
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

/// A `--sim-clock` node hosting its naming service on a free loopback port, running the system
/// file `config` (with `extra` arguments), returned once it says it has applied the file.
fn sim_node(config: &std::path::Path, extra: &[&str]) -> (std::net::SocketAddr, Child) {
    let listen = penelope_testkit::net::free_tcp_addr();
    let child = PENELOPE
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
        .unwrap();
    let mut node = Child(child, None);
    let mut out = std::io::BufReader::new(node.0.stdout.take().unwrap());
    // The node says so once the file is applied, its controllers recorded and active.
    let mut line = String::new();
    while !line.contains("Ctrl-C stops the node") {
        line.clear();
        let n = std::io::BufRead::read_line(&mut out, &mut line).unwrap();
        assert!(n > 0, "the node ended before applying its file");
    }
    node.1 = Some(out);
    (listen, node)
}

/// The demo's system file.
const DEMO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../config/demo.toml");

fn ctl(naming: std::net::SocketAddr, args: &[&str]) -> std::process::Output {
    PENELOPE
        .command()
        .args(["ctl", "--naming", &naming.to_string(), "--timeout", "300"])
        .args(args)
        .stdin(std::process::Stdio::null())
        .output()
        .unwrap()
}

#[test]
fn a_node_records_every_tick_from_the_first_to_mcap_and_it_reads_back() {
    use std::time::{Duration, Instant};
    let dir = scratch("node");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("lab.mcap");
    let (listen, mut node) = sim_node(DEMO.as_ref(), &["--record", file.to_str().unwrap()]);
    let o = ctl(listen, &["advance", "lab", "1500ms"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // Readable while the node still writes it (what `penelope bench layout` does).
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let r = penelope_runtime::objects::recording::read_recording(&file).unwrap();
        if r.controllers.get("follow").is_some_and(|t| t.len() >= 1000) {
            break;
        }
        assert!(Instant::now() < deadline, "ticks not flushed while running");
        std::thread::sleep(Duration::from_millis(100));
    }
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(node.0.id() as i32),
        nix::sys::signal::Signal::SIGINT,
    )
    .unwrap();
    let status = node.0.wait().unwrap();
    assert!(status.success(), "the node stops cleanly on SIGINT");

    let r = penelope_runtime::objects::recording::read_recording(&file).unwrap();
    assert_eq!(r.node, "lab");
    for name in ["display", "follow"] {
        let ticks = &r.controllers[name];
        // Every tick from the first: 1.5 s at 1 kHz, then those of the deactivation.
        assert!(ticks.len() >= 1500, "{name}: {}", ticks.len());
        for (i, t) in ticks.iter().enumerate() {
            assert_eq!(
                t.sample.seq,
                i as u64 + 1,
                "{name}: tick {i} not decimated, none lost"
            );
        }
        assert_eq!(r.dropped[name], 0);
    }
    let replay = PENELOPE
        .command()
        .args(["recording", "info"])
        .arg(&file)
        .arg("--json")
        .output()
        .unwrap();
    assert!(replay.status.success());
    let listed: serde_json::Value = serde_json::from_slice(&replay.stdout).unwrap();
    let count = |topic: &str| {
        listed["channels"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["topic"] == topic)
            .and_then(|c| c["messages"].as_u64())
    };
    assert_eq!(
        count("/controllers/follow"),
        Some(r.controllers["follow"].len() as u64)
    );
    assert!(
        count("/safety").unwrap() >= 2,
        "activation and deactivation of each"
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn ctl_record_starts_and_stops_a_recording_and_refuses_bad_input_with_the_reason() {
    let dir = scratch("ctl");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("part.mcap");
    let (listen, _node) = sim_node(DEMO.as_ref(), &["--records", dir.to_str().unwrap()]);
    // A client names a plain file name in the node's recordings directory.
    let path = "part.mcap";
    let refused = |args: &[&str], why: &str| {
        let o = ctl(listen, args);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(!o.status.success(), "{args:?} refused");
        assert!(err.contains(why), "{args:?}: {err}");
    };
    refused(&["record", "start", "lab", "part.txt"], "*.mcap");
    refused(&["record", "start", "lab", path, "nosuch"], "nosuch");
    refused(
        &["record", "start", "lab", path, "hand"],
        "only controllers, channels and cameras",
    );
    refused(&["record", "stop", "lab"], "not recording");
    assert!(!file.exists(), "nothing created by a refused start");

    let o = ctl(
        listen,
        &[
            "record", "start", "lab", path, "display", "follow", "--json",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let started: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        started["controllers"],
        serde_json::json!(["display", "follow"])
    );
    refused(&["record", "start", "lab", path], "already recording");
    let o = ctl(listen, &["advance", "lab", "500ms"]);
    assert!(o.status.success());
    let o = ctl(listen, &["record", "stop", "lab", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stopped: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let ticks = stopped["ticks"].as_u64().unwrap();
    assert_eq!(ticks, 1000, "500 ms of both controllers at 1 kHz");
    let r = penelope_runtime::objects::recording::read_recording(&file).unwrap();
    for name in ["display", "follow"] {
        let t = &r.controllers[name];
        assert_eq!(t.len(), 500, "{name}");
        for w in t.windows(2) {
            assert_eq!(w[1].sample.seq, w[0].sample.seq + 1, "{name}: every tick");
        }
    }
    // Never overwritten; the node still serves.
    refused(&["record", "start", "lab", path], "exists");
    assert!(ctl(listen, &["ls"]).status.success());
    let _ = std::fs::remove_dir_all(dir);
}

/// A hostile client: a recording it names is a plain file name, created new in
/// the node's recordings directory without following a link; nothing outside the directory is
/// created or changed, and an existing file is left as it was.
#[test]
fn a_client_cannot_make_a_node_record_outside_its_directory_or_through_a_link() {
    let dir = scratch("confined");
    let records = dir.join("records");
    let outside = dir.join("outside");
    std::fs::create_dir_all(&records).unwrap();
    std::fs::create_dir_all(&outside).unwrap();
    // A link named like a recording, to a file that does not exist yet, and one to a file
    // that does; an existing recording.
    let target = outside.join("created.mcap");
    std::os::unix::fs::symlink(&target, records.join("x.mcap")).unwrap();
    let precious = outside.join("precious.txt");
    std::fs::write(&precious, b"keep me").unwrap();
    std::os::unix::fs::symlink(&precious, records.join("y.mcap")).unwrap();
    std::fs::write(records.join("old.mcap"), b"old").unwrap();
    let (listen, _node) = sim_node(DEMO.as_ref(), &["--records", records.to_str().unwrap()]);
    let refused = |name: &str, why: &str| {
        let o = ctl(listen, &["record", "start", "lab", name]);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(!o.status.success(), "{name} refused");
        assert!(err.contains(why), "{name}: {err}");
    };
    refused("x.mcap", "exists");
    refused("y.mcap", "exists");
    refused("old.mcap", "exists");
    refused("../x.mcap", "not a plain file name");
    refused("../outside/z.mcap", "not a plain file name");
    let absolute = outside.join("abs.mcap");
    refused(absolute.to_str().unwrap(), "not a plain file name");
    assert!(!target.exists(), "nothing created through the link");
    assert!(!absolute.exists() && !dir.join("x.mcap").exists());
    assert_eq!(std::fs::read(&precious).unwrap(), b"keep me");
    assert_eq!(std::fs::read(records.join("old.mcap")).unwrap(), b"old");
    let mut outside_files: Vec<_> = std::fs::read_dir(&outside)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    outside_files.sort();
    assert_eq!(outside_files, ["precious.txt"], "nothing new outside");
    // A plain new name is recorded, in the directory, and the reply says where.
    let o = ctl(listen, &["record", "start", "lab", "new.mcap", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let started: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let at = std::path::PathBuf::from(started["path"].as_str().unwrap());
    assert_eq!(at.file_name().unwrap(), "new.mcap");
    assert_eq!(
        at.parent().unwrap().canonicalize().unwrap(),
        records.canonicalize().unwrap()
    );
    let o = ctl(listen, &["record", "stop", "lab"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(records.join("new.mcap").is_file());
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn the_system_files_record_key_records_a_node_from_its_first_tick() {
    let dir = scratch("file");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("from-file.mcap");
    let demo = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../config/demo.toml"))
        .unwrap();
    let text = demo.replacen(
        "[nodes.lab]\n",
        &format!("[nodes.lab]\nrecord = {:?}\n", file.to_str().unwrap()),
        1,
    );
    assert_ne!(text, demo);
    let config = dir.join("system.toml");
    std::fs::write(&config, text).unwrap();
    let (listen, mut node) = sim_node(&config, &[]);
    assert!(ctl(listen, &["advance", "lab", "300ms"]).status.success());
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(node.0.id() as i32),
        nix::sys::signal::Signal::SIGINT,
    )
    .unwrap();
    assert!(node.0.wait().unwrap().success());
    let r = penelope_runtime::objects::recording::read_recording(&file).unwrap();
    let follow = &r.controllers["follow"];
    assert!(follow.len() >= 300, "{}", follow.len());
    assert_eq!(follow[0].sample.seq, 1, "from the first tick");
    let _ = std::fs::remove_dir_all(dir);
}
