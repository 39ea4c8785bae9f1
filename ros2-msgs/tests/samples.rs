//! One sample of every message type, encoded by this crate, committed as
//! `tests/data/samples.jsonl` (type, RIHS01 hash, schema text, CDR in hex) for the independent
//! check in `python/tests/test_ros2_profile.py`: `rosbags` decodes each to the values written
//! there, re-encodes it to the same bytes, and computes the same hash. This test keeps the
//! file equal to what the encoder writes now (`PENELOPE_BLESS=1` rewrites it).

use penelope_ros2_msgs::*;

fn header(sec: i32, nanosec: u32, frame: &str) -> Header {
    Header {
        stamp: Time { sec, nanosec },
        frame_id: frame.into(),
    }
}

fn v3(x: f64, y: f64, z: f64) -> Vector3 {
    Vector3 { x, y, z }
}

fn q(x: f64, y: f64, z: f64, w: f64) -> Quaternion {
    Quaternion { x, y, z, w }
}

fn world_to_base() -> TransformStamped {
    TransformStamped {
        header: header(11, 12, "world"),
        child_frame_id: "puma/base_link".into(),
        transform: Transform {
            translation: v3(0.0, 1.0, 0.0),
            rotation: q(0.0, 0.0, 0.6, 0.8),
        },
    }
}

fn link_warn() -> DiagnosticStatus {
    DiagnosticStatus {
        level: DiagnosticStatus::WARN,
        name: "link: link".into(),
        message: "up; lost 1 times, restored 1 times".into(),
        hardware_id: String::new(),
        values: vec![
            KeyValue {
                key: "round_trip_ns".into(),
                value: "250000".into(),
            },
            KeyValue {
                key: "clock_offset_ns".into(),
                value: String::new(),
            },
        ],
    }
}

fn line<M: RosMessage>(message: &M) -> String {
    let hex: String = message
        .to_cdr()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    let schema = M::schema_text().replace('\\', "\\\\").replace('\n', "\\n");
    format!(
        "{{\"type\": \"{}\", \"hash\": \"{}\", \"schema\": \"{schema}\", \"cdr\": \"{hex}\"}}\n",
        M::TYPE_NAME,
        M::type_hash()
    )
}

fn samples() -> String {
    [
        line(&Time {
            sec: 1_700_000_000,
            nanosec: 123_456_789,
        }),
        line(&header(5, 6, "puma/base_link")),
        line(&Point {
            x: 1.5,
            y: -2.25,
            z: 3.125,
        }),
        line(&q(0.5, -0.5, 0.5, 0.5)),
        line(&v3(0.1, 0.2, 0.3)),
        line(&Pose {
            position: Point {
                x: 1.0,
                y: 2.0,
                z: 3.0,
            },
            orientation: q(0.0, 0.0, 0.0, 1.0),
        }),
        line(&PoseStamped {
            header: header(7, 8, "world"),
            pose: Pose {
                position: Point {
                    x: 0.4,
                    y: 0.5,
                    z: 0.6,
                },
                orientation: q(0.0, 0.0, 1.0, 0.0),
            },
        }),
        line(&Wrench {
            force: v3(1.0, 2.0, 3.0),
            torque: v3(-1.0, -2.0, -3.0),
        }),
        line(&WrenchStamped {
            header: header(9, 10, "puma/sensor"),
            wrench: Wrench {
                force: v3(0.5, 0.0, -9.81),
                torque: v3(0.01, 0.02, 0.03),
            },
        }),
        line(&Transform {
            translation: v3(1.0, 0.0, 0.0),
            rotation: q(0.0, 0.0, 0.0, 1.0),
        }),
        line(&world_to_base()),
        line(&JointState {
            header: header(13, 14, ""),
            name: vec!["j1".into(), "j2".into(), "joint_three".into()],
            position: vec![0.1, -0.2, 0.3],
            velocity: vec![1.0, 2.0, 3.0],
            effort: vec![],
        }),
        line(&Joy {
            header: header(15, 16, "pedals"),
            axes: vec![0.5, -1.0],
            buttons: vec![0, 1, 1],
        }),
        line(&CompressedImage {
            header: header(23, 24, "camera_optical"),
            format: "jpeg".into(),
            data: vec![0xff, 0xd8, 0xff, 0xe0, 0x00, 0x10, 0xff, 0xd9],
        }),
        line(&RegionOfInterest {
            x_offset: 1,
            y_offset: 2,
            height: 3,
            width: 4,
            do_rectify: true,
        }),
        line(&CameraInfo::pinhole(
            header(25, 26, "camera_optical"),
            640,
            480,
            [500.0, 510.0],
            [320.5, 240.25],
        )),
        line(&TFMessage {
            transforms: vec![
                world_to_base(),
                TransformStamped {
                    header: header(17, 18, "puma/base_link"),
                    child_frame_id: "puma/link1".into(),
                    transform: Transform {
                        translation: v3(0.0, 0.0, 0.5),
                        rotation: q(0.6, 0.0, 0.0, 0.8),
                    },
                },
            ],
        }),
        line(&KeyValue {
            key: "lost".into(),
            value: "3".into(),
        }),
        line(&link_warn()),
        line(&DiagnosticArray {
            header: header(19, 20, ""),
            status: vec![
                link_warn(),
                DiagnosticStatus {
                    level: DiagnosticStatus::ERROR,
                    name: "b: link".into(),
                    message: "down".into(),
                    hardware_id: "hw".into(),
                    values: vec![],
                },
            ],
        }),
        line(&OperatingState {
            header: header(21, 22, ""),
            state: OperatingState::ENABLED.into(),
            is_homed: true,
            is_busy: false,
        }),
    ]
    .concat()
}

#[test]
fn the_committed_samples_are_what_the_encoder_writes() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/samples.jsonl");
    let now = samples();
    assert_eq!(now.lines().count(), ALL_TYPES.len(), "one sample per type");
    if std::env::var_os("PENELOPE_BLESS").is_some() {
        std::fs::write(&path, &now).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap();
    assert_eq!(
        committed, now,
        "tests/data/samples.jsonl is stale: PENELOPE_BLESS=1 rewrites it"
    );
}
