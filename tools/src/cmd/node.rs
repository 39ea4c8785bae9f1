//! `penelope node`: one Penelope process of the distributed system (one per PC in the paper).
//!
//! ```text
//! penelope node --name lab-a --host-naming                     # hosts the naming service on :7300
//! penelope node --name lab-b --naming 127.0.0.1:7300           # registers in it
//! penelope node --name lab --config config/teleop.toml       # objects up at start
//! penelope node --name lab-c --listen 0.0.0.0:7302 --advertise 10.0.0.3:7302 \
//!     --naming 10.0.0.1:7300 --secret-file lab.secret          # a LAN needs the shared secret
//! ```
//!
//! At start only the node's creator exists, bound at `/<name>/creator`. With `--config`, the
//! objects a system file places on this node are created, related, configured and activated;
//! the format is documented in [`penelope_supervisor::system`], with examples at
//! `config/teleop.toml` (the paper's task) and `config/node-example.toml`. The node runs until
//! Ctrl-C or SIGTERM, then deactivates every loop (amplifiers off) and unregisters from the
//! naming service.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context as _;
use penelope_protocol::proto::{DEFAULT_PORT, ObjectInfo};
use penelope_runtime::objects::recording::RecordProfile;
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_supervisor::ros2::Ros2Settings;
use penelope_supervisor::system::SystemFile;
use penelope_supervisor::zenoh_bridge::ZenohSettings;

use super::naming::{block_stop_signals, read_secret, refuse_open_listen, wait_for_stop};

/// Options of `penelope node`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The node's name: its context /NAME in the naming tree (letters, digits, `_ . -`).
    #[arg(long)]
    pub name: String,
    /// Address to listen on [default: 127.0.0.1:7300 with --host-naming, else 127.0.0.1 on any
    /// free port]. Anything but loopback requires --secret-file.
    #[arg(long)]
    pub listen: Option<SocketAddr>,
    /// Address registered in the naming tree, when it differs from --listen (0.0.0.0, NAT).
    #[arg(long, value_name = "HOST:PORT")]
    pub advertise: Option<String>,
    /// The naming service's address.
    #[arg(long, value_name = "ADDR", conflicts_with = "host_naming",
          default_value_t = SocketAddr::from(([127, 0, 0, 1], DEFAULT_PORT)))]
    pub naming: SocketAddr,
    /// Host the naming service in this node.
    #[arg(long)]
    pub host_naming: bool,
    /// A system file: the objects it places on this node are created, related, configured and
    /// activated at start (its `[nodes.NAME]` real-time policy applies unless overridden here).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// File holding the shared secret of the system (its bytes, a trailing newline ignored;
    /// readable by its owner only).
    #[arg(long, value_name = "FILE")]
    pub secret_file: Option<PathBuf>,
    /// File holding the admin secret (with --secret-file): creating and destroying this
    /// node's objects over the network, and writing anywhere in the naming service it hosts,
    /// need it.
    #[arg(long, value_name = "FILE", requires = "secret_file")]
    pub admin_secret_file: Option<PathBuf>,
    /// SCHED_FIFO priority of the control threads (1-99; 0: normal scheduling) [default: the
    /// system file's, else 80].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(0..=99))]
    pub priority: Option<u8>,
    /// Pin the control threads to this CPU.
    #[arg(long, value_name = "N")]
    pub cpu: Option<usize>,
    /// Lock memory (mlockall) before the first control tick.
    #[arg(long)]
    pub lock_memory: bool,
    /// Clock the loops on a simulated clock instead of real time: it stands still until
    /// `penelope ctl advance NODE DURATION` moves it (faster than real time, reproducible).
    #[arg(long)]
    pub sim_clock: bool,
    /// Record every control tick of the controllers the system file activates on this node,
    /// their safety events and the statistics of its channels' links to the MCAP file FILE,
    /// from their first tick until the node stops (`penelope recording info FILE` lists it; `penelope
    /// bench layout` reads it back for its report). Overrides the system file's `record` for
    /// this node.
    #[arg(long, value_name = "FILE", requires = "config")]
    pub record: Option<PathBuf>,
    /// How often that recording draws the robots in 3D (`/tf`, `/scene`: every link of every
    /// recorded robot, the contact shapes, the force arrows), Hz of tick time, 0..=10000 (0:
    /// the robots' descriptions only) [default: the system file's `record_scene_hz`, else 100].
    #[arg(long, value_name = "HZ")]
    pub record_scene_hz: Option<u32>,
    /// What that recording holds: `penelope` (every tick in full, events, links, the 3D
    /// scene: what replay and task reports read) or `ros2` (the ROS 2 topic set as CDR with
    /// `ros2msg` schemas, for `ros2 bag` and ROS tools; its rate is `--record-scene-hz`, 0:
    /// every tick) [default: the system file's `record_profile`, else penelope].
    #[arg(long, value_name = "PROFILE", value_parser = ["penelope", "ros2"])]
    pub record_profile: Option<String>,
    /// The directory `penelope ctl record start NODE NAME` creates its recordings in: a client
    /// names a plain file name there, created new, never through a link [default: the system
    /// file's `records`, else `recordings` under $XDG_STATE_HOME/penelope/NAME or
    /// ~/.local/state/penelope/NAME]. (`--record FILE` is the node owner's own path.)
    #[arg(long, value_name = "DIR")]
    pub records: Option<PathBuf>,
    /// A directory a `robot/urdf`'s `file` may be read from (repeat for several) [default: the
    /// system file's `robot_files`, else the system file's directory; without either, no robot
    /// file is read].
    #[arg(long, value_name = "DIR")]
    pub robot_files: Vec<PathBuf>,
    /// Run a Zenoh bridge connected to the router or peer at ENDPOINT (`tcp/127.0.0.1:7447`):
    /// telemetry, safety events and link statistics on `penelope/NAME/OBJECT/STREAM`, the
    /// object tree on `penelope/NAME/objects`, operator poses into channels with
    /// `zenoh_reference` (docs/zenoh.md). Overrides the system file's `zenoh`. Needs a build
    /// with `--features zenoh`.
    #[arg(long, value_name = "ENDPOINT")]
    pub zenoh: Option<String>,
    /// Zenoh's own configuration file (JSON5), passed through to the bridge's session
    /// (multicast scouting stays off unless it mentions `multicast`).
    #[arg(long, value_name = "FILE")]
    pub zenoh_config: Option<PathBuf>,
    /// A Zenoh user (user-password authentication, set in --zenoh-config) that may publish
    /// operator poses to this node; repeat for several. With it, the bridge's access control
    /// lets every participant subscribe and query, and only these users put (docs/zenoh.md).
    /// Overrides the system file's `operators`.
    #[arg(long, value_name = "USER")]
    pub zenoh_operator: Vec<String>,
    /// Appear in the ROS 2 graph over rmw_zenoh as node `penelope_NAME` (docs/ros2.md): the
    /// CRTK topics of every robot a controller here drives, `/tf`, `/diagnostics`, and
    /// `servo_jp` / `servo_cp` subscriptions. Runs on the Zenoh bridge: without --zenoh it
    /// connects to rmw_zenoh's router at `tcp/127.0.0.1:7447`. Overrides the system file's `ros2`.
    #[arg(long)]
    pub ros2: bool,
    /// The ROS domain with --ros2 (0 to 232) [default: the system file's, else $ROS_DOMAIN_ID,
    /// else 0].
    #[arg(long, value_name = "N")]
    pub ros2_domain_id: Option<u32>,
    /// The ROS 2 topics' rate with --ros2, Hz of tick time (1 to 1000) [default: the system
    /// file's, else 100].
    #[arg(long, value_name = "HZ")]
    pub ros2_rate_hz: Option<u32>,
    /// Lease in the naming service, ms (renewed every third of it).
    #[arg(long, value_name = "MS", default_value_t = 3000)]
    pub lease_ms: u64,
}

/// Runs `penelope node`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let secret = read_secret(args.secret_file.as_deref())?;
    let admin_secret = read_secret(args.admin_secret_file.as_deref())?;
    let listen = args.listen.unwrap_or_else(|| {
        let port = if args.host_naming { DEFAULT_PORT } else { 0 };
        SocketAddr::from(([127, 0, 0, 1], port))
    });
    refuse_open_listen(listen, secret.is_some())?;
    let file = read_system_file(args.config.as_deref())?;
    let naming = if args.host_naming {
        NamingChoice::Host
    } else {
        NamingChoice::Remote(args.naming)
    };
    let mut config = NodeConfig::new(args.name.clone(), naming.clone());
    config.listen = listen;
    config.advertise = args.advertise.clone();
    config.secret = secret;
    config.server.admin_secret = admin_secret;
    config.lease = Duration::from_millis(args.lease_ms);
    // The system file's policy for this node, then what the command line says.
    let mut rt = file.as_ref().map_or(config.creator.rt, |f| {
        f.policy(&args.name, config.creator.rt)
    });
    if let Some(p) = args.priority {
        rt.priority = (p > 0).then_some(p);
    }
    if args.cpu.is_some() {
        rt.cpu = args.cpu;
    }
    rt.lock_memory |= args.lock_memory;
    config.creator.rt = rt;
    if args.sim_clock {
        config.creator.clock = penelope_runtime::objects::clock::ClockMode::Simulated;
    }
    set_file_dirs(&mut config, &args, file.as_ref());
    let mut zenoh = zenoh_settings(&args, file.as_ref());
    config.ros2 = ros2_settings(&args, file.as_ref())?;
    if config.ros2.is_some() && zenoh.is_none() {
        zenoh = Some(ZenohSettings {
            connect: Some(RMW_ZENOH_ROUTER.into()),
            ..ZenohSettings::default()
        });
    }
    let (config_zenoh, config_ros2) = (zenoh.clone(), config.ros2);
    config.zenoh = zenoh;

    let signals = block_stop_signals()?;
    let node = Node::start(config).map_err(|e| match e {
        penelope_supervisor::node::NodeError::BadName(_)
        | penelope_supervisor::node::NodeError::BadLease(_) => crate::cmd::usage(e.to_string()),
        other => anyhow::Error::new(other).context(format!("starting node `{}`", args.name)),
    })?;
    announce(&node, &naming, config_zenoh.as_ref(), config_ros2);
    let mut recorder = None;
    if let Some(file) = file {
        // `--record`, else the file's `record` for this node.
        let record = args
            .record
            .clone()
            .or_else(|| file.nodes.get(node.name()).and_then(|p| p.record.clone()));
        let scene_hz = args
            .record_scene_hz
            .or_else(|| file.nodes.get(node.name()).and_then(|p| p.record_scene_hz))
            .map_or(
                penelope_runtime::objects::recording::DEFAULT_SCENE_HZ,
                f64::from,
            );
        // (clap has checked the word.)
        let profile = args
            .record_profile
            .as_deref()
            .and_then(RecordProfile::from_name)
            .or_else(|| file.nodes.get(node.name()).and_then(|p| p.record_profile))
            .unwrap_or_default();
        let applied = match &record {
            None => file.apply(&node).map_err(anyhow::Error::new),
            Some(path) => penelope_supervisor::runs::recording::apply_recorded(
                &node, &file, path, scene_hz, profile,
            )
            .map(|(created, r)| {
                recorder = Some(r);
                created
            })
            .map_err(anyhow::Error::new),
        };
        match applied {
            Ok(created) => print_created(&node, created),
            Err(e) => {
                node.shutdown();
                return Err(e.context("applying the system file"));
            }
        }
    }
    println!("Ctrl-C stops the node");
    let signal = wait_for_stop(&signals)?;
    println!("{signal}: deactivating the loops and unregistering");
    node.shutdown();
    if let Some(r) = recorder {
        let ticks = r.finish().context("finishing the recording")?;
        println!("recorded {ticks} control ticks");
    }
    Ok(ExitCode::SUCCESS)
}

/// The system file at `path`, read and parsed, when one is given.
fn read_system_file(path: Option<&Path>) -> anyhow::Result<Option<SystemFile>> {
    let Some(path) = path else {
        return Ok(None);
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading the system file {}", path.display()))?;
    Ok(Some(SystemFile::parse(&text).map_err(|e| {
        crate::cmd::usage(format!("{}: {e}", path.display()))
    })?))
}

/// Where clients' files go and come from: the command line, the system file, defaults (the
/// node's records directory; robot files next to the system file).
fn set_file_dirs(config: &mut NodeConfig, args: &Args, file: Option<&SystemFile>) {
    let policy = file.and_then(|f| f.nodes.get(&args.name));
    config.creator.records = Some(
        args.records
            .clone()
            .or_else(|| policy.and_then(|p| p.records.clone()))
            .unwrap_or_else(|| penelope_runtime::objects::files::default_records_dir(&args.name)),
    );
    config.creator.robot_files = if !args.robot_files.is_empty() {
        args.robot_files.clone()
    } else if let Some(dirs) = policy.and_then(|p| p.robot_files.clone()) {
        dirs
    } else {
        args.config
            .as_deref()
            .map(|c| {
                let dir = c.parent().unwrap_or(std::path::Path::new(""));
                vec![if dir.as_os_str().is_empty() {
                    PathBuf::from(".")
                } else {
                    dir.to_path_buf()
                }]
            })
            .unwrap_or_default()
    };
}

/// The system file's Zenoh settings for this node, then what the command line says.
fn zenoh_settings(args: &Args, file: Option<&SystemFile>) -> Option<ZenohSettings> {
    let mut zenoh = file
        .and_then(|f| f.nodes.get(&args.name))
        .and_then(|p| p.zenoh.clone());
    if args.zenoh.is_some() || args.zenoh_config.is_some() || !args.zenoh_operator.is_empty() {
        let z = zenoh.get_or_insert_with(Default::default);
        if args.zenoh.is_some() {
            z.connect = args.zenoh.clone();
        }
        if args.zenoh_config.is_some() {
            z.config = args.zenoh_config.clone();
        }
        if !args.zenoh_operator.is_empty() {
            z.operators = args.zenoh_operator.clone();
        }
    }
    zenoh
}

/// Where rmw_zenoh's router (`rmw_zenohd`) listens by default.
const RMW_ZENOH_ROUTER: &str = "tcp/127.0.0.1:7447";

/// The system file's ROS 2 settings for this node, then what the command line says.
fn ros2_settings(args: &Args, file: Option<&SystemFile>) -> anyhow::Result<Option<Ros2Settings>> {
    let mut ros2 = file
        .and_then(|f| f.nodes.get(&args.name))
        .and_then(|p| p.ros2);
    if args.ros2 || args.ros2_domain_id.is_some() || args.ros2_rate_hz.is_some() {
        let r = ros2.get_or_insert_with(|| Ros2Settings {
            domain_id: std::env::var("ROS_DOMAIN_ID")
                .ok()
                .and_then(|d| d.trim().parse().ok())
                .unwrap_or(0),
            ..Ros2Settings::default()
        });
        if let Some(d) = args.ros2_domain_id {
            r.domain_id = d;
        }
        if let Some(hz) = args.ros2_rate_hz {
            r.rate_hz = hz;
        }
        r.check().map_err(crate::cmd::usage)?;
    }
    Ok(ros2)
}

/// Prints where the node listens, its naming service, its Zenoh bridge and its ROS 2 presence.
fn announce(
    node: &Node,
    naming: &NamingChoice,
    zenoh: Option<&ZenohSettings>,
    ros2: Option<Ros2Settings>,
) {
    let naming_text = match naming {
        NamingChoice::Host => format!("hosted here ({})", node.advertised()),
        NamingChoice::Remote(a) if node.is_registered() => a.to_string(),
        NamingChoice::Remote(a) => format!("{a}, not answering yet: registering when it does"),
        NamingChoice::None => "none".into(),
    };
    println!(
        "node {} on {} (naming path {}/creator, naming service {naming_text})",
        node.name(),
        node.advertised(),
        node.context()
    );
    if let Some(z) = zenoh {
        println!(
            "zenoh bridge: connecting to {}, publishing penelope/{}/**",
            z.connect
                .as_deref()
                .unwrap_or("what its configuration file says"),
            node.name()
        );
    }
    if let Some(r) = ros2 {
        println!(
            "ros2: node /penelope_{} in domain {} (rmw_zenoh), topics at {} Hz",
            penelope_runtime::objects::recording::ros2_topics::ros_name(node.name()),
            r.domain_id,
            r.rate_hz
        );
    }
}

/// Prints the objects the system file created on the node, each with its state now.
fn print_created(node: &Node, created: Vec<ObjectInfo>) {
    for info in created {
        let state = node
            .creator()
            .info(&info.name)
            .map_or(info.state, |i| i.state);
        println!("  {} {} ({state:?})", info.kind, info.name);
    }
}
