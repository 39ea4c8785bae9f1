//! `penelope bench layout`: the paper's modularity experiment with today's numbers. The demo's
//! task runs from system files alone in three layouts of hosts (network namespaces joined by
//! veth pairs to a bridge, each with its own address), with `penelope naming` and
//! `penelope node` processes started in them, and for each layout the task's tracking and
//! force results, end-to-end latencies, a raw UDP echo between the same hosts measured in the
//! same run, and loop timing are reported:
//!
//! - `1-host`: naming service and one node (`config/demo.toml`) on one host;
//! - `2-host`: the joystick (FRHC, hand) on one host; robot, sensor and naming service on the
//!   other (`config/demo-two-nodes.toml`);
//! - `4-host`: robot, joystick, sensor and naming service each alone
//!   (`config/demo-four-nodes.toml`).
//!
//! Each node's data-plane address in the file (and a sensor's `publish` address) is moved to
//! its host's address; nothing else changes. Needs root (namespaces) and `ip` (iproute2).

pub mod hosts;
pub mod latency;
mod launch;

use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context;
use penelope_protocol::proto::LinkRecord;
use penelope_runtime::objects::link_source::{StreamDatagram, StreamName};
use penelope_runtime::objects::recording::Recording;
use penelope_supervisor::runs::report::{LoopTiming, report};
use penelope_supervisor::runs::{DEMO_SYSTEM, RunOutput};
use penelope_supervisor::system::SystemFile;
use serde::Serialize;

use latency::{EndToEnd, Percentiles};

pub use launch::{LayoutPlan, WatchContext, Watcher, run_layout, run_layout_watched};

/// The demo's task split over two nodes.
pub const TWO_NODES: &str = include_str!("../../../../../config/demo-two-nodes.toml");

/// The demo's task over four nodes: joystick, robot and sensor apart.
pub const FOUR_NODES: &str = include_str!("../../../../../config/demo-four-nodes.toml");

/// Where each process of a layout runs.
#[derive(Clone, Copy, Debug)]
pub struct Layout {
    /// Its name in reports: `1-host`, `2-host`, `4-host`.
    pub name: &'static str,
    /// The system file.
    pub system: &'static str,
    /// Per host, what runs there: `None` the naming service, `Some(node)` a node.
    pub hosts: &'static [&'static [Option<&'static str>]],
    /// The joystick's host and the robot's (the echo runs between them).
    pub ends: (usize, usize),
}

/// The three layouts of the paper's modularity experiment.
pub const LAYOUTS: [Layout; 3] = [
    Layout {
        name: "1-host",
        system: DEMO_SYSTEM,
        hosts: &[&[None, Some("lab")]],
        ends: (0, 0),
    },
    Layout {
        name: "2-host",
        system: TWO_NODES,
        hosts: &[&[Some("master")], &[None, Some("slave")]],
        ends: (0, 1),
    },
    Layout {
        name: "4-host",
        system: FOUR_NODES,
        hosts: &[
            &[None],
            &[Some("master")],
            &[Some("slave")],
            &[Some("sensor")],
        ],
        ends: (1, 2),
    },
];

/// The naming service's port on its host.
const NAMING_PORT: u16 = 7300;
/// A node's server port on its host.
const NODE_PORT: u16 = 7301;
/// How long a process may take to be ready.
const READY: Duration = Duration::from_secs(30);

/// Options of `penelope bench layout`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The layouts to run, comma-separated [default: all].
    #[arg(long, value_delimiter = ',', value_parser = ["1-host", "2-host", "4-host"])]
    pub layouts: Vec<String>,
    /// Length of the task, s [default: the operator's script, 20 s].
    #[arg(long)]
    pub duration: Option<f64>,
    /// One JSON record per layout on standard output instead of the table.
    #[arg(long)]
    pub json: bool,
    /// The channel's handoff (`handoff` of `trajectory/teleop`): `event`, samples crossing as
    /// they are made, or `periodic`, at the communication period [default: the file's].
    #[arg(long, value_parser = ["event", "periodic"])]
    pub handoff: Option<String>,
}

/// What one layout's run measured.
#[derive(Clone, Debug, Serialize)]
pub struct LayoutRecord {
    /// `1-host`, `2-host` or `4-host`.
    pub layout: String,
    /// Hosts (network namespaces).
    pub hosts: usize,
    /// Processes started (naming service and nodes).
    pub processes: usize,
    /// Length of the task measured, s.
    pub duration_s: f64,
    /// RMS distance of the slave's tool from its reference in free motion, mm.
    pub tracking_rms_mm: f64,
    /// RMS distance of the slave's tool from the master's mapped pose at the same instant, mm.
    pub tracking_against_master_rms_mm: f64,
    /// Mean contact force the wrist sensor measured, N.
    pub sensed_force_n: f64,
    /// `|displayed - expected| / |expected|` of the mean force in steady contact, percent.
    pub display_error_pct: f64,
    /// Master motion to slave command, beside its limit (the data plane's one-way trip plus
    /// the wait for the slave's tick).
    pub motion_to_command: EndToEnd,
    /// Slave contact to master force, beside its limit.
    pub contact_to_force: EndToEnd,
    /// A raw UDP echo between the joystick's and the robot's hosts in the same run: half the
    /// round trip.
    pub udp_echo_one_way: Percentiles,
    /// Echoes lost.
    pub udp_echo_lost: usize,
    /// Control ticks the recorders lost (master, slave).
    pub dropped_ticks: (u64, u64),
    /// Safety events per robot.
    pub safety_events: std::collections::BTreeMap<String, u64>,
    /// The control loops' timing.
    pub loops: Vec<LoopTiming>,
    /// The channel's data-plane link, as its two ends recorded it at the end (`None` on one
    /// node, where the channel is a pair of cells).
    pub link: Option<LinkSummary>,
    /// The data plane's streams as the two nodes recorded them, matched sample by sample.
    pub streams: StreamsCheck,
}

/// One direction of the data plane as recorded on both hosts: what the sender's recording
/// says it sent, what the receiver's says it took, and whether each sample taken is one that
/// was sent, bit for bit.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct StreamCheck {
    /// Samples the sender's recording holds as sent.
    pub sent: u64,
    /// Samples the receiver's recording holds as taken.
    pub taken: u64,
    /// Taken samples equal, sequence number, clutch and sample to the last bit, to one sent.
    pub matched: u64,
    /// Stream samples the two recorders lost, both directions (written to `/recorder`).
    pub recorder_dropped: u64,
}

/// Both directions of [`StreamCheck`].
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct StreamsCheck {
    /// The master's samples to the slave.
    pub master_to_slave: StreamCheck,
    /// The slave's samples to the master.
    pub slave_to_master: StreamCheck,
}

/// Matches what the `master` node's and the `slave` node's recordings say their ends sent and
/// took.
fn check_streams(read: &[Recording], master: &str, slave: &str) -> StreamsCheck {
    fn of<'a>(read: &'a [Recording], node: &'a str) -> impl Iterator<Item = &'a Recording> {
        read.iter().filter(move |r| r.node == node)
    }
    let one_way = |from: &str, to: &str, stream: StreamName| {
        let sent: std::collections::HashMap<u64, &StreamDatagram> = of(read, from)
            .flat_map(|r| r.datagrams.values().flatten())
            .filter(|d| d.stream == stream && d.arrived_ns.is_none())
            .map(|d| (d.sequence, d))
            .collect();
        let mut check = StreamCheck {
            sent: sent.len() as u64,
            recorder_dropped: of(read, from)
                .chain(of(read, to))
                .flat_map(|r| r.datagrams_dropped.values())
                .sum(),
            ..StreamCheck::default()
        };
        for d in of(read, to)
            .flat_map(|r| r.datagrams.values().flatten())
            .filter(|d| d.stream == stream && d.arrived_ns.is_some())
        {
            check.taken += 1;
            if sent.get(&d.sequence).is_some_and(|s| {
                s.clutch == d.clutch
                    && s.sent_ns == d.sent_ns
                    && s.reference == d.reference
                    && s.wave == d.wave
                    && s.energy == d.energy
            }) {
                check.matched += 1;
            }
        }
        check
    };
    StreamsCheck {
        master_to_slave: one_way(master, slave, StreamName::MasterToSlave),
        slave_to_master: one_way(slave, master, StreamName::SlaveToMaster),
    }
}

/// One direction's one-way trips on the data plane: from the sender's clock read before the
/// send to the kernel's arrival stamp, on the common clock.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Trips {
    /// Median, µs.
    pub p50_us: Option<f64>,
    /// 99th percentile, µs.
    pub p99_us: Option<f64>,
    /// Longest, µs.
    pub max_us: Option<f64>,
    /// Trips measured.
    pub trips: u64,
}

/// A channel's link between two nodes at the end of a run.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct LinkSummary {
    /// The master's samples to the slave (the slave end's record).
    pub master_to_slave: Trips,
    /// The slave's samples to the master (the master end's record).
    pub slave_to_master: Trips,
    /// The master end's estimate of the slave node's clock less its own, µs (the hosts share
    /// one clock here, so this is the estimate's error).
    pub clock_offset_us: Option<f64>,
    /// The heartbeats' round trip, µs (the other side's turnaround excluded).
    pub round_trip_us: Option<f64>,
    /// Samples taken by both ends.
    pub samples_taken: u64,
    /// Sequence numbers skipped between taken samples, both ends (lost or overtaken).
    pub samples_missed: u64,
    /// Datagrams refused, both ends.
    pub refused: u64,
    /// Times either end lost the link.
    pub losses: u64,
    /// The data plane's trip over the raw UDP echo's, at the median (both directions' worse).
    pub trip_over_echo_p50: Option<f64>,
    /// The same at the 99th percentile.
    pub trip_over_echo_p99: Option<f64>,
}

fn trips(r: &LinkRecord) -> Trips {
    let us = |ns: Option<i64>| ns.map(|n| n as f64 / 1e3);
    Trips {
        p50_us: us(r.trip_p50_ns),
        p99_us: us(r.trip_p99_ns),
        max_us: us(r.trip_max_ns),
        trips: r.trips,
    }
}

/// The link as the two ends' last records show it, against the echo.
fn summary(master: &LinkRecord, slave: &LinkRecord, echo: &Percentiles) -> LinkSummary {
    let (m2s, s2m) = (trips(slave), trips(master));
    let ratio = |a: Option<f64>, b: Option<f64>, base: f64| match (a, b) {
        (Some(a), Some(b)) if base > 0.0 => Some(a.max(b) / base),
        _ => None,
    };
    LinkSummary {
        master_to_slave: m2s,
        slave_to_master: s2m,
        clock_offset_us: master.clock_offset_ns.map(|n| n as f64 / 1e3),
        round_trip_us: master.round_trip_ns.map(|n| n as f64 / 1e3),
        samples_taken: master.samples_taken + slave.samples_taken,
        samples_missed: master.samples_missed + slave.samples_missed,
        refused: master.refused + slave.refused,
        losses: master.losses + slave.losses,
        trip_over_echo_p50: ratio(m2s.p50_us, s2m.p50_us, echo.p50_us),
        trip_over_echo_p99: ratio(m2s.p99_us, s2m.p99_us, echo.p99_us),
    }
}

/// Runs `penelope bench layout`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let chosen: Vec<Layout> = all_layouts()
        .into_iter()
        .filter(|l| args.layouts.is_empty() || args.layouts.iter().any(|n| n == l.name))
        .collect();
    let duration = args.duration.map(Duration::from_secs_f64);
    let mut records = Vec::new();
    for layout in chosen {
        if !args.json {
            eprintln!("running the {} layout ...", layout.name);
        }
        let record = run_layout(&layout, duration, args.handoff.as_deref())
            .with_context(|| format!("the {} layout", layout.name))?;
        if args.json {
            println!("{}", serde_json::to_string(&record)?);
        }
        records.push(record);
    }
    if !args.json {
        print_table(&records);
    }
    Ok(ExitCode::SUCCESS)
}

/// Every layout this build knows.
pub fn all_layouts() -> Vec<Layout> {
    LAYOUTS.to_vec()
}

fn print_table(records: &[LayoutRecord]) {
    println!(
        "{:<7} {:>5} {:>8} {:>8} {:>7} {:>24} {:>24} {:>13} {:>13} {:>9}",
        "layout",
        "procs",
        "track mm",
        "display%",
        "force N",
        "motion->cmd (limit) x",
        "contact->force (limit) x",
        "data plane",
        "udp echo",
        "offset µs"
    );
    let pair = |a: f64, b: f64| format!("{a:.0}/{b:.0}");
    let beside = |e: &EndToEnd| {
        format!(
            "{} ({}) {:.2}",
            pair(e.latency.p50_us, e.latency.p99_us),
            pair(e.limit.p50_us, e.limit.p99_us),
            e.ratio_p99.max(e.ratio_p50)
        )
    };
    let opt = |x: Option<f64>| x.map_or("-".to_string(), |v| format!("{v:.0}"));
    for r in records {
        let (trip, offset) = match &r.link {
            Some(l) => {
                let worse = |a: Option<f64>, b: Option<f64>| match (a, b) {
                    (Some(a), Some(b)) => Some(a.max(b)),
                    _ => None,
                };
                (
                    format!(
                        "{}/{}",
                        opt(worse(l.master_to_slave.p50_us, l.slave_to_master.p50_us)),
                        opt(worse(l.master_to_slave.p99_us, l.slave_to_master.p99_us))
                    ),
                    l.clock_offset_us.map_or("-".into(), |o| format!("{o:.1}")),
                )
            }
            None => ("-".into(), "-".into()),
        };
        println!(
            "{:<7} {:>5} {:>8.3} {:>8.2} {:>7.2} {:>24} {:>24} {:>13} {:>13} {:>9}",
            r.layout,
            r.processes,
            r.tracking_rms_mm,
            r.display_error_pct,
            r.sensed_force_n,
            beside(&r.motion_to_command),
            beside(&r.contact_to_force),
            trip,
            pair(r.udp_echo_one_way.p50_us, r.udp_echo_one_way.p99_us),
            offset,
        );
    }
    println!(
        "latencies in µs, p50/p99: motion->cmd from the master's control tick to the slave's \
         that used it, contact->force from the slave's tick to the master's, beside their limit \
         (the data plane's one-way trip plus the wait for the receiving tick, for the same \
         samples) and the worse of the p50 and p99 ratios; data plane and udp echo one-way, send to kernel arrival (the worse direction); hosts are network \
         namespaces of this machine"
    );
}

/// The layout's figures from the run, its recordings and the UDP echo's.
fn layout_record(
    layout: &Layout,
    output: &RunOutput,
    read: &[Recording],
    task_nodes: (&str, &str),
    udp_echo_one_way: Percentiles,
    udp_echo_lost: usize,
) -> LayoutRecord {
    let rep = report(output);
    // Each end's last record within the task (the nodes stopping afterwards lose the link).
    let end_ns = output.master.last().map_or(0, |t| t.sample.time.as_nanos());
    let last_link = |node: &str| {
        read.iter()
            .find(|r| r.node == node)
            .and_then(|r| r.links.values().next())
            .and_then(|l| l.iter().rev().find(|x| x.time_ns <= end_ns))
    };
    let link = match (last_link(task_nodes.0), last_link(task_nodes.1)) {
        (Some(m), Some(s)) => Some(summary(m, s, &udp_echo_one_way)),
        _ => None,
    };
    // The transport each way: the data plane's median one-way trip (cells on one node: none).
    let trip = |t: Option<f64>| Duration::from_secs_f64(t.unwrap_or(0.0).max(0.0) / 1e6);
    let transport = link.map_or((Duration::ZERO, Duration::ZERO), |l| {
        (
            trip(l.master_to_slave.p50_us),
            trip(l.slave_to_master.p50_us),
        )
    });
    let (motion_to_command, contact_to_force) = latency::end_to_end(output, transport);
    LayoutRecord {
        layout: layout.name.into(),
        hosts: layout.hosts.len(),
        processes: layout.hosts.iter().map(|h| h.len()).sum(),
        duration_s: rep.duration_s,
        tracking_rms_mm: rep.tracking.rms_mm,
        tracking_against_master_rms_mm: rep.tracking.against_master_rms_mm,
        sensed_force_n: rep.contact.sensed_force_n,
        display_error_pct: rep.contact.display_error_pct,
        motion_to_command,
        contact_to_force,
        udp_echo_one_way,
        udp_echo_lost,
        dropped_ticks: output.dropped,
        safety_events: rep.safety_events.clone(),
        loops: rep.timing.clone(),
        link,
        streams: check_streams(read, task_nodes.0, task_nodes.1),
    }
}

/// The nodes of the task's master and slave controllers.
fn system_nodes_of_task(system: &SystemFile) -> anyhow::Result<(&str, &str)> {
    let channel = system
        .objects
        .iter()
        .find(|o| o.kind == "trajectory/teleop")
        .context("no teleoperation channel")?;
    let table: toml::Table = channel.config.parse()?;
    let robot = |key: &str| -> anyhow::Result<&str> {
        let name = table
            .get(key)
            .and_then(toml::Value::as_str)
            .context(key.to_string())?;
        let node = system
            .objects
            .iter()
            .find(|o| o.kind.starts_with("robot/") && o.name == name)
            .map(|o| o.node.as_str())
            .with_context(|| format!("no robot `{name}`"))?;
        Ok(node)
    };
    let (m, s) = (robot("master")?, robot("slave")?);
    // A one-node file leaves `node` out: the node is then the file's only one.
    fn only(n: &str) -> &str {
        if n.is_empty() { "lab" } else { n }
    }
    Ok((only(m), only(s)))
}
