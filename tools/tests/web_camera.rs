//! The web page's camera panel, end to end: a node running `config/demo-camera.toml` (the
//! demo's teleoperation with a simulated camera watching the slave), `penelope web` in front of
//! it, and its `/api/camera` socket read as a browser would: every frame comes as a
//! description (capture time, the force and pose sample aligned to it, the live skew figures)
//! followed by its JPEG, the aligned sample's residual skew under a frame period.

use penelope_testkit::net::free_tcp_addr;
use penelope_testkit::process::{Children, Penelope};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::time::{Duration, Instant};

use serde_json::Value;
use tungstenite::Message;

/// The binary under test.
const PENELOPE: Penelope = Penelope::at(env!("CARGO_BIN_EXE_penelope"));
/// Frames read.
const FRAMES: usize = 30;
/// The bound on every wait (a loaded 2-core machine starts a node slowly).
const WAIT: Duration = Duration::from_secs(120);

/// One HTTP/1.1 GET; the body.
fn get(addr: &str, path: &str) -> String {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let req = format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n");
    s.write_all(req.as_bytes()).unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).unwrap();
    text.split_once("\r\n\r\n")
        .map(|(_, b)| b.to_string())
        .unwrap_or_default()
}

fn percentile(values: &mut [f64], p: f64) -> f64 {
    values.sort_by(f64::total_cmp);
    let rank = ((p * values.len() as f64).ceil() as usize).clamp(1, values.len());
    values[rank - 1]
}

#[test]
fn the_camera_socket_sends_frames_with_the_force_of_their_capture_instant() {
    let config = Path::new(env!("CARGO_MANIFEST_DIR")).join("../config/demo-camera.toml");
    let naming = free_tcp_addr().to_string();
    let (node, _) = PENELOPE.start(
        &[
            "node",
            "--name",
            "lab",
            "--host-naming",
            "--listen",
            &naming,
            "--config",
            config.to_str().unwrap(),
            "--priority",
            "0",
        ],
        "Ctrl-C stops the node",
    );
    let mut children = Children(vec![node]);
    let (web, line) = PENELOPE.start(
        &["web", "--naming", &naming, "--listen", "127.0.0.1:0"],
        "penelope web: serving",
    );
    children.0.push(web);
    let addr = line
        .split("http://")
        .nth(1)
        .and_then(|r| r.split('/').next())
        .unwrap()
        .trim()
        .to_string();

    // The camera, once configured (a camera streams from then on; it has no loop to activate).
    let deadline = Instant::now() + WAIT;
    let camera = loop {
        let tree: Value = serde_json::from_str(&get(&addr, "/api/tree")).unwrap_or_default();
        let found = tree["entries"].as_array().and_then(|entries| {
            entries.iter().find(|e| {
                e["class"] == "sensor"
                    && e["kind"].as_str().is_some_and(|k| k.contains("camera"))
                    && (e["state"] == "active" || e["state"] == "inactive")
            })
        });
        if let Some(e) = found {
            break e["path"].as_str().unwrap().to_string();
        }
        assert!(Instant::now() < deadline, "no running camera: {tree}");
        std::thread::sleep(Duration::from_millis(100));
    };

    let url = format!("ws://{addr}/api/camera?path={camera}");
    let connect = || {
        let (ws, _) = tungstenite::connect(url.as_str()).expect("the camera socket");
        if let tungstenite::stream::MaybeTlsStream::Plain(s) = ws.get_ref() {
            s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
        }
        ws
    };
    let mut ws = connect();
    let mut frames: Vec<(Value, Vec<u8>)> = Vec::new();
    let mut pending: Option<Value> = None;
    let mut robot = None;
    let deadline = Instant::now() + WAIT;
    while frames.len() < FRAMES {
        assert!(Instant::now() < deadline, "{} frames only", frames.len());
        match ws.read().expect("the socket stays open") {
            Message::Text(text) => {
                let msg: Value = serde_json::from_str(&text).unwrap();
                match msg["type"].as_str() {
                    Some("frame") => pending = Some(msg),
                    Some("subscribed") => robot = msg["robot"].as_str().map(String::from),
                    // The camera's first frames are yet to come (its thread starting): again.
                    Some("error") if frames.is_empty() => {
                        println!("not yet: {msg}");
                        std::thread::sleep(Duration::from_millis(200));
                        ws = connect();
                    }
                    Some("error") => panic!("the socket failed: {msg}"),
                    _ => {}
                }
            }
            Message::Binary(jpeg) => {
                let description = pending.take().expect("a frame's description before it");
                frames.push((description, jpeg.to_vec()));
            }
            _ => {}
        }
    }
    let _ = ws.close(None);
    assert!(robot.is_some_and(|r| r.contains("/robots/")));

    // Each image is a JPEG of the described size.
    for (d, jpeg) in &frames {
        assert_eq!(&jpeg[..2], &[0xff, 0xd8], "a JPEG");
        assert_eq!(d["bytes"].as_u64(), Some(jpeg.len() as u64));
    }
    // The aligned sample's residual skew is under one frame period.
    let captures: Vec<u64> = frames
        .iter()
        .map(|(d, _)| d["capture_ns"].as_u64().unwrap())
        .collect();
    let mut periods: Vec<f64> = captures
        .windows(2)
        .filter(|w| w[1] > w[0])
        .map(|w| (w[1] - w[0]) as f64 * 1e-6)
        .collect();
    let frame_period_ms = percentile(&mut periods, 0.5);
    // The first frames may be older than the robot's first sample (its subscription opens
    // with the camera's): those say so ("oldest") and are left out, a few at most.
    let leading = frames
        .iter()
        .take_while(|(d, _)| d["aligned"]["how"] == "oldest" || d["aligned"].is_null())
        .count();
    assert!(
        leading <= 5,
        "{leading} frames before the robot's first sample"
    );
    let hows: Vec<&str> = frames[leading..]
        .iter()
        .filter_map(|(d, _)| d["aligned"]["how"].as_str())
        .collect();
    assert!(
        hows.iter().all(|h| *h == "interpolated" || *h == "nearest"),
        "{hows:?}"
    );
    let mut aligned: Vec<f64> = frames[leading..]
        .iter()
        .filter_map(|(d, _)| d["aligned"]["skew_ms"].as_f64())
        .map(f64::abs)
        .collect();
    let mut unaligned: Vec<f64> = frames
        .iter()
        .filter_map(|(d, _)| d["newest"]["skew_ms"].as_f64())
        .map(f64::abs)
        .collect();
    assert_eq!(
        aligned.len(),
        FRAMES - leading,
        "frames without an aligned sample"
    );
    let last = &frames[FRAMES - 1].0;
    println!(
        "{FRAMES} frames ({leading} before the first sample), period {frame_period_ms:.1} ms; \
         aligned residual skew p50 {:.2} ms \
         p99 {:.2} ms; newest sample's skew p50 {:.1} ms; video latency p50 {} ms; {}",
        percentile(&mut aligned, 0.5),
        percentile(&mut aligned, 0.99),
        percentile(&mut unaligned, 0.5),
        last["summary"]["video_latency"]["p50_ms"],
        last["figures"]["text"]
    );
    assert!(percentile(&mut aligned, 0.99) < frame_period_ms);
    // The live skew figure is there, said as the page says it.
    let text = last["figures"]["text"].as_str().unwrap_or_default();
    assert!(text.starts_with("video "), "{last}");
    assert!(last["figures"]["operator_skew_ms"].is_number());
    assert!(last["summary"]["operator_skew"]["p99_ms"].is_number());
    // The force arrow is drawn at the tool's pixel, inside the image.
    let arrows = frames
        .iter()
        .filter(|(d, _)| {
            let tool = &d["aligned"]["arrow"]["tool"];
            let (w, h) = (d["width"].as_f64().unwrap(), d["height"].as_f64().unwrap());
            tool[0].as_f64().is_some_and(|x| (0.0..w).contains(&x))
                && tool[1].as_f64().is_some_and(|y| (0.0..h).contains(&y))
        })
        .count();
    assert!(
        arrows >= FRAMES / 2,
        "{arrows} of {FRAMES} frames have the tool in view"
    );
}
