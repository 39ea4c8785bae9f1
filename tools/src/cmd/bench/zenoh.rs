//! `penelope bench zenoh`: the Zenoh bridge's one-way latency beside the data plane's, on
//! loopback, in the same run.
//!
//! Both carry the same thing at the same rate: an operator's master pose (clutch and seven
//! doubles), every communication period, from a sender thread to the cell a slave's
//! communication thread reads.
//! - **data plane**: our UDP stream (postcard frame with header, newest wins), from `send` to
//!   the receiving endpoint's decode and cell write (the receiver polls its socket without
//!   pause, yielding the CPU between polls), and to the kernel's receive stamp (the transport
//!   alone: what a communication thread that polls once per tick is measured from).
//! - **zenoh**: a station's Zenoh peer publishes the 58-byte pose (`docs/zenoh.md`) to the
//!   bridge's peer over loopback TCP; measured from `put` to the end of the bridge's own
//!   subscriber path (`BridgedChannels::offer`: decode, check, write the cell).
//!
//! Neither figure includes the wait for the slave's next communication tick (up to one
//! period, the same for both). Times are read in one process: the data plane's on the
//! real-time clock (the kernel stamps on it), the bridge's on the monotonic one.

use std::net::{SocketAddr, TcpListener};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use penelope_runtime::dataplane::endpoint::Endpoint;
use penelope_runtime::dataplane::frame::StreamId;
use penelope_runtime::dataplane::stream::StreamSender;
use penelope_runtime::objects::bridged::BridgedChannels;
use penelope_runtime::objects::teleop::{Side, TeleopLink};
use penelope_supervisor::zenoh_bridge::encoding::OperatorPose;
use zenoh::Wait;

/// Options of `penelope bench zenoh`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Poses sent over each transport.
    #[arg(long, default_value_t = 5000)]
    pub samples: usize,
    /// Poses per second (the slave's communication rate; 500: T_com = 2 ms).
    #[arg(long, default_value_t = 500)]
    pub rate: u32,
    /// The station publishes with Zenoh's `express` QoS (each pose sent at once, never
    /// batched with others).
    #[arg(long)]
    pub express: bool,
}

/// The key of the benchmark's poses.
const KEY: &str = "bench/station/hand/pose";

/// One transport's one-way trips, ns, and what was lost.
struct Trips {
    ns: Vec<u64>,
    lost: usize,
}

impl Trips {
    fn quantile(&self, q: f64) -> f64 {
        let mut s = self.ns.clone();
        s.sort_unstable();
        if s.is_empty() {
            return f64::NAN;
        }
        let i = ((s.len() - 1) as f64 * q).round() as usize;
        s[i] as f64 / 1e3
    }
}

/// The pose of sample `k`: a slow circle.
fn pose(k: usize) -> OperatorPose {
    let a = k as f64 * 1e-3;
    OperatorPose {
        clutch: false,
        position: [0.4 + 0.03 * a.sin(), 0.1 + 0.03 * a.cos(), 0.3],
        orientation: [1.0, 0.0, 0.0, 0.0],
    }
}

/// Sleeps until `deadline` (the sender's pacing).
fn pace(deadline: Instant) {
    let now = Instant::now();
    if deadline > now {
        std::thread::sleep(deadline - now);
    }
}

/// Now on the real-time clock, ns (the clock of the kernel's receive stamps).
fn realtime_ns() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
}

/// The data plane's trips: to the reader that polls without pause, and to the kernel's receive
/// stamp (the transport alone, without the reader's wake-up).
fn data_plane(args: &Args) -> anyhow::Result<(Trips, Trips)> {
    let loopback = SocketAddr::from(([127, 0, 0, 1], 0));
    let mut receiver = Endpoint::bind(loopback, None).context("binding the receiver")?;
    receiver
        .enable_receive_timestamps()
        .context("kernel receive stamps")?;
    let mut sender = Endpoint::bind(loopback, None).context("binding the sender")?;
    let to = receiver.local_addr()?;
    let done = Arc::new(AtomicBool::new(false));
    let flag = done.clone();
    let samples = args.samples;
    let reader = std::thread::spawn(move || {
        let (mut cell, _reader) = penelope_rt_core::cell::latest::<(bool, [f64; 7])>();
        let (mut read, mut stamped) = (Vec::with_capacity(samples), Vec::with_capacity(samples));
        while !flag.load(Ordering::Relaxed) {
            match receiver.receive_stamped::<(bool, [f64; 7])>() {
                Some(r) => {
                    cell.write(r.payload);
                    let sent = r.header.sent_ns;
                    read.push(u64::try_from(realtime_ns() - sent).unwrap_or(0));
                    if let Some(k) = r.kernel_realtime_ns {
                        stamped.push(u64::try_from(k - sent).unwrap_or(0));
                    }
                }
                None => std::thread::yield_now(),
            }
        }
        (read, stamped)
    });
    let mut stream = StreamSender::new(StreamId(1));
    let period = Duration::from_secs(1) / args.rate;
    let start = Instant::now();
    for k in 0..args.samples {
        pace(start + period * k as u32);
        let p = pose(k);
        let mut numbers = [0.0; 7];
        numbers[..3].copy_from_slice(&p.position);
        numbers[3..].copy_from_slice(&p.orientation);
        let header = stream.next(realtime_ns());
        let _ = sender.send(&header, &(p.clutch, numbers), to);
    }
    // Lets the last datagrams land (loopback: microseconds).
    std::thread::sleep(Duration::from_millis(50));
    done.store(true, Ordering::Relaxed);
    let (read, stamped) = reader
        .join()
        .map_err(|_| anyhow::anyhow!("receiver panicked"))?;
    let lost = |n: usize| args.samples.saturating_sub(n);
    Ok((
        Trips {
            lost: lost(read.len()),
            ns: read,
        },
        Trips {
            lost: lost(stamped.len()),
            ns: stamped,
        },
    ))
}

fn peer(listen: Option<u16>, connect: Option<u16>) -> anyhow::Result<zenoh::Session> {
    let mut c = zenoh::Config::default();
    let set = |c: &mut zenoh::Config, k: &str, v: String| {
        c.insert_json5(k, &v)
            .map_err(|e| anyhow::anyhow!("zenoh config {k}: {e}"))
    };
    set(&mut c, "mode", r#""peer""#.into())?;
    set(&mut c, "scouting/multicast/enabled", "false".into())?;
    let listen = listen.map_or(String::new(), |p| format!(r#""tcp/127.0.0.1:{p}""#));
    set(&mut c, "listen/endpoints", format!("[{listen}]"))?;
    if let Some(p) = connect {
        set(
            &mut c,
            "connect/endpoints",
            format!(r#"["tcp/127.0.0.1:{p}"]"#),
        )?;
    }
    zenoh::open(c)
        .wait()
        .map_err(|e| anyhow::anyhow!("opening a Zenoh session: {e}"))
}

fn zenoh_bridge(args: &Args) -> anyhow::Result<Trips> {
    let port = TcpListener::bind("127.0.0.1:0")?.local_addr()?.port();
    let station = peer(Some(port), None)?;
    let bridge = peer(None, Some(port))?;
    let channels = BridgedChannels::default();
    let (_link, end) = TeleopLink::bridged(Side::Slave);
    channels.insert("link", KEY, "slave", end);
    let sent: Arc<Vec<AtomicU64>> =
        Arc::new((0..args.samples).map(|_| AtomicU64::new(0)).collect());
    let arrivals = Arc::new(Mutex::new(Vec::with_capacity(args.samples)));
    let counting = Arc::new(AtomicBool::new(false));
    let origin = Instant::now();
    let (feed, times, at, on) = (
        channels.clone(),
        sent.clone(),
        arrivals.clone(),
        counting.clone(),
    );
    let _subscriber = bridge
        .declare_subscriber(KEY)
        .callback(move |sample| {
            let taken = feed.offer(KEY, &sample.payload().to_bytes()).is_ok();
            let now = origin.elapsed().as_nanos() as u64;
            if taken
                && on.load(Ordering::Relaxed)
                && let Ok(mut a) = at.lock()
            {
                let k = a.len();
                if let Some(t) = times.get(k) {
                    a.push(now.saturating_sub(t.load(Ordering::Relaxed)));
                }
            }
        })
        .wait()
        .map_err(|e| anyhow::anyhow!("subscribing: {e}"))?;
    let publisher = station
        .declare_publisher(KEY)
        .congestion_control(zenoh::qos::CongestionControl::Block)
        .express(args.express)
        .wait()
        .map_err(|e| anyhow::anyhow!("declaring the publisher: {e}"))?;
    // Ready when a probe is taken: the two peers see each other's declarations.
    let ready_by = Instant::now() + Duration::from_secs(10);
    while channels.counts("link").map_or(0, |c| c.taken) == 0 {
        if Instant::now() > ready_by {
            bail!("the bridge's subscriber never heard the station's publisher");
        }
        publisher
            .put(pose(0).encode().to_vec())
            .wait()
            .map_err(|e| anyhow::anyhow!("put: {e}"))?;
        std::thread::sleep(Duration::from_millis(1));
    }
    // Drains the probes before counting.
    std::thread::sleep(Duration::from_millis(50));
    counting.store(true, Ordering::Relaxed);
    let period = Duration::from_secs(1) / args.rate;
    let start = Instant::now();
    for (k, slot) in sent.iter().enumerate() {
        pace(start + period * k as u32);
        let bytes = pose(k).encode().to_vec();
        slot.store(origin.elapsed().as_nanos() as u64, Ordering::Relaxed);
        publisher
            .put(bytes)
            .wait()
            .map_err(|e| anyhow::anyhow!("put: {e}"))?;
    }
    std::thread::sleep(Duration::from_millis(50));
    counting.store(false, Ordering::Relaxed);
    let ns = std::mem::take(&mut *arrivals.lock().map_err(|_| anyhow::anyhow!("poisoned"))?);
    let lost = args.samples.saturating_sub(ns.len());
    drop(_subscriber);
    let _ = station.close().wait();
    let _ = bridge.close().wait();
    Ok(Trips { ns, lost })
}

/// Runs `penelope bench zenoh`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if args.samples == 0 || args.rate == 0 || args.rate > 100_000 {
        return Err(crate::cmd::usage(
            "--samples must be above 0 and --rate within 1..=100000",
        ));
    }
    println!(
        "one-way latency on loopback, {} poses at {} Hz each, in one process{}",
        args.samples,
        args.rate,
        if args.express { "; zenoh express" } else { "" }
    );
    let (plane, plane_kernel) = data_plane(&args)?;
    let bridge = zenoh_bridge(&args)?;
    println!(
        "{:<42} {:>8} {:>6} {:>10} {:>10} {:>10}",
        "transport", "samples", "lost", "p50 µs", "p99 µs", "max µs"
    );
    for (name, t) in [
        ("data plane (UDP, postcard), kernel stamp", &plane_kernel),
        ("data plane (UDP, postcard), reader", &plane),
        ("zenoh bridge (TCP peer, 58 B pose)", &bridge),
    ] {
        println!(
            "{name:<42} {:>8} {:>6} {:>10.1} {:>10.1} {:>10.1}",
            t.ns.len(),
            t.lost,
            t.quantile(0.5),
            t.quantile(0.99),
            t.quantile(1.0)
        );
    }
    println!(
        "zenoh / data plane (reader): p50 x{:.2}, p99 x{:.2}",
        bridge.quantile(0.5) / plane.quantile(0.5),
        bridge.quantile(0.99) / plane.quantile(0.99)
    );
    println!(
        "zenoh / data plane (kernel stamp): p50 x{:.2}, p99 x{:.2}",
        bridge.quantile(0.5) / plane_kernel.quantile(0.5),
        bridge.quantile(0.99) / plane_kernel.quantile(0.99)
    );
    Ok(ExitCode::SUCCESS)
}
