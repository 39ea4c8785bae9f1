//! `penelope demo` from the command line: files, JSON, reproducibility, bad input.

use penelope_testkit::process::Penelope;
use std::path::{Path, PathBuf};

/// The binary under test.
const PENELOPE: Penelope = Penelope::at(env!("CARGO_BIN_EXE_penelope"));

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("penelope-demo-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn run_sim(out: &Path, seed: u64) -> serde_json::Value {
    let output = PENELOPE
        .command()
        .args([
            "demo",
            "--sim-clock",
            "--duration",
            "13s",
            "--json",
            "--seed",
            &seed.to_string(),
            "--out",
        ])
        .arg(out)
        .output()
        .expect("penelope runs");
    assert!(
        output.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).expect("--json prints the report as JSON")
}

#[test]
fn sim_clock_runs_write_identical_files_for_a_seed_and_different_ones_for_another() {
    let (a, b, c) = (scratch("a"), scratch("b"), scratch("c"));
    let report = run_sim(&a, 3);
    run_sim(&b, 3);
    run_sim(&c, 4);
    assert_eq!(report["clock"], "simulated");
    assert!(report["tracking"]["rms_mm"].as_f64().unwrap() < 2.0);
    for file in [
        "telemetry-master.csv",
        "telemetry-slave.csv",
        "tracking.svg",
        "forces.svg",
        "report.json",
    ] {
        assert!(a.join(file).is_file(), "{file} written");
    }
    let slave = |d: &Path| std::fs::read(d.join("telemetry-slave.csv")).unwrap();
    assert!(slave(&a).len() > 1_000_000, "13 s of 1 kHz telemetry");
    assert_eq!(slave(&a), slave(&b), "same seed, same bytes");
    assert_ne!(slave(&a), slave(&c), "another seed, other sensor noise");
    for d in [a, b, c] {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[test]
fn bad_options_exit_with_code_two_and_say_why() {
    let out = scratch("bad");
    for args in [
        vec!["demo", "--sim-clock", "--scale", "-1"],
        vec!["demo", "--sim-clock", "--duration", "soon"],
        vec!["demo", "--sim-clock", "--config", "/nonexistent/lab.toml"],
    ] {
        let output = PENELOPE
            .command()
            .args(&args)
            .arg("--out")
            .arg(&out)
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
}

#[test]
fn the_kinematics_option_runs_the_master_on_its_fpga_board_and_reports_the_latency() {
    let out = scratch("fpga");
    let output = PENELOPE
        .command()
        .args([
            "demo",
            "--sim-clock",
            "--duration",
            "5s",
            "--kinematics",
            "fpga",
            "--json",
            "--out",
        ])
        .arg(&out)
        .output()
        .expect("penelope runs");
    assert!(
        output.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let k = &report["kinematics"];
    assert_eq!(k["master"], "fpga", "{k}");
    assert_eq!(k["fk_cycles"], 61);
    assert_eq!(k["fk_force_cycles"], 92);
    assert!(k["command_delay_us"].as_f64().unwrap() > 2.3, "{k}");
    assert!(report["tracking"]["rms_mm"].as_f64().unwrap() < 2.0);
    // A word it does not know is a usage error.
    let bad = PENELOPE
        .command()
        .args(["demo", "--sim-clock", "--kinematics", "abacus", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(2));
    let _ = std::fs::remove_dir_all(out);
}
