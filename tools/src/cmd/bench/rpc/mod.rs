//! `penelope bench rpc`: the paper's communication experiment with today's tools.
//!
//! The paper compared a CORBA "ping" with the ICMP ping of Linux under several network loads
//! (its figures 9 and 10). Here three round trips of the same payload (56 bytes by default,
//! ICMP's default data size) are timed on loopback from this process, each with [`Instant`]
//! around one request and its answer:
//!
//! - **rpc**: `Call::Ping { payload }` through a node's [`Server`] (a minimal service answering
//!   Ping) and a client [`Connection`], one call at a time;
//! - **tcp echo**: the same bytes through a plain echo server thread over a TCP_NODELAY socket,
//!   the baseline the remote call is judged against;
//! - **icmp echo**: an ICMP echo request answered by the kernel (a raw socket as root, or a
//!   datagram ICMP socket where `net.ipv4.ping_group_range` allows);
//! - optionally (`--echo-handoff`) **tcp echo+handoff**: the echo through a reader thread that
//!   hands the bytes to a writer thread, the node server's structure without the protocol.
//!
//! The probes run in short alternating slices (`--slice` round trips each, rotating which goes
//! first) so a changing background hits them alike, idle and under load: CPU stress
//! (`stress-ng --cpu`), a competing loopback TCP flood, or both. Then the calls per second of
//! one client, sequential and pipelined (`call_many` batches).
//!
//! Writes `rpc.json` and one SVG per load (`rpc-<load>.svg`, plus `rpc-loads.svg` with every
//! load) to `--out`.
//!
//! [`Server`]: penelope_protocol::net::server::Server
//! [`Connection`]: penelope_protocol::net::conn::Connection
//! [`Instant`]: std::time::Instant

pub mod load;
pub mod plot;
pub mod probes;
pub mod stats;

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context as _;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use crate::cmd::usage;
use load::Load;
use probes::{IcmpProbe, Probe, ProbeKind, RpcProbe, TcpProbe};
use stats::{Summary, ratio};

/// The goal: the remote call's p50 and p99 within this factor of the TCP echo's.
pub const GOAL_RATIO: f64 = 1.2;

/// Alternating rounds the throughput runs are cut into.
const THROUGHPUT_ROUNDS: u32 = 10;

/// The goal: calls per second from one client.
pub const GOAL_CALLS_PER_S: f64 = 50_000.0;

/// Options of `penelope bench rpc`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Round trips measured per probe and per load.
    #[arg(long, default_value_t = 20_000)]
    pub samples: usize,
    /// Payload bytes of every probe (56 is ICMP's default data size).
    #[arg(long, default_value_t = 56)]
    pub payload: usize,
    /// Background load(s), comma-separated, measured one after the other: idle, cpu
    /// (stress-ng --cpu), net (loopback TCP flood), all (cpu and net at once).
    #[arg(long, value_enum, value_delimiter = ',', default_value = "idle")]
    pub load: Vec<Load>,
    /// Round trips per probe in one alternation slice.
    #[arg(long, default_value_t = 500)]
    pub slice: usize,
    /// Seconds of each throughput run (sequential and pipelined); 0 skips them.
    #[arg(long, default_value_t = 2.0)]
    pub throughput_secs: f64,
    /// Calls per pipelined batch (`Connection::call_many`).
    #[arg(long, default_value_t = 64)]
    pub batch: usize,
    /// stress-ng CPU workers for the cpu load (default: one per CPU).
    #[arg(long)]
    pub cpu_workers: Option<usize>,
    /// Sender/receiver thread pairs of the net load.
    #[arg(long, default_value_t = 2)]
    pub flood_streams: usize,
    /// Also time a TCP echo whose server hands each read to a writer thread (diagnostic).
    #[arg(long)]
    pub echo_handoff: bool,
    /// Leave out the ICMP echo (which needs root, CAP_NET_RAW or ping_group_range).
    #[arg(long)]
    pub no_ping: bool,
    /// Print the JSON document instead of the tables.
    #[arg(long)]
    pub json: bool,
    /// Directory for rpc.json and the SVG plots.
    #[arg(long, default_value = "target/bench-rpc")]
    pub out: PathBuf,
}

/// One load's measurements.
struct LoadRun {
    load: Load,
    description: String,
    flood_bytes_per_s: Option<f64>,
    samples: Vec<(ProbeKind, Vec<u64>)>,
    icmp_socket: Option<&'static str>,
    icmp_lost: u64,
    throughput: Vec<Throughput>,
}

/// Calls (or echoes) per second of one client.
struct Throughput {
    kind: ProbeKind,
    sequential: f64,
    pipelined: f64,
}

impl LoadRun {
    fn samples_of(&self, kind: ProbeKind) -> Option<&[u64]> {
        self.samples
            .iter()
            .find(|(k, _)| *k == kind)
            .map(|(_, s)| s.as_slice())
    }

    /// Median over slices of the rpc/tcp ratio of `pick`.
    fn slice_ratio(&self, slice: usize, pick: fn(&Summary) -> f64) -> f64 {
        self.slice_ratio_of(ProbeKind::Rpc, slice, pick)
    }

    /// Median over slices of the `kind`/tcp ratio of `pick`.
    fn slice_ratio_of(&self, kind: ProbeKind, slice: usize, pick: fn(&Summary) -> f64) -> f64 {
        match (self.samples_of(kind), self.samples_of(ProbeKind::Tcp)) {
            (Some(a), Some(b)) => slice_median_ratio(a, b, slice, pick),
            _ => f64::NAN,
        }
    }

    fn summary(&self, kind: ProbeKind) -> Option<Summary> {
        self.samples
            .iter()
            .find(|(k, _)| *k == kind)
            .and_then(|(_, s)| Summary::of(s))
    }
}

/// Runs `penelope bench rpc`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    check_args(&args)?;
    let mut loads = args.load.clone();
    loads.dedup();
    // Fail before measuring anything when a requested load or probe cannot run.
    for &l in &loads {
        load::check(l)?;
    }
    if !args.no_ping {
        IcmpProbe::start(&payload(args.payload))
            .context("the ICMP echo probe (--no-ping leaves it out)")?;
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;

    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    let cpu_workers = args.cpu_workers.unwrap_or(cpus).max(1);
    let kinds = args.kinds();
    let bar = ProgressBar::new((loads.len() * kinds.len() * args.samples) as u64);
    bar.set_style(
        ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len} round trips, {eta} left")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );

    let mut runs = Vec::new();
    for &l in &loads {
        bar.set_message(l.name());
        let running = load::Running::start(l, cpu_workers, args.flood_streams)?;
        let description = running.description.clone();
        let measured = measure(&args, &kinds, &bar);
        let flood = running.stop();
        let (samples, icmp, throughput) = measured.with_context(|| format!("load {}", l.name()))?;
        runs.push(LoadRun {
            load: l,
            description,
            flood_bytes_per_s: flood,
            samples,
            icmp_socket: icmp
                .as_ref()
                .map(|p| if p.is_raw() { "raw" } else { "datagram" }),
            icmp_lost: icmp.map_or(0, |p| p.lost),
            throughput,
        });
    }
    bar.finish_and_clear();

    let doc = document(&args, &runs);
    let json_path = args.out.join("rpc.json");
    std::fs::write(&json_path, serde_json::to_string_pretty(&doc)?)
        .with_context(|| format!("writing {}", json_path.display()))?;
    let mut written = vec![json_path];
    write_charts(&args, &runs, &mut written)?;

    if args.json {
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        print!("{}", render(&args, &runs));
        let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
        println!("wrote {}", names.join(", "));
    }
    Ok(ExitCode::SUCCESS)
}

/// The arguments' bounds: samples, slice, payload, batch, throughput time, flood streams.
fn check_args(args: &Args) -> anyhow::Result<()> {
    if args.samples == 0 || args.slice == 0 {
        return Err(usage("--samples and --slice must be at least 1"));
    }
    if args.payload > 60_000 {
        return Err(usage("--payload must be at most 60000 bytes"));
    }
    if args.batch == 0 || args.batch > 10_000 {
        return Err(usage("--batch must be 1 to 10000"));
    }
    if !(args.throughput_secs.is_finite() && (0.0..=600.0).contains(&args.throughput_secs)) {
        return Err(usage("--throughput-secs must be 0 to 600"));
    }
    if args.net_load() && !(1..=64).contains(&args.flood_streams) {
        return Err(usage("--flood-streams must be 1 to 64"));
    }
    Ok(())
}

/// One round-trip chart per load (`rpc-LOAD.svg`), and all loads in one when there are
/// several (`rpc-loads.svg`); their paths go into `written`.
fn write_charts(args: &Args, runs: &[LoadRun], written: &mut Vec<PathBuf>) -> anyhow::Result<()> {
    let charts: Vec<(String, Vec<plot::Curve<'_>>)> = runs
        .iter()
        .map(|r| {
            let curves = r
                .samples
                .iter()
                .filter_map(|(kind, s)| {
                    Summary::of(s).map(|summary| plot::Curve {
                        kind: *kind,
                        samples: s,
                        summary,
                    })
                })
                .collect();
            (
                format!(
                    "Round trip on loopback, {} B payload, load {}",
                    args.payload,
                    r.load.name()
                ),
                curves,
            )
        })
        .collect();
    for (run, chart) in runs.iter().zip(&charts) {
        let path = args.out.join(format!("rpc-{}.svg", run.load.name()));
        plot::write(&path, std::slice::from_ref(chart))?;
        written.push(path);
    }
    if charts.len() > 1 {
        let path = args.out.join("rpc-loads.svg");
        plot::write(&path, &charts)?;
        written.push(path);
    }
    Ok(())
}

impl Args {
    fn net_load(&self) -> bool {
        self.load.iter().any(|l| matches!(l, Load::Net | Load::All))
    }

    fn kinds(&self) -> Vec<ProbeKind> {
        let mut k = vec![ProbeKind::Rpc, ProbeKind::SealedRpc, ProbeKind::Tcp];
        if self.echo_handoff {
            k.push(ProbeKind::TcpHandoff);
        }
        if !self.no_ping {
            k.push(ProbeKind::Icmp);
        }
        k
    }
}

/// The payload: bytes 0, 1, 2, ... (mod 251, so no pattern lines up with a power of two).
fn payload(len: usize) -> Vec<u8> {
    (0..len).map(|i| (i % 251) as u8).collect()
}

type Measured = (
    Vec<(ProbeKind, Vec<u64>)>,
    Option<IcmpProbe>,
    Vec<Throughput>,
);

/// Interleaved latency slices of every probe, then the throughput runs, under the running load.
fn measure(args: &Args, kinds: &[ProbeKind], bar: &ProgressBar) -> anyhow::Result<Measured> {
    let data = payload(args.payload);
    let mut probes = Vec::new();
    for &k in kinds {
        probes.push(match k {
            ProbeKind::Rpc => Probe::Rpc(Box::new(RpcProbe::start(&data, false)?)),
            ProbeKind::SealedRpc => Probe::Rpc(Box::new(RpcProbe::start(&data, true)?)),
            ProbeKind::Tcp => Probe::Tcp(TcpProbe::start(&data, false)?),
            ProbeKind::TcpHandoff => Probe::Tcp(TcpProbe::start(&data, true)?),
            ProbeKind::Icmp => Probe::Icmp(IcmpProbe::start(&data)?),
        });
    }
    // Warm-up, not recorded.
    for p in &mut probes {
        for _ in 0..200 {
            p.round_trip()?;
        }
    }
    let mut samples: Vec<Vec<u64>> = probes
        .iter()
        .map(|_| Vec::with_capacity(args.samples))
        .collect();
    let slices = args.samples.div_ceil(args.slice);
    for slice in 0..slices {
        let n = args.slice.min(args.samples - slice * args.slice);
        // Rotate which probe goes first so none always follows the same one.
        for j in 0..probes.len() {
            let i = (slice + j) % probes.len();
            for _ in 0..n {
                let t = probes[i].round_trip()?;
                samples[i].push(t);
            }
            bar.inc(n as u64);
        }
    }

    // Throughput in THROUGHPUT_ROUNDS alternating rounds too: (calls, time) sequential and
    // pipelined, per probe.
    let mut totals: Vec<[(u64, Duration); 2]> =
        probes.iter().map(|_| [(0, Duration::ZERO); 2]).collect();
    if args.throughput_secs > 0.0 {
        let step = Duration::from_secs_f64(args.throughput_secs / THROUGHPUT_ROUNDS as f64);
        for _ in 0..THROUGHPUT_ROUNDS {
            for (p, total) in probes.iter_mut().zip(&mut totals) {
                for (mode, batch) in [(0, 1), (1, args.batch)] {
                    let (n, t) = match p {
                        Probe::Rpc(r) => r.throughput(step, batch)?,
                        Probe::Tcp(t) => t.throughput(step, batch)?,
                        Probe::Icmp(_) => continue,
                    };
                    total[mode].0 += n;
                    total[mode].1 += t;
                }
            }
        }
    }
    let rate = |(n, t): (u64, Duration)| n as f64 / t.as_secs_f64();
    let throughput = probes
        .iter()
        .zip(&totals)
        .filter(|(_, t)| !t[0].1.is_zero() && !t[1].1.is_zero())
        .map(|(p, t)| Throughput {
            kind: p.kind(),
            sequential: rate(t[0]),
            pipelined: rate(t[1]),
        })
        .collect();
    let kinds: Vec<ProbeKind> = probes.iter().map(Probe::kind).collect();
    let icmp = probes.into_iter().find_map(|p| match p {
        Probe::Icmp(i) => Some(i),
        _ => None,
    });
    Ok((kinds.into_iter().zip(samples).collect(), icmp, throughput))
}

/// The median over alternation slices of `pick(a's slice) / pick(b's slice)`: robust to a
/// background load that changes between slices.
fn slice_median_ratio(a: &[u64], b: &[u64], slice: usize, pick: fn(&Summary) -> f64) -> f64 {
    super::finite_median(
        a.chunks(slice)
            .zip(b.chunks(slice))
            .filter_map(|(x, y)| Some(ratio(pick(&Summary::of(x)?), pick(&Summary::of(y)?)))),
    )
}

fn document(args: &Args, runs: &[LoadRun]) -> serde_json::Value {
    json!({
        "payload_bytes": args.payload,
        "samples_per_probe": args.samples,
        "slice": args.slice,
        "batch": args.batch,
        "throughput_secs": args.throughput_secs,
        "goals": { "rpc_over_tcp_max": GOAL_RATIO, "calls_per_s_min": GOAL_CALLS_PER_S },
        "loads": runs.iter().map(|r| {
            let rpc = r.summary(ProbeKind::Rpc);
            let sealed = r.summary(ProbeKind::SealedRpc);
            let tcp = r.summary(ProbeKind::Tcp);
            let icmp = r.summary(ProbeKind::Icmp);
            let rat = |a: Option<Summary>, b: Option<Summary>, f: fn(&Summary) -> f64| match (a, b) {
                (Some(a), Some(b)) => super::finite_or_null(ratio(f(&a), f(&b))),
                _ => json!(null),
            };
            json!({
                "load": r.load.name(),
                "description": r.description,
                "flood_bytes_per_s": r.flood_bytes_per_s,
                "icmp_socket": r.icmp_socket,
                "icmp_lost": r.icmp_lost,
                "probes": r.samples.iter().filter_map(|(k, s)| Summary::of(s).map(|x| {
                    let mut v = x.json();
                    v["probe"] = json!(k.name());
                    v
                })).collect::<Vec<_>>(),
                "ratios": {
                    "rpc_over_tcp": { "p50": rat(rpc, tcp, |s| s.p50), "p99": rat(rpc, tcp, |s| s.p99) },
                    "rpc_over_icmp": { "p50": rat(rpc, icmp, |s| s.p50), "p99": rat(rpc, icmp, |s| s.p99) },
                    "sealed_over_tcp": { "p50": rat(sealed, tcp, |s| s.p50), "p99": rat(sealed, tcp, |s| s.p99) },
                    "sealed_over_rpc": { "p50": rat(sealed, rpc, |s| s.p50), "p99": rat(sealed, rpc, |s| s.p99) },
                    "sealed_over_tcp_median_of_slices": {
                        "p50": super::finite_or_null(r.slice_ratio_of(ProbeKind::SealedRpc, args.slice, |s| s.p50)),
                        "p99": super::finite_or_null(r.slice_ratio_of(ProbeKind::SealedRpc, args.slice, |s| s.p99)),
                    },
                    "rpc_over_tcp_median_of_slices": {
                        "p50": super::finite_or_null(r.slice_ratio(args.slice, |s| s.p50)),
                        "p99": super::finite_or_null(r.slice_ratio(args.slice, |s| s.p99)),
                    },
                },
                "throughput": r.throughput.iter().map(|t| json!({
                    "probe": t.kind.name(),
                    "sequential_per_s": t.sequential,
                    "pipelined_per_s": t.pipelined,
                })).collect::<Vec<_>>(),
            })
        }).collect::<Vec<_>>(),
    })
}

fn render(args: &Args, runs: &[LoadRun]) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "\nRound trips on loopback, payload {} B, {} per probe and load, alternating slices of {}",
        args.payload, args.samples, args.slice
    );
    for r in runs {
        let _ = writeln!(o, "\nload {}: {}", r.load.name(), r.description);
        if let Some(rate) = r.flood_bytes_per_s {
            let _ = writeln!(
                o,
                "  flood carried {:.2} Gbit/s on loopback while measuring",
                rate * 8.0 / 1e9
            );
        }
        write_probe_table(&mut o, r);
        write_ratios(&mut o, args, r);
        for t in &r.throughput {
            let _ = writeln!(
                o,
                "  {:<17} {:>9.0} /s one at a time, {:>9.0} /s pipelined (batches of {}){}",
                t.kind.name(),
                t.sequential,
                t.pipelined,
                args.batch,
                if matches!(t.kind, ProbeKind::Rpc | ProbeKind::SealedRpc) {
                    format!(
                        "   goal >= {GOAL_CALLS_PER_S:.0}/s: {}",
                        if t.pipelined.max(t.sequential) >= GOAL_CALLS_PER_S {
                            "met"
                        } else {
                            "NOT met"
                        }
                    )
                } else {
                    String::new()
                }
            );
        }
    }
    o
}

/// One load's round-trip figures per probe (µs), and the ICMP probe's losses.
fn write_probe_table(o: &mut String, r: &LoadRun) {
    let _ = writeln!(
        o,
        "  {:<17} {:>6} {:>8} {:>8} {:>10} {:>7} {:>7} {:>7} {:>8} {:>8}",
        "probe (µs)", "n", "mean", "std", "var µs²", "p50", "p90", "p99", "p99.9", "max"
    );
    for (kind, s) in &r.samples {
        let Some(s) = Summary::of(s) else { continue };
        let _ = writeln!(
            o,
            "  {:<17} {:>6} {:>8.2} {:>8.2} {:>10.2} {:>7.2} {:>7.2} {:>7.2} {:>8.1} {:>8.1}",
            kind.name(),
            s.n,
            s.mean / 1e3,
            s.std() / 1e3,
            s.variance / 1e6,
            s.p50 / 1e3,
            s.p90 / 1e3,
            s.p99 / 1e3,
            s.p999 / 1e3,
            s.max / 1e3
        );
    }
    if let Some(sock) = r.icmp_socket {
        let _ = writeln!(
            o,
            "  (icmp: {sock} socket, {} echo(es) lost and resent)",
            r.icmp_lost
        );
    }
}

/// One load's ratios of probes against their baselines (and the goals), whole and per slice.
fn write_ratios(o: &mut String, args: &Args, r: &LoadRun) {
    let pairs = [
        (ProbeKind::Rpc, ProbeKind::Tcp, "rpc/tcp"),
        (ProbeKind::Rpc, ProbeKind::TcpHandoff, "rpc/tcp+handoff"),
        (ProbeKind::Rpc, ProbeKind::Icmp, "rpc/icmp"),
        (ProbeKind::SealedRpc, ProbeKind::Tcp, "sealed/tcp"),
        (ProbeKind::SealedRpc, ProbeKind::Rpc, "sealed/rpc"),
    ];
    for (probe, base, name) in pairs {
        if let (Some(a), Some(b)) = (r.summary(probe), r.summary(base)) {
            let (p50, p99) = (ratio(a.p50, b.p50), ratio(a.p99, b.p99));
            let goal = if base == ProbeKind::Tcp {
                format!(
                    "   goal <= {GOAL_RATIO}: {}",
                    if p50 <= GOAL_RATIO && p99 <= GOAL_RATIO {
                        "met"
                    } else {
                        "NOT met"
                    }
                )
            } else {
                String::new()
            };
            let _ = writeln!(o, "  {name:<15} p50 {p50:>5.3}   p99 {p99:>5.3}{goal}");
        }
    }
    let (m50, m99) = (
        r.slice_ratio(args.slice, |s| s.p50),
        r.slice_ratio(args.slice, |s| s.p99),
    );
    if m50.is_finite() && args.samples / args.slice >= 3 {
        let _ = writeln!(
            o,
            "  rpc/tcp, median over the {} slice pairs: p50 {m50:.3}   p99 {m99:.3}",
            args.samples.div_ceil(args.slice)
        );
    }
    let (s50, s99) = (
        r.slice_ratio_of(ProbeKind::SealedRpc, args.slice, |s| s.p50),
        r.slice_ratio_of(ProbeKind::SealedRpc, args.slice, |s| s.p99),
    );
    if s50.is_finite() && args.samples / args.slice >= 3 {
        let _ = writeln!(
            o,
            "  sealed/tcp, median over the {} slice pairs: p50 {s50:.3}   p99 {s99:.3}",
            args.samples.div_ceil(args.slice)
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: Args,
    }

    #[test]
    fn loads_parse_as_a_list_and_bad_values_are_refused() {
        let cli = Cli::try_parse_from(["x", "--load", "idle,cpu,net,all", "--no-ping"]).unwrap();
        assert_eq!(
            cli.args.load,
            vec![Load::Idle, Load::Cpu, Load::Net, Load::All]
        );
        assert_eq!(
            cli.args.kinds(),
            vec![ProbeKind::Rpc, ProbeKind::SealedRpc, ProbeKind::Tcp]
        );
        assert!(Cli::try_parse_from(["x", "--load", "disk"]).is_err());
        let cli = Cli::try_parse_from(["x"]).unwrap();
        assert_eq!(
            (cli.args.payload, cli.args.load.as_slice()),
            (56, &[Load::Idle][..])
        );
        assert_eq!(cli.args.kinds().last(), Some(&ProbeKind::Icmp));
        assert_eq!(payload(3), vec![0, 1, 2]);
        assert_eq!(payload(300)[251], 0);
    }

    #[test]
    fn slice_ratios_take_the_median_of_the_pairs() {
        let a = [10, 10, 30, 30, 50, 50];
        let b = [10, 10, 10, 10, 10, 10];
        // Slices of 2: ratios 1, 3, 5.
        assert_eq!(slice_median_ratio(&a, &b, 2, |s| s.p50), 3.0);
        assert_eq!(slice_median_ratio(&a[..4], &b[..4], 2, |s| s.p50), 2.0);
        assert!(slice_median_ratio(&[], &[], 2, |s| s.p50).is_nan());
    }

    #[test]
    fn the_tcp_echo_probes_answer_and_count() {
        for handoff in [false, true] {
            let mut p = Probe::Tcp(TcpProbe::start(&payload(56), handoff).unwrap());
            assert!(p.round_trip().unwrap() > 0);
            if let Probe::Tcp(t) = &mut p {
                let (n, t) = t.throughput(Duration::from_millis(20), 8).unwrap();
                assert!(n >= 8 && n % 8 == 0 && t >= Duration::from_millis(20));
            }
        }
    }
}
