//! The emulated DMC driving a PUMA 200 rigid-body plant (gravity included): a joint PD with
//! gravity compensation, closed through the Galil board's cells over a pseudo-terminal, holds a
//! target away from the start pose when the torque directions come from the model, and runs
//! away when they do not (the PUMA 200's waist and elbow gears are negative) — so a sign error
//! cannot hide. Brakes hold the arm while its amplifiers are off.

use std::time::{Duration, Instant};

use penelope_drivers::galil::emulator::{ArmConfig, DmcConfig, PtyEmulator, PtyOptions};
use penelope_drivers::galil::{GalilBoard, GalilBoardConfig, axis_bindings};
use penelope_drivers::model::{DhRobot, puma200};
use penelope_hal::JointVector;
use penelope_hal::board::{AxisCommand, AxisState, Board};
use penelope_hal::robot::{Dynamics, NamedPose, RobotModel};
use penelope_hal::time::Timestamp;

const VOLTS_PER_NM: f64 = 0.1;

/// Ticks the arm must stay within [`SETTLED`] of the target to count as converged.
const SETTLED_TICKS: u32 = 250;

/// The error below which the arm counts as on the target, rad.
const SETTLED: f64 = 1e-3;

/// Runs a PD + gravity loop toward `start + offset` for at most `run`; returns the initial and
/// the last largest joint error (rad). It stops early once the error exceeds `give_up`, or once
/// the arm has stayed within [`SETTLED`] for [`SETTLED_TICKS`] loop ticks: the emulator's arm
/// moves on wall time, so on a loaded machine the loop ticks slower and converges later, and a
/// fixed run would judge the machine's load, not the torque directions.
fn pd_on_the_arm(orient: bool, run: Duration, give_up: f64) -> (f64, f64) {
    let model = puma200();
    let start = model.named_pose(NamedPose::Start);
    let emu = PtyEmulator::spawn(PtyOptions {
        dmc: DmcConfig {
            // Friction off: no stiction band, so convergence is to the goal itself.
            arm: Some(ArmConfig {
                friction: false,
                ..ArmConfig::new(model.clone(), start, 1.0 / VOLTS_PER_NM)
            }),
            ..DmcConfig::default()
        },
        ..PtyOptions::default()
    })
    .unwrap();
    let robot = DhRobot::new(model.clone());
    let bindings = axis_bindings(&robot);
    // The board's watchdog at one second: a loaded test machine that stalls this loop for
    // 30 ms would trip the default one, the brakes would freeze the arm short of the target,
    // and the test would judge the machine's load (the watchdog has its own tests).
    let mut board = GalilBoard::open(GalilBoardConfig {
        watchdog: Some(Duration::from_secs(1)),
        ..GalilBoardConfig::new(emu.path().to_string_lossy(), 6, &[VOLTS_PER_NM; 6])
    })
    .unwrap();
    if orient {
        board.orient(&bindings[..6]);
    }
    let limits = *model.limits();
    let mut kp = JointVector::zeros();
    let mut kd = JointVector::zeros();
    for j in 0..6 {
        kp[j] = 10.0 * limits.effort_max[j];
        kd[j] = 0.5 * limits.effort_max[j];
    }
    let mut target = start;
    for j in 0..6 {
        target[j] += if j % 2 == 0 { 0.05 } else { -0.05 };
    }
    let t0 = Instant::now();
    let now = || Timestamp::from_nanos(t0.elapsed().as_nanos() as u64);
    board.set_enabled(true).unwrap();
    let mut axes = [AxisState::default(); 6];
    let mut error = 0.0;
    let mut settled = 0;
    let initial = (target - start).amax();
    while t0.elapsed() < run {
        if board.read_axes(now(), &mut axes).is_err() {
            std::thread::sleep(Duration::from_millis(1));
            continue;
        }
        let mut q = JointVector::zeros();
        let mut qd = JointVector::zeros();
        for j in 0..6 {
            let cpr = bindings[j].counts_per_radian;
            q[j] = start[j] + axes[j].position as f64 / cpr;
            qd[j] = axes[j].velocity / cpr;
        }
        let g = model.gravity(&q);
        let mut cmd = [AxisCommand::Off; 6];
        for j in 0..6 {
            let tau = kp[j] * (target[j] - q[j]) - kd[j] * qd[j] + g[j];
            cmd[j] = AxisCommand::Effort(tau.clamp(-limits.effort_max[j], limits.effort_max[j]));
        }
        board.write_axes(now(), &cmd).unwrap();
        // The arm itself, not the encoders' report of it.
        let arm = emu.inspect(|d| d.arm_joints()).unwrap();
        error = (arm - target).amax();
        if error > give_up {
            break;
        }
        settled = if error < SETTLED { settled + 1 } else { 0 };
        if settled >= SETTLED_TICKS {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    board.release();
    // Released: the amplifiers are off and the brakes hold the arm where it is.
    let held = emu.inspect(|d| d.arm_joints()).unwrap();
    std::thread::sleep(Duration::from_millis(100));
    let later = emu.inspect(|d| d.arm_joints()).unwrap();
    assert!((later - held).amax() < 1e-9, "{held:?} -> {later:?}");
    (initial, error)
}

#[test]
fn a_gravity_compensated_pd_converges_with_the_model_s_torque_directions() {
    let (initial, error) = pd_on_the_arm(true, Duration::from_secs(20), 1.0);
    println!("PD + gravity, oriented: error {initial:.3} rad -> {error:.1e} rad");
    assert!(error < 2e-3, "{error}");
}

#[test]
fn the_same_pd_runs_away_with_one_sign_for_every_axis() {
    let (initial, error) = pd_on_the_arm(false, Duration::from_secs(20), 0.5);
    println!("PD + gravity, one sign: error {initial:.3} rad -> {error:.1e} rad");
    assert!(error > 4.0 * initial, "{error}");
}

#[test]
fn brakes_hold_the_arm_while_the_amplifiers_are_off() {
    let model = puma200();
    let start = model.named_pose(NamedPose::Start);
    let emu = PtyEmulator::spawn(PtyOptions {
        dmc: DmcConfig {
            arm: Some(ArmConfig::new(model.clone(), start, 10.0)),
            ..DmcConfig::default()
        },
        ..PtyOptions::default()
    })
    .unwrap();
    // Gravity pulls on the shoulder at the start pose, yet nothing moves with the motors off.
    assert!(model.gravity(&start).amax() > 0.1);
    let end = Instant::now() + Duration::from_secs(5);
    while emu.inspect(|d| d.now()) < Duration::from_millis(300) {
        assert!(Instant::now() < end);
        std::thread::sleep(Duration::from_millis(5));
    }
    let q = emu.inspect(|d| d.arm_joints()).unwrap();
    assert!((q - start).amax() < 1e-12, "{q:?}");
}
