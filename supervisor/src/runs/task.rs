//! The task a system file describes: its teleoperation channel, the law's controller halves
//! activated, the robots' models, the operator's script, the sensor mount and the slave's
//! environment, with the run options applied to a copy of the file.

use std::path::Path;
use std::time::Duration;

use penelope_drivers::model as models;
use penelope_drivers::sim::environment::Environment;
use penelope_drivers::sim::operator::{Motion, OperatorScript, Segment};
use penelope_drivers::sim::scripts;
use penelope_hal::{Pose, Timestamp};

use super::{
    FPGA_BOARD, Law, RunError, RunInfo, RunOptions, SIM_BOARD, WAVE_SLAVE, parse, set_key,
    task_error, teleop_channel,
};
use crate::system::{ObjectSpec, SystemFile};
use penelope_runtime::objects::fpga_board;
use penelope_runtime::objects::kinds::{self, RobotConfig, SensorConfig, SimBoardConfig};
use penelope_runtime::objects::kinematics::RobotKinematics;
use penelope_runtime::objects::recording::mcap_log::summarize;
use penelope_runtime::objects::replay::OperatorReplayConfig;
use penelope_runtime::objects::teleop::{HandConfig, TeleopConfig};

/// The task a system file describes, found in it.
pub(super) struct Task {
    /// The file with the options applied and the law's controllers active.
    pub(super) file: SystemFile,
    /// What the report needs to know of the run.
    pub(super) info: RunInfo,
    /// How long the run lasts.
    pub(super) duration: Duration,
    /// The nodes of the master's and the slave's controllers.
    pub(super) node_of: (String, String),
}

/// Finds the teleoperation task in `file` and applies the options' changes to a copy.
pub(super) fn find_task(file: &SystemFile, options: &RunOptions) -> Result<Task, RunError> {
    let mut file = file.clone();
    apply_seed_and_scale(&mut file, options)?;
    let (channel, teleop) = teleop_channel(&file)?;
    teleop
        .check(&channel.kind)
        .map_err(|e| task_error(format!("{}: {e}", channel.name)))?;
    let channel_name = channel.name.clone();
    let law = match options.law {
        Some(l) => l,
        None => law_of_file(&file, &teleop),
    };
    activate_law(&mut file, options, law, &channel_name, &teleop)?;
    let master_ctl = controller_on_channel(&file, &channel_name, law, &teleop.master)?;
    let slave_ctl = controller_on_channel(&file, &channel_name, law, &teleop.slave)?;
    let timing: penelope_runtime::objects::config::LoopTiming =
        penelope_runtime::objects::config::loop_timing(&master_ctl.kind, &master_ctl.config)
            .map_err(|e| task_error(format!("{}: {e}", master_ctl.name)))?;
    let (master_model, master_dynamics) = robot_models(&file, &teleop.master)?;
    let (slave_model, _) = robot_models(&file, &teleop.slave)?;
    let script = operator_script(&file, &teleop, options)?;
    let sensor_mount = sensor_mount(&file, slave_ctl)?;
    let environment = slave_environment(&file, &teleop)?;
    let node_of = (master_ctl.node.clone(), slave_ctl.node.clone());
    let info = RunInfo {
        system: file.name.clone().unwrap_or_else(|| "system".into()),
        law,
        mapping: teleop.mapping(),
        seed: options.seed,
        clock: options.clock,
        start: Timestamp::ZERO,
        control_period: timing.period,
        comm_period: timing.comm_period,
        script: script.clone(),
        master_model,
        slave_model,
        master_dynamics,
        environment,
        sensor_mount,
        controllers: (master_ctl.name.clone(), slave_ctl.name.clone()),
        robots: (
            (teleop.master.clone(), robot_row(&file, &teleop.master)),
            (teleop.slave.clone(), robot_row(&file, &teleop.slave)),
        ),
    };
    Ok(Task {
        duration: options.duration.unwrap_or(script.duration()),
        file,
        info,
        node_of,
    })
}

/// The place of robot `name` among the file's robots, in file order (0 when absent).
fn robot_row(file: &SystemFile, name: &str) -> usize {
    file.objects
        .iter()
        .filter(|o| o.kind.starts_with("robot/"))
        .position(|o| o.name == name)
        .unwrap_or(0)
}

/// The options' seed into every virtual sensor, and their scale into the teleop channel.
fn apply_seed_and_scale(file: &mut SystemFile, options: &RunOptions) -> Result<(), RunError> {
    for o in &mut file.objects {
        if o.kind == "sensor/virtual" {
            set_key(o, "seed", toml::Value::Integer(options.seed as i64))?;
        }
        if let (Some(scale), "trajectory/teleop") = (options.scale, o.kind.as_str()) {
            set_key(o, "scale", toml::Value::Float(scale))?;
        }
    }
    Ok(())
}

/// The law the file runs when none is asked for, told by its active master half: its kind,
/// or for a four-channel master its passivity setting.
fn law_of_file(file: &SystemFile, teleop: &TeleopConfig) -> Law {
    file.objects
        .iter()
        .find(|o| o.active && o.robot.as_deref() == Some(teleop.master.as_str()))
        .map_or(Law::ForcePosition, |o| {
            if o.kind == Law::PositionError.master_kind() {
                Law::PositionError
            } else if o.kind == Law::Wave.master_kind() {
                Law::Wave
            } else if o
                .config
                .parse::<toml::Table>()
                .is_ok_and(|t| t.get("passivity").and_then(|v| v.as_str()) == Some("impedance"))
            {
                Law::Tdpa
            } else {
                Law::ForcePosition
            }
        })
}

/// Activates the controller halves on `channel_name` that run `law`: the law picks the master
/// half (its kind is activated, the other master half is not) and, for the wave law, the
/// slave half; an asked-for law's passivity setting goes into both halves.
fn activate_law(
    file: &mut SystemFile,
    options: &RunOptions,
    law: Law,
    channel_name: &str,
    teleop: &TeleopConfig,
) -> Result<(), RunError> {
    // The other laws share the file's slave half; the wave law has its own.
    let slave_fallback = file
        .objects
        .iter()
        .any(|o| o.active && o.kind == WAVE_SLAVE && !law.wave_slave());
    for o in &mut file.objects {
        if o.trajectory.as_deref() != Some(channel_name) {
            continue;
        }
        let passivity = law.passivity().filter(|_| options.law.is_some());
        if o.robot.as_deref() == Some(teleop.master.as_str()) {
            // Without a law asked for, the file's own master half runs (whatever its kind: a
            // four-channel master is either classical law, as its coefficients say).
            if options.law.is_some() {
                o.active = o.kind == law.master_kind();
            }
            if let (true, Some((word, _))) = (o.active, passivity) {
                set_key(o, "passivity", toml::Value::String(word.into()))?;
            }
        } else if o.robot.as_deref() == Some(teleop.slave.as_str()) {
            if let (true, Some((_, word))) = (
                matches!(
                    o.kind.as_str(),
                    "controller/slave-tracking" | "controller/slave-position"
                ),
                passivity,
            ) {
                set_key(o, "passivity", toml::Value::String(word.into()))?;
            }
            if law.wave_slave() {
                o.active = o.kind == WAVE_SLAVE;
            } else if o.kind == WAVE_SLAVE {
                o.active = false;
            } else if slave_fallback && o.kind == "controller/slave-tracking" {
                o.active = true;
            }
        }
    }
    Ok(())
}

/// The active controller that drives `robot` on `channel_name`.
fn controller_on_channel<'a>(
    file: &'a SystemFile,
    channel_name: &str,
    law: Law,
    robot: &str,
) -> Result<&'a ObjectSpec, RunError> {
    file.objects
        .iter()
        .find(|o| {
            o.active
                && o.trajectory.as_deref() == Some(channel_name)
                && o.robot.as_deref() == Some(robot)
        })
        .ok_or_else(|| {
            task_error(format!(
                "no active controller drives `{robot}` on channel `{channel_name}` with the {} law",
                law.as_str()
            ))
        })
}

/// The robot object called `name`.
fn robot_object<'a>(file: &'a SystemFile, name: &str) -> Result<&'a ObjectSpec, RunError> {
    file.objects
        .iter()
        .find(|o| o.kind.starts_with("robot/") && o.name == name)
        .ok_or_else(|| task_error(format!("no robot `{name}`")))
}

/// The kinematics robot `name` computes with (its boards': an fpga board's, or the float
/// model) and its float model.
fn robot_models(
    file: &SystemFile,
    name: &str,
) -> Result<(RobotKinematics, models::SerialRobotModel), RunError> {
    let o = robot_object(file, name)?;
    let cfg: RobotConfig = parse(o)?;
    let word = o.kind.trim_start_matches("robot/");
    let model = cfg
        .model(&o.kind, word)
        .map_err(|e| task_error(format!("{name}: {e}")))?;
    let boards: Vec<(&str, bool)> = o
        .joints
        .iter()
        .map(|m| {
            let fpga = file
                .objects
                .iter()
                .any(|b| b.name == m.board && b.kind == FPGA_BOARD);
            (m.board.as_str(), fpga)
        })
        .collect();
    let on_fpga = fpga_board::robot_on_boards(name, word, &boards)
        .map_err(|e| task_error(e.to_string()))?
        .is_some();
    let kin = match on_fpga {
        true => RobotKinematics::on_fpga_board(model.clone())
            .ok_or_else(|| task_error(format!("{name}: no fpga model")))?,
        false => RobotKinematics::Float(model.clone()),
    };
    Ok((kin, model))
}

/// What the operator does: the master's simulated hand's script, or a replayed hand's
/// recording.
fn operator_script(
    file: &SystemFile,
    teleop: &TeleopConfig,
    options: &RunOptions,
) -> Result<OperatorScript, RunError> {
    let hand = file
        .objects
        .iter()
        .filter(|o| o.kind == "sensor/operator-hand")
        .map(parse::<HandConfig>)
        .collect::<Result<Vec<_>, _>>()?
        .into_iter()
        .find(|h| h.robot == teleop.master);
    match hand {
        Some(hand) => scripts::by_name(&hand.script)
            .ok_or_else(|| task_error(format!("unknown operator script `{}`", hand.script))),
        // A replayed hand: its recording is its script.
        None => replayed_hand_script(file, &teleop.master, options.duration),
    }
}

/// Where the slave controller's force sensor sits on the tool (identity without one).
fn sensor_mount(file: &SystemFile, slave_ctl: &ObjectSpec) -> Result<Pose, RunError> {
    Ok(match &slave_ctl.sensor {
        Some(s) => match file.objects.iter().find(|o| &o.name == s) {
            Some(o) if o.kind == "sensor/virtual" => {
                let c: SensorConfig = parse(o)?;
                Pose::translation(c.mount_xyz[0], c.mount_xyz[1], c.mount_xyz[2])
            }
            Some(o) if o.kind == "sensor/replay" => {
                parse::<penelope_runtime::objects::replay::ReplaySensorConfig>(o)?.mount()
            }
            Some(o) if o.kind == "sensor/netft" => {
                parse::<penelope_runtime::objects::netft::NetFtSensorConfig>(o)?.mount()
            }
            _ => Pose::identity(),
        },
        None => Pose::identity(),
    })
}

/// The environment the slave touches: its first board's shapes when it is simulated.
fn slave_environment(file: &SystemFile, teleop: &TeleopConfig) -> Result<Environment, RunError> {
    let slave_board = robot_object(file, &teleop.slave)?
        .joints
        .first()
        .map(|m| m.board.clone())
        .unwrap_or_default();
    Ok(match file.objects.iter().find(|o| o.name == slave_board) {
        Some(o) if o.kind == SIM_BOARD || o.kind == FPGA_BOARD => {
            let c: SimBoardConfig = parse(o)?;
            kinds::environment(&o.kind, &c.shapes).map_err(|e| task_error(e.to_string()))?
        }
        _ => Environment::new(),
    })
}

/// `sensor/operator-replay`'s script, for a run's report: one segment, `replay`, as long as
/// `duration` or the recording.
///
/// # Errors
/// [`RunError::Task`] when no hand holds `master`, or its recording cannot be read.
fn replayed_hand_script(
    file: &SystemFile,
    master: &str,
    duration: Option<Duration>,
) -> Result<OperatorScript, RunError> {
    let hand = file
        .objects
        .iter()
        .filter(|o| o.kind == "sensor/operator-replay")
        .map(super::parse::<OperatorReplayConfig>)
        .collect::<Result<Vec<_>, _>>()?
        .into_iter()
        .find(|h| h.robot == master)
        .ok_or_else(|| {
            task_error(format!(
                "no sensor/operator-hand or sensor/operator-replay holds `{master}`"
            ))
        })?;
    let duration = match duration {
        Some(d) => d,
        None => {
            let s = summarize(Path::new(&hand.file)).map_err(|e| task_error(e.to_string()))?;
            // The last tick's period: ticks stand for the millisecond that follows them.
            Duration::from_nanos(s.duration_ns()) + Duration::from_millis(1)
        }
    };
    OperatorScript::new(&[Segment {
        label: "replay",
        motion: Motion::Hold,
        duration,
        clutch: false,
    }])
    .map_err(|_| task_error("operator script"))
}
