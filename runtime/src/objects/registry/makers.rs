//! The makers of the built-in kinds: each parses and checks its kind's configuration and makes
//! the object's state; nothing is opened until `configure`. The catalog names one per kind.

use std::sync::{Arc, Mutex};

use super::kind_entry::MakeArgs;
use super::{
    ControllerConfig, GalilObj, KindState, RobotObj, SensorObj, SimBoardObj, TeleopObj,
    TrajectoryObj, controller_body,
};
use crate::objects::config::{LoopTiming, parse};
use crate::objects::error::ObjectError;
use crate::objects::kinds::{
    self, GalilConfig, ImpedanceConfigToml, JointGroupsConfig, JointPidConfig, JointPositionConfig,
    Kind, RobotConfig, SensorConfig, SimBoardConfig,
};
use crate::objects::kinematics::RobotKinematics;
use crate::objects::runtime::VirtualSensor;
use crate::objects::teleop::{
    ForceDisplayToml, FourChannelSlaveToml, FourChannelToml, HandConfig, HandObj,
    PositionErrorToml, SlaveTrackingToml, TeleopConfig,
};
use crate::objects::teleop_wave::{WaveMasterToml, WaveSlaveToml};

/// `robot/<model>`: a built-in model, or a URDF file's.
pub(super) fn robot(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: RobotConfig = parse(k, a.config)?;
    let start = cfg.start_pose(k)?;
    let role = cfg.role(k)?;
    let model = cfg.model_in(k, a.kind.model(), a.robot_files)?;
    Ok(KindState::Robot(Box::new(RobotObj {
        kinematics: RobotKinematics::Float(model.clone()),
        model,
        role,
        caps: (cfg.max_force_n, cfg.max_moment_nm),
        start,
        maps: Vec::new(),
        body: None,
        created: super::ROBOTS_MADE.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
    })))
}

/// `board/sim`, and `board/fpga` (the same plant behind the FRHC's FPGA kinematics).
pub(super) fn sim_board(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: SimBoardConfig = parse(k, a.config)?;
    cfg.check(k)?;
    Ok(KindState::SimBoard(SimBoardObj {
        config: cfg,
        fpga: a.kind == Kind::FPGA_BOARD,
    }))
}

/// `board/galil`.
pub(super) fn galil_board(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: GalilConfig = parse(k, a.config)?;
    cfg.check(k)?;
    Ok(KindState::Galil(GalilObj {
        config: cfg,
        board: None,
    }))
}

/// `sensor/virtual`.
pub(super) fn virtual_sensor(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: SensorConfig = parse(k, a.config)?;
    cfg.check(k)?;
    let env = kinds::environment(k, &cfg.shapes)?;
    Ok(KindState::Sensor(SensorObj {
        state: Arc::new(Mutex::new(VirtualSensor::new(env))),
        config: cfg,
        publisher: None,
    }))
}

/// `sensor/operator-hand`.
pub(super) fn operator_hand(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: HandConfig = parse(k, a.config)?;
    let script = cfg.check(k)?;
    Ok(KindState::Hand(Box::new(HandObj {
        config: cfg,
        script,
        clutch: Arc::default(),
    })))
}

/// `sensor/replay` and `sensor/operator-replay`.
pub(super) fn replay(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    super::replay::replay_body(a.kind, a.config)
}

/// `trajectory/teleop`.
pub(super) fn teleop(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: TeleopConfig = parse(k, a.config)?;
    cfg.check(k)?;
    Ok(KindState::Teleop(Box::new(TeleopObj {
        config: cfg,
        link: None,
    })))
}

/// `trajectory/step`, `ramp`, `trapezoidal` and `spline`.
pub(super) fn trajectory(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    Ok(KindState::Trajectory(TrajectoryObj {
        spec: kinds::trajectory_spec(a.kind, a.config)?,
    }))
}

/// A controller of configuration `config`, its loop timing `timing`, from text `a.config`.
fn controller(a: &MakeArgs<'_>, config: ControllerConfig, timing: LoopTiming) -> KindState {
    controller_body(config, timing, a.config)
}

/// `controller/joint-pid`.
pub(super) fn joint_pid(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: JointPidConfig = parse(k, a.config)?;
    let timing = cfg.check(k)?;
    Ok(controller(a, ControllerConfig::Pid(cfg), timing))
}

/// `controller/cartesian-impedance`.
pub(super) fn cartesian_impedance(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: ImpedanceConfigToml = parse(k, a.config)?;
    let timing = cfg.check(k)?;
    Ok(controller(a, ControllerConfig::Impedance(cfg), timing))
}

/// `controller/joint-position`.
pub(super) fn joint_position(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: JointPositionConfig = parse(k, a.config)?;
    let timing = cfg.check(k)?;
    Ok(controller(a, ControllerConfig::Position(cfg), timing))
}

/// `controller/joint-groups`.
pub(super) fn joint_groups(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: JointGroupsConfig = parse(k, a.config)?;
    let timing = cfg.check(k)?;
    Ok(controller(a, ControllerConfig::Groups(cfg), timing))
}

/// `controller/force-display`.
pub(super) fn force_display(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: ForceDisplayToml = parse(k, a.config)?;
    cfg.law(k)?;
    let timing = cfg.timing(k)?;
    Ok(controller(a, ControllerConfig::ForceDisplay(cfg), timing))
}

/// `controller/position-error-master`.
pub(super) fn position_error_master(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: PositionErrorToml = parse(k, a.config)?;
    cfg.law(k)?;
    let timing = cfg.timing(k)?;
    Ok(controller(a, ControllerConfig::PositionError(cfg), timing))
}

/// `controller/four-channel-master`.
pub(super) fn four_channel_master(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: FourChannelToml = parse(k, a.config)?;
    cfg.law(k)?;
    let timing = cfg.timing(k)?;
    Ok(controller(a, ControllerConfig::FourChannel(cfg), timing))
}

/// `controller/four-channel-slave`.
pub(super) fn four_channel_slave(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: FourChannelSlaveToml = parse(k, a.config)?;
    cfg.law(k)?;
    let timing = cfg.timing(k)?;
    Ok(controller(
        a,
        ControllerConfig::FourChannelSlave(cfg),
        timing,
    ))
}

/// `controller/slave-tracking`, and `controller/slave-position` (for a board with its own
/// servo).
pub(super) fn slave_tracking(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: SlaveTrackingToml = parse(k, a.config)?;
    let servo = a.kind == Kind::SLAVE_POSITION;
    cfg.law(k, servo)?;
    let timing = cfg.timing(k)?;
    Ok(controller(
        a,
        ControllerConfig::Tracking(cfg, servo),
        timing,
    ))
}

/// `controller/wave-master`.
pub(super) fn wave_master(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: WaveMasterToml = parse(k, a.config)?;
    cfg.law(k)?;
    cfg.wave(k)?;
    let timing = cfg.timing(k)?;
    Ok(controller(a, ControllerConfig::WaveMaster(cfg), timing))
}

/// `controller/wave-slave`.
pub(super) fn wave_slave(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: WaveSlaveToml = parse(k, a.config)?;
    cfg.law(k)?;
    cfg.wave(k)?;
    let timing = cfg.timing(k)?;
    Ok(controller(a, ControllerConfig::WaveSlave(cfg), timing))
}
