//! The simulated lab's plant and board behave like physics and like a board.

use core::time::Duration;

use nalgebra::Vector3;
use penelope_drivers::model;
use penelope_drivers::sim::FreeSpace;
use penelope_drivers::sim::board::{SimBoard, SimBoardConfig};
use penelope_drivers::sim::environment::{ContactModel, Environment, Shape};
use penelope_drivers::sim::force_sensor::{ForceSensorConfig, VirtualForceSensor};
use penelope_drivers::sim::plant::{PlantConfig, RigidBodyPlant};
use penelope_drivers::sim::tap::TapWriter;
use penelope_hal::{
    AxisCommand, AxisState, Board, Dynamics, Frame, JointVector, Kinematics, NamedPose, Pose,
    Sensor, Timestamp, Wrench,
};

fn ms(t: u64) -> Timestamp {
    Timestamp::from_nanos(t * 1_000_000)
}

#[test]
fn holding_torque_holds_and_no_torque_falls() {
    let robot = model::puma200();
    let q0 = robot.named_pose(NamedPose::Work);
    let hold = robot.gravity(&q0);
    let config = PlantConfig {
        friction: false,
        ..PlantConfig::default()
    };
    let mut held = RigidBodyPlant::new(model::puma200(), config, q0, Timestamp::ZERO);
    held.advance_to(ms(500), &hold, &mut FreeSpace);
    let drift = (held.snapshot().joints.position - q0).norm();
    assert!(drift < 1e-3, "held arm drifted {drift} rad");

    let mut dropped = RigidBodyPlant::new(model::puma200(), config, q0, Timestamp::ZERO);
    dropped.advance_to(ms(200), &JointVector::zeros(), &mut FreeSpace);
    let fell = (dropped.snapshot().joints.position - q0).norm();
    assert!(
        fell > 1e-2,
        "an unpowered arm must fall, moved only {fell} rad"
    );
    assert!(dropped.snapshot().kinetic_energy > 0.0);
}

#[test]
fn friction_and_motor_limits_take_effect() {
    let robot = model::puma200();
    let q0 = robot.named_pose(NamedPose::Work);
    let push = robot.gravity(&q0) + JointVector::new(50.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let limited = PlantConfig {
        motor_torque_limit: JointVector::repeat(1.0),
        friction: false,
        ..PlantConfig::default()
    };
    let mut plant = RigidBodyPlant::new(model::puma200(), limited, q0, Timestamp::ZERO);
    plant.advance_to(ms(10), &push, &mut FreeSpace);
    assert!(
        plant
            .snapshot()
            .joints
            .effort
            .iter()
            .all(|e| e.abs() <= 1.0)
    );

    let free = PlantConfig {
        friction: false,
        ..PlantConfig::default()
    };
    let with_friction = PlantConfig {
        friction: true,
        ..PlantConfig::default()
    };
    let mut a = RigidBodyPlant::new(model::puma200(), free, q0, Timestamp::ZERO);
    let mut b = RigidBodyPlant::new(model::puma200(), with_friction, q0, Timestamp::ZERO);
    a.advance_to(ms(100), &push, &mut FreeSpace);
    b.advance_to(ms(100), &push, &mut FreeSpace);
    let (va, vb) = (
        a.snapshot().joints.velocity[0],
        b.snapshot().joints.velocity[0],
    );
    assert!(
        va > 0.0 && vb < va,
        "friction must slow the joint: {vb} vs {va}"
    );
}

fn board_config(counts_per_radian: f64) -> SimBoardConfig {
    SimBoardConfig {
        counts_per_radian: JointVector::repeat(counts_per_radian),
        effort_full_scale: JointVector::repeat(100.0),
        dac_bits: 8,
        position_kp: JointVector::repeat(2000.0),
        position_kd: JointVector::repeat(40.0),
        velocity_cutoff_hz: 0.0,
        command_timeout: None,
        brake: false,
    }
}

#[test]
fn the_board_quantises_encoders_and_the_dac() {
    let robot = model::puma200();
    let q0 = robot.named_pose(NamedPose::Work);
    let mut board = SimBoard::new(
        model::puma200(),
        PlantConfig::default(),
        board_config(1000.0),
        FreeSpace,
        q0,
        Timestamp::ZERO,
    );
    let mut axes = [AxisState::default(); 8];
    board.read_axes(Timestamp::ZERO, &mut axes).unwrap();
    for j in 0..6 {
        assert_eq!(axes[j].position, (q0[j] * 1000.0).floor() as i64);
    }
    board.set_enabled(true).unwrap();
    let mut commands = [AxisCommand::Off; 8];
    commands[0] = AxisCommand::Effort(1000.0); // beyond full scale
    commands[1] = AxisCommand::Effort(0.3); // below one 8-bit DAC step (200/256 N·m)
    board.write_axes(Timestamp::ZERO, &commands).unwrap();
    board.read_axes(ms(1), &mut axes).unwrap();
    assert_eq!(axes[0].effort, 100.0, "saturated at full scale");
    assert_eq!(axes[1].effort, 0.0, "rounded to the nearest DAC level");
    commands[0] = AxisCommand::Effort(f64::NAN);
    assert!(
        board.write_axes(ms(1), &commands).is_err(),
        "NaN is refused"
    );
    assert!(
        board.read_axes(ms(2), &mut axes[..3]).is_err(),
        "short slices are refused"
    );
}

#[test]
fn the_on_board_position_loop_reaches_its_target() {
    let robot = model::puma200();
    let q0 = robot.named_pose(NamedPose::Work);
    let mut board = SimBoard::new(
        model::puma200(),
        PlantConfig::default(),
        board_config(10_000.0),
        FreeSpace,
        q0,
        Timestamp::ZERO,
    );
    board.set_enabled(true).unwrap();
    let mut commands = [AxisCommand::Off; 8];
    let target = q0 + JointVector::new(0.05, 0.0, 0.0, 0.0, 0.0, 0.0);
    for j in 0..6 {
        commands[j] = AxisCommand::Position((target[j] * 10_000.0).round() as i64);
    }
    board.write_axes(Timestamp::ZERO, &commands).unwrap();
    let mut axes = [AxisState::default(); 8];
    board.read_axes(ms(1500), &mut axes).unwrap();
    // The PD loop without gravity feed-forward leaves a steady error on loaded joints; joint 1
    // (vertical axis) carries no gravity load and must arrive.
    assert!(
        axes[0].following_error.abs() < 200,
        "joint 1 error {} counts",
        axes[0].following_error
    );
}

#[test]
fn the_virtual_sensor_reads_the_wall_in_its_own_frame() {
    let robot = model::puma200();
    let q0 = robot.named_pose(NamedPose::Work);
    let tool = robot.forward(&q0).translation.vector;
    // A floor whose surface is 1 mm above the tool: the tool starts 1 mm inside it.
    let wall = ContactModel {
        shape: Shape::Plane {
            point: tool + Vector3::new(0.0, 0.0, 0.001),
            normal: Vector3::z_axis(),
        },
        stiffness: 10_000.0,
        damping: 0.0,
    };
    let environment = Environment::new().with(wall).unwrap();
    let mut tap = TapWriter::new();
    let reader = tap.reader().unwrap();
    let mut truth = tap.reader().unwrap();
    let mut board = SimBoard::new(
        model::puma200(),
        PlantConfig::default(),
        board_config(10_000.0),
        environment,
        q0,
        Timestamp::ZERO,
    )
    .with_tap(tap);
    let mut sensor = VirtualForceSensor::new(
        ForceSensorConfig {
            mount: Pose::identity(),
            bias: Wrench::zero(Frame::Sensor),
            force_noise: 0.0,
            torque_noise: 0.0,
            cutoff_hz: 0.0,
            seed: 7,
        },
        reader,
    );
    assert!(
        sensor.read(Timestamp::ZERO).is_err(),
        "no data before the first board read"
    );
    let mut axes = [AxisState::default(); 8];
    board
        .read_axes(Timestamp::from_nanos(200_000), &mut axes)
        .unwrap();
    let reading = sensor.read(Timestamp::from_nanos(200_000)).unwrap();
    let sample = truth.latest().unwrap();
    // The wall pushes the tool up with ~10 N; the sensor reports the tool pushing down, in the
    // tool frame.
    assert!(
        (sample.base_wrench.force - Vector3::new(0.0, 0.0, 10.0)).norm() < 0.5,
        "{:?}",
        sample.base_wrench
    );
    let expected = sample.tool_pose.rotation.inverse() * -sample.base_wrench.force;
    assert!((reading.force - expected).norm() < 1e-9);
    assert_eq!(reading.frame, Frame::Sensor);
    let _ = Duration::ZERO;
}
