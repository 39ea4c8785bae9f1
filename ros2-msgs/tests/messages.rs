//! Round trips of every message type, typed errors on bad payloads, and the RIHS01 hashes of
//! a few types against ROS 2's published ones.

use penelope_ros2_msgs::cdr::MAX_LENGTH;
use penelope_ros2_msgs::*;

fn header(ns: u64, frame: &str) -> Header {
    Header {
        stamp: Time::from_ns(ns),
        frame_id: frame.into(),
    }
}

fn transform_stamped() -> TransformStamped {
    TransformStamped {
        header: header(7_000_000_123, "world"),
        child_frame_id: "arm_base".into(),
        transform: Transform {
            translation: Vector3 {
                x: 0.5,
                y: -0.25,
                z: 1.0,
            },
            rotation: Quaternion {
                x: 0.0,
                y: 0.0,
                z: std::f64::consts::FRAC_1_SQRT_2,
                w: std::f64::consts::FRAC_1_SQRT_2,
            },
        },
    }
}

fn joint_state() -> JointState {
    JointState {
        header: header(1_234_567_890_123, ""),
        name: vec!["shoulder".into(), "elbow".into(), "wrist".into()],
        position: vec![0.1, -0.2, 0.3],
        velocity: vec![1.0, 2.0, 3.0],
        effort: vec![],
    }
}

fn diagnostic_array() -> DiagnosticArray {
    DiagnosticArray {
        header: header(5, ""),
        status: vec![DiagnosticStatus {
            level: DiagnosticStatus::WARN,
            name: "link master-slave".into(),
            message: "losses".into(),
            hardware_id: String::new(),
            values: vec![KeyValue {
                key: "lost".into(),
                value: "3".into(),
            }],
        }],
    }
}

fn round_trip<M: RosMessage + PartialEq + std::fmt::Debug>(message: &M) {
    let bytes = message.to_cdr();
    assert_eq!(&bytes[..4], &[0, 1, 0, 0], "{}", M::TYPE_NAME);
    assert_eq!(&M::decode_cdr(&bytes).unwrap(), message, "{}", M::TYPE_NAME);
    // Every truncation is a typed error, never a panic or a silently short message.
    for len in 0..bytes.len() {
        let error = M::decode_cdr(&bytes[..len]).expect_err(M::TYPE_NAME);
        assert!(
            matches!(
                error,
                CdrError::NoHeader { .. } | CdrError::Truncated { .. }
            ),
            "{} cut at {len}: {error}",
            M::TYPE_NAME
        );
    }
}

#[test]
fn every_type_round_trips_and_every_truncation_is_a_typed_error() {
    round_trip(&Time::from_ns(3_000_000_001));
    round_trip(&header(42, "arm_base"));
    round_trip(&Point {
        x: 1.0,
        y: 2.0,
        z: 3.0,
    });
    round_trip(&Quaternion::default());
    round_trip(&PoseStamped {
        header: header(1, "arm_base"),
        pose: Pose {
            position: Point {
                x: 0.1,
                y: 0.2,
                z: 0.3,
            },
            orientation: Quaternion::default(),
        },
    });
    round_trip(&WrenchStamped {
        header: header(2, "arm_tool"),
        wrench: Wrench {
            force: Vector3 {
                x: 1.5,
                y: 0.0,
                z: -9.81,
            },
            torque: Vector3::default(),
        },
    });
    round_trip(&transform_stamped());
    round_trip(&joint_state());
    round_trip(&Joy {
        header: header(3, ""),
        axes: vec![0.5, -1.0],
        buttons: vec![0, 1, 1],
    });
    round_trip(&TFMessage {
        transforms: vec![transform_stamped(), transform_stamped()],
    });
    round_trip(&diagnostic_array());
    round_trip(&CompressedImage {
        header: header(5, "cam_optical"),
        format: "jpeg".into(),
        data: vec![0xff, 0xd8, 1, 2, 3, 0xff, 0xd9],
    });
    let mut info = CameraInfo::pinhole(
        header(6, "cam_optical"),
        640,
        480,
        [500.0; 2],
        [320.0, 240.0],
    );
    info.roi.do_rectify = true;
    round_trip(&info);
    round_trip(&OperatingState {
        header: header(4, ""),
        state: OperatingState::ENABLED.into(),
        is_homed: true,
        is_busy: false,
    });
}

#[test]
fn the_layout_is_cdr_little_endian_with_alignment_after_the_header() {
    // Header{stamp{sec 1, nanosec 2}, frame_id "ab"}: int32, uint32, then the string length
    // 3 (with NUL), 'a' 'b' NUL.
    let bytes = header(1_000_000_002, "ab").to_cdr();
    assert_eq!(
        bytes,
        [
            0, 1, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 3, 0, 0, 0, b'a', b'b', 0
        ]
    );
    // A float64 after a 1-byte string body is aligned to 8 from after the header:
    // JointState with an empty frame: stamp (8) + frame "" (4 + 1) -> offset 13; names count
    // at 16; ... the positions' float64s start at a multiple of 8.
    let message = JointState {
        header: header(0, ""),
        name: vec![],
        position: vec![1.5],
        velocity: vec![],
        effort: vec![],
    };
    let bytes = message.to_cdr();
    let body = &bytes[4..];
    // 0..8 stamp, 8..12 len 1, 12 NUL, 13..16 pad, 16..20 names 0, 20..24 positions 1,
    // 24..32 1.5
    assert_eq!(&body[16..20], &[0, 0, 0, 0]);
    assert_eq!(&body[20..24], &[1, 0, 0, 0]);
    assert_eq!(&body[24..32], &1.5f64.to_le_bytes());
    assert_eq!(body.len(), 32 + 8);
}

#[test]
fn bad_payloads_are_typed_errors() {
    assert_eq!(
        Time::decode_cdr(&[0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]),
        Err(CdrError::UnsupportedEncapsulation(0, 0))
    );
    // A string length past the limit.
    let mut bytes = vec![0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
    bytes.extend_from_slice(&((MAX_LENGTH as u32) + 1).to_le_bytes());
    assert!(matches!(
        Header::decode_cdr(&bytes),
        Err(CdrError::TooLong { offset: 8, .. })
    ));
    // A sequence count far beyond the bytes left.
    let mut bytes = TFMessage::default().to_cdr();
    bytes[4..8].copy_from_slice(&1000u32.to_le_bytes());
    assert!(matches!(
        TFMessage::decode_cdr(&bytes),
        Err(CdrError::Truncated { .. })
    ));
    // A string without its NUL, and one that is not UTF-8.
    let mut bytes = header(0, "ab").to_cdr();
    let last = bytes.len() - 1;
    bytes[last] = b'c';
    assert_eq!(
        Header::decode_cdr(&bytes),
        Err(CdrError::StringNotTerminated { offset: 8 })
    );
    bytes[last - 1] = 0xff;
    bytes[last] = 0;
    assert_eq!(
        Header::decode_cdr(&bytes),
        Err(CdrError::InvalidUtf8 { offset: 8 })
    );
    // A bool that is 2.
    let mut bytes = OperatingState::default().to_cdr();
    let is_homed = bytes.len() - 2;
    bytes[is_homed] = 2;
    assert!(matches!(
        OperatingState::decode_cdr(&bytes),
        Err(CdrError::InvalidBool { value: 2, .. })
    ));
    // Another type's payload: bytes left over beyond end padding.
    let bytes = transform_stamped().to_cdr();
    assert!(matches!(
        Header::decode_cdr(&bytes),
        Err(CdrError::TrailingBytes { .. })
    ));
    // Up to 3 bytes of end padding (as some middlewares add) are accepted.
    let mut bytes = header(0, "ab").to_cdr();
    bytes.extend_from_slice(&[0, 0, 0]);
    assert_eq!(Header::decode_cdr(&bytes), Ok(header(0, "ab")));
}

#[test]
fn type_hashes_match_ros2s_published_ones() {
    // The values ROS 2 (Humble and later) publishes for these types, as `ros2 topic info -v`
    // shows them; ours are computed from the descriptions.
    assert_eq!(
        Time::type_hash(),
        "RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197"
    );
    assert_eq!(
        Header::type_hash(),
        "RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01"
    );
    assert_eq!(
        JointState::type_hash(),
        "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"
    );
    assert_eq!(
        TIME.hashable_json(),
        r#"{"type_description": {"type_name": "builtin_interfaces/msg/Time", "fields": [{"name": "sec", "type": {"type_id": 6, "capacity": 0, "string_capacity": 0, "nested_type_name": ""}}, {"name": "nanosec", "type": {"type_id": 7, "capacity": 0, "string_capacity": 0, "nested_type_name": ""}}]}, "referenced_type_descriptions": []}"#
    );
}

#[test]
fn schema_text_lists_each_dependency_once() {
    let schema = TFMessage::schema_text();
    assert!(schema.starts_with("geometry_msgs/TransformStamped[] transforms\n"));
    for dependency in [
        "geometry_msgs/msg/TransformStamped",
        "std_msgs/msg/Header",
        "builtin_interfaces/msg/Time",
        "geometry_msgs/msg/Transform",
        "geometry_msgs/msg/Vector3",
        "geometry_msgs/msg/Quaternion",
    ] {
        let line = format!("\nMSG: {dependency}\n");
        assert_eq!(
            schema.matches(&line).count(),
            1,
            "{dependency} in\n{schema}"
        );
    }
    assert_eq!(schema.matches("MSG: ").count(), 6);
    assert_eq!(Time::schema_text(), "int32 sec\nuint32 nanosec\n");
    assert_eq!(ALL_TYPES.len(), 21);
}

#[test]
fn time_from_ns_splits_seconds_and_nanoseconds() {
    let time = Time::from_ns(12_345_678_901);
    assert_eq!((time.sec, time.nanosec), (12, 345_678_901));
    assert_eq!(time.as_ns(), 12_345_678_901);
    assert_eq!(Time::from_ns(u64::MAX).sec, i32::MAX);
}
