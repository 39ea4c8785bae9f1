//! The FRHC on its FPGA board (`board/fpga`, issue 19): one word in the system file swaps the
//! master's float kinematics for the board's bit-exact ones, the demo meets the same tracking,
//! force and energy bounds as with float kinematics, its report shows the board's latency, and
//! a robot the board does not model is refused with a typed error.

use penelope_fpga::FpgaKinematics;
use penelope_hal::{Frame, JointVector, Kinematics, RobotModel, Transition, Wrench};
use penelope_protocol::proto::{
    CallError, JointAxis, Method, PoseMsg, Reply, RobotMethod, WireError, WrenchMsg,
    joints_to_vector,
};
use penelope_runtime::objects::clock::ClockMode;
use penelope_runtime::objects::error::ObjectError;
use penelope_runtime::objects::fpga_board::FpgaBoardError;
use penelope_runtime::objects::kinematics::RobotKinematics;
use penelope_runtime::objects::{Creator, CreatorConfig};
use penelope_supervisor::runs::report::{Report, report};
use penelope_supervisor::runs::{
    DEMO_SYSTEM, Law, MasterKinematics, RunError, RunOptions, RunOutput, run,
    with_master_kinematics,
};
use penelope_supervisor::system::SystemFile;

/// The one word of the paper's test: the FRHC's board kind.
const FLOAT_WORD: &str = "[boards.frhc-io]\nkind = \"sim\"";
const FPGA_WORD: &str = "[boards.frhc-io]\nkind = \"fpga\"";

fn simulate(text: &str, law: Law) -> (RunOutput, Report) {
    let file = SystemFile::parse(text).expect("a valid system file");
    let options = RunOptions {
        law: Some(law),
        seed: 1,
        clock: ClockMode::Simulated,
        ..RunOptions::default()
    };
    let out = run(&file, &options, &mut |_| {}).expect("the demo builds and runs");
    let r = report(&out);
    (out, r)
}

#[test]
fn the_demo_on_the_fpga_board_meets_the_float_demos_bounds_and_reports_the_latency() {
    assert!(
        DEMO_SYSTEM.contains(FLOAT_WORD),
        "the demo file names the word"
    );
    let fpga_text = DEMO_SYSTEM.replacen(FLOAT_WORD, FPGA_WORD, 1);
    let (out, r) = simulate(&fpga_text, Law::ForcePosition);
    assert!(matches!(
        out.info.master_model,
        RobotKinematics::FpgaBoard { .. }
    ));
    // The bounds of `demo.rs` for the float kinematics.
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    assert!(r.tracking.samples > 5_000, "{}", r.tracking.samples);
    assert!(
        r.tracking.rms_mm < 2.0,
        "tracking RMS {} mm",
        r.tracking.rms_mm
    );
    assert!(
        r.tracking.max_mm < 5.0,
        "tracking max {} mm",
        r.tracking.max_mm
    );
    let c = &r.contact;
    assert!(c.samples > 500 && c.sensed_force_n > 5.0, "{c:?}");
    assert!(
        c.display_error_pct < 5.0,
        "display {}% off",
        c.display_error_pct
    );
    let hand_error = (c.hand_force_n - c.expected_display_n).abs() / c.expected_display_n * 100.0;
    assert!(hand_error < 5.0, "the hand feels {hand_error}% off");
    let peaks = &r.energy.tap_cycle_peaks_j;
    assert!(peaks.len() >= 5, "tap cycles {peaks:?}");
    assert!(r.energy.growth_ratio <= 1.05, "energy grows: {peaks:?}");
    // The report shows the board's latency.
    let k = &r.kinematics;
    assert_eq!(k.master, "fpga");
    assert_eq!((k.fk_cycles, k.fk_force_cycles), (61, 92));
    assert!(
        k.fk_latency_us > 1.525 && k.fk_force_latency_us > 2.3,
        "{k:?}"
    );
    assert!(
        k.command_delay_us > k.fk_latency_us + k.fk_force_latency_us,
        "{k:?}"
    );

    // The float run differs (the board's words and its delay are in the loop), but little.
    let (float, rf) = simulate(DEMO_SYSTEM, Law::ForcePosition);
    assert!(matches!(float.info.master_model, RobotKinematics::Float(_)));
    assert_eq!(rf.kinematics.master, "float");
    assert!(out.master != float.master, "the FPGA path must be in use");
    let drift = out
        .slave
        .iter()
        .zip(&float.slave)
        .map(|(a, b)| (a.sample.tool_position - b.sample.tool_position).norm())
        .fold(0.0f64, f64::max);
    assert!(
        drift < 1e-3,
        "the FPGA and float runs drift apart by {drift} m"
    );
}

#[test]
fn the_position_error_law_on_the_fpga_board_tracks_like_the_float_one() {
    let fpga_text = DEMO_SYSTEM.replacen(FLOAT_WORD, FPGA_WORD, 1);
    let (_, r) = simulate(&fpga_text, Law::PositionError);
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    assert!(
        r.tracking.rms_mm < 2.0,
        "tracking RMS {} mm",
        r.tracking.rms_mm
    );
    assert!(
        r.tracking.max_mm < 5.0,
        "tracking max {} mm",
        r.tracking.max_mm
    );
    assert!(r.energy.growth_ratio <= 1.05, "{:?}", r.energy);
}

#[test]
fn the_demos_kinematics_option_is_the_one_word() {
    let demo = SystemFile::parse(DEMO_SYSTEM).unwrap();
    let by_hand = SystemFile::parse(&DEMO_SYSTEM.replacen(FLOAT_WORD, FPGA_WORD, 1)).unwrap();
    let kinds = |f: &SystemFile| -> Vec<(String, String)> {
        f.objects
            .iter()
            .map(|o| (o.name.clone(), o.kind.clone()))
            .collect()
    };
    let fpga = with_master_kinematics(&demo, MasterKinematics::Fpga).unwrap();
    assert_eq!(kinds(&fpga), kinds(&by_hand));
    let back = with_master_kinematics(&fpga, MasterKinematics::Float).unwrap();
    assert_eq!(kinds(&back), kinds(&demo));
    // A Galil master stays a Galil master: said, not silently ignored.
    let galil = SystemFile::parse(&DEMO_SYSTEM.replacen(
        FLOAT_WORD,
        "[boards.frhc-io]\nkind = \"galil\"\naddress = \"127.0.0.1:1\"",
        1,
    ))
    .unwrap();
    let err = with_master_kinematics(&galil, MasterKinematics::Fpga).unwrap_err();
    assert!(
        matches!(&err, RunError::Task(why) if why.contains("board/galil")),
        "{err}"
    );
}

fn creator() -> Creator {
    let mut config = CreatorConfig::new("fpga");
    config.rt.priority = None;
    Creator::new(config)
}

fn map_all(c: &Creator, robot: &str, board: &str) -> Result<Reply, WireError> {
    c.call_object(
        robot,
        Method::Robot(RobotMethod::MapJoints {
            board: board.into(),
            joints: (0..6).map(|j| JointAxis { joint: j, axis: j }).collect(),
        }),
    )
    .map_err(WireError::from)
}

#[test]
fn the_boards_kinematics_are_the_bit_exact_models_and_describe_shows_the_latency() {
    let c = creator();
    c.create("robot/frhc", "frhc", "").unwrap();
    c.create("board/fpga", "io", "").unwrap();
    map_all(&c, "frhc", "io").unwrap();
    for name in ["io", "frhc"] {
        c.transition(name, Transition::Configure).unwrap();
    }
    let model = FpgaKinematics::frhc();
    let q = JointVector::from([0.2, 1.0, 2.3, -0.5, 0.4, 0.9]);
    let qmsg = || Some(q.iter().copied().collect::<Vec<f64>>());
    match c
        .call_object(
            "frhc",
            Method::Robot(RobotMethod::ForwardKinematics { q: qmsg() }),
        )
        .unwrap()
    {
        Reply::Pose(p) => assert_eq!(PoseMsg::from(&model.forward(&q)), p),
        other => panic!("{other:?}"),
    }
    let w = Wrench {
        force: nalgebra::Vector3::new(2.0, -3.0, 4.0),
        torque: nalgebra::Vector3::new(0.1, 0.0, -0.2),
        frame: Frame::Base,
    };
    match c
        .call_object(
            "frhc",
            Method::Robot(RobotMethod::WrenchToTorques {
                wrench: WrenchMsg::from(&w),
                q: qmsg(),
            }),
        )
        .unwrap()
    {
        Reply::Joints(tau) => {
            assert_eq!(
                joints_to_vector(&tau, 6).unwrap(),
                model.joint_torques(&q, &w).unwrap()
            );
            let float = penelope_drivers::model::frhc();
            assert_ne!(
                joints_to_vector(&tau, 6).unwrap(),
                float.wrench_to_torques(&q, &w).unwrap()
            );
        }
        other => panic!("{other:?}"),
    }
    // `describe` of the board and of the robot: the latency per FK and FK + force.
    for name in ["io", "frhc"] {
        let info = c.info(name).unwrap();
        let get = |k: &str| {
            info.relations
                .iter()
                .find(|(key, _)| key == k)
                .map(|(_, v)| v.clone())
                .unwrap_or_else(|| panic!("{name}: no `{k}` in {:?}", info.relations))
        };
        assert!(
            get("fk").starts_with("61 cycles = 1.525 us"),
            "{}",
            get("fk")
        );
        assert!(
            get("fk+force").starts_with("92 cycles = 2.300 us"),
            "{}",
            get("fk+force")
        );
        assert!(get("command-delay").contains("us"));
    }
    // Cleanup gives the robot its float kinematics back.
    c.transition("frhc", Transition::Cleanup).unwrap();
    let info = c.info("frhc").unwrap();
    assert!(
        info.relations
            .iter()
            .any(|(k, v)| k == "kinematics" && v.starts_with("float")),
        "{:?}",
        info.relations
    );
}

#[test]
fn a_robot_the_board_does_not_model_and_a_bad_key_are_typed_errors() {
    let c = creator();
    c.create("robot/puma200", "puma", "").unwrap();
    c.create("board/fpga", "io", "").unwrap();
    match map_all(&c, "puma", "io") {
        Err(WireError::Call(CallError::BadConfig { kind, message })) => {
            assert_eq!(kind, "board/fpga");
            assert!(
                message.contains("FRHC") && message.contains("puma200"),
                "{message}"
            );
        }
        other => panic!("{other:?}"),
    }
    // A board created after the mapping: refused at configure.
    c.create("robot/puma560", "arm", "").unwrap();
    map_all(&c, "arm", "later").unwrap();
    c.create("board/fpga", "later", "").unwrap();
    c.transition("later", Transition::Configure).unwrap();
    match c
        .transition("arm", Transition::Configure)
        .map_err(WireError::from)
    {
        Err(WireError::Call(CallError::BadConfig { kind, message })) => {
            assert_eq!(kind, "board/fpga");
            assert!(message.contains("puma560"), "{message}");
        }
        other => panic!("{other:?}"),
    }
    // The robot key is gone: the board chooses the kinematics.
    match c
        .create("robot/frhc", "frhc", "kinematics = \"fpga\"")
        .map_err(WireError::from)
    {
        Err(WireError::Call(CallError::BadConfig { message, .. })) => {
            assert!(message.contains("kinematics"), "{message}")
        }
        other => panic!("{other:?}"),
    }
    match c
        .create("board/fpga", "io2", "clock_mhz = 80")
        .map_err(WireError::from)
    {
        Err(WireError::Call(CallError::BadConfig { kind, message })) => {
            assert_eq!(kind, "board/fpga");
            assert!(message.contains("clock_mhz"), "{message}");
        }
        other => panic!("{other:?}"),
    }
    // Half the FRHC on the board, half elsewhere: the board computes the whole chain.
    c.create("robot/frhc", "frhc", "").unwrap();
    c.create("board/sim", "sim", "").unwrap();
    c.call_object(
        "frhc",
        Method::Robot(RobotMethod::MapJoints {
            board: "io".into(),
            joints: (0..3).map(|j| JointAxis { joint: j, axis: j }).collect(),
        }),
    )
    .unwrap();
    let err = c
        .call_object(
            "frhc",
            Method::Robot(RobotMethod::MapJoints {
                board: "sim".into(),
                joints: (3..6).map(|j| JointAxis { joint: j, axis: j }).collect(),
            }),
        )
        .unwrap_err();
    assert!(
        matches!(&err, ObjectError::FpgaBoard(FpgaBoardError::SplitChain { robot, board, other })
            if robot == "frhc" && board == "io" && other == "sim"),
        "{err}"
    );
}
