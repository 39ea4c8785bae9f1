//! The system file: one TOML file that names every object of a system, its kind and
//! configuration, its relations and the node that hosts it (DESIGN.md section 1).
//! `penelope node --name N --config FILE` creates, relates, configures and activates the
//! objects the file places on node `N` ([`SystemFile::apply`]); a file that cannot be applied
//! whole leaves nothing behind.
//!
//! ```toml
//! name = "teleop"                       # optional: what the system is called
//!
//! [timing]                              # optional: loop keys every controller gets unless it
//! period_us = 1000                      # sets them itself (`penelope ctl kinds` lists them)
//! comm_period_us = 2000
//!
//! [nodes.lab]                           # optional: real-time policy of a node
//! priority = 80                         # SCHED_FIFO priority of control threads (0: normal)
//! cpu = 1                               # pin them to this CPU
//! lock_memory = false                   # mlockall before the first tick
//! data_plane = "127.0.0.1:7410"         # where a channel to a robot on another node binds
//! record = "lab.mcap"                   # `penelope node` records from the first tick (MCAP)
//! record_scene_hz = 100                 # its 3D scene's rate (/tf, /scene), Hz of tick time
//! record_profile = "penelope"           # or "ros2": the ROS 2 topic set as CDR (docs/recordings.md)
//! records = "/var/lib/penelope/rec"     # where `ctl record start NAME` creates its files
//! robot_files = ["robots"]              # where a robot/urdf's `file` is read from
//! zenoh = "tcp/127.0.0.1:7447"          # a Zenoh bridge to this router or peer (or a table
//!                                       # { connect = ENDPOINT, config = "zenoh.json5" })
//! ros2 = true                           # in the ROS 2 graph over rmw_zenoh (or a table
//!                                       # { domain_id = 0, rate_hz = 100 }; docs/ros2.md)
//!
//! [boards.puma-io]                      # <class>.<name>: boards, robots, sensors,
//! kind = "sim"                          #   trajectories, controllers; `kind` without the class
//! node = "lab"                          # optional: default, the file's only node
//! dac_bits = 16                         # every other key is the kind's configuration
//!
//! [robots.puma]
//! kind = "puma200"
//! joints = [{ board = "puma-io", axes = [0, 1, 2, 3, 4, 5] }]  # joint i on axis axes[i];
//!                                       # `joints = [3, 4, 5]` picks joints of a robot spread
//!                                       # over several boards
//!
//! [controllers.follow]
//! kind = "slave-tracking"
//! robot = "puma"                        # relations: names on the same node...
//! trajectory = "link"
//! sensor = "wrist"                      # a sensor on another node: its name (read over the
//!                                       # data plane, see below) or its naming path
//! active = true                         # activate at start (the default)
//! ```
//!
//! A `trajectory/teleop` whose master and slave robots are on different nodes is placed on both
//! (leave out its `node`), each copy with `listen` at its node's `data_plane` address and `peer`
//! at the other's (the file's second such channel takes the next port of each, and so on); its
//! samples cross on the data plane.
//!
//! A controller whose `sensor` names a sensor on another node reads it over the data plane: the
//! relation becomes the sensor's naming path (`/node/sensors/wrist`), and the sensor needs
//! `publish = "host:port"` (where its node serves it to every reader; port 0: any free port).
//! A sensor read from several nodes is published once, and every reader gets the same samples.
//!
//! Order of work: every object is created (boards, sensors, robots, trajectories, controllers;
//! in file order within a class), then related, then configured in the same order (so a hand
//! exists before the robot it holds is configured, and robots before the channel between them),
//! then the controllers marked `active` are activated in file order (except the members of a
//! `joint-groups` controller, which run in the group's loop). Any refusal destroys
//! everything created so far and names the line, the object and the step.

mod apply;
mod cross_node;
mod parse;

use std::collections::BTreeMap;

use serde::Deserialize;

use penelope_protocol::proto::{JointAxis, WireError};
use penelope_runtime::objects::RtPolicy;

pub use apply::ApplyTarget;

/// The classes of a system file, in the order their objects are created and configured.
pub const CLASSES: [&str; 5] = ["boards", "sensors", "robots", "trajectories", "controllers"];

/// A node's real-time policy in a system file.
#[derive(Clone, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodePolicy {
    /// SCHED_FIFO priority of control threads (1-99; 0: normal scheduling).
    pub priority: Option<u8>,
    /// Pin control threads to this CPU.
    pub cpu: Option<usize>,
    /// `mlockall` before the first tick.
    pub lock_memory: Option<bool>,
    /// The node's data-plane address: a teleoperation channel between a robot on this node
    /// and one on another binds it (the file's first such channel on this port, the next on
    /// the port after, and so on).
    pub data_plane: Option<std::net::SocketAddr>,
    /// `penelope node` records every tick of the controllers the file activates on this node,
    /// their safety events and its channels' links, from the first tick, to this MCAP file
    /// (relative to the node's working directory; `--record` overrides it).
    pub record: Option<std::path::PathBuf>,
    /// How often that recording draws the robots in 3D (`/tf`, `/scene`), Hz of tick time, 0..=10000
    /// (0: their descriptions only; default 100; `--record-scene-hz` overrides it).
    pub record_scene_hz: Option<u32>,
    /// What that recording holds: `"penelope"` (default) or `"ros2"` (the ROS 2 topic set as
    /// CDR; `--record-profile` overrides it).
    pub record_profile: Option<penelope_runtime::objects::recording::RecordProfile>,
    /// The directory `ctl record start` creates this node's recordings in (a client names a
    /// plain file name; `--records` overrides it; default: `recordings` under the node's
    /// state directory, `$XDG_STATE_HOME/penelope/<node>`).
    pub records: Option<std::path::PathBuf>,
    /// The directories a `robot/urdf`'s `file` is read from on this node (`--robot-files`
    /// overrides them; default: the system file's directory).
    pub robot_files: Option<Vec<std::path::PathBuf>>,
    /// `penelope node` runs a Zenoh bridge ([`crate::zenoh_bridge`]) with these settings
    /// (`--zenoh` and `--zenoh-config` override them).
    pub zenoh: Option<crate::zenoh_bridge::ZenohSettings>,
    /// `penelope node` appears in the ROS 2 graph over rmw_zenoh ([`crate::ros2`]): `true` or
    /// `{ domain_id, rate_hz }` (`--ros2` and its options override it). Without `zenoh`, the
    /// bridge connects to rmw_zenoh's router at `tcp/127.0.0.1:7447`.
    pub ros2: Option<crate::ros2::Ros2Settings>,
}

impl NodePolicy {
    /// `base` with what this policy sets.
    pub fn applied_to(&self, mut base: RtPolicy) -> RtPolicy {
        if let Some(p) = self.priority {
            base.priority = (p > 0).then_some(p);
        }
        if let Some(c) = self.cpu {
            base.cpu = Some(c);
        }
        if let Some(l) = self.lock_memory {
            base.lock_memory = l;
        }
        base
    }
}

/// Joints of a robot on one board's axes.
#[derive(Clone, Debug, PartialEq)]
pub struct JointMap {
    /// The board's name.
    pub board: String,
    /// Joint and axis pairs.
    pub joints: Vec<JointAxis>,
}

/// One object of a system file.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectSpec {
    /// `class/kind`, as `penelope ctl kinds` lists it.
    pub kind: String,
    /// Its name on its node.
    pub name: String,
    /// The node that hosts it.
    pub node: String,
    /// The kind's configuration, as TOML text.
    pub config: String,
    /// Robots: joints on board axes.
    pub joints: Vec<JointMap>,
    /// Controllers: robot, trajectory and sensor.
    pub robot: Option<String>,
    /// Controllers: the trajectory.
    pub trajectory: Option<String>,
    /// Controllers: the sensor (a name, or a naming path on another node).
    pub sensor: Option<String>,
    /// Controllers: activate at start.
    pub active: bool,
    /// Line of its table in the file (1-based).
    pub line: usize,
}

/// A parsed system file.
#[derive(Clone, Debug, PartialEq)]
pub struct SystemFile {
    /// What the system is called.
    pub name: Option<String>,
    /// Real-time policy per node.
    pub nodes: BTreeMap<String, NodePolicy>,
    /// Every object, in creation order.
    pub objects: Vec<ObjectSpec>,
}

/// Why a system file could not be read or applied.
#[derive(Debug, thiserror::Error)]
pub enum SystemFileError {
    /// Not TOML, or not a system file; names the line and key where it can.
    #[error("line {line}: {message}")]
    Parse {
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// An object is wrong before anything was created.
    #[error("line {line}: {key}: {message}")]
    Invalid {
        /// 1-based line of the object's table.
        line: usize,
        /// The key, such as `robots.puma.joints`.
        key: String,
        /// What is wrong.
        message: String,
    },
    /// The node refused a step; everything created from the file was destroyed again.
    #[error("line {line}: {key}: {step}: {error} (nothing from the file was kept)")]
    Step {
        /// 1-based line of the object's table.
        line: usize,
        /// The object, such as `robots.puma`.
        key: String,
        /// The step (`create`, `map joints`, `configure`, ...).
        step: String,
        /// The node's error.
        error: WireError,
    },
}

impl SystemFile {
    /// The nodes the file places objects on (or names in `[nodes]`).
    pub fn node_names(&self) -> Vec<String> {
        let mut names: Vec<String> = self.nodes.keys().cloned().collect();
        for o in &self.objects {
            if !o.node.is_empty() && !names.contains(&o.node) {
                names.push(o.node.clone());
            }
        }
        names
    }

    /// The objects on node `node` (objects without `node` belong to the file's only node,
    /// whatever it is called).
    pub fn objects_on<'a>(&'a self, node: &'a str) -> impl Iterator<Item = &'a ObjectSpec> + 'a {
        self.objects
            .iter()
            .filter(move |o| o.node.is_empty() || o.node == node)
    }

    /// The real-time policy of node `node` applied to `base`.
    pub fn policy(&self, node: &str, base: RtPolicy) -> RtPolicy {
        self.nodes.get(node).map_or(base, |p| p.applied_to(base))
    }
}

/// The system-file class key of a `class/kind`.
fn class_key(kind: &str) -> &'static str {
    match kind.split('/').next() {
        Some("board") => "boards",
        Some("sensor") => "sensors",
        Some("robot") => "robots",
        Some("trajectory") => "trajectories",
        _ => "controllers",
    }
}
