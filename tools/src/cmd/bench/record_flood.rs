//! `penelope bench record --flood N`: the demo's loops on the real clock, in a node of this
//! process, measured side by side in four stretches of `--duration` each: idle, recording
//! every tick, recording while `N` clients (`ctl watch` processes whose output nobody reads)
//! subscribe to every tick and stop reading (their frames back up in the node: the telemetry
//! a slow client cannot take is dropped for it, and a client that takes nothing for the write
//! timeout, 5 s, is dropped), and idle again (the
//! machine's load may drift over a run: the two idle stretches bound it).
//!
//! Per stretch: the loops' ticks, overruns and telemetry-ring losses (a ring overflows only
//! when the pump that feeds the recorder and the clients is held up), and what the recorder
//! wrote and lost. A recording or a flood that disturbed the loops would show as overruns or
//! ring losses above the idle stretches'.

use std::net::SocketAddr;
use std::path::Path;
use std::time::Duration;

use anyhow::Context as _;
use penelope_protocol::proto::{Call, ControllerMethod, CreatorCall, Method, Reply};
use penelope_runtime::objects::recording::read_recording;
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_supervisor::runs::DEMO_SYSTEM;
use penelope_supervisor::system::SystemFile;
use serde::Serialize;

/// The demo's controllers.
const CONTROLLERS: [&str; 2] = ["display", "follow"];

/// One stretch's counts (both loops summed).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Stretch {
    /// What ran beside the loops.
    pub load: String,
    /// Control ticks.
    pub ticks: u64,
    /// Ticks that ended past their period.
    pub overruns: u64,
    /// Samples the loops' telemetry rings lost (their pump held up).
    pub ring_dropped: u64,
    /// Ticks the recorder wrote (from its start to its stop, a little more than the stretch).
    pub recorded: Option<u64>,
    /// Ticks the recorder lost (its streams full), as its file says.
    pub recorder_dropped: Option<u64>,
    /// Connections the node dropped in the stretch (slow clients past the write timeout).
    pub clients_dropped: u64,
}

/// A `penelope ctl watch` process whose output nobody reads; killed when dropped.
struct SlowReader {
    child: std::process::Child,
    // Kept open: what it says later must not meet a closed pipe.
    _stderr: std::io::BufReader<std::process::ChildStderr>,
}

impl SlowReader {
    fn start(naming: SocketAddr, controller: &str) -> anyhow::Result<SlowReader> {
        use std::io::BufRead as _;
        use std::process::{Command, Stdio};
        let mut child = Command::new(std::env::current_exe()?)
            .args(["ctl", "--naming", &naming.to_string(), "--timeout", "300"])
            .args(["watch", &format!("/lab/controllers/{controller}")])
            .args(["--decimation", "1", "--json"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .context("starting a `ctl watch`")?;
        let mut stderr = std::io::BufReader::new(child.stderr.take().context("its stderr")?);
        let mut said = String::new();
        stderr.read_line(&mut said)?;
        anyhow::ensure!(said.starts_with("watching "), "ctl watch: {said}");
        Ok(SlowReader {
            child,
            _stderr: stderr,
        })
    }
}

impl Drop for SlowReader {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The loops' counters now: (ticks, overruns, ring losses), both loops summed.
fn counters(node: &Node) -> anyhow::Result<(u64, u64, u64)> {
    let mut sum = (0, 0, 0);
    for c in CONTROLLERS {
        let reply = node.call(Call::Object {
            object: c.into(),
            method: Method::Controller(ControllerMethod::Status),
        })?;
        let Reply::Status(s) = reply else {
            anyhow::bail!("{c}: status answered {reply:?}");
        };
        anyhow::ensure!(s.running, "{c} stopped running");
        sum.0 += s.ticks;
        sum.1 += s.overruns;
        sum.2 += s.telemetry_dropped;
    }
    Ok(sum)
}

/// Runs the four stretches, `duration` each, with `clients` slow subscribers in the third;
/// recordings go to `dir`.
///
/// # Errors
/// The node or the demo cannot start, a call fails, a file cannot be written.
pub fn measure(dir: &Path, clients: usize, duration: Duration) -> anyhow::Result<Vec<Stretch>> {
    let mut config = NodeConfig::new("lab", NamingChoice::Host);
    config.listen = SocketAddr::from(([127, 0, 0, 1], 0));
    config.creator.records = Some(dir.to_path_buf());
    let node = Node::start(config).context("starting a node")?;
    let system = SystemFile::parse(DEMO_SYSTEM)?;
    system
        .apply(&node)
        .context("applying the demo's system file")?;
    let mut stretches = Vec::new();
    let stretch = |load: &str, record: Option<&str>, flood: usize| -> anyhow::Result<Stretch> {
        let dropped_before = node.stats().dropped;
        if let Some(file) = record {
            node.call(Call::Creator(CreatorCall::RecordStart {
                path: file.to_string(),
                objects: Vec::new(),
            }))?;
        }
        // The slow clients: `ctl watch` of every tick into a pipe nobody reads (a pipe fills
        // in a tenth of a second; then the watcher stops reading its socket, and the node's
        // sends to it back up), subscribed one at a time, each ready when it says so.
        let mut slow = Vec::new();
        for i in 0..flood {
            slow.push(SlowReader::start(node.address(), CONTROLLERS[i % 2])?);
        }
        let before = counters(&node)?;
        std::thread::sleep(duration);
        let after = counters(&node)?;
        let (recorded, recorder_dropped) = match record {
            Some(file) => match node.call(Call::Creator(CreatorCall::RecordStop))? {
                Reply::Recorded { ticks, .. } => {
                    let r = read_recording(&dir.join(file))?;
                    (Some(ticks), Some(r.dropped.values().sum()))
                }
                other => anyhow::bail!("record stop answered {other:?}"),
            },
            None => (None, None),
        };
        drop(slow);
        Ok(Stretch {
            load: load.into(),
            ticks: after.0 - before.0,
            overruns: after.1 - before.1,
            ring_dropped: after.2 - before.2,
            recorded,
            recorder_dropped,
            clients_dropped: node.stats().dropped - dropped_before,
        })
    };
    stretches.push(stretch("idle", None, 0)?);
    stretches.push(stretch("recording", Some("recording.mcap"), 0)?);
    let flood = format!("recording + {clients} slow clients");
    stretches.push(stretch(&flood, Some("flooded.mcap"), clients)?);
    stretches.push(stretch("idle again", None, 0)?);
    node.shutdown();
    Ok(stretches)
}

/// Prints the stretches as a table.
pub fn print(stretches: &[Stretch]) {
    println!("  the demo's loops on the real clock, stretches side by side:");
    println!(
        "    {:<32} {:>7} {:>9} {:>13} {:>9} {:>9} {:>15}",
        "beside the loops",
        "ticks",
        "overruns",
        "ring dropped",
        "recorded",
        "rec lost",
        "clients dropped"
    );
    let opt = |v: Option<u64>| v.map_or("-".to_string(), |v| v.to_string());
    for s in stretches {
        println!(
            "    {:<32} {:>7} {:>9} {:>13} {:>9} {:>9} {:>15}",
            s.load,
            s.ticks,
            s.overruns,
            s.ring_dropped,
            opt(s.recorded),
            opt(s.recorder_dropped),
            s.clients_dropped
        );
    }
}
