//! `penelope camera probe DEVICE`: check a V4L2 camera by hand: what it offers (formats, sizes,
//! rates), then a few frames with their timestamp source, capture-to-dequeue delay and size.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::Subcommand;
use penelope_drivers::v4l2::{V4l2Camera, V4l2Error, V4l2Settings, probe};

/// Camera commands.
#[derive(Subcommand, Debug)]
pub enum CameraCommand {
    /// List a V4L2 device's formats, sizes and rates, then capture a few frames and print their
    /// timestamp source and delay.
    Probe(ProbeArgs),
}

/// Options of `camera probe`.
#[derive(clap::Args, Debug)]
pub struct ProbeArgs {
    /// The device node (`/dev/video0`).
    pub device: PathBuf,
    /// Frames to capture after the listing (0: list only).
    #[arg(long, default_value_t = 10)]
    pub frames: u32,
    /// Requested width, pixels.
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    /// Requested height, pixels.
    #[arg(long, default_value_t = 480)]
    pub height: u32,
    /// Requested frame rate, fps.
    #[arg(long, default_value_t = 30)]
    pub rate: u32,
}

/// Runs the subcommand.
pub fn run(command: CameraCommand) -> anyhow::Result<ExitCode> {
    let CameraCommand::Probe(args) = command;
    if args.frames > 10_000 {
        return Err(crate::cmd::usage("--frames must be at most 10000"));
    }
    let report = probe(&args.device)?;
    let id = &report.identity;
    println!(
        "{}: {} (driver {}, {})",
        args.device.display(),
        id.card,
        id.driver,
        id.bus
    );
    for f in &report.formats {
        let usable = if f.usable { "" } else { " (not usable here)" };
        println!("  {} {}{usable}", f.fourcc, f.description);
        for s in &f.sizes {
            let rates: Vec<String> = s.rates_hz.iter().map(|r| format!("{r:.2}")).collect();
            println!("    {}x{}: {} fps", s.width, s.height, rates.join(", "));
        }
    }
    if args.frames == 0 {
        return Ok(ExitCode::SUCCESS);
    }
    let settings = V4l2Settings {
        width: args.width,
        height: args.height,
        rate_hz: args.rate,
        ..V4l2Settings::new(&args.device)
    };
    let mut camera = V4l2Camera::open(&settings)?;
    println!("negotiated: {}", camera.negotiated());
    let mut captured = 0;
    let mut attempts = 0;
    while captured < args.frames && attempts < args.frames * 2 {
        attempts += 1;
        match camera.next(Duration::from_secs(2)) {
            Ok(f) => {
                captured += 1;
                let exposure = f.exposure_ns.map_or("not reported".to_string(), |e| {
                    format!("{:.1} ms", e as f64 / 1e6)
                });
                println!(
                    "  frame {:>6}: {:<26} capture to dequeue {:>6.1} ms, exposure {exposure}, {} bytes of JPEG",
                    f.sequence,
                    f.timestamp_source.name(),
                    f.dequeued_ns.saturating_sub(f.capture_ns) as f64 / 1e6,
                    f.jpeg.len()
                );
            }
            Err(e @ V4l2Error::Garbled { .. }) => println!("  {e}"),
            Err(e) => return Err(e.into()),
        }
    }
    println!("{:?}", camera.stats());
    Ok(ExitCode::SUCCESS)
}
