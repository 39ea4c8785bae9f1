//! `penelope experiment delay` from the command line: the stability map of issue 14 on the
//! simulated clock. Each run is the demo's 20-second task (about 1.5 s of wall time).

use std::path::PathBuf;

use penelope_testkit::process::Penelope;
use serde_json::Value;

/// The binary under test.
const PENELOPE: Penelope = Penelope::at(env!("CARGO_BIN_EXE_penelope"));

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "penelope-experiment-delay-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Runs the experiment with `args` and `--json --out DIR`; its `runs`.
fn experiment(args: &[&str], out: &PathBuf) -> Vec<Value> {
    let output = PENELOPE
        .command()
        .args(["experiment", "delay", "--json", "--out"])
        .arg(out)
        .args(args)
        .output()
        .expect("penelope runs");
    assert!(
        output.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let json: Value = serde_json::from_slice(&output.stdout).expect("--json prints JSON");
    json["runs"].as_array().expect("a list `runs`").clone()
}

fn find<'a>(runs: &'a [Value], law: &str, delay_ms: f64) -> &'a Value {
    runs.iter()
        .find(|r| r["law"] == law && r["delay_ms"].as_f64() == Some(delay_ms))
        .unwrap_or_else(|| panic!("no run of {law} at {delay_ms} ms in {runs:#?}"))
}

#[test]
fn without_delay_every_law_is_stable_and_with_delay_force_position_is_not_and_waves_and_tdpa_are() {
    let out = scratch("map");
    let runs = experiment(&["--delays", "0,10,200ms", "--jobs", "2"], &out);
    assert_eq!(runs.len(), 12, "four laws at three delays");
    for r in &runs {
        println!(
            "{} at {} ms round trip: stable {} (growth {:.2}, ripple {:.2}, rest {:.2} mm, \
             tracking RMS {:.3} mm max {:.3} mm, faults {}) {}",
            r["law"],
            r["delay_ms"],
            r["stable"],
            r["energy_growth"].as_f64().unwrap(),
            r["contact_ripple"].as_f64().unwrap(),
            r["rest_motion_mm"].as_f64().unwrap(),
            r["tracking_rms_mm"].as_f64().unwrap(),
            r["tracking_max_mm"].as_f64().unwrap(),
            r["faults"],
            r["reasons"]
        );
        assert_eq!(
            r["one_way_ms"].as_f64(),
            r["delay_ms"].as_f64().map(|d| d / 2.0)
        );
        // Every law's channel is observed on both sides (the live stability monitor): the
        // two-port observers, or the wave line's reserve, which cannot go below zero.
        for side in ["master_channel_min_j", "slave_channel_min_j"] {
            let e = r[side]
                .as_f64()
                .unwrap_or_else(|| panic!("{} has no {side}: {r:#}", r["law"]));
            if r["law"] == "wave" {
                assert!(e >= 0.0, "the wave line's reserve at {side}: {e} J");
            }
        }
    }
    // Zero delay: the demo's bounds (supervisor/tests/demo.rs): free-motion tracking under 2 mm
    // RMS and 5 mm at most, and stable by every criterion.
    for law in ["force-position", "position-error", "wave", "tdpa"] {
        let r = find(&runs, law, 0.0);
        assert_eq!(r["stable"], true, "{law} without delay: {:#}", r["reasons"]);
        assert!(r["tracking_rms_mm"].as_f64().unwrap() < 2.0, "{law}: {r:#}");
        assert!(r["tracking_max_mm"].as_f64().unwrap() < 5.0, "{law}: {r:#}");
    }
    // 200 ms round trip: the plain force-position law is found unstable.
    let r = find(&runs, "force-position", 200.0);
    assert_eq!(
        r["stable"], false,
        "force-position at 200 ms must be detected unstable: {r:#}"
    );
    assert!(!r["reasons"].as_array().unwrap().is_empty());
    // 200 ms round trip: the wave-variable law completes the task, its tapping energy bounded
    // (no growth from cycle to cycle), no fault, no limit cycle.
    let r = find(&runs, "wave", 200.0);
    assert_eq!(r["stable"], true, "wave at 200 ms: {r:#}");
    assert!(r["energy_growth"].as_f64().unwrap() <= 1.0, "{r:#}");
    assert_eq!(r["faults"].as_array().map(Vec::len), Some(0), "{r:#}");
    // 200 ms round trip: time-domain passivity completes it too, and its two-port observer
    // stays bounded where the plain law's does not.
    let r = find(&runs, "tdpa", 200.0);
    assert_eq!(r["stable"], true, "tdpa at 200 ms: {r:#}");
    assert!(r["energy_growth"].as_f64().unwrap() <= 1.0, "{r:#}");
    assert_eq!(r["faults"].as_array().map(Vec::len), Some(0), "{r:#}");
    let plain = find(&runs, "force-position", 200.0);
    for side in ["master_channel_min_j", "slave_channel_min_j"] {
        let (with, without) = (r[side].as_f64().unwrap(), plain[side].as_f64().unwrap());
        println!("{side}: tdpa {with:.4} J, plain {without:.4} J");
        // Held at the ports' allowed initial energy (10 mJ), within a couple of mJ.
        assert!(with > -0.012, "tdpa's observer at {side}: {with} J");
        assert!(
            without < 10.0 * with.min(-1e-3),
            "plain: {without} J, tdpa: {with} J"
        );
    }
    // 10 ms round trip: no fault stops it, but the slave bounces on the wall while the
    // operator holds still (a limit cycle the energy growth alone would miss).
    let r = find(&runs, "force-position", 10.0);
    assert_eq!(r["stable"], false, "force-position at 10 ms: {r:#}");
    assert!(
        r["contact_ripple"].as_f64().unwrap() > 0.25,
        "a limit cycle in steady contact: {r:#}"
    );
    for file in ["runs.json", "stability-map.svg"] {
        assert!(out.join(file).is_file(), "{file} written");
    }
    let _ = std::fs::remove_dir_all(out);
}

#[test]
fn the_same_seed_draws_the_same_jittered_delays_and_verdicts() {
    let (a, b) = (scratch("a"), scratch("b"));
    let args = [
        "--laws",
        "force-position",
        "--delays",
        "20",
        "--jitter",
        "5",
        "--seed",
        "3",
    ];
    let strip = |mut runs: Vec<Value>| {
        for r in &mut runs {
            r.as_object_mut().unwrap().remove("wall_time_s");
        }
        runs
    };
    let first = strip(experiment(&args, &a));
    let second = strip(experiment(&args, &b));
    assert_eq!(first, second, "same seed, same runs");
    assert_eq!(first[0]["jitter_ms"].as_f64(), Some(5.0));
    for d in [a, b] {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[test]
fn bad_options_exit_with_code_two_and_say_why() {
    let out = scratch("bad");
    for args in [
        vec!["--laws", "wave-variables-someday"],
        vec!["--delays", "soon"],
        vec!["--delays", "-10"],
        vec!["--wall-stiffness", "-1"],
        vec!["--jitter", "fast"],
    ] {
        let output = PENELOPE
            .command()
            .args(["experiment", "delay", "--out"])
            .arg(&out)
            .args(&args)
            .output()
            .unwrap();
        assert_eq!(
            output.status.code(),
            Some(2),
            "{args:?}: {}",
            String::from_utf8_lossy(&output.stderr)
        );
        assert!(!output.stderr.is_empty(), "{args:?} explains itself");
    }
    let _ = std::fs::remove_dir_all(out);
}
