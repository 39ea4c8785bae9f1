//! `penelope ctl`: talk to the nodes of a running system through the naming service.
//!
//! ```text
//! penelope ctl [--naming ADDR] [--secret-file FILE] [--json] [--timeout S] VERB ...
//! ```
//!
//! Objects are named by their naming path (`/lab-a/robots/slave`) or by the shorthand
//! `NODE/NAME` (`lab-a/slave`; names are unique on a node, so it is never ambiguous).
//!
//! | verb | what it does |
//! |---|---|
//! | `ls [CONTEXT]` | the naming tree under `CONTEXT` (default `/`), with each object's kind and lifecycle state |
//! | `kinds [NODE]` | the kinds every node (or `NODE`) can create, with their configuration keys |
//! | `create NODE KIND NAME [--config TOML \| --config-file F] [key=value ...]` | makes an object (it starts `unconfigured`) |
//! | `destroy PATH [--force]` | removes it; refused while an active object depends on it unless `--force` |
//! | `configure PATH`, `activate PATH`, `deactivate PATH`, `cleanup PATH` | lifecycle transitions (ROS 2 words) |
//! | `describe PATH` | kind, state and relations of an object |
//! | `estop PATH \| NODE \| --all` | latches the e-stop of a controller, of every loop of a node, or of every loop of every node (asked in parallel, each on a connection of its own, served before any other work of the node) |
//! | `call PATH METHOD [ARGS...]` | any method of the object: see [`method::METHODS`] (`joint-positions`, `fk [Q]`, `jacobian`, `ik X Y Z`, `gravity`, `inertia`, `named-pose work`, `go-to work 2.0`, `read`, `bias`, `set-robot NAME`, `set-gains TOML`, `status`, `estop`, `rearm`, `reference 0.5`, `map-joints BOARD J:A ...`) |
//! | `watch PATH [--decimation N] [--count N \| --seconds S]` | live telemetry lines: time, sequence, joints, tool position, force, safety state; for a `trajectory/teleop` channel linked to another node, its link every 100 ms: clock offset, one-way delay, jitter, trip p50/p99, samples taken/missed, refused, heartbeats lost, up/down, last heard |
//! | `run SCRIPT` | runs a file of these verbs, one per line (`#` comments, shell quoting), stopping at the first error with its line number; `-` reads standard input |
//!
//! Output is for humans unless `--json` (one JSON value per verb; for `call`, the reply as the
//! protocol defines it; for `watch`, one JSON telemetry or link record per line). Bad input exits with
//! code 2 (nothing is sent), an error from a node with code 1 and the node's message.

use penelope_web::cli::{config_text, method, object_states, show};
mod watch;

use std::io::{Read, Write};
use std::net::{SocketAddr, ToSocketAddrs};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context as _;
use clap::Parser;
use penelope_protocol::client::Client;
use penelope_protocol::net::conn::ClientConfig;
use penelope_protocol::proto::{
    BoardMethod, Call, Class, ControllerMethod, Method, NameEntry, ObjectRef, Reply, RobotMethod,
    object_path, parse_transition,
};
use serde_json::json;

use crate::cmd::usage;

/// `println!` that returns the error instead of panicking (a closed pipe, as in `ctl ls | head`,
/// ends the command quietly: see [`run`]).
macro_rules! say {
    ($($arg:tt)*) => {
        writeln!(std::io::stdout(), $($arg)*)?
    };
}

/// Examples shown by `penelope ctl --help`.
const EXAMPLES: &str = "\
Examples:
  penelope ctl ls
  penelope ctl kinds lab-a
  penelope ctl create lab-a robot/puma560 slave
  penelope ctl create lab-a board/sim sim0 axes=6
  penelope ctl call /lab-a/robots/slave map-joints sim0 0:0 1:1 2:2 3:3 4:4 5:5
  penelope ctl configure /lab-a/robots/slave
  penelope ctl call lab-a/slave fk work
  penelope ctl --json call lab-a/slave jacobian 0 0.5 -0.5 0 0 0
  penelope ctl watch /lab-a/controllers/pid --count 20
  penelope ctl watch master/link --json --count 3
  penelope ctl run setup.ctl

Objects are named by naming path (/lab-a/robots/slave) or NODE/NAME (lab-a/slave).
Exit codes: 0 done, 1 a node refused or could not be reached, 2 bad input.";

/// Options of `penelope ctl`.
#[derive(clap::Args, Debug)]
#[command(after_long_help = EXAMPLES)]
pub struct Args {
    /// The naming service, HOST:PORT.
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:7300")]
    pub naming: String,
    /// A file holding the shared secret of the system (its bytes, a trailing newline ignored),
    /// as given to `penelope node` and `penelope naming` (readable by its owner only). With it,
    /// ctl sends nothing to a node that does not prove the secret.
    #[arg(long, value_name = "FILE")]
    pub secret_file: Option<PathBuf>,
    /// A file holding the admin secret (with --secret-file): ctl then connects as an
    /// administrator.
    #[arg(long, value_name = "FILE", requires = "secret_file")]
    pub admin_secret_file: Option<PathBuf>,
    /// Print JSON instead of text (for `call`: the protocol's reply; for `watch`: one record
    /// per line).
    #[arg(long, global = true)]
    pub json: bool,
    /// Seconds to wait for a node's answer (and, in `watch`, for the first sample).
    #[arg(long, value_name = "S", default_value_t = 5.0)]
    pub timeout: f64,
    /// What to do.
    #[command(subcommand)]
    pub verb: Verb,
}

/// The verbs of `penelope ctl`.
#[derive(clap::Subcommand, Debug)]
pub enum Verb {
    /// The naming tree: contexts, objects with their kind and lifecycle state.
    Ls {
        /// The context to list (default: the root).
        #[arg(default_value = "/")]
        context: String,
    },
    /// The kinds each node can create, with their configuration keys (units, defaults).
    Kinds {
        /// Only this node.
        node: Option<String>,
    },
    /// Create an object on a node; it starts unconfigured and is bound in the naming tree.
    Create {
        /// The node (its name in the naming tree).
        node: String,
        /// The kind, such as robot/puma560, board/sim, controller/joint-pid (see `kinds`).
        kind: String,
        /// The object's name on the node: letters, digits, `_`, `.`, `-`.
        name: String,
        /// Configuration as TOML text.
        #[arg(long, value_name = "TOML", conflicts_with = "config_file")]
        config: Option<String>,
        /// Configuration from a TOML file.
        #[arg(long, value_name = "FILE")]
        config_file: Option<PathBuf>,
        /// Settings as key=value (value in TOML; a bare word is taken as a string).
        #[arg(value_name = "KEY=VALUE")]
        settings: Vec<String>,
    },
    /// Destroy an object (refused while an active object uses it, unless --force).
    Destroy {
        /// The object: naming path or NODE/NAME.
        path: String,
        /// Stop the active objects that use it first (amplifiers off, loops stopped).
        #[arg(long)]
        force: bool,
    },
    /// Move a node's simulated clock on (a node started with --sim-clock), stepping its loops.
    Advance {
        /// The node (its name in the naming tree).
        node: String,
        /// How far, for example `20s` or `500ms`.
        #[arg(value_parser = crate::cmd::demo::parse_duration)]
        duration: std::time::Duration,
    },
    /// unconfigured -> inactive: check the relations and build the object.
    Configure {
        /// The object: naming path or NODE/NAME.
        path: String,
    },
    /// inactive -> active: a controller starts its real-time loop from the measured state.
    Activate {
        /// The object: naming path or NODE/NAME.
        path: String,
    },
    /// active -> inactive: a controller stops its loop safely.
    Deactivate {
        /// The object: naming path or NODE/NAME.
        path: String,
    },
    /// inactive -> unconfigured.
    Cleanup {
        /// The object: naming path or NODE/NAME.
        path: String,
    },
    /// Latch the emergency stop (amplifiers off until re-armed) of a running controller
    /// (PATH), of every loop of a node (NODE), or of every loop of the system (--all). Served
    /// ahead of any other work of the node, on a connection of its own.
    Estop {
        /// The controller (naming path or NODE/NAME), or a node's name.
        #[arg(required_unless_present = "all", conflicts_with = "all")]
        path: Option<String>,
        /// Every loop on every node in the naming tree, the nodes asked in parallel.
        #[arg(long)]
        all: bool,
    },
    /// Re-arm, once the cause is gone: a controller after a fault, an e-stop or a failed thread
    /// (its loop restarts from the measured state, no jump), or a board that latched a fault of
    /// its own (a lost Galil line).
    Rearm {
        /// The controller or board: naming path or NODE/NAME.
        path: String,
    },
    /// Kind, lifecycle state and relations of an object.
    Describe {
        /// The object: naming path or NODE/NAME.
        path: String,
    },
    /// Call a method of an object (`call PATH help` lists them).
    #[command(after_long_help = method::METHODS)]
    Call {
        /// The object: naming path or NODE/NAME.
        path: String,
        /// The method, kebab-case: joint-positions, fk, jacobian, ik, gravity, inertia,
        /// named-pose, go-to, map-joints, read, bias, measure, set-robot, set-trajectory,
        /// set-sensor, set-gains, status, estop, rearm, reference, duration, ...
        method: String,
        /// The method's arguments (numbers may be negative).
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
    /// Live telemetry of a running controller (or the robot it drives), one line per sample;
    /// of a teleoperation channel linked to another node, its link's statistics every 100 ms.
    Watch {
        /// The object: naming path or NODE/NAME.
        path: String,
        /// Show one control tick (or one link record) in N.
        #[arg(long, value_name = "N", default_value_t = 1)]
        decimation: u32,
        /// Stop after N samples (or records).
        #[arg(long, value_name = "N")]
        count: Option<u64>,
        /// Stop after S seconds.
        #[arg(long, value_name = "S")]
        seconds: Option<f64>,
    },
    /// Record to MCAP on a node: `record start NODE PATH [OBJECTS...]`, `record stop NODE`.
    #[command(subcommand)]
    Record(RecordVerb),
    /// Run a script: one verb per line, `#` comments, shell quoting; stops at the first error.
    Run {
        /// The script file, or `-` for standard input.
        script: String,
    },
}

/// `penelope ctl record`.
#[derive(clap::Subcommand, Debug)]
pub enum RecordVerb {
    /// Start recording every tick of controllers, their safety events and channels' link
    /// statistics to a new MCAP file on the node's host (`penelope recording info FILE` lists it).
    Start {
        /// The node (its name in the naming tree).
        node: String,
        /// The file: a plain name `*.mcap` (no `/`), created new in the node's recordings
        /// directory (`penelope node --records DIR`); never overwritten, never through a link.
        path: String,
        /// The controllers and channels to record, by name on the node (default: all).
        objects: Vec<String>,
        /// How often the recording draws the recorded robots in 3D (`/tf`, `/scene`), Hz of
        /// tick time, 0..=10000 (0: their descriptions only) [default: 100].
        #[arg(long, value_name = "HZ")]
        scene_hz: Option<f64>,
    },
    /// Stop the node's recording and close its file.
    Stop {
        /// The node (its name in the naming tree).
        node: String,
    },
}

/// One line of a script.
#[derive(Parser, Debug)]
#[command(name = "ctl", no_binary_name = true, disable_help_subcommand = true)]
struct ScriptLine {
    /// JSON output for this line.
    #[arg(long, global = true)]
    json: bool,
    #[command(subcommand)]
    verb: Verb,
}

/// Runs `penelope ctl`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if !(args.timeout.is_finite() && args.timeout > 0.0) {
        return Err(usage(format!(
            "--timeout must be > 0 s, got {}",
            args.timeout
        )));
    }
    let naming = args
        .naming
        .to_socket_addrs()
        .ok()
        .and_then(|mut a| a.next())
        .ok_or_else(|| usage(format!("--naming: `{}` is not HOST:PORT", args.naming)))?;
    let mut config = ClientConfig::new("penelope-ctl");
    config.timeout = Duration::from_secs_f64(args.timeout);
    // Read exactly as `penelope node` and `penelope naming` read it.
    config.secret = crate::cmd::naming::read_secret(args.secret_file.as_deref())?;
    config.admin_secret = crate::cmd::naming::read_secret(args.admin_secret_file.as_deref())?;
    // The most these files prove: admin with the admin secret (or on a plain, loopback-only
    // system, where claims are taken on trust), operator with the shared secret alone.
    config.role =
        ClientConfig::strongest_role(config.secret.as_ref(), config.admin_secret.as_ref());
    let mut ctl = Ctl {
        naming,
        config,
        client: None,
    };
    match ctl.exec(args.verb, args.json, false) {
        Ok(()) => Ok(ExitCode::SUCCESS),
        // The reader went away (`penelope ctl ls | head`): nothing more to say.
        Err(e)
            if e.downcast_ref::<std::io::Error>()
                .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe) =>
        {
            Ok(ExitCode::SUCCESS)
        }
        Err(e) => Err(e),
    }
}

/// The state of one `penelope ctl` run (a script shares one client).
struct Ctl {
    naming: SocketAddr,
    config: ClientConfig,
    client: Option<Client>,
}

impl Ctl {
    fn client(&mut self) -> anyhow::Result<Client> {
        if let Some(c) = &self.client {
            return Ok(c.clone());
        }
        let c = Client::connect(self.naming, self.config.clone())
            .with_context(|| format!("cannot reach the naming service at {}", self.naming))?;
        self.client = Some(c.clone());
        Ok(c)
    }

    fn exec(&mut self, verb: Verb, json: bool, in_script: bool) -> anyhow::Result<()> {
        match verb {
            Verb::Ls { context } => self.ls(&context, json),
            Verb::Kinds { node } => self.kinds(node.as_deref(), json),
            Verb::Create {
                node,
                kind,
                name,
                config,
                config_file,
                settings,
            } => {
                let text = config_text(config, config_file.as_deref(), &settings)?;
                self.create(&node, &kind, &name, &text, json)
            }
            Verb::Destroy { path, force } => self.destroy(&path, force, json),
            Verb::Advance { node, duration } => self.advance(&node, duration, json),
            Verb::Record(RecordVerb::Start {
                node,
                path,
                objects,
                scene_hz,
            }) => self.record_start(&node, &path, &objects, scene_hz, json),
            Verb::Record(RecordVerb::Stop { node }) => self.record_stop(&node, json),
            Verb::Configure { path } => self.method(&path, "configure", &[], json),
            Verb::Activate { path } => self.method(&path, "activate", &[], json),
            Verb::Deactivate { path } => self.method(&path, "deactivate", &[], json),
            Verb::Cleanup { path } => self.method(&path, "cleanup", &[], json),
            Verb::Describe { path } => self.method(&path, "describe", &[], json),
            Verb::Estop { path, all } => self.estop(path.as_deref(), all, json),
            Verb::Rearm { path } => self.method(&path, "rearm", &[], json),
            Verb::Call { path, method, args } => {
                // `--json` after the method's arguments is ours, not the method's.
                let json = json || args.iter().any(|a| a == "--json");
                let args: Vec<String> = args.into_iter().filter(|a| a != "--json").collect();
                if method == "help" {
                    say!("{}", method::METHODS);
                    return Ok(());
                }
                self.method(&path, &method, &args, json)
            }
            Verb::Watch {
                path,
                decimation,
                count,
                seconds,
            } => self.watch(&path, decimation, count, seconds, json, in_script),
            Verb::Run { script } => {
                if in_script {
                    return Err(usage("`run` cannot be used inside a script"));
                }
                self.script(&script, json)
            }
        }
    }

    /// `create`: a new object on a node, configured from `text`.
    fn create(
        &mut self,
        node: &str,
        kind: &str,
        name: &str,
        text: &str,
        json: bool,
    ) -> anyhow::Result<()> {
        let client = self.client()?;
        let node = client.node(node)?;
        let info = node.create(kind, name, text)?;
        let path = node.path_of(&info);
        if json {
            say!("{}", json!({ "path": path, "object": info }));
        } else {
            say!("created {path} ({}): {}", info.kind, info.state);
        }
        Ok(())
    }

    /// `destroy`: an object, by its path.
    fn destroy(&mut self, path: &str, force: bool, json: bool) -> anyhow::Result<()> {
        let client = self.client()?;
        let r = client.locate(path)?;
        client.node(&r.node)?.destroy(&r.name, force)?;
        let path = path_of(&r);
        if json {
            say!("{}", json!({ "destroyed": path }));
        } else {
            say!("destroyed {path}");
        }
        Ok(())
    }

    /// `advance`: a node's simulated clock, by `duration`.
    fn advance(
        &mut self,
        node: &str,
        duration: std::time::Duration,
        json: bool,
    ) -> anyhow::Result<()> {
        let now = self.client()?.node(node)?.advance(duration)?;
        if json {
            say!("{}", json!({ "node": node, "time_s": now.as_secs_f64() }));
        } else {
            say!("{node}: simulated clock at {:.3} s", now.as_secs_f64());
        }
        Ok(())
    }

    /// `record start`: a node's recording of `objects` (all when empty) into `path`, its 3D
    /// scene at `scene_hz` (the node's default without).
    fn record_start(
        &mut self,
        node: &str,
        path: &str,
        objects: &[String],
        scene_hz: Option<f64>,
        json: bool,
    ) -> anyhow::Result<()> {
        let proxy = self.client()?.node(node)?;
        let (path, controllers, links) = match scene_hz {
            None => proxy.record_start_at(path, objects)?,
            Some(hz) => proxy.record_start_scene(path, objects, hz)?,
        };
        if json {
            say!(
                "{}",
                json!({ "node": node, "path": path, "controllers": controllers, "links": links })
            );
        } else {
            say!(
                "{node}: recording {} to {path}{}",
                controllers.join(", "),
                if links.is_empty() {
                    String::new()
                } else {
                    format!(" (links of {})", links.join(", "))
                }
            );
        }
        Ok(())
    }

    /// `record stop`: a node's recording, ended.
    fn record_stop(&mut self, node: &str, json: bool) -> anyhow::Result<()> {
        let (path, ticks) = self.client()?.node(node)?.record_stop()?;
        if json {
            say!("{}", json!({ "node": node, "path": path, "ticks": ticks }));
        } else {
            say!("{node}: recorded {ticks} control ticks to {path}");
        }
        Ok(())
    }

    /// Calls a method by its kebab-case name and prints the reply.
    fn method(
        &mut self,
        path: &str,
        name: &str,
        args: &[String],
        json: bool,
    ) -> anyhow::Result<()> {
        let client = self.client()?;
        let r = client.locate(path)?;
        let mut lookup = |m: RobotMethod| -> anyhow::Result<Reply> {
            Ok(client.call_ref(&r, Method::Robot(m))?)
        };
        let (method, hint) = method::parse(name, args, &mut lookup)?;
        // `rearm` means the board's own latch when the object is a board.
        let method = match (method, r.class) {
            (Method::Controller(ControllerMethod::Rearm), Class::Board) => {
                Method::Board(BoardMethod::Rearm)
            }
            (m, _) => m,
        };
        let reply = client.call_ref(&r, method)?;
        if json {
            say!("{}", serde_json::to_string(&reply)?);
            return Ok(());
        }
        match (
            &reply,
            parse_transition(name).is_some() || name == "describe",
        ) {
            (Reply::Object(info), true) => {
                say!("{}: {}", path_of(&r), info.state);
                if name == "describe" {
                    say!("kind {} ({})", info.kind, info.class);
                    for (rel, target) in &info.relations {
                        say!("{rel}: {target}");
                    }
                }
            }
            _ => say!("{}", show::reply(&reply, hint)),
        }
        Ok(())
    }

    /// `estop PATH`, `estop NODE` or `estop --all`: never through a creator's `list` (which
    /// waits for the node's object lock), always on fresh connections.
    fn estop(&mut self, target: Option<&str>, all: bool, json: bool) -> anyhow::Result<()> {
        let client = self.client()?;
        let reports = match (target, all) {
            (_, true) => client.estop_all()?,
            (Some(node), false) if !node.contains('/') => {
                let report = client.node(node)?.estop();
                vec![(node.to_string(), report)]
            }
            (Some(path), false) => {
                let (address, name, shown) = if path.starts_with('/') {
                    let r = client.resolve(path)?;
                    let address = r.address.parse().with_context(|| {
                        format!("`{path}` names an unusable address {}", r.address)
                    })?;
                    (address, r.name.clone(), path_of(&r))
                } else {
                    let (node, name) = path.split_once('/').unwrap_or((path, ""));
                    (
                        client.node(node)?.address(),
                        name.to_string(),
                        path.to_string(),
                    )
                };
                let call = Call::Object {
                    object: name,
                    method: Method::Controller(ControllerMethod::EStop),
                };
                client.call_alone(address, call)?;
                if json {
                    say!("{}", json!({ "estopped": shown }));
                } else {
                    say!("{shown}: e-stop latched");
                }
                return Ok(());
            }
            (None, false) => return Err(usage("estop needs a PATH, a NODE or --all")),
        };
        let mut failed = Vec::new();
        for (node, report) in &reports {
            match report {
                Ok(r) => {
                    if json {
                        say!("{}", serde_json::to_string(r)?);
                    } else {
                        say!(
                            "{node}: e-stop latched by {} loop(s){}{}",
                            r.stopped.len(),
                            if r.stopped.is_empty() {
                                String::new()
                            } else {
                                format!(" ({})", r.stopped.join(", "))
                            },
                            if r.pending.is_empty() {
                                String::new()
                            } else {
                                format!("; asked, not yet ticked: {}", r.pending.join(", "))
                            }
                        );
                    }
                }
                Err(e) => {
                    if json {
                        say!("{}", json!({ "node": node, "error": e.to_string() }));
                    } else {
                        say!("{node}: NOT REACHED: {e}");
                    }
                    failed.push(node.clone());
                }
            }
        }
        if failed.is_empty() {
            Ok(())
        } else {
            anyhow::bail!("e-stop did not reach node(s) {}", failed.join(", "))
        }
    }

    fn ls(&mut self, context: &str, json: bool) -> anyhow::Result<()> {
        let client = self.client()?;
        let tree = client.naming().tree(context)?;
        let states = object_states(&client, &tree);
        let state_of = |r: &ObjectRef| -> Option<String> {
            if r.class == penelope_protocol::proto::Class::Creator {
                None
            } else {
                Some(
                    states
                        .get(&(r.node.clone(), r.name.clone()))
                        .cloned()
                        .unwrap_or_else(|| "unreachable".into()),
                )
            }
        };
        if json {
            let entries: Vec<_> = tree
                .iter()
                .map(|(path, depth, entry)| match entry {
                    NameEntry::Context { .. } => {
                        json!({ "path": path, "depth": depth, "context": true })
                    }
                    NameEntry::Object { reference, .. } => json!({
                        "path": path, "depth": depth, "context": false,
                        "reference": reference, "state": state_of(reference),
                    }),
                })
                .collect();
            say!("{}", json!({ "context": context, "entries": entries }));
            return Ok(());
        }
        say!("{context}");
        if tree.is_empty() {
            say!("(empty)");
            return Ok(());
        }
        let mut lines = Vec::new();
        let mut open: Vec<bool> = Vec::new();
        for (i, (_, depth, entry)) in tree.iter().enumerate() {
            let last = tree[i + 1..]
                .iter()
                .find(|(_, d, _)| d <= depth)
                .is_none_or(|(_, d, _)| d < depth);
            open.truncate(*depth);
            let mut prefix: String = open
                .iter()
                .map(|more| if *more { "│   " } else { "    " })
                .collect();
            prefix += if last { "└── " } else { "├── " };
            open.push(!last);
            let (name, detail) = match entry {
                NameEntry::Context { name } => (format!("{name}/"), String::new()),
                NameEntry::Object { name, reference } => {
                    let detail = match state_of(reference) {
                        Some(state) => format!("{:<28} {state}", reference.kind),
                        None => format!("node {} at {}", reference.node, reference.address),
                    };
                    (name.clone(), detail)
                }
            };
            lines.push((format!("{prefix}{name}"), detail));
        }
        let width = lines
            .iter()
            .map(|(l, _)| l.chars().count())
            .max()
            .unwrap_or(0);
        for (left, detail) in lines {
            let pad = width.saturating_sub(left.chars().count());
            let line = format!("{left}{}  {detail}", " ".repeat(pad));
            say!("{}", line.trim_end());
        }
        Ok(())
    }

    fn kinds(&mut self, node: Option<&str>, json: bool) -> anyhow::Result<()> {
        let client = self.client()?;
        let nodes = match node {
            Some(n) => vec![client.node(n)?],
            None => client.nodes()?,
        };
        let mut all = Vec::new();
        for node in &nodes {
            all.push((node, node.kinds()?));
        }
        if json {
            let list: Vec<_> = all
                .iter()
                .map(|(n, k)| json!({ "node": n.name(), "address": n.address().to_string(), "kinds": k }))
                .collect();
            say!("{}", json!({ "nodes": list }));
            return Ok(());
        }
        if all.is_empty() {
            say!(
                "no node is registered in the naming service at {}",
                self.naming
            );
        }
        for (n, kinds) in all {
            say!("{} ({})", n.name(), n.address());
            for k in &kinds {
                say!("{}", show::kind(k));
            }
        }
        Ok(())
    }

    fn script(&mut self, script: &str, json: bool) -> anyhow::Result<()> {
        let (name, text) = if script == "-" {
            let mut text = String::new();
            std::io::stdin()
                .lock()
                .read_to_string(&mut text)
                .map_err(|e| usage(format!("reading the script from standard input: {e}")))?;
            ("stdin".to_string(), text)
        } else {
            let text = std::fs::read_to_string(script)
                .map_err(|e| usage(format!("script {script}: {e}")))?;
            (script.to_string(), text)
        };
        for (i, line) in text.lines().enumerate() {
            let at = format!("{name}:{}", i + 1);
            let words =
                shlex::split(line).ok_or_else(|| usage(format!("{at}: unbalanced quotes")))?;
            if words.is_empty() {
                continue;
            }
            let parsed = ScriptLine::try_parse_from(words).map_err(|e| {
                let text = e.to_string();
                let first = text
                    .lines()
                    .find(|l| !l.trim().is_empty())
                    .unwrap_or("cannot parse")
                    .trim_start_matches("error: ")
                    .to_string();
                usage(format!("{at}: {first}"))
            })?;
            if !json {
                say!("> {}", line.trim());
            }
            self.exec(parsed.verb, json || parsed.json, true)
                .with_context(|| format!("{at}: {}", line.trim()))?;
        }
        Ok(())
    }
}

/// The naming path of a reference.
fn path_of(r: &ObjectRef) -> String {
    object_path(&r.node, r.class, &r.name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn script_lines_parse_as_verbs() {
        let line =
            ScriptLine::try_parse_from(shlex::split("call lab-a/slave fk 0 -0.5 0 0 0 0").unwrap())
                .unwrap();
        match line.verb {
            Verb::Call { path, method, args } => {
                assert_eq!((path.as_str(), method.as_str()), ("lab-a/slave", "fk"));
                assert_eq!(args[1], "-0.5");
            }
            other => panic!("{other:?}"),
        }
        let line = ScriptLine::try_parse_from(
            shlex::split("call /a/controllers/c set-gains 'kp = [1, 2]'").unwrap(),
        )
        .unwrap();
        assert!(matches!(line.verb, Verb::Call { ref args, .. } if args == &["kp = [1, 2]"]));
        assert!(ScriptLine::try_parse_from(shlex::split("frobnicate x").unwrap()).is_err());
        assert_eq!(shlex::split("  # a comment").unwrap().len(), 0);
    }

    #[test]
    fn the_default_naming_address_is_the_default_port() {
        use clap::CommandFactory as _;
        #[derive(Parser)]
        struct Top {
            #[command(flatten)]
            args: Args,
        }
        let cmd = Top::command();
        let naming = cmd
            .get_arguments()
            .find(|a| a.get_id() == "naming")
            .and_then(|a| a.get_default_values().first().cloned())
            .unwrap();
        assert_eq!(
            naming.to_str().unwrap(),
            format!("127.0.0.1:{}", penelope_protocol::proto::DEFAULT_PORT)
        );
    }
}
