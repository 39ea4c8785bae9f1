//! One module per subcommand.

use std::process::ExitCode;

pub mod bench;
pub mod camera;
pub mod ctl;
pub mod demo;
pub mod doctor;
pub mod experiment;
pub mod foxglove;
pub mod galil;
pub mod galil_sim;
pub mod kin;
pub mod naming;
pub mod netft;
pub mod netft_sim;
pub mod node;
pub mod recording;

pub mod secret;
pub mod web;

// Shared with the web server, which the tools sit above.
pub use penelope_web::cli::{UsageError, usage};

/// Prints `err` and picks the exit code: 2 for a [`UsageError`], 1 for anything else.
pub fn report_error(err: &anyhow::Error) -> ExitCode {
    eprintln!("error: {err:#}");
    if err.downcast_ref::<UsageError>().is_some() {
        ExitCode::from(2)
    } else {
        ExitCode::from(1)
    }
}

/// Lets an emulator serve until `duration` seconds have passed (none: until interrupted),
/// checking every 100 ms that it still runs (`running`).
///
/// # Errors
/// When the emulator's thread stopped on its own.
pub fn serve_until(duration: Option<f64>, running: impl Fn() -> bool) -> anyhow::Result<()> {
    let start = std::time::Instant::now();
    loop {
        std::thread::sleep(std::time::Duration::from_millis(100));
        if duration.is_some_and(|d| start.elapsed().as_secs_f64() >= d) {
            return Ok(());
        }
        if !running() {
            anyhow::bail!("the emulator thread stopped");
        }
    }
}
