//! Runs: a system file's teleoperation task run for a duration through the node runtime, on
//! either clock, with every control tick of both sides recorded for the report.
//!
//! [`run`] starts the nodes the file names in this process (the first hosts the naming
//! service, on loopback), applies the file to each through its creator with the controllers
//! still inactive, starts recording the active ones, activates them, then moves the clock on
//! (the simulated clock by [`Creator::advance`](penelope_runtime::objects::Creator::advance), the real
//! one by waiting) and deactivates them at the end (amplifiers off). What a `penelope node
//! --config` runs is exactly this, without the duration and the recording.
//!
//! [`report`] turns a run's ticks into the figures a person wants; [`delay`] runs the task
//! for several laws against several delays and judges each run's stability (`penelope
//! experiment delay`).

pub mod delay;
pub mod latency;
pub mod recording;
pub mod report;
pub mod rerun;
mod task;

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use nalgebra::UnitQuaternion;
use penelope_drivers::model as models;
use penelope_drivers::sim::environment::Environment;
use penelope_drivers::sim::operator::OperatorScript;
use penelope_hal::{Pose, Timestamp, Transition};
use penelope_rt_core::teleop::MappingConfig;

use crate::node::{NamingChoice, Node, NodeConfig};
use crate::system::{ObjectSpec, SystemFile, SystemFileError};
use penelope_protocol::proto::{Call, CallError, Method, WireError};
use penelope_runtime::objects::clock::ClockMode;
use penelope_runtime::objects::kinematics::RobotKinematics;
use penelope_runtime::objects::teleop::TeleopConfig;
use penelope_runtime::objects::tick::TickRecord;
use penelope_runtime::objects::tick::TickStream;
use task::{Task, find_task};

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
        .ok_or_else(|| task_error(format!("no robot `{}`", teleop.master)))?
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
            return Err(task_error(format!(
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
    pub master_dynamics: models::SerialRobotModel,
    /// The slave's environment (its simulated board's shapes).
    pub environment: Environment,
    /// The slave's wrist sensor mount in its tool frame.
    pub sensor_mount: Pose,
    /// The master and slave controllers recorded.
    pub controllers: (String, String),
    /// The master and slave robot objects, each with its place among the file's robots (the
    /// 3D scene stands them side by side in this order).
    pub robots: ((String, usize), (String, usize)),
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

/// The file's teleoperation channel and its configuration.
fn teleop_channel(file: &SystemFile) -> Result<(&ObjectSpec, TeleopConfig), RunError> {
    let channel = file
        .objects
        .iter()
        .find(|o| o.kind == "trajectory/teleop")
        .ok_or_else(|| task_error("the system has no trajectory/teleop channel"))?;
    Ok((channel, parse(channel)?))
}

fn parse<T: serde::de::DeserializeOwned + Default>(o: &ObjectSpec) -> Result<T, RunError> {
    penelope_runtime::objects::config::parse(&o.kind, &o.config)
        .map_err(|e| RunError::Task(format!("{}: {e}", o.name)))
}

fn task_error(e: impl Into<String>) -> RunError {
    RunError::Task(e.into())
}

/// Sets `key` to `value` in `o`'s configuration text.
fn set_key(o: &mut ObjectSpec, key: &str, value: toml::Value) -> Result<(), RunError> {
    let mut table: toml::Table = o
        .config
        .parse()
        .map_err(|e| task_error(format!("{}: {e}", o.name)))?;
    table.insert(key.to_string(), value);
    o.config = table.to_string();
    Ok(())
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

    /// The node called `name`, or an error naming it.
    fn node(&self, name: &str) -> Result<&Node, RunError> {
        self.get(name).ok_or_else(|| RunError::Node {
            what: format!("node `{name}`"),
            error: WireError::Call(CallError::UnknownName(name.into())),
        })
    }

    /// Starts recording the ticks of `controller` on node `node_name`.
    fn record(&self, node_name: &str, controller: &str) -> Result<TickStream, RunError> {
        self.node(node_name)?
            .creator()
            .record_ticks(controller, RECORD_CAPACITY)
            .map_err(|error| RunError::Node {
                what: format!("recording `{controller}`"),
                error: error.into(),
            })
    }

    /// Takes object `name` on node `node_name` through transition `t`.
    fn transition(&self, node_name: &str, name: &str, t: Transition) -> Result<(), RunError> {
        self.node(node_name)?
            .call(Call::Object {
                object: name.to_string(),
                method: Method::Transition(t),
            })
            .map(|_| ())
            .map_err(|error| RunError::Node {
                what: format!("{t:?} `{name}`"),
                error,
            })
    }

    /// Moves every node's simulated clock on by `by`. Nodes exchange samples between their
    /// loops' ticks (the data plane), so several nodes move on together, one millisecond at a
    /// time.
    fn advance(&self, by: Duration) -> Result<(), RunError> {
        let tick = if self.nodes.len() > 1 {
            Duration::from_millis(1)
        } else {
            by
        };
        let mut moved = Duration::ZERO;
        while moved < by {
            let sub = tick.min(by - moved);
            for n in &self.nodes {
                n.creator().advance(sub).map_err(|error| RunError::Node {
                    what: "advancing the simulated clock".into(),
                    error: error.into(),
                })?;
            }
            moved += sub;
        }
        Ok(())
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
        return Err(task_error(format!("scale must be positive, got {s}")));
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
    let master_stream = nodes.record(&node_of.0, &info.controllers.0)?;
    let slave_stream = nodes.record(&node_of.1, &info.controllers.1)?;
    for (n, name) in to_activate {
        nodes.transition(n, name, Transition::Activate)?;
    }
    let (mut master, mut slave) = (Vec::new(), Vec::new());
    let step = Duration::from_millis(50);
    let wall = Instant::now();
    let mut elapsed = Duration::ZERO;
    while elapsed < duration {
        let by = step.min(duration - elapsed);
        match info.clock {
            ClockMode::Simulated => {
                nodes.advance(by)?;
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
        nodes.transition(n, name, Transition::Deactivate)?;
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
