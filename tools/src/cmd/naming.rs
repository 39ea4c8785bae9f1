//! `penelope naming`: the naming service alone (the paper's setup with a fourth PC for the CORBA
//! naming service).
//!
//! ```text
//! penelope naming                                  # 127.0.0.1:7300
//! penelope naming --listen 0.0.0.0:7300 --secret-file lab.secret
//! ```
//!
//! It serves [`Call::Naming`](penelope_protocol::proto::Call::Naming) (plus `Ping` and
//! `NodeInfo`) until Ctrl-C or SIGTERM. Nodes register in it with `penelope node --naming ADDR`.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context as _;
use nix::sys::signal::{SigSet, Signal};
use penelope_protocol::net::server::{Server, ServerConfig};
use penelope_protocol::proto::DEFAULT_PORT;
use penelope_supervisor::naming::{NamingLimits, NamingService};
pub(crate) use penelope_web::cli::read_secret;

/// Options of `penelope naming`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Address to listen on. Anything but loopback requires --secret-file.
    #[arg(long, default_value_t = SocketAddr::from(([127, 0, 0, 1], DEFAULT_PORT)))]
    pub listen: SocketAddr,
    /// File holding the shared secret of the system (its bytes, a trailing newline ignored;
    /// readable by its owner only).
    #[arg(long, value_name = "FILE")]
    pub secret_file: Option<PathBuf>,
    /// File holding the admin secret (with --secret-file): only clients proving it may
    /// unregister other nodes or write outside their own context.
    #[arg(long, value_name = "FILE", requires = "secret_file")]
    pub admin_secret_file: Option<PathBuf>,
    /// Most object bindings in the tree.
    #[arg(long, default_value_t = NamingLimits::default().max_bindings)]
    pub max_bindings: u32,
}

/// Runs `penelope naming`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let secret = read_secret(args.secret_file.as_deref())?;
    let admin_secret = read_secret(args.admin_secret_file.as_deref())?;
    refuse_open_listen(args.listen, secret.is_some())?;
    let signals = block_stop_signals()?;
    let limits = NamingLimits {
        max_bindings: args.max_bindings,
        ..NamingLimits::default()
    };
    let service = Arc::new(NamingService::new("naming", limits));
    let reaper = service
        .start_reaper(Duration::from_millis(100))
        .context("starting the lease reaper")?;
    let mut config = ServerConfig::new("naming");
    config.secret = secret;
    config.admin_secret = admin_secret;
    let server = Server::bind(args.listen, config, service.clone())
        .with_context(|| format!("listening on {}", args.listen))?;
    println!(
        "naming service on {} (nodes: penelope node --naming {}); Ctrl-C stops it",
        server.local_addr(),
        server.local_addr()
    );
    let signal = wait_for_stop(&signals)?;
    println!("{signal}: stopping the naming service");
    server.shutdown();
    reaper.stop();
    Ok(ExitCode::SUCCESS)
}

/// A usage error (exit 2) for a non-loopback `listen` without a secret.
pub(crate) fn refuse_open_listen(listen: SocketAddr, has_secret: bool) -> anyhow::Result<()> {
    if !listen.ip().is_loopback() && !has_secret {
        return Err(crate::cmd::usage(format!(
            "refusing to listen on {listen} without a shared secret: anyone who reaches this \
             address could drive the robots. Give --secret-file FILE (the same secret on every \
             node and client), or listen on loopback (127.0.0.1)"
        )));
    }
    Ok(())
}

/// Blocks SIGINT and SIGTERM in this thread (and so in every thread it spawns afterwards), so
/// that [`wait_for_stop`] receives them. Call it before starting any thread.
///
/// # Errors
/// The OS refused to change the signal mask.
pub(crate) fn block_stop_signals() -> anyhow::Result<SigSet> {
    let mut set = SigSet::empty();
    set.add(Signal::SIGINT);
    set.add(Signal::SIGTERM);
    set.thread_block().context("blocking SIGINT and SIGTERM")?;
    Ok(set)
}

/// Waits for one of the signals of `set` (blocked by [`block_stop_signals`]).
///
/// # Errors
/// The wait failed.
pub(crate) fn wait_for_stop(set: &SigSet) -> anyhow::Result<Signal> {
    set.wait().context("waiting for a signal")
}

#[cfg(test)]
mod tests {
    use super::*;
    use penelope_protocol::net::auth::Secret;

    #[test]
    fn open_listen_needs_a_secret_and_secrets_are_trimmed() {
        let open: SocketAddr = "0.0.0.0:7300".parse().unwrap();
        let err = refuse_open_listen(open, false).unwrap_err();
        assert!(err.downcast_ref::<crate::cmd::UsageError>().is_some());
        assert!(refuse_open_listen(open, true).is_ok());
        assert!(refuse_open_listen("127.0.0.1:7300".parse().unwrap(), false).is_ok());

        use std::os::unix::fs::PermissionsExt as _;
        let dir = std::env::temp_dir().join(format!("penelope-secret-{}", std::process::id()));
        const STRONG: &[u8] = b"0f3c9a7be21d4c58a9e6b2d07f1c3e95";
        std::fs::write(&dir, [STRONG, b"\n"].concat()).unwrap();
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o644)).unwrap();
        let err = read_secret(Some(&dir)).unwrap_err().to_string();
        assert!(
            err.contains(&format!("chmod 600 {}", dir.display())),
            "{err}"
        );
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o600)).unwrap();
        assert_eq!(read_secret(Some(&dir)).unwrap(), Some(Secret::from(STRONG)));
        // Too weak: refused, saying how to make one.
        std::fs::write(&dir, b"s3cret\n").unwrap();
        let err = read_secret(Some(&dir)).unwrap_err();
        assert!(err.downcast_ref::<crate::cmd::UsageError>().is_some());
        assert!(err.to_string().contains("penelope secret new"), "{err}");
        std::fs::write(&dir, b"\n").unwrap();
        assert!(read_secret(Some(&dir)).is_err());
        std::fs::remove_file(&dir).unwrap();
        assert_eq!(read_secret(None).unwrap(), None);
    }
}
