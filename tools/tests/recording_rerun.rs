//! `penelope recording rerun FILE`: a simulated-clock demo run again against its recorded
//! operator and contact forces gives its telemetry back bit for bit; a changed gain is found
//! and reported; the replay kinds' inputs are the recording's (a changed sensor model changes
//! nothing), their errors are typed, and a recording shorter than the run ends as documented.

use penelope_testkit::process::Penelope;
use penelope_testkit::scratch::scratch_dir;
use std::path::{Path, PathBuf};
use std::process::Output;

/// The binary under test.
const PENELOPE: Penelope = Penelope::at(env!("CARGO_BIN_EXE_penelope"));

fn demo(out: &Path, duration: &str, config: Option<&Path>) -> Output {
    let mut c = PENELOPE.command();
    c.args([
        "demo",
        "--sim-clock",
        "--duration",
        duration,
        "--json",
        "--out",
    ])
    .arg(out);
    if let Some(config) = config {
        c.arg("--config").arg(config);
    }
    c.output().expect("penelope runs")
}

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// `recording rerun --json` on `file` (with `config`): its exit code and report.
fn rerun(file: &Path, config: Option<&Path>) -> (i32, serde_json::Value) {
    let mut c = PENELOPE.command();
    c.args(["recording", "rerun", "--json"]).arg(file);
    if let Some(config) = config {
        c.arg("--config").arg(config);
    }
    let o = c.output().expect("penelope runs");
    let code = o.status.code().expect("exit code");
    assert!(
        code == 0 || code == 1,
        "{code}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    (
        code,
        serde_json::from_slice(&o.stdout).expect("a JSON report"),
    )
}

fn controller<'a>(report: &'a serde_json::Value, name: &str) -> &'a serde_json::Value {
    report["controllers"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["controller"] == name)
        .unwrap_or_else(|| panic!("{name} in {report}"))
}

fn differing_signals(c: &serde_json::Value) -> Vec<String> {
    c["signals"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["signal"].as_str().unwrap().to_string())
        .collect()
}

/// The shipped demo file with `from` replaced by `to` (which must be there).
fn demo_file_with(dir: &Path, from: &str, to: &str) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("config/demo.toml")).unwrap();
    assert!(text.contains(from), "{from}");
    let path = dir.join("changed.toml");
    std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
    path
}

#[test]
fn a_rerun_of_a_simulated_demo_is_bit_for_bit_and_a_changed_gain_is_reported() {
    let dir = scratch_dir("rerun", "same");
    ok(&demo(&dir, "2s", None));
    let file = dir.join("run.mcap");

    // Unchanged: every tick of both controllers, every value, bit for bit.
    let (code, report) = rerun(&file, None);
    assert_eq!(code, 0, "{report}");
    assert_eq!(report["identical"], true);
    for name in ["display", "follow"] {
        let c = controller(&report, name);
        assert_eq!(c["recorded"], 2000, "{c}");
        assert_eq!(c["rerun"], 2000, "{c}");
        assert_eq!(c["differing_ticks"], 0, "{c}");
    }

    // A softer slave: its efforts and motion change; the master's motion is the recording's
    // (the replayed hand), so its joint positions do not.
    let softer = demo_file_with_tables(
        &dir,
        "softer.toml",
        &[(
            "[controllers.follow]",
            "kind = \"slave-tracking\"\nrobot = \"puma\"\ntrajectory = \"link\"\nsensor = \"wrist\"\n\
             kp = [3600.0, 3600.0, 3600.0, 3600.0, 3600.0, 3600.0]"
                .to_string(),
        )],
    );
    let (code, report) = rerun(&file, Some(&softer));
    assert_eq!(code, 1, "{report}");
    assert_eq!(report["identical"], false);
    let follow = controller(&report, "follow");
    assert!(
        follow["differing_ticks"].as_u64().unwrap() > 1000,
        "{follow}"
    );
    let signals = differing_signals(follow);
    for s in ["sample.effort", "sample.q", "truth.joints"] {
        assert!(signals.contains(&s.to_string()), "{s} in {signals:?}");
    }
    let effort = follow["signals"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["signal"] == "sample.effort")
        .unwrap();
    assert!(effort["max_abs_diff"].as_f64().unwrap() > 0.0, "{effort}");
    let display = controller(&report, "display");
    let signals = differing_signals(display);
    assert!(!signals.contains(&"sample.q".to_string()), "{signals:?}");
    assert!(
        !signals.contains(&"truth.joints".to_string()),
        "{signals:?}"
    );
}

#[test]
fn the_replayed_inputs_are_the_recordings_whatever_the_live_models_say() {
    let dir = scratch_dir("rerun", "inputs");
    ok(&demo(&dir, "1s", None));
    let file = dir.join("run.mcap");
    // Ten times the sensor noise, another hand script stiffness: the rerun replays the
    // recorded sensor readings and hand, so nothing changes.
    let changed = demo_file_with(&dir, "force_noise = 0.05 ", "force_noise = 0.5  ");
    let text = std::fs::read_to_string(&changed).unwrap().replacen(
        "stiffness_n_per_m = 400.0",
        "stiffness_n_per_m = 800.0",
        1,
    );
    std::fs::write(&changed, text).unwrap();
    let (code, report) = rerun(&file, Some(&changed));
    assert_eq!(code, 0, "{report}");
    // The same file run live is another run.
    let live = dir.join("live");
    ok(&demo(&live, "1s", Some(&changed)));
    let (code, report) = rerun(&file, None);
    assert_eq!(code, 0, "{report}");
    let other = dir.join("other");
    ok(&demo(&other, "1s", None));
    let a = std::fs::read(live.join("telemetry-slave.csv")).unwrap();
    let b = std::fs::read(other.join("telemetry-slave.csv")).unwrap();
    assert_ne!(a, b, "the changed models change a live run");
}

/// The shipped demo file with whole tables replaced: `(header, body)`.
fn demo_file_with_tables(dir: &Path, name: &str, tables: &[(&str, String)]) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("config/demo.toml")).unwrap();
    let mut out = String::new();
    let mut skipping = false;
    for line in text.lines() {
        if line.starts_with('[') {
            skipping = false;
            if let Some((h, body)) = tables.iter().find(|(h, _)| line.trim() == *h) {
                out += &format!("{h}\n{body}\n\n");
                skipping = true;
                continue;
            }
        }
        if !skipping {
            out += line;
            out.push('\n');
        }
    }
    for (h, _) in tables {
        assert!(out.contains(h), "{h}");
    }
    let path = dir.join(name);
    std::fs::write(&path, out).unwrap();
    path
}

/// The demo file with its hand and wrist sensor replayed from `recording` (`topic`s default).
fn replayed_demo_file(dir: &Path, recording: &Path, wrist_topic: Option<&str>) -> PathBuf {
    let file = format!("{:?}", recording.display().to_string());
    let topic = wrist_topic.map_or(String::new(), |t| format!("\ntopic = {t:?}"));
    demo_file_with_tables(
        dir,
        "replayed.toml",
        &[
            (
                "[sensors.hand]",
                format!("kind = \"operator-replay\"\nrobot = \"frhc\"\nfile = {file}"),
            ),
            (
                "[sensors.wrist]",
                format!("kind = \"replay\"\nfile = {file}\nmount_xyz = [0.0, 0.0, 0.02]{topic}"),
            ),
        ],
    )
}

/// Every tick message of `topic` in the MCAP file at `path`, in order.
fn ticks(path: &Path, topic: &str) -> Vec<serde_json::Value> {
    let bytes = std::fs::read(path).unwrap();
    mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(Result::unwrap)
        .filter(|m| m.channel.topic == topic)
        .map(|m| serde_json::from_slice(&m.data).unwrap())
        .collect()
}

#[test]
fn a_recording_shorter_than_the_run_ends_in_a_held_hand_and_a_silent_sensor() {
    let dir = scratch_dir("rerun", "short");
    ok(&demo(&dir.join("rec"), "1s", None));
    let rec = dir.join("rec/run.mcap");
    let config = replayed_demo_file(&dir, &rec, None);
    let out = dir.join("long");
    ok(&demo(&out, "2s", Some(&config)));
    let follow = ticks(&out.join("run.mcap"), "/controllers/follow");
    let display = ticks(&out.join("run.mcap"), "/controllers/display");
    assert_eq!((follow.len(), display.len()), (2000, 2000));
    // `events` is rt-core's bit set; `sensor-error` is bit 14 (`SafetyEvent::SensorError`).
    let sensor_error =
        |t: &serde_json::Value| t["sample"]["events"].as_u64().expect("events") & (1 << 14) != 0;
    // The first second is the recording's: the replayed readings, no sensor error.
    let recorded = ticks(&rec, "/controllers/follow");
    for (live, rec) in follow.iter().zip(&recorded).take(1000) {
        assert_eq!(live["sample"]["wrench"], rec["sample"]["wrench"]);
        assert!(!sensor_error(live), "{live}");
    }
    // Past it, the sensor is silent: every tick notes a sensor error.
    assert!(follow[1001..].iter().all(sensor_error), "{}", follow[1500]);
    // The master's hand holds the last recorded pose, at rest.
    let last_recorded = &ticks(&rec, "/controllers/display")[999]["truth"]["joints"]["position"];
    for t in &display[1001..] {
        assert_eq!(&t["truth"]["joints"]["position"], last_recorded);
        assert!(
            t["truth"]["joints"]["velocity"]
                .as_array()
                .unwrap()
                .iter()
                .all(|v| v.as_f64() == Some(0.0)),
            "{t}"
        );
    }
}

#[test]
fn replay_kinds_refuse_a_missing_recording_or_channel_with_the_reason() {
    let dir = scratch_dir("rerun", "errors");
    let missing = dir.join("nothing.mcap");
    let config = replayed_demo_file(&dir, &missing, None);
    let o = demo(&dir.join("out"), "1s", Some(&config));
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("no such recording"), "{err}");

    // A recording without the channel asked for.
    ok(&demo(&dir.join("rec"), "1s", None));
    let config = replayed_demo_file(&dir, &dir.join("rec/run.mcap"), Some("/controllers/nobody"));
    let o = demo(&dir.join("out2"), "1s", Some(&config));
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("no channel /controllers/nobody") && err.contains("/controllers/follow"),
        "{err}"
    );

    // Not a recording: typed, exit code 2.
    let o = PENELOPE
        .command()
        .args(["recording", "rerun"])
        .arg(&missing)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
}
