//! `penelope foxglove`: the live stream for Foxglove, served by the `penelope-foxglove` crate
//! (which needs the protocol and nothing of the runtime). This module only reads the options.

use std::net::{SocketAddr, ToSocketAddrs};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use penelope_foxglove::{Config, DEFAULT_RATE_HZ, Error};
use penelope_protocol::net::conn::ClientConfig;
use penelope_web::cli::{read_secret, usage};

/// Options of `penelope foxglove`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The naming service, HOST:PORT.
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:7300")]
    pub naming: String,
    /// Where Foxglove connects, HOST:PORT: loopback only (the Foxglove protocol has no
    /// authentication; forward the port to reach it from another host).
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:8765")]
    pub listen: String,
    /// A file holding the shared secret of the system (owner-readable only), as given to
    /// `penelope node`: the gateway talks to the nodes with it, as a reader.
    #[arg(long, value_name = "FILE")]
    pub secret_file: Option<PathBuf>,
    /// Messages per second per controller (its ticks, its robot's transforms) at most.
    #[arg(long, value_name = "HZ", default_value_t = DEFAULT_RATE_HZ)]
    pub rate: f64,
    /// Do not offer the global e-stop as a service (a display that only watches).
    #[arg(long)]
    pub no_estop: bool,
    /// A browser origin allowed to connect besides loopback pages and Foxglove's web app
    /// (`https://lab.example`; `*` for any); repeat for several.
    #[arg(long = "allow-origin", value_name = "ORIGIN")]
    pub allow_origins: Vec<String>,
    /// Seconds to wait for a node's answer.
    #[arg(long, value_name = "S", default_value_t = 5.0)]
    pub timeout: f64,
}

/// Runs `penelope foxglove` until interrupted.
///
/// # Errors
/// Bad options (a usage error), or the address cannot be listened on.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let resolve = |what: &str, text: &str| -> anyhow::Result<SocketAddr> {
        text.to_socket_addrs()
            .ok()
            .and_then(|mut a| a.next())
            .ok_or_else(|| usage(format!("--{what}: `{text}` is not HOST:PORT")))
    };
    if !(args.timeout.is_finite() && args.timeout > 0.0) {
        return Err(usage(format!(
            "--timeout must be > 0 s, got {}",
            args.timeout
        )));
    }
    let mut client = ClientConfig::new("penelope-foxglove");
    client.timeout = Duration::from_secs_f64(args.timeout);
    client.secret = read_secret(args.secret_file.as_deref())?;
    let config = Config {
        naming: resolve("naming", &args.naming)?,
        listen: resolve("listen", &args.listen)?,
        client,
        rate_hz: args.rate,
        estop: !args.no_estop,
        allowed_origins: args.allow_origins,
    };
    match penelope_foxglove::run(config, Arc::new(AtomicBool::new(false))) {
        Ok(()) => Ok(ExitCode::SUCCESS),
        Err(Error::Usage(message)) => Err(usage(message)),
        Err(e) => Err(e.into()),
    }
}
