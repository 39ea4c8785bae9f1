//! `penelope galil-sim`: a Galil DMC-40x0 emulator on a pseudo-terminal.
//!
//! Prints the device path, then serves it until interrupted; drive it with `penelope galil
//! --port PATH ...` or any serial terminal program.

use std::process::ExitCode;
use std::time::Duration;

use penelope_drivers::galil::emulator::{ArmConfig, DmcConfig, PtyEmulator, PtyOptions};
use penelope_hal::NamedPose;
use penelope_hal::robot::RobotModel as _;

/// Options.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Number of axes, 1..=8.
    #[arg(long, default_value_t = 6)]
    pub axes: usize,
    /// Model string answered to `^R^V`.
    #[arg(long, default_value = "DMC4060")]
    pub model: String,
    /// Pace both directions like a serial line at this baud rate (bits/s); unpaced by default.
    #[arg(long)]
    pub baud: Option<u32>,
    /// Print an unsolicited message (as a board program's `MG` would) every this many ms.
    #[arg(long, value_name = "MS")]
    pub unsolicited_every: Option<u64>,
    /// The unsolicited message text (a CR LF is appended).
    #[arg(long, default_value = "#AUTO running")]
    pub unsolicited_text: String,
    /// Also make a symbolic link to the device at this path (replaced if it exists).
    #[arg(long)]
    pub link: Option<std::path::PathBuf>,
    /// Stop after this many seconds (default: run until interrupted).
    #[arg(long, value_name = "S")]
    pub duration: Option<f64>,
    /// Drive a built-in robot's rigid-body plant (gravity, friction, brakes while an amplifier is
    /// off) instead of bare motors: `puma200`, `puma560` or `frhc`. The encoders read zero at its
    /// `start` pose.
    #[arg(long, value_name = "ROBOT")]
    pub arm: Option<String>,
    /// With `--arm`: joint torque per output volt, N·m/V, for every axis (default: each joint's
    /// torque limit at 10 V, the demo's convention; 10 N·m/V matches a node's default 0.1 V/N·m).
    #[arg(long, value_name = "NM_PER_V")]
    pub newton_metres_per_volt: Option<f64>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if !(1..=8).contains(&args.axes) {
        return Err(crate::cmd::usage("--axes must be 1..=8"));
    }
    if args.baud == Some(0) {
        return Err(crate::cmd::usage("--baud must be positive"));
    }
    if args.model.is_empty() || !args.model.is_ascii() || args.model.contains(char::is_whitespace) {
        return Err(crate::cmd::usage(
            "--model must be one ASCII word, e.g. DMC4060",
        ));
    }
    if let Some(d) = args.duration
        && !(d.is_finite() && d >= 0.0)
    {
        return Err(crate::cmd::usage(
            "--duration must be a non-negative number of seconds",
        ));
    }
    let unsolicited = args.unsolicited_every.map(|ms| {
        let mut text = args.unsolicited_text.clone().into_bytes();
        text.extend_from_slice(b"\r\n");
        (Duration::from_millis(ms.max(1)), text)
    });
    let arm = match &args.arm {
        None => None,
        Some(name) => {
            let Some(robot) = penelope_drivers::model::by_name(name) else {
                return Err(crate::cmd::usage("--arm must be puma200, puma560 or frhc"));
            };
            let start = robot.named_pose(NamedPose::Start);
            let mut arm = ArmConfig::new(robot.clone(), start, 1.0);
            for (j, k) in arm.newton_metres_per_volt.iter_mut().enumerate() {
                let limit = robot.limits().effort_max[j.min(penelope_hal::MAX_JOINTS - 1)];
                *k = match args.newton_metres_per_volt {
                    Some(v) => v,
                    None if limit.is_finite() && limit > 0.0 => limit / 10.0,
                    None => 10.0,
                };
            }
            if !arm
                .newton_metres_per_volt
                .iter()
                .all(|v| v.is_finite() && *v > 0.0)
            {
                return Err(crate::cmd::usage(
                    "--newton-metres-per-volt must be positive",
                ));
            }
            Some(arm)
        }
    };
    let emu = PtyEmulator::spawn(PtyOptions {
        dmc: DmcConfig {
            axes: args.axes,
            model: args.model.clone(),
            arm,
            ..DmcConfig::default()
        },
        baud: args.baud,
        unsolicited,
    })?;
    if let Some(link) = &args.link {
        let _ = std::fs::remove_file(link);
        std::os::unix::fs::symlink(emu.path(), link)?;
    }
    println!("{}", emu.path().display());
    eprintln!(
        "galil-sim: {} with {} axes on {}{}; interrupt to stop",
        args.model,
        args.axes,
        emu.path().display(),
        args.baud
            .map(|b| format!(", paced at {b} baud"))
            .unwrap_or_default()
    );
    super::serve_until(args.duration, || emu.is_running())?;
    if let Some(link) = &args.link {
        let _ = std::fs::remove_file(link);
    }
    emu.stop();
    Ok(ExitCode::SUCCESS)
}
