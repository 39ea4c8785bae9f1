//! Cameras: each camera's frames on `/<camera>/image` (`foxglove.CompressedImage`), its
//! optics on `/<camera>/calibration` (`foxglove.CameraCalibration`), the force of the robot
//! it watches drawn on the frame on `/<camera>/annotations` (`foxglove.ImageAnnotations`: an
//! arrow at the tool and a text with the skew), and that force sample on `/<camera>/force`
//! (`penelope.AlignedForce`). Every one is stamped with the frame's capture instant on the
//! common clock, and the force is the sample measured at that instant
//! ([`SampleHistory::at`]), so Foxglove's Image panel draws each frame with its own force,
//! whatever the frame's delay.
//!
//! A reader follows the camera's frames; a helper thread of it follows the telemetry of the
//! robot the camera's model names (every tick, on the common clock with the offset its node
//! sends with each batch). The haptic display is never delayed: only this view is aligned.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use penelope_protocol::client::Client;
use penelope_protocol::client::sync::{
    Aligned, ForceSample, FrameFigures, Match, SampleHistory, describe_skew, force_arrow,
};
use penelope_protocol::proto::{CameraFrame, CameraModelMsg, PoseMsg, TelemetryRecord};
use penelope_scene::{CameraCalibration, CompressedImage, Timestamp};
use serde_json::{Value, json};

/// The aligned force sample's schema.
pub const ALIGNED_FORCE: &str = "penelope.AlignedForce";
/// Its JSON Schema.
pub const ALIGNED_FORCE_SCHEMA: &str = r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"penelope.AlignedForce","description":"The force and tool position of the robot a camera watches, measured at a frame's capture instant (interpolated between the two samples around it), stamped with that instant on the common clock; with the residual skew (the nearest measurement less the capture instant) and the newest sample's skew (what an unaligned view would show).","type":"object","properties":{"timestamp":{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}},"frame_seq":{"type":"integer"},"robot":{"type":"string"},"force":{"type":"array","items":{"type":"number"},"description":"N, the robot's base frame"},"torque":{"type":"array","items":{"type":"number"}},"tool_position":{"type":"array","items":{"type":"number"},"description":"m, the robot's base frame"},"how":{"type":"string","description":"interpolated, nearest, newest or oldest"},"residual_skew_ms":{"type":"number"},"unaligned_skew_ms":{"type":["number","null"]},"video_latency_ms":{"type":"number"},"operator_skew_ms":{"type":["number","null"],"description":"video latency less the force's: how far the picture is behind the hand"}},"required":["timestamp","force","tool_position","residual_skew_ms"]}"#;
/// How long the force arrow is drawn in the robot's world: 1 cm per newton, as on `/scene`.
pub const ARROW_METRES_PER_NEWTON: f64 = 0.01;
/// How often the tool's orientation is read (the wrist sensor's force is in the tool's frame;
/// the arrow is drawn in the base frame, turned by an orientation at most this old).
pub const TOOL_POSE_PERIOD: Duration = Duration::from_millis(200);
/// How long a frame waits for the samples of its capture instant to arrive.
const WAIT_FOR_SAMPLES: Duration = Duration::from_millis(100);

/// A camera's topics, by the camera's name.
pub fn topics(camera: &str) -> [(String, &'static str, &'static str); 4] {
    let schema = |name| penelope_scene::schema(name).unwrap_or("{}");
    [
        (
            format!("/{camera}/image"),
            penelope_scene::COMPRESSED_IMAGE,
            schema(penelope_scene::COMPRESSED_IMAGE),
        ),
        (
            format!("/{camera}/calibration"),
            penelope_scene::CAMERA_CALIBRATION,
            schema(penelope_scene::CAMERA_CALIBRATION),
        ),
        (
            format!("/{camera}/annotations"),
            penelope_scene::IMAGE_ANNOTATIONS,
            schema(penelope_scene::IMAGE_ANNOTATIONS),
        ),
        (
            format!("/{camera}/force"),
            ALIGNED_FORCE,
            ALIGNED_FORCE_SCHEMA,
        ),
    ]
}

/// A frame as `foxglove.CompressedImage`, stamped with its capture instant.
pub fn image(frame: &CameraFrame) -> CompressedImage {
    CompressedImage {
        timestamp: Timestamp::from_ns(frame.capture_ns),
        frame_id: frame.model.frame_id.clone(),
        data: frame.data.clone(),
        format: frame.encoding.name().to_string(),
    }
}

/// A camera's optics as `foxglove.CameraCalibration` (no distortion: the image is a pinhole's).
pub fn calibration(model: &CameraModelMsg, time_ns: u64) -> CameraCalibration {
    CameraCalibration::pinhole(
        Timestamp::from_ns(time_ns),
        model.frame_id.clone(),
        (model.width, model.height),
        [model.fx, model.fy],
        [model.cx, model.cy],
    )
}

fn ms(ns: i64) -> f64 {
    ns as f64 * 1e-6
}

fn point(p: [f64; 2]) -> Value {
    json!({ "x": p[0], "y": p[1] })
}

/// The annotations of a frame (`foxglove.ImageAnnotations`), stamped with its capture instant:
/// the aligned force as an arrow at the tool (a line and a two-stroke head) with its magnitude,
/// and a text with the operator's skew.
pub fn annotations(
    frame: &CameraFrame,
    aligned: Option<&Aligned>,
    figures: &FrameFigures,
) -> Value {
    let stamp = Timestamp::from_ns(frame.capture_ns);
    let yellow = json!({ "r": 1.0, "g": 0.83, "b": 0.0, "a": 1.0 });
    let dark = json!({ "r": 0.0, "g": 0.0, "b": 0.0, "a": 0.6 });
    let white = json!({ "r": 1.0, "g": 1.0, "b": 1.0, "a": 1.0 });
    let mut points = Vec::new();
    let mut circles = Vec::new();
    let mut texts = vec![json!({
        "timestamp": stamp,
        "position": point([8.0, 22.0]),
        "text": figures.operator_skew_ns.map_or_else(|| "no force yet".to_string(), describe_skew),
        "font_size": 18.0,
        "text_color": white,
        "background_color": dark,
    })];
    let arrow = aligned.and_then(|a| force_arrow(&frame.model, &a.sample, ARROW_METRES_PER_NEWTON));
    if let Some(arrow) = arrow {
        let [x0, y0] = arrow.tool_px;
        let [x1, y1] = arrow.tip_px;
        let angle = (y1 - y0).atan2(x1 - x0);
        let head = |side: f64| {
            [
                x1 - 14.0 * (angle + side).cos(),
                y1 - 14.0 * (angle + side).sin(),
            ]
        };
        points.push(json!({
            "timestamp": stamp,
            "type": 4,
            "points": [point([x0, y0]), point([x1, y1]), point([x1, y1]), point(head(0.45)),
                       point([x1, y1]), point(head(-0.45))],
            "outline_color": yellow,
            "outline_colors": [],
            "fill_color": yellow,
            "thickness": 4.0,
        }));
        circles.push(json!({
            "timestamp": stamp,
            "position": point(arrow.tool_px),
            "diameter": 10.0,
            "thickness": 2.0,
            "fill_color": { "r": 0.0, "g": 0.0, "b": 0.0, "a": 0.0 },
            "outline_color": yellow,
        }));
        texts.push(json!({
            "timestamp": stamp,
            "position": point([x1 + 8.0, y1]),
            "text": format!("{:.1} N", arrow.magnitude_n),
            "font_size": 16.0,
            "text_color": yellow,
            "background_color": dark,
        }));
    }
    json!({ "timestamp": stamp, "circles": circles, "points": points, "texts": texts })
}

/// The sample aligned to a frame (`penelope.AlignedForce`), stamped with its capture instant.
pub fn aligned_force(
    frame: &CameraFrame,
    robot: &str,
    aligned: &Aligned,
    figures: &FrameFigures,
) -> Value {
    let how = match aligned.how {
        Match::Interpolated => "interpolated",
        Match::Nearest => "nearest",
        Match::Newest => "newest",
        Match::Oldest => "oldest",
    };
    json!({
        "timestamp": Timestamp::from_ns(frame.capture_ns),
        "frame_seq": frame.seq,
        "robot": robot,
        "force": aligned.sample.wrench.force,
        "torque": aligned.sample.wrench.torque,
        "tool_position": aligned.sample.tool_position,
        "how": how,
        "residual_skew_ms": ms(aligned.skew_ns),
        "unaligned_skew_ms": figures.unaligned_skew_ns.map(ms),
        "video_latency_ms": ms(figures.video_latency_ns),
        "operator_skew_ms": figures.operator_skew_ns.map(ms),
    })
}

/// The force samples of the robot a camera watches, filled by a thread of their own.
pub struct RobotSamples {
    history: Arc<Mutex<SampleHistory>>,
    stop: Arc<AtomicBool>,
    reader: Option<std::thread::JoinHandle<()>>,
}

impl RobotSamples {
    /// Follows the robot at `path` (every tick) until dropped, its times made common with the
    /// offset its node sends; the subscription is asked again after a failure, while not
    /// stopped.
    pub fn follow(client: Client, path: String) -> Self {
        let history = Arc::new(Mutex::new(SampleHistory::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let (h, s) = (history.clone(), stop.clone());
        let reader = std::thread::Builder::new()
            .name("fox-cam-force".into())
            .spawn(move || {
                while !s.load(Ordering::Acquire) {
                    let Ok(mut stream) = client.subscribe(&path, 1) else {
                        pause(&s);
                        continue;
                    };
                    while !s.load(Ordering::Acquire) {
                        match stream.recv_timeout(Duration::from_millis(200)) {
                            Ok(Some(r)) => push(&h, &r, stream.common_offset_ns()),
                            Ok(None) => {}
                            Err(_) => break,
                        }
                    }
                }
            })
            .ok();
        RobotSamples {
            history,
            stop,
            reader,
        }
    }

    /// The sample at a frame's capture instant (after waiting, bounded, for the samples to
    /// reach it) and the newest.
    pub fn for_frame(&self, capture_ns: u64) -> (Option<Aligned>, Option<Aligned>) {
        let deadline = Instant::now() + WAIT_FOR_SAMPLES;
        loop {
            let history = self.history.lock().unwrap_or_else(PoisonError::into_inner);
            let reached = history.newest().is_some_and(|s| s.time_ns >= capture_ns);
            if reached || Instant::now() >= deadline || self.stop.load(Ordering::Acquire) {
                return (history.at(capture_ns), history.newest_for(capture_ns));
            }
            drop(history);
            std::thread::sleep(Duration::from_millis(2));
        }
    }
}

impl Drop for RobotSamples {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(r) = self.reader.take() {
            let _ = r.join();
        }
    }
}

fn push(history: &Mutex<SampleHistory>, r: &TelemetryRecord, offset_ns: i64) {
    let sample = ForceSample::from_record(r, offset_ns);
    history
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .push(sample);
}

fn pause(stop: &AtomicBool) {
    let until = Instant::now() + Duration::from_secs(1);
    while !stop.load(Ordering::Acquire) && Instant::now() < until {
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The samples' sensed force (in the tool's frame) turned into the base frame by the tool's
/// orientation, read from the robot at `robot_path` at most every [`TOOL_POSE_PERIOD`] (`tool`
/// keeps the last); as they are when it cannot be read.
pub fn in_base(
    client: &Client,
    robot_path: Option<&str>,
    tool: &mut Option<(Instant, PoseMsg)>,
    aligned: Option<Aligned>,
    newest: Option<Aligned>,
) -> (Option<Aligned>, Option<Aligned>) {
    if let Some(path) = robot_path
        && tool
            .as_ref()
            .is_none_or(|(at, _)| at.elapsed() >= TOOL_POSE_PERIOD)
        && let Ok(pose) = client.robot(path).and_then(|r| r.forward_kinematics(None))
    {
        *tool = Some((Instant::now(), PoseMsg::from(&pose)));
    }
    let turn = |a: Option<Aligned>| match (a, tool.as_ref()) {
        (Some(mut a), Some((_, pose))) => {
            a.sample = a.sample.in_base(pose);
            Some(a)
        }
        (a, _) => a,
    };
    (turn(aligned), turn(newest))
}

/// One frame's figures: displayed (handed to the Foxglove clients) at `display_ns` on the
/// common clock, the hand feeling the newest sample (master and slave on one node; the web
/// page's camera socket takes the master's loop and link when given).
pub fn figures(
    display_ns: u64,
    frame: &CameraFrame,
    aligned: Option<&Aligned>,
    newest: Option<&Aligned>,
) -> FrameFigures {
    FrameFigures::of(
        display_ns,
        frame.capture_ns,
        newest.map(|n| n.sample.time_ns),
        aligned,
        newest,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use penelope_protocol::proto::{ImageEncoding, PoseMsg, WrenchMsg};

    fn frame() -> CameraFrame {
        CameraFrame {
            seq: 7,
            capture_ns: 5_250_000_123,
            ready_ns: 5_260_000_000,
            sent_ns: 5_270_000_000,
            encoding: ImageEncoding::Jpeg,
            data: vec![0xff, 0xd8, 0xff, 0xd9],
            model: CameraModelMsg {
                frame_id: "cam_optical".into(),
                width: 640,
                height: 480,
                fx: 500.0,
                fy: 500.0,
                cx: 320.0,
                cy: 240.0,
                pose_in_robot_base: Some(PoseMsg {
                    position: [2.0, 0.0, 0.0],
                    n: [0.0, 1.0, 0.0],
                    o: [0.0, 0.0, -1.0],
                    a: [-1.0, 0.0, 0.0],
                }),
                robot: Some("slave".into()),
            },
        }
    }

    /// Every key of `value` is a property of `schema` (recursively through objects and
    /// arrays of objects), and every required one is there.
    fn conforms(value: &Value, schema: &Value, at: &str) {
        if let (Some(obj), Some(props)) = (value.as_object(), schema["properties"].as_object()) {
            for (k, v) in obj {
                let sub = props
                    .get(k)
                    .unwrap_or_else(|| panic!("{at}.{k}: not in the schema"));
                conforms(v, sub, &format!("{at}.{k}"));
            }
            for r in schema["required"].as_array().into_iter().flatten() {
                assert!(obj.contains_key(r.as_str().unwrap()), "{at}: lacks {r}");
            }
        }
        if let (Some(items), Some(item_schema)) = (value.as_array(), schema.get("items")) {
            for v in items {
                conforms(v, item_schema, &format!("{at}[]"));
            }
        }
    }

    #[test]
    fn a_frames_annotations_carry_its_capture_stamp_and_the_arrow_at_the_tool() {
        let f = frame();
        let aligned = Aligned {
            sample: ForceSample {
                time_ns: f.capture_ns,
                tool_position: [0.0; 3],
                wrench: WrenchMsg {
                    force: [0.0, 3.0, 4.0],
                    torque: [0.0; 3],
                },
            },
            skew_ns: -400_000,
            how: Match::Interpolated,
        };
        let figures = FrameFigures::of(
            f.capture_ns + 62_000_000,
            f.capture_ns,
            Some(f.capture_ns + 61_000_000),
            Some(&aligned),
            None,
        );
        let a = annotations(&f, Some(&aligned), &figures);
        let schema: Value = serde_json::from_str(
            penelope_scene::schema(penelope_scene::IMAGE_ANNOTATIONS).unwrap(),
        )
        .unwrap();
        conforms(&a, &schema, "annotations");
        assert_eq!(a["timestamp"], json!({ "sec": 5, "nsec": 250_000_123 }));
        assert_eq!(a["points"][0]["timestamp"], a["timestamp"]);
        assert_eq!(
            a["points"][0]["points"][0],
            json!({ "x": 320.0, "y": 240.0 })
        );
        assert_eq!(a["texts"][0]["text"], "video 61 ms behind the hand");
        assert_eq!(a["texts"][1]["text"], "5.0 N");
        let force = aligned_force(&f, "slave", &aligned, &figures);
        conforms(
            &force,
            &serde_json::from_str(ALIGNED_FORCE_SCHEMA).unwrap(),
            "force",
        );
        assert!((force["residual_skew_ms"].as_f64().unwrap() + 0.4).abs() < 1e-9);
        let image = serde_json::to_value(image(&f)).unwrap();
        assert_eq!(image["timestamp"], a["timestamp"]);
        assert_eq!(image["format"], "jpeg");
        let cal = serde_json::to_value(calibration(&f.model, f.capture_ns)).unwrap();
        assert_eq!(cal["K"][0], 500.0);
        assert_eq!(cal["P"][6], 240.0);
        // No force known: only the text.
        let bare = annotations(&f, None, &FrameFigures::of(1, 0, None, None, None));
        assert_eq!(bare["points"], json!([]));
        assert_eq!(bare["texts"][0]["text"], "no force yet");
    }
}
