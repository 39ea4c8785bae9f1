//! `penelope camera probe` without a camera: a missing node and a node that is not V4L2 exit 1
//! with the typed error's message, and bad input exits 2. (Against a real device:
//! drivers/tests/v4l2_device.rs, with PENELOPE_CAMERA.)

use penelope_testkit::process::Penelope;

/// The binary under test.
const PENELOPE: Penelope = Penelope::at(env!("CARGO_BIN_EXE_penelope"));

fn probe(args: &[&str]) -> (Option<i32>, String) {
    let out = PENELOPE
        .command()
        .args(["camera", "probe"])
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn camera_probe_of_a_missing_node_says_no_such_device() {
    let (code, stderr) = probe(&["/dev/penelope-no-such-video-node"]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("no such device"), "{stderr}");
}

#[test]
fn camera_probe_of_a_node_that_is_not_v4l2_says_so() {
    let (code, stderr) = probe(&["/dev/null"]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("not a streaming video capture device"),
        "{stderr}"
    );
}

#[test]
fn camera_probe_with_too_many_frames_is_a_usage_error() {
    let (code, stderr) = probe(&["/dev/video0", "--frames", "20000"]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("--frames"), "{stderr}");
}
