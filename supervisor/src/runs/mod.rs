//! Runs: a system file's teleoperation task run for a duration through the node runtime, on
//! either clock, with every control tick of both sides recorded for the report.
//!
//! [`run`] starts the nodes the file names in this process (the first hosts the naming
//! service, on loopback), applies the file to each through its creator with the controllers
//! still inactive, starts recording the active ones, activates them, then moves the clock on
//! (the simulated clock by [`Creator::advance`](crate::objects::Creator::advance), the real
//! one by waiting) and deactivates them at the end (amplifiers off). What a `penelope node
//! --config` runs is exactly this, without the duration and the recording.
//!
//! [`report`] turns a run's ticks into the figures a person wants; [`delay`] runs the task
//! for several laws against several delays and judges each run's stability (`penelope
//! experiment delay`).

pub mod delay;
pub mod mcap_log;
pub mod recording;
pub mod report;
pub mod rerun;

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use nalgebra::UnitQuaternion;
use penelope_drivers::model as models;
use penelope_drivers::sim::environment::Environment;
use penelope_drivers::sim::operator::OperatorScript;
use penelope_drivers::sim::scripts;
use penelope_hal::{Pose, Timestamp, Transition};
use penelope_rt_core::teleop::MappingConfig;

use crate::node::{NamingChoice, Node, NodeConfig};
use crate::objects::clock::ClockMode;
use crate::objects::fpga_board;
use crate::objects::kinds::{self, RobotConfig, SensorConfig, SimBoardConfig};
use crate::objects::kinematics::RobotKinematics;
use crate::objects::runtime::{TickRecord, TickStream};
use crate::objects::teleop::{HandConfig, TeleopConfig};
use crate::system::{ObjectSpec, SystemFile, SystemFileError};
use penelope_protocol::proto::{Call, CallError, Method, WireError};

/// The demo's system file (`config/demo.toml`), built in.
pub const DEMO_SYSTEM: &str = include_str!("../../../config/demo.toml");

/// The simulated board's kind.
const SIM_BOARD: &str = "board/sim";
/// The FPGA board's kind: the simulated board with the FRHC's FPGA kinematics in front.
const FPGA_BOARD: &str = "board/fpga";

/// The kinematics a run's master computes with: the board its joints are on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MasterKinematics {
    /// Float kinematics on the host: the master's joints on `board/sim`.
    Float,
    /// The FPGA board's bit-exact kinematics and force transformation: on `board/fpga`.
    Fpga,
}

impl MasterKinematics {
    /// The word for it (`float`, `fpga`).
    pub fn as_str(self) -> &'static str {
        match self {
            MasterKinematics::Float => "float",
            MasterKinematics::Fpga => "fpga",
        }
    }

    /// The kinematics named `name`, if there is one.
    pub fn from_name(name: &str) -> Option<MasterKinematics> {
        [MasterKinematics::Float, MasterKinematics::Fpga]
            .into_iter()
            .find(|k| k.as_str() == name)
    }
}

/// `file` with the master of its teleoperation channel on the board kind `kinematics` names:
/// each simulated board its joints are on becomes `board/fpga` (or back to `board/sim`), the
/// one word a person would change in the file.
///
/// # Errors
/// [`RunError::Task`] when the file has no channel or master, or the master's joints are on a
/// board that is neither simulated nor an fpga board (a Galil board stays what it is).
pub fn with_master_kinematics(
    file: &SystemFile,
    kinematics: MasterKinematics,
) -> Result<SystemFile, RunError> {
    let mut file = file.clone();
    let (_, teleop) = teleop_channel(&file)?;
    let boards: Vec<String> = file
        .objects
        .iter()
        .find(|o| o.kind.starts_with("robot/") && o.name == teleop.master)
        .ok_or_else(|| task(format!("no robot `{}`", teleop.master)))?
        .joints
        .iter()
        .map(|m| m.board.clone())
        .collect();
    let kind = match kinematics {
        MasterKinematics::Float => SIM_BOARD,
        MasterKinematics::Fpga => FPGA_BOARD,
    };
    for o in file.objects.iter_mut().filter(|o| boards.contains(&o.name)) {
        if o.kind != SIM_BOARD && o.kind != FPGA_BOARD {
            return Err(task(format!(
                "the master's board `{}` is {}: only a simulated board (board/sim) and \
                 board/fpga swap kinematics",
                o.name, o.kind
            )));
        }
        o.kind = kind.to_string();
    }
    Ok(file)
}

/// The bilateral law of a run: which master half is active.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Law {
    /// Position forward, force back (`controller/force-display`).
    ForcePosition,
    /// Position error both ways (`controller/position-error-master`).
    PositionError,
    /// Wave variables (`controller/wave-master` and `controller/wave-slave`).
    Wave,
    /// Force-position with time-domain passivity: the two-port controllers on the channel
    /// (`passivity = "impedance"` on the force display, `"admittance"` on the slave half).
    Tdpa,
}

impl Law {
    /// Every law, in the order experiments list them.
    pub const ALL: [Law; 4] = [Law::ForcePosition, Law::PositionError, Law::Wave, Law::Tdpa];

    /// The law named `name` (its [`as_str`](Self::as_str)), if there is one.
    pub fn from_name(name: &str) -> Option<Law> {
        Law::ALL.into_iter().find(|l| l.as_str() == name)
    }

    /// Its name on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Law::ForcePosition => "force-position",
            Law::PositionError => "position-error",
            Law::Wave => "wave",
            Law::Tdpa => "tdpa",
        }
    }

    /// The master half's kind.
    fn master_kind(self) -> &'static str {
        match self {
            Law::ForcePosition | Law::Tdpa => "controller/force-display",
            Law::PositionError => "controller/position-error-master",
            Law::Wave => "controller/wave-master",
        }
    }

    /// Whether the slave half is the wave law's own (`controller/wave-slave`) rather than the
    /// file's other slave half.
    fn wave_slave(self) -> bool {
        self == Law::Wave
    }

    /// The `passivity` word of the master and of the slave half, where the law sets one.
    fn passivity(self) -> Option<(&'static str, &'static str)> {
        match self {
            Law::Tdpa => Some(("impedance", "admittance")),
            // (Force-position keeps the file's words.)
            Law::ForcePosition | Law::PositionError | Law::Wave => None,
        }
    }
}

/// The wave law's slave half.
const WAVE_SLAVE: &str = "controller/wave-slave";

/// What to change in the file for a run, and how long and on which clock it runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunOptions {
    /// Length of the run (default: the operator's script).
    pub duration: Option<Duration>,
    /// The law (default: the master half the file activates).
    pub law: Option<Law>,
    /// Position scale of every teleoperation channel (default: the file's).
    pub scale: Option<f64>,
    /// Seed of every virtual sensor's noise.
    pub seed: u64,
    /// Real time or simulated.
    pub clock: ClockMode,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            duration: None,
            law: None,
            scale: None,
            seed: 1,
            clock: ClockMode::Simulated,
        }
    }
}

/// Why a run could not start or finish.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The file does not describe a teleoperation task this runner can report on.
    #[error("{0}")]
    Task(String),
    /// A node refused the file.
    #[error(transparent)]
    System(#[from] SystemFileError),
    /// A node refused a call during the run.
    #[error("{what}: {error}")]
    Node {
        /// What was being done.
        what: String,
        /// The node's error.
        error: WireError,
    },
}

/// What a run was, for its report and files.
#[derive(Clone, Debug)]
pub struct RunInfo {
    /// The system's name.
    pub system: String,
    /// The law.
    pub law: Law,
    /// The channel's mapping (scale, rotation, gains).
    pub mapping: MappingConfig,
    /// Seed.
    pub seed: u64,
    /// Clock.
    pub clock: ClockMode,
    /// The first control tick.
    pub start: Timestamp,
    /// Control period.
    pub control_period: Duration,
    /// Communication period.
    pub comm_period: Duration,
    /// The operator's script.
    pub script: OperatorScript,
    /// The master's model, as its loops compute with it.
    pub master_model: RobotKinematics,
    /// The slave's model.
    pub slave_model: RobotKinematics,
    /// The master's float model (dynamics: gravity for the displayed force).
    pub master_dynamics: models::DhRobotModel,
    /// The slave's environment (its simulated board's shapes).
    pub environment: Environment,
    /// The slave's wrist sensor mount in its tool frame.
    pub sensor_mount: Pose,
    /// The master and slave controllers recorded.
    pub controllers: (String, String),
}

impl RunInfo {
    /// `R_ms`: the master base frame to the slave's.
    pub fn rotation(&self) -> UnitQuaternion<f64> {
        self.mapping.rotation
    }
}

/// Everything a run recorded.
pub struct RunOutput {
    /// What ran.
    pub info: RunInfo,
    /// Every master control tick.
    pub master: Vec<TickRecord>,
    /// Every slave control tick.
    pub slave: Vec<TickRecord>,
    /// Ticks lost by the recorders (master, slave).
    pub dropped: (u64, u64),
}

/// Progress of a run, for a status line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Progress {
    /// Time since the start.
    pub elapsed: Duration,
    /// Planned length.
    pub total: Duration,
    /// The operator script's phase.
    pub phase: &'static str,
    /// Latest slave tool position error against its reference, m.
    pub tracking_error: f64,
    /// Latest wrist sensor force magnitude, N.
    pub contact_force: f64,
    /// Latest force the master's law commands, N.
    pub commanded_force: f64,
}

/// The task a system file describes, found in it.
struct Task {
    file: SystemFile,
    info: RunInfo,
    duration: Duration,
    node_of: (String, String),
}

/// The file's teleoperation channel and its configuration.
fn teleop_channel(file: &SystemFile) -> Result<(&ObjectSpec, TeleopConfig), RunError> {
    let channel = file
        .objects
        .iter()
        .find(|o| o.kind == "trajectory/teleop")
        .ok_or_else(|| task("the system has no trajectory/teleop channel"))?;
    Ok((channel, parse(channel)?))
}

fn parse<T: serde::de::DeserializeOwned + Default>(o: &ObjectSpec) -> Result<T, RunError> {
    kinds::parse(&o.kind, &o.config).map_err(|e| RunError::Task(format!("{}: {e}", o.name)))
}

fn task(e: impl Into<String>) -> RunError {
    RunError::Task(e.into())
}

/// Sets `key` to `value` in `o`'s configuration text.
fn set_key(o: &mut ObjectSpec, key: &str, value: toml::Value) -> Result<(), RunError> {
    let mut table: toml::Table = o
        .config
        .parse()
        .map_err(|e| task(format!("{}: {e}", o.name)))?;
    table.insert(key.to_string(), value);
    o.config = table.to_string();
    Ok(())
}

/// Finds the teleoperation task in `file` and applies the options' changes to a copy.
fn find_task(file: &SystemFile, options: &RunOptions) -> Result<Task, RunError> {
    let mut file = file.clone();
    for o in &mut file.objects {
        if o.kind == "sensor/virtual" {
            set_key(o, "seed", toml::Value::Integer(options.seed as i64))?;
        }
        if let (Some(scale), "trajectory/teleop") = (options.scale, o.kind.as_str()) {
            set_key(o, "scale", toml::Value::Float(scale))?;
        }
    }
    let (channel, teleop) = teleop_channel(&file)?;
    teleop
        .check(&channel.kind)
        .map_err(|e| task(format!("{}: {e}", channel.name)))?;
    let channel_name = channel.name.clone();
    // The law picks the master half: its kind is activated, the other master half is not.
    let law = match options.law {
        Some(l) => l,
        None => {
            file.objects
                .iter()
                .find(|o| o.active && o.robot.as_deref() == Some(teleop.master.as_str()))
                .map_or(Law::ForcePosition, |o| {
                    if o.kind == Law::PositionError.master_kind() {
                        Law::PositionError
                    } else if o.kind == Law::Wave.master_kind() {
                        Law::Wave
                    } else if o.config.parse::<toml::Table>().is_ok_and(|t| {
                        t.get("passivity").and_then(|v| v.as_str()) == Some("impedance")
                    }) {
                        Law::Tdpa
                    } else {
                        Law::ForcePosition
                    }
                })
        }
    };
    // The other laws share the file's slave half; the wave law has its own.
    let slave_fallback = file
        .objects
        .iter()
        .any(|o| o.active && o.kind == WAVE_SLAVE && !law.wave_slave());
    for o in &mut file.objects {
        if o.trajectory.as_deref() != Some(channel_name.as_str()) {
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
    let on_channel = |robot: &str| {
        file.objects
            .iter()
            .find(|o| {
                o.active
                    && o.trajectory.as_deref() == Some(channel_name.as_str())
                    && o.robot.as_deref() == Some(robot)
            })
            .ok_or_else(|| {
                task(format!(
                    "no active controller drives `{robot}` on channel `{channel_name}` with the {} law",
                    law.as_str()
                ))
            })
    };
    let master_ctl = on_channel(&teleop.master)?;
    let slave_ctl = on_channel(&teleop.slave)?;
    let timing: kinds::LoopTiming = kinds::loop_timing(&master_ctl.kind, &master_ctl.config)
        .map_err(|e| task(format!("{}: {e}", master_ctl.name)))?;
    let robot = |name: &str| {
        file.objects
            .iter()
            .find(|o| o.kind.starts_with("robot/") && o.name == name)
            .ok_or_else(|| task(format!("no robot `{name}`")))
    };
    // A robot computes with its boards' kinematics: an fpga board's, or the float model.
    let model_of = |name: &str| -> Result<(RobotKinematics, models::DhRobotModel), RunError> {
        let o = robot(name)?;
        let cfg: RobotConfig = parse(o)?;
        let word = o.kind.trim_start_matches("robot/");
        let model = cfg
            .model(&o.kind, word)
            .map_err(|e| task(format!("{name}: {e}")))?;
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
            .map_err(|e| task(e.to_string()))?
            .is_some();
        let kin = match on_fpga {
            true => RobotKinematics::on_fpga_board(model.clone())
                .ok_or_else(|| task(format!("{name}: no fpga model")))?,
            false => RobotKinematics::Float(model.clone()),
        };
        Ok((kin, model))
    };
    let (master_model, master_dynamics) = model_of(&teleop.master)?;
    let (slave_model, _) = model_of(&teleop.slave)?;
    let hand = file
        .objects
        .iter()
        .filter(|o| o.kind == "sensor/operator-hand")
        .map(parse::<HandConfig>)
        .collect::<Result<Vec<_>, _>>()?
        .into_iter()
        .find(|h| h.robot == teleop.master);
    let script = match hand {
        Some(hand) => scripts::by_name(&hand.script)
            .ok_or_else(|| task(format!("unknown operator script `{}`", hand.script)))?,
        // A replayed hand: its recording is its script.
        None => rerun::replayed_hand_script(&file, &teleop.master, options.duration)?,
    };
    let sensor_mount = match &slave_ctl.sensor {
        Some(s) => match file.objects.iter().find(|o| &o.name == s) {
            Some(o) if o.kind == "sensor/virtual" => {
                let c: SensorConfig = parse(o)?;
                Pose::translation(c.mount_xyz[0], c.mount_xyz[1], c.mount_xyz[2])
            }
            Some(o) if o.kind == "sensor/replay" => {
                parse::<crate::objects::replay::ReplaySensorConfig>(o)?.mount()
            }
            Some(o) if o.kind == "sensor/netft" => parse::<kinds::NetFtSensorConfig>(o)?.mount(),
            _ => Pose::identity(),
        },
        None => Pose::identity(),
    };
    let slave_board = robot(&teleop.slave)?
        .joints
        .first()
        .map(|m| m.board.clone())
        .unwrap_or_default();
    let environment = match file.objects.iter().find(|o| o.name == slave_board) {
        Some(o) if o.kind == SIM_BOARD || o.kind == FPGA_BOARD => {
            let c: SimBoardConfig = parse(o)?;
            kinds::environment(&o.kind, &c.shapes).map_err(|e| task(e.to_string()))?
        }
        _ => Environment::new(),
    };
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
    };
    Ok(Task {
        duration: options.duration.unwrap_or(script.duration()),
        file,
        info,
        node_of,
    })
}

/// The nodes of a run, started in this process.
struct Nodes {
    nodes: Vec<Node>,
}

impl Nodes {
    fn start(file: &SystemFile, clock: ClockMode) -> Result<Nodes, RunError> {
        let mut names = file.node_names();
        if names.is_empty() {
            names.push("lab".into());
        }
        let mut nodes: Vec<Node> = Vec::new();
        for name in names {
            let naming = match nodes.first() {
                None => NamingChoice::Host,
                Some(first) => NamingChoice::Remote(first.address()),
            };
            let mut config = NodeConfig::new(name.clone(), naming);
            config.listen = SocketAddr::from(([127, 0, 0, 1], 0));
            config.creator.rt = file.policy(&name, config.creator.rt);
            config.creator.clock = clock;
            let node = Node::start(config).map_err(|e| RunError::Node {
                what: format!("starting node `{name}`"),
                error: WireError::Call(CallError::Internal(e.to_string())),
            })?;
            nodes.push(node);
        }
        Ok(Nodes { nodes })
    }

    fn get(&self, name: &str) -> Option<&Node> {
        self.nodes
            .iter()
            .find(|n| name.is_empty() || n.name() == name)
    }

    fn shutdown(self) {
        for n in self.nodes.into_iter().rev() {
            n.shutdown();
        }
    }
}

/// Ticks a recorder may hold before its reader drains it (over a minute at 1 kHz).
const RECORD_CAPACITY: usize = 1 << 16;

/// Runs the teleoperation task of `file`. `on_progress` is called from the calling thread
/// about 20 times a second of run time.
///
/// # Errors
/// [`RunError`] when the file has no task to run, a node refuses it, or a call fails.
pub fn run(
    file: &SystemFile,
    options: &RunOptions,
    on_progress: &mut dyn FnMut(&Progress),
) -> Result<RunOutput, RunError> {
    if let Some(s) = options.scale
        && !(s.is_finite() && s > 0.0)
    {
        return Err(task(format!("scale must be positive, got {s}")));
    }
    let Task {
        mut file,
        mut info,
        duration,
        node_of,
    } = find_task(file, options)?;
    // Everything is created and configured first; the loops start once they are recorded.
    let to_activate: Vec<(String, String)> = file
        .objects
        .iter()
        .filter(|o| o.active)
        .map(|o| (o.node.clone(), o.name.clone()))
        .collect();
    for o in &mut file.objects {
        o.active = false;
    }
    let nodes = Nodes::start(&file, options.clock)?;
    let result = run_on(
        &nodes,
        &file,
        &mut info,
        duration,
        &node_of,
        &to_activate,
        on_progress,
    );
    nodes.shutdown();
    let (master, slave, dropped) = result?;
    Ok(RunOutput {
        info,
        master,
        slave,
        dropped,
    })
}

type Recorded = (Vec<TickRecord>, Vec<TickRecord>, (u64, u64));

fn run_on(
    nodes: &Nodes,
    file: &SystemFile,
    info: &mut RunInfo,
    duration: Duration,
    node_of: &(String, String),
    to_activate: &[(String, String)],
    on_progress: &mut dyn FnMut(&Progress),
) -> Result<Recorded, RunError> {
    for n in &nodes.nodes {
        if file.objects_on(n.name()).next().is_some() {
            file.apply(n)?;
        }
    }
    let node = |name: &str| {
        nodes.get(name).ok_or_else(|| RunError::Node {
            what: format!("node `{name}`"),
            error: WireError::Call(CallError::UnknownName(name.into())),
        })
    };
    let record = |node_name: &str, controller: &str| -> Result<TickStream, RunError> {
        node(node_name)?
            .creator()
            .record_ticks(controller, RECORD_CAPACITY)
            .map_err(|error| RunError::Node {
                what: format!("recording `{controller}`"),
                error: error.into(),
            })
    };
    let master_stream = record(&node_of.0, &info.controllers.0)?;
    let slave_stream = record(&node_of.1, &info.controllers.1)?;
    let transition = |node_name: &str, name: &str, t: Transition| -> Result<(), RunError> {
        node(node_name)?
            .call(Call::Object {
                object: name.to_string(),
                method: Method::Transition(t),
            })
            .map(|_| ())
            .map_err(|error| RunError::Node {
                what: format!("{t:?} `{name}`"),
                error,
            })
    };
    for (n, name) in to_activate {
        transition(n, name, Transition::Activate)?;
    }
    let (mut master, mut slave) = (Vec::new(), Vec::new());
    let step = Duration::from_millis(50);
    let wall = Instant::now();
    let mut elapsed = Duration::ZERO;
    while elapsed < duration {
        let by = step.min(duration - elapsed);
        match info.clock {
            ClockMode::Simulated => {
                // Nodes exchange samples between their loops' ticks (the data plane), so
                // several nodes move on together, one millisecond at a time.
                let tick = if nodes.nodes.len() > 1 {
                    Duration::from_millis(1)
                } else {
                    by
                };
                let mut moved = Duration::ZERO;
                while moved < by {
                    let sub = tick.min(by - moved);
                    for n in &nodes.nodes {
                        n.creator().advance(sub).map_err(|error| RunError::Node {
                            what: "advancing the simulated clock".into(),
                            error: error.into(),
                        })?;
                    }
                    moved += sub;
                }
                elapsed += by;
            }
            ClockMode::RealTime => {
                std::thread::sleep(by);
                elapsed = wall.elapsed();
            }
        }
        master_stream.drain_into(&mut master);
        slave_stream.drain_into(&mut slave);
        if let Some(first) = master.first().or(slave.first()) {
            info.start = first.sample.time;
        }
        on_progress(&progress_of(info, &master, &slave, duration));
    }
    for (n, name) in to_activate.iter().rev() {
        transition(n, name, Transition::Deactivate)?;
    }
    master_stream.drain_into(&mut master);
    slave_stream.drain_into(&mut slave);
    let dropped = (
        master_stream
            .dropped
            .load(std::sync::atomic::Ordering::Relaxed),
        slave_stream
            .dropped
            .load(std::sync::atomic::Ordering::Relaxed),
    );
    // The run ends at its duration: the ticks of the deactivation are not part of it.
    let end = info.start + duration;
    master.retain(|t| t.sample.time < end);
    slave.retain(|t| t.sample.time < end);
    Ok((master, slave, dropped))
}

fn progress_of(
    info: &RunInfo,
    master: &[TickRecord],
    slave: &[TickRecord],
    total: Duration,
) -> Progress {
    let now = slave.last().map_or(info.start, |s| s.sample.time);
    let elapsed = now.saturating_since(info.start);
    let (tracking_error, contact_force) = slave.last().map_or((0.0, 0.0), |s| {
        (
            (s.sample.reference_position - s.sample.tool_position).norm(),
            s.sample.wrench.force.norm(),
        )
    });
    let commanded_force = master
        .last()
        .map_or(0.0, |s| s.sample.commanded_wrench.force.norm());
    let phase = info
        .script
        .segment_at(elapsed)
        .map_or("", |(_, s, _)| s.label);
    Progress {
        elapsed,
        total,
        phase,
        tracking_error,
        contact_force,
        commanded_force,
    }
}
