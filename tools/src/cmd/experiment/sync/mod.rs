//! `penelope experiment sync`: the paper's open problem measured. A camera on the robot's node
//! and the wrist sensor (on a node of its own in the four-host layout) feed the operator's
//! station; the camera's link gets the fault layer's delay and jitter. A watcher on the
//! operator's host (the master's node's namespace) takes every frame and the slave's force
//! samples as a view does, and the run reports:
//!
//! - the video's capture-to-display latency (the frame's capture instant to its arrival at the
//!   operator's host, both on the common clock);
//! - the force's measurement-to-display latency (the slave tick that sensed a force to the
//!   master tick that displays it, matched sample by sample off the recordings:
//!   `contact->force` of `bench layout`);
//! - the skew the operator would live with unaligned (video latency less force latency: how
//!   far what the eye sees lags what the hand feels);
//! - the residual skew after alignment (the force sample a view puts beside a frame less the
//!   frame's capture instant);
//!
//! as p50, p99 and max, with the frames' rate and losses and the loops' overruns, in a table,
//! JSON and a plot.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use penelope_protocol::client::Client;
use penelope_protocol::client::clock::{CommonClockView, REFRESH};
use penelope_protocol::client::sync::{ForceSample, SampleHistory};
use penelope_protocol::net::conn::{ClientConfig, RpcError};
use penelope_protocol::proto::Role;
use penelope_supervisor::runs::latency::Percentiles;
use serde::Serialize;

mod plot;

use crate::cmd::bench::layout::{
    LayoutPlan, LayoutRecord, WatchContext, Watcher, all_layouts, run_layout_watched,
};

/// Options of `penelope experiment sync`.
#[derive(clap::Args, Debug)]
pub struct SyncArgs {
    /// The layouts, comma-separated: `1-host` (one node) and `4-host` (naming service,
    /// joystick, robot and sensor each on a host of its own, network namespaces).
    #[arg(long, value_delimiter = ',', default_value = "1-host,4-host", value_parser = ["1-host", "2-host", "4-host"])]
    layouts: Vec<String>,
    /// Added one-way delay on the camera's link only, ms.
    #[arg(long, value_name = "MS", default_value_t = 20.0)]
    camera_delay: f64,
    /// Jitter on the camera's link, ms: every frame a further U(0, jitter) late.
    #[arg(long, value_name = "MS", default_value_t = 0.0)]
    camera_jitter: f64,
    /// The camera's frame rate, frames per second.
    #[arg(long, default_value_t = 30.0)]
    fps: f64,
    /// Image width, pixels.
    #[arg(long, default_value_t = 640)]
    width: u32,
    /// Image height, pixels.
    #[arg(long, default_value_t = 480)]
    height: u32,
    /// Length of the task, s [default: the operator's script, 20 s].
    #[arg(long)]
    duration: Option<f64>,
    /// One JSON record per layout on standard output instead of the table.
    #[arg(long)]
    json: bool,
    /// Output folder for the plot and `sync.json` (default: `out/sync-<unix time>`).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

/// One frame as the watcher saw it, ns on the common clock.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct FrameSeen {
    /// The camera's frame number.
    pub seq: u64,
    /// Its capture instant.
    pub capture_ns: u64,
    /// When it existed on the camera's node (read out, or dequeued from the driver).
    pub ready_ns: u64,
    /// When the camera's node handed it to the watcher's connection (after the link's faults).
    pub sent_ns: u64,
    /// Its arrival at the operator's host.
    pub display_ns: u64,
    /// The aligned force sample's residual skew: the nearest measurement used less the
    /// capture instant (`None`: the history had none around it).
    pub aligned_skew_ns: Option<i64>,
}

/// What the watcher found.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Watched {
    /// Every frame taken, in arrival order.
    pub frames: Vec<FrameSeen>,
    /// Frames the node reported lost for this subscription (its queue, the camera's link).
    pub dropped: u64,
    /// Force samples taken.
    pub samples: u64,
}

/// One layout's figures.
#[derive(Clone, Debug, Serialize)]
pub struct SyncRecord {
    /// `1-host`, `4-host`.
    pub layout: String,
    /// The camera's configured rate, frames/s.
    pub fps: f64,
    /// Frames per second that reached the operator's host, over the watched span.
    pub fps_received: f64,
    /// Frames received.
    pub frames: usize,
    /// Frames lost on the way (the node's count: full queue, the link's loss).
    pub frames_dropped: u64,
    /// Sequence numbers skipped between frames received.
    pub frames_missing: u64,
    /// The added one-way delay on the camera's link, ms.
    pub camera_delay_ms: f64,
    /// Capture to display, µs.
    pub video_latency: Percentiles,
    /// Its parts: capture to ready (the exposure's second half and the readout: the sensor),
    /// µs.
    pub capture_to_ready: Percentiles,
    /// Ready to sent (rendering or dequeuing, encoding, the camera link's delay), µs.
    pub ready_to_sent: Percentiles,
    /// Sent to display (the connection to the operator's host), µs.
    pub sent_to_display: Percentiles,
    /// Force measured (slave tick) to displayed (master tick), µs.
    pub force_latency: Percentiles,
    /// Unaligned skew: video latency less the force latency's median, µs (how far the eye lags
    /// the hand).
    pub unaligned_skew: Percentiles,
    /// After alignment: |the aligned force sample's instant - the capture instant|, µs.
    pub aligned_residual: Percentiles,
    /// Control-loop overruns during the run, all loops.
    pub overruns: u64,
    /// The layout's own figures.
    pub layout_record: LayoutRecord,
    /// Every frame, for the plot.
    #[serde(skip)]
    pub seen: Vec<FrameSeen>,
}

/// Runs `penelope experiment sync`.
pub fn run(args: SyncArgs) -> anyhow::Result<ExitCode> {
    if !(args.fps.is_finite() && args.fps > 0.0 && args.fps <= 240.0) {
        return Err(super::super::usage("--fps must be in (0, 240]"));
    }
    if !(args.camera_delay.is_finite() && (0.0..=60_000.0).contains(&args.camera_delay)) {
        return Err(super::super::usage(
            "--camera-delay must be in 0..=60000 ms",
        ));
    }
    if !(args.camera_jitter.is_finite() && (0.0..=60_000.0).contains(&args.camera_jitter)) {
        return Err(super::super::usage(
            "--camera-jitter must be in 0..=60000 ms",
        ));
    }
    let out_dir = args.out.clone().unwrap_or_else(|| {
        let secs = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        PathBuf::from(format!("out/sync-{secs}"))
    });
    let mut records = Vec::new();
    for name in &args.layouts {
        if !args.json {
            eprintln!("running the {name} layout with a camera ...");
        }
        let record = run_one(name, &args).with_context(|| format!("the {name} layout"))?;
        if args.json {
            println!("{}", serde_json::to_string(&record)?);
        }
        records.push(record);
    }
    if !args.json {
        print_table(&records);
    }
    std::fs::create_dir_all(&out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    std::fs::write(
        out_dir.join("sync.json"),
        serde_json::to_string_pretty(&records)?,
    )?;
    for r in &records {
        let path = out_dir.join(format!("sync-{}.svg", r.layout));
        plot::write(&path, r)?;
        if !args.json {
            println!("plot: {}", path.display());
        }
    }
    if !args.json {
        println!("JSON: {}", out_dir.join("sync.json").display());
    }
    Ok(ExitCode::SUCCESS)
}

/// The camera of `config/demo-camera.toml` (placed to watch the PUMA and the wall), moved to
/// `node`, at the rate and size asked, with the faults asked on its link.
fn camera_table(node: &str, args: &SyncArgs) -> anyhow::Result<toml::Table> {
    let demo: toml::Table = DEMO_CAMERA
        .parse()
        .context("parsing config/demo-camera.toml")?;
    let mut camera = demo
        .get("sensors")
        .and_then(|s| s.get("camera"))
        .and_then(toml::Value::as_table)
        .cloned()
        .context("config/demo-camera.toml has no [sensors.camera]")?;
    camera.insert("node".into(), node.into());
    camera.insert("rate_hz".into(), args.fps.into());
    camera.insert("width".into(), i64::from(args.width).into());
    camera.insert("height".into(), i64::from(args.height).into());
    let mut link = toml::Table::new();
    link.insert("delay_ms".into(), args.camera_delay.into());
    link.insert("jitter_ms".into(), args.camera_jitter.into());
    camera.insert("link".into(), link.into());
    let mut sensors = toml::Table::new();
    sensors.insert("camera".into(), camera.into());
    let mut extra = toml::Table::new();
    extra.insert("sensors".into(), sensors.into());
    Ok(extra)
}

fn run_one(name: &str, args: &SyncArgs) -> anyhow::Result<SyncRecord> {
    let layout = all_layouts()
        .into_iter()
        .find(|l| l.name == name)
        .with_context(|| format!("no layout `{name}`"))?;
    // The robot's node and the operator's: the layout's ends.
    let node_of = |host: usize| {
        layout.hosts[host]
            .iter()
            .flatten()
            .next()
            .copied()
            .context("a layout end without a node")
    };
    let (operator_node, robot_node) = (node_of(layout.ends.0)?, node_of(layout.ends.1)?);
    let extra = camera_table(robot_node, args)?;
    let plan = LayoutPlan {
        layout: &layout,
        duration: args.duration.map(Duration::from_secs_f64),
        handoff: None,
        extra: Some(&extra),
    };
    let camera = format!("{robot_node}/camera");
    let robot = format!("{robot_node}/puma");
    let watcher: Watcher<Watched> = (
        operator_node,
        Box::new(move |context| watch(&context, &camera, &robot)),
    );
    let (layout_record, watched) = run_layout_watched(&plan, Some(watcher))?;
    let watched = watched.context("the watcher returned nothing")?;
    Ok(figures(name, args, layout_record, &watched))
}

/// The demo with a camera on the slave's node.
const DEMO_CAMERA: &str = include_str!("../../../../../config/demo-camera.toml");

/// How long the watcher waits for the camera and the robot to be there.
const READY: Duration = Duration::from_secs(30);

/// Runs on the operator's host: takes the camera's frames and the slave's force samples for
/// the task's length, as a view does.
fn watch(context: &WatchContext, camera: &str, robot: &str) -> anyhow::Result<Watched> {
    let mut config = ClientConfig::new("experiment-sync");
    config.role = Role::Reader;
    config.secret = crate::cmd::naming::read_secret(Some(&context.secret_file))?;
    let client = Client::connect(context.naming, config)?;
    // This host's common clock, as a view's: four-timestamp exchanges with the naming service.
    let clock =
        CommonClockView::follow(&client, REFRESH).context("estimating this host's common clock")?;

    let frames = retry_until_ready(|| client.watch_camera(camera, 1))
        .with_context(|| format!("watching camera `{camera}`"))?;
    let telemetry = retry_until_ready(|| client.subscribe(robot, 1))
        .with_context(|| format!("subscribing to `{robot}`"))?;
    let history = Arc::new(Mutex::new(SampleHistory::default()));
    let end = Instant::now() + context.task_length;
    let samples = {
        let history = history.clone();
        std::thread::spawn(move || -> u64 {
            let mut telemetry = telemetry;
            let mut n = 0;
            while Instant::now() < end {
                match telemetry.recv_timeout(Duration::from_millis(200)) {
                    Ok(Some(r)) => {
                        let sample = ForceSample::from_record(&r, telemetry.common_offset_ns());
                        history
                            .lock()
                            .unwrap_or_else(std::sync::PoisonError::into_inner)
                            .push(sample);
                        n += 1;
                    }
                    Ok(None) => {}
                    Err(_) => break,
                }
            }
            n
        })
    };
    let mut watched = Watched::default();
    let mut frames = frames;
    while Instant::now() < end {
        let left = end.saturating_duration_since(Instant::now());
        let Some(frame) = frames
            .recv_timeout(left.min(Duration::from_millis(500)))
            .context("the camera's frames")?
        else {
            continue;
        };
        let display_ns = clock.now_ns();
        let aligned_skew_ns = history
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .at(frame.capture_ns)
            .map(|a| a.skew_ns);
        watched.frames.push(FrameSeen {
            seq: frame.seq,
            capture_ns: frame.capture_ns,
            ready_ns: frame.ready_ns,
            sent_ns: frame.sent_ns,
            display_ns,
            aligned_skew_ns,
        });
    }
    watched.dropped = frames.dropped();
    watched.samples = samples
        .join()
        .map_err(|_| anyhow::anyhow!("the telemetry thread panicked"))?;
    Ok(watched)
}

/// Calls `open` until it succeeds, or [`READY`] passes (a camera not yet running, a robot not
/// yet driven).
fn retry_until_ready<T>(mut open: impl FnMut() -> Result<T, RpcError>) -> anyhow::Result<T> {
    let deadline = Instant::now() + READY;
    loop {
        match open() {
            Ok(t) => return Ok(t),
            Err(e) if Instant::now() >= deadline => bail!("not ready within {READY:?}: {e}"),
            Err(_) => std::thread::sleep(Duration::from_millis(100)),
        }
    }
}

/// The figures of one run.
fn figures(name: &str, args: &SyncArgs, layout_record: LayoutRecord, w: &Watched) -> SyncRecord {
    let us = |ns: i128| ns as f64 / 1e3;
    let force_latency = layout_record.contact_to_force.latency;
    let between = |from: fn(&FrameSeen) -> u64, to: fn(&FrameSeen) -> u64| -> Vec<f64> {
        w.frames
            .iter()
            .map(|f| us(i128::from(to(f)) - i128::from(from(f))))
            .collect()
    };
    let video = between(|f| f.capture_ns, |f| f.display_ns);
    let unaligned: Vec<f64> = video.iter().map(|v| v - force_latency.p50_us).collect();
    let aligned: Vec<f64> = w
        .frames
        .iter()
        .filter_map(|f| f.aligned_skew_ns.map(|a| us(i128::from(a)).abs()))
        .collect();
    let span_s = match (w.frames.first(), w.frames.last()) {
        (Some(a), Some(b)) if b.capture_ns > a.capture_ns => {
            (b.capture_ns - a.capture_ns) as f64 / 1e9
        }
        _ => 0.0,
    };
    let missing = w
        .frames
        .windows(2)
        .map(|p| p[1].seq.saturating_sub(p[0].seq + 1))
        .sum();
    SyncRecord {
        layout: name.into(),
        fps: args.fps,
        fps_received: if span_s > 0.0 {
            (w.frames.len().saturating_sub(1)) as f64 / span_s
        } else {
            0.0
        },
        frames: w.frames.len(),
        frames_dropped: w.dropped,
        frames_missing: missing,
        camera_delay_ms: args.camera_delay,
        video_latency: Percentiles::of(video),
        capture_to_ready: Percentiles::of(between(|f| f.capture_ns, |f| f.ready_ns)),
        ready_to_sent: Percentiles::of(between(|f| f.ready_ns, |f| f.sent_ns)),
        sent_to_display: Percentiles::of(between(|f| f.sent_ns, |f| f.display_ns)),
        force_latency,
        unaligned_skew: Percentiles::of(unaligned),
        aligned_residual: Percentiles::of(aligned),
        overruns: layout_record.loops.iter().map(|l| l.overruns).sum(),
        layout_record,
        seen: w.frames.clone(),
    }
}

fn print_table(records: &[SyncRecord]) {
    let ms = |p: &Percentiles| {
        format!(
            "{:>6.1} {:>6.1} {:>6.1}",
            p.p50_us / 1e3,
            p.p99_us / 1e3,
            p.max_us / 1e3
        )
    };
    println!(
        "{:<7} {:>11} {:>5} {:>22} {:>22} {:>22} {:>22} {:>8}",
        "layout",
        "fps got/set",
        "lost",
        "video ms p50 p99 max",
        "force ms p50 p99 max",
        "unaligned skew ms",
        "aligned residual ms",
        "overruns"
    );
    for r in records {
        println!(
            "{:<7} {:>5.1}/{:<5.1} {:>5} {:>22} {:>22} {:>22} {:>22} {:>8}",
            r.layout,
            r.fps_received,
            r.fps,
            r.frames_dropped + r.frames_missing,
            ms(&r.video_latency),
            ms(&r.force_latency),
            ms(&r.unaligned_skew),
            ms(&r.aligned_residual),
            r.overruns
        );
    }
    println!(
        "\nthe video's latency in parts (ms p50 p99 max), camera link delayed {} ms:",
        records.first().map_or(0.0, |r| r.camera_delay_ms)
    );
    println!(
        "{:<7} {:>22} {:>22} {:>22}",
        "layout", "capture->ready", "ready->sent", "sent->display"
    );
    for r in records {
        println!(
            "{:<7} {:>22} {:>22} {:>22}",
            r.layout,
            ms(&r.capture_to_ready),
            ms(&r.ready_to_sent),
            ms(&r.sent_to_display)
        );
    }
}
