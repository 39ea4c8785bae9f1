//! The paper's modularity experiment as a test: the demo's task, from system files alone, in the
//! two- and four-host layouts (hosts are network namespaces joined by veth pairs; `penelope
//! naming` and `penelope node` processes in them), against the single-process demo. Runs as
//! root (CI does); without namespaces it fails loudly.

use std::process::Command;

use penelope_supervisor::runs::report::{Report, report};
use penelope_supervisor::runs::{DEMO_SYSTEM, RunOptions, run};
use penelope_supervisor::system::SystemFile;

/// The layouts this test runs.
const LAYOUTS: [&str; 2] = ["2-host", "4-host"];

/// The namespaces a `penelope` process with this pid made (they carry its pid).
fn namespaces_of(pid: u32) -> Vec<String> {
    let out = Command::new("ip")
        .args(["netns", "list"])
        .output()
        .expect("ip runs");
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .filter(|n| n.starts_with(&format!("pen{pid}x")))
        .map(String::from)
        .collect()
}

#[test]
fn the_two_and_four_host_layouts_complete_the_task_as_the_single_process_demo_does() {
    let demo = report(
        &run(
            &SystemFile::parse(DEMO_SYSTEM).expect("the demo's file"),
            &RunOptions::default(),
            &mut |_| {},
        )
        .expect("the demo runs"),
    );
    let child = Command::new(env!("CARGO_BIN_EXE_penelope"))
        .args(["bench", "layout", "--json", "--layouts", &LAYOUTS.join(",")])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("penelope starts");
    let pid = child.id();
    let output = child.wait_with_output().expect("penelope runs");
    // Everything it made is gone, whatever happened.
    assert_eq!(namespaces_of(pid), Vec::<String>::new());
    assert!(
        output.status.success(),
        "penelope bench layout failed (hosts are network namespaces: this test needs root and \
         iproute2): {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let records: Vec<serde_json::Value> = String::from_utf8_lossy(&output.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("one JSON record per line"))
        .collect();
    let layouts: Vec<&str> = records
        .iter()
        .map(|r| r["layout"].as_str().unwrap_or_default())
        .collect();
    assert_eq!(layouts, LAYOUTS);
    for r in &records {
        the_layout_does_what_the_demo_does(r, &demo);
    }
}

/// One layout's record against the single-process demo: the same run length, tracking, contact
/// force and display; no fault, nothing dropped; the link measured both ways with nothing
/// refused and the clock offset found; the streams matched sample for sample; latencies
/// measured.
fn the_layout_does_what_the_demo_does(r: &serde_json::Value, demo: &Report) {
    let name = r["layout"].as_str().unwrap_or_default();
    let num = |k: &str| r[k].as_f64().unwrap_or(f64::NAN);
    eprintln!(
        "{name}: tracking {:.3} mm (demo {:.3}), display {:.2}% (demo {:.2}), sensed {:.2} N \
         (demo {:.2}), motion->command p50 {} µs, contact->force p50 {} µs, link {}, \
         streams {}",
        num("tracking_rms_mm"),
        demo.tracking.rms_mm,
        num("display_error_pct"),
        demo.contact.display_error_pct,
        num("sensed_force_n"),
        demo.contact.sensed_force_n,
        r["motion_to_command"]["p50_us"],
        r["contact_to_force"]["p50_us"],
        r["link"],
        r["streams"],
    );
    assert!((num("duration_s") - 20.0).abs() < 0.01, "{name}: {r}");
    // Tracking: the same sub-millimetre class as the demo (real clock, several processes).
    assert!(
        num("tracking_rms_mm") <= 2.0 * demo.tracking.rms_mm + 0.1,
        "{name}: {r}"
    );
    // Force: the same contact, displayed as faithfully.
    assert!(
        (num("sensed_force_n") - demo.contact.sensed_force_n).abs()
            <= 0.1 * demo.contact.sensed_force_n,
        "{name}: {r}"
    );
    assert!(
        (num("display_error_pct") - demo.contact.display_error_pct).abs() <= 2.0,
        "{name}: {r}"
    );
    // Nothing faulted; every tick was recorded; latencies were measured.
    let events = r["safety_events"].as_object().expect("events");
    assert!(
        !events.keys().any(|k| k.ends_with("/faulted")),
        "{name}: {events:?}"
    );
    assert_eq!(r["dropped_ticks"], serde_json::json!([0, 0]), "{name}");
    // The link: measured both ways, nothing refused or lost, and the clock estimate right
    // (the hosts share the machine's clock: the true offset is zero).
    let link = &r["link"];
    for way in ["master_to_slave", "slave_to_master"] {
        assert!(
            link[way]["trips"].as_u64().unwrap_or(0) > 5000,
            "{name} {way}: {link}"
        );
    }
    assert_eq!(link["refused"], 0, "{name}: {link}");
    // (A stall of two communication periods on a shared machine is a lost link, held
    // safely and counted: `losses` is reported, not required to be zero.)
    let offset = link["clock_offset_us"]
        .as_f64()
        .expect("an offset estimate");
    assert!(offset.abs() < 100.0, "{name}: clock offset {offset} µs");
    // The data plane as both hosts recorded it (`/streams/...`): every sample one host
    // took is one the other recorded as sent, to the last bit, and the recorders lost none.
    for way in ["master_to_slave", "slave_to_master"] {
        let s = &r["streams"][way];
        let n = |k: &str| s[k].as_u64().unwrap_or(u64::MAX);
        assert!(
            n("taken") > 5000 && n("taken") <= n("sent"),
            "{name} {way}: {s}"
        );
        assert_eq!(n("matched"), n("taken"), "{name} {way}: {s}");
        assert_eq!(n("recorder_dropped"), 0, "{name} {way}: {s}");
    }
    for key in ["motion_to_command", "contact_to_force", "udp_echo_one_way"] {
        assert!(
            r[key]["samples"].as_u64().unwrap_or(0) > 1000,
            "{name} {key}: {r}"
        );
    }
    // Event-driven handoff (the default): each sample is used by the first tick of the
    // receiving loop after it crossed, so the median is at its limit (the data plane's trip
    // plus the wait for that tick). Generous: 1.00 measured on a loaded 2-core machine, 1.0
    // to 16 with `handoff = "periodic"`.
    for key in ["motion_to_command", "contact_to_force"] {
        let e = &r[key];
        eprintln!(
            "{name} {key}: p50/p99 {}/{} µs, limit {}/{} µs, ratio {}/{}",
            e["p50_us"],
            e["p99_us"],
            e["limit"]["p50_us"],
            e["limit"]["p99_us"],
            e["ratio_p50"],
            e["ratio_p99"]
        );
        assert_eq!(e["limit"]["samples"], e["samples"], "{name} {key}: {e}");
        let ratio = e["ratio_p50"].as_f64().unwrap_or(f64::NAN);
        assert!((0.5..=2.0).contains(&ratio), "{name} {key}: {e}");
    }
    // Tick phase: the slave's loop ticks half a period (of 1 ms) after the master's on the
    // common clock, so the median sample of either direction waits about half a period for
    // its receiving tick (the transport and the offset estimate's error add microseconds; a
    // sample that misses its tick waits a period more). Without the phase the two medians were
    // whatever phase the loops started with, adding up to one period (743 and 257 µs, say).
    for key in ["motion_to_command", "contact_to_force"] {
        let p50 = r[key]["p50_us"].as_f64().unwrap_or(f64::NAN);
        assert!(
            (300.0..=700.0).contains(&p50),
            "{name} {key}: p50 {p50} µs, not half a period: {}",
            r[key]
        );
    }
}
