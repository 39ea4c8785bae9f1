//! `penelope experiment sync` as a test, on the four-host layout (hosts are network namespaces:
//! runs as root, as CI does; without namespaces it fails loudly): with 20 ms of added one-way
//! delay on the camera's link only, a view that aligns each frame with the force sample of its
//! capture instant is left with under one frame period of skew at p99, while the skew an
//! unaligned view lives with grows by the 20 ms against the same layout without the delay.

use std::process::Command;

use serde_json::Value;

/// Runs the four-host layout with `delay_ms` on the camera's link; its JSON record.
fn sync_run(delay_ms: f64, out: &std::path::Path) -> Value {
    let output = Command::new(env!("CARGO_BIN_EXE_penelope"))
        .args(["experiment", "sync", "--layouts", "4-host", "--json"])
        .args(["--camera-delay", &delay_ms.to_string()])
        .arg("--out")
        .arg(out)
        .output()
        .expect("penelope runs");
    assert!(
        output.status.success(),
        "penelope experiment sync failed (hosts are network namespaces: this test needs root \
         and iproute2): {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let text = String::from_utf8_lossy(&output.stdout);
    let line = text.lines().next().expect("one JSON record");
    serde_json::from_str(line).expect("a JSON record")
}

fn ms(record: &Value, figure: &str, at: &str) -> f64 {
    record[figure][at]
        .as_f64()
        .unwrap_or_else(|| panic!("{figure}.{at}"))
        / 1e3
}

#[test]
fn aligned_views_keep_video_and_force_within_a_frame_while_unaligned_ones_show_the_cameras_delay() {
    let out = std::env::temp_dir().join(format!("penelope-sync-test-{}", std::process::id()));
    let delayed = sync_run(20.0, &out.join("delayed"));
    let direct = sync_run(0.0, &out.join("direct"));
    for (name, r) in [("+20 ms", &delayed), ("+0 ms", &direct)] {
        println!(
            "{name}: {} frames at {:.1} fps ({} lost); video p50 {:.1} ms p99 {:.1} ms; force \
             p50 {:.2} ms; unaligned skew p50 {:.1} ms p99 {:.1} ms; aligned residual p50 \
             {:.2} ms p99 {:.2} ms max {:.2} ms; overruns {}",
            r["frames"],
            r["fps_received"].as_f64().unwrap(),
            r["frames_dropped"].as_u64().unwrap() + r["frames_missing"].as_u64().unwrap(),
            ms(r, "video_latency", "p50_us"),
            ms(r, "video_latency", "p99_us"),
            ms(r, "force_latency", "p50_us"),
            ms(r, "unaligned_skew", "p50_us"),
            ms(r, "unaligned_skew", "p99_us"),
            ms(r, "aligned_residual", "p50_us"),
            ms(r, "aligned_residual", "p99_us"),
            ms(r, "aligned_residual", "max_us"),
            r["overruns"]
        );
        let fps = r["fps"].as_f64().unwrap();
        let frame_period_ms = 1e3 / fps;
        // The camera kept its rate to the operator's host: the task is 20 s.
        assert!(
            r["frames"].as_u64().unwrap() as f64 >= 0.8 * 20.0 * fps,
            "{name}: {} frames",
            r["frames"]
        );
        // The force reached the master within a few periods: the samples were matched.
        assert!(
            r["force_latency"]["samples"].as_u64().unwrap() > 100,
            "{name}"
        );
        assert!(ms(r, "force_latency", "p50_us") < 5.0, "{name}");
        // Aligned: under one frame period at p99.
        assert!(
            ms(r, "aligned_residual", "p99_us") < frame_period_ms,
            "{name}: aligned residual p99 {:.2} ms against a frame period of {frame_period_ms:.1} ms",
            ms(r, "aligned_residual", "p99_us")
        );
        assert!(
            r["aligned_residual"]["samples"].as_u64().unwrap()
                >= r["frames"].as_u64().unwrap() * 9 / 10
        );
    }
    // Unaligned: the eye lags the hand by the camera's own latency (exposure, readout, the
    // rendering) and, with the delay, 20 ms more.
    let grown = ms(&delayed, "unaligned_skew", "p50_us") - ms(&direct, "unaligned_skew", "p50_us");
    println!("the unaligned skew's median grew by {grown:.1} ms with 20 ms on the camera's link");
    // Not less than the delay less a few ms of scheduling; not more than the delay plus what a
    // busy machine adds (the camera's thread late to a frame's readout, a render taking longer).
    assert!(
        (15.0..=35.0).contains(&grown),
        "the unaligned skew's median grew by {grown:.1} ms, not about 20"
    );
    assert!(ms(&delayed, "unaligned_skew", "p50_us") > 20.0);
    let _ = std::fs::remove_dir_all(&out);
}
