//! Keeps `docs/zenoh.md` true: its operator pose bytes and its JSON messages are compared with
//! what the bridge's encoder makes of the examples they name, and the key expressions it shows
//! with the ones the code builds.
//!
//! A block is marked by an HTML comment `<!-- zenoh: NAME -->` followed by a fenced block:
//! hex bytes (each line optionally ending in a `# comment`) for `pose`, one line of JSON for the
//! others. Run with `ZENOH_DOC_PRINT=1 -- --nocapture` to print every example.
//! Needs no Zenoh: the encoding is compiled in every build.

use penelope_hal::{
    CartesianReference, HybridReference, Pose, Reference, Timestamp, Twist, Wrench,
};
use penelope_protocol::proto::LinkRecord;
use penelope_rt_core::safety::{EventSet, SafetyEvent, SafetyState};
use penelope_rt_core::telemetry::TelemetrySample;
use penelope_rt_core::teleop::TeleopSample;
use penelope_runtime::objects::tick::TickRecord;
use penelope_supervisor::zenoh_bridge::encoding::{
    self, EVENTS, FEEDBACK, LINK, OperatorPose, PoseError, TELEMETRY, objects_key, stream_key,
};

/// The document, relative to this crate.
const DOC: &str = include_str!("../../docs/zenoh.md");

/// The fenced block after `<!-- zenoh: NAME -->`.
fn block(name: &str) -> String {
    let marker = format!("<!-- zenoh: {name} -->");
    let at = DOC
        .find(&marker)
        .unwrap_or_else(|| panic!("docs/zenoh.md has no {marker}"));
    let rest = &DOC[at + marker.len()..];
    let open = rest.find("```").expect("a fenced block follows the marker");
    let body = &rest[open + 3..];
    let body = &body[body.find('\n').expect("a fence line") + 1..];
    let close = body.find("```").expect("the block is closed");
    body[..close].to_string()
}

/// The bytes of a hex block.
fn hex(block: &str) -> Vec<u8> {
    block
        .lines()
        .map(|l| l.split('#').next().unwrap_or(""))
        .flat_map(str::split_whitespace)
        .map(|b| u8::from_str_radix(b, 16).expect("hex bytes"))
        .collect()
}

fn print(name: &str, text: &str) {
    if std::env::var_os("ZENOH_DOC_PRINT").is_some() {
        println!("<!-- zenoh: {name} -->\n{text}\n");
    }
}

/// The example pose: the clutch released, the tool half a metre ahead, a quarter to the
/// right, a metre up, not rotated.
fn example_pose() -> OperatorPose {
    OperatorPose {
        clutch: false,
        position: [0.5, -0.25, 1.0],
        orientation: [1.0, 0.0, 0.0, 0.0],
    }
}

#[test]
fn the_documented_pose_bytes_are_the_encoders() {
    let bytes = example_pose().encode();
    let text: Vec<String> = bytes
        .chunks(8)
        .map(|c| {
            c.iter()
                .map(|b| format!("{b:02x}"))
                .collect::<Vec<_>>()
                .join(" ")
        })
        .collect();
    print("pose", &text.join("\n"));
    assert_eq!(hex(&block("pose")), bytes.to_vec());
    assert_eq!(OperatorPose::decode(&bytes), Ok(example_pose()));
    // The refused example: one byte short.
    assert_eq!(
        OperatorPose::decode(&hex(&block("pose-short"))),
        Err(PoseError::Length(57))
    );
}

/// A tick of controller `follow` that found its reference stale and went to hold.
fn example_tick() -> TickRecord {
    let mut events = EventSet::default();
    events.insert(SafetyEvent::ReferenceStale);
    TickRecord {
        sample: TelemetrySample {
            time: Timestamp::from_nanos(2_000_000_000),
            seq: 2000,
            state: SafetyState::Holding,
            events,
            ..TelemetrySample::default()
        },
        truth: None,
        clutch: None,
    }
}

#[test]
fn the_documented_event_is_the_encoders() {
    let previous = Some((SafetyState::Running, None));
    let event = encoding::event_message("follow", &example_tick(), previous).expect("an event");
    let event = String::from_utf8(event).unwrap();
    print("event", &event);
    assert_eq!(block("event").trim(), event);
    // Nothing changed, nothing raised: no event.
    let quiet = TickRecord {
        sample: TelemetrySample {
            events: EventSet::default(),
            ..example_tick().sample
        },
        truth: None,
        clutch: None,
    };
    assert!(
        encoding::event_message("follow", &quiet, Some((SafetyState::Holding, None))).is_none()
    );
}

#[test]
fn the_documented_link_record_is_the_encoders() {
    let record = LinkRecord {
        time_ns: 1_000_000_000,
        down: false,
        losses: 0,
        restorations: 0,
        samples_taken: 1234,
        samples_dropped: 0,
        samples_missed: 2,
        refused: 0,
        clock_offset_ns: Some(2500),
        round_trip_ns: Some(60_000),
        one_way_delay_ns: Some(30_000),
        jitter_ns: Some(1000),
        last_heard_ns: Some(400_000),
        heartbeat_loss: 0.0,
        trips: 1234,
        trip_p50_ns: Some(31_000),
        trip_p99_ns: Some(90_000),
        trip_max_ns: None,
    };
    let json = serde_json::to_string(&record).unwrap();
    print("link", &json);
    assert_eq!(block("link").trim(), json);
}

#[test]
fn the_documented_feedback_is_the_encoders() {
    let pose = Pose::translation(0.35, 0.127, 0.33);
    let sample = TeleopSample::new(
        42,
        Timestamp::from_nanos(84_000_000),
        Reference::Hybrid(HybridReference {
            motion: CartesianReference {
                pose,
                twist: Twist::default(),
            },
            wrench: Wrench {
                force: [0.0, 0.0, 2.5].into(),
                ..Wrench::default()
            },
            force_axes: [true; 6],
        }),
    );
    let json = String::from_utf8(encoding::feedback_message(&sample)).unwrap();
    print("feedback", &json);
    assert_eq!(block("feedback").trim(), json);
}

#[test]
fn the_documented_keys_are_the_codes() {
    for (stream, shown) in [
        (TELEMETRY, "penelope/lab/follow/telemetry"),
        (EVENTS, "penelope/lab/follow/events"),
        (LINK, "penelope/lab/link/link"),
        (FEEDBACK, "penelope/lab/link/feedback"),
    ] {
        let object = if shown.contains("/follow/") {
            "follow"
        } else {
            "link"
        };
        assert_eq!(stream_key("lab", object, stream), shown);
        assert!(DOC.contains(shown), "docs/zenoh.md shows {shown}");
    }
    assert!(DOC.contains(&objects_key("lab")));
}
