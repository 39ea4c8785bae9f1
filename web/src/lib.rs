//! `penelope web`: the paper's planned web interface (its `webInterface` class), as a browser
//! page served by this process. A client of the protocol crate and nothing of the runtime:
//! a system file is applied by the node it is sent to (`CreatorCall::ApplySystem`).
//!
//! ```text
//! penelope web [--naming ADDR] [--listen 127.0.0.1:8080] [--secret-file FILE]
//!               [--allow-host NAME[:PORT]]...
//! ```
//!
//! It is one more client of the system: every request becomes calls of the client library
//! ([`penelope_protocol::client`], as `penelope ctl` makes them), run on tokio's blocking pool
//! because the library blocks; live telemetry is a subscription like `ctl watch`'s, decimated
//! by the node, so the real-time rings never see the browser.
//!
//! # Layers
//! - `doors`: before any handler: a `Host` that names this server (no DNS rebinding),
//!   connection caps (in all and per client) and a deadline for a request's head.
//! - `session`: who may ask: loopback needs nothing, any other address (or a `--secret-file`)
//!   needs the shared secret once at `/login`, then a login cookie; state-changing requests
//!   and WebSockets from another site are refused.
//! - `api`: the JSON endpoints behind the page: the naming tree with states, kinds with their
//!   configuration keys, create, destroy, lifecycle, method calls, e-stop and re-arm.
//! - `system`: experiments as wholes: system files (the demo's among them) sent to the
//!   node, which applies them, recordings started, stopped and downloaded.
//! - `live`: one WebSocket per plot (and per robot of the 3D view): telemetry records thinned
//!   for a browser, and safety events (changes of the loop's safety state) as they happen.
//! - `camera`: one WebSocket per camera panel: a camera's frames with the force and pose
//!   samples measured at each frame's capture instant, and how far the video is behind the hand.
//! - `robots`: what the 3D view draws a robot from: its description (URDF, frames, joints,
//!   the contact shapes of its simulated world).
//! - `assets`: the page, its scripts and style and the vendored uPlot, three.js and
//!   urdf-loader, compiled into the binary (nothing is fetched from the network when the page
//!   runs).
//! - [`cli`]: what the server shares with `penelope ctl`: method text parsed into calls, replies
//!   formatted for people, usage errors, secret files.

#![warn(missing_docs)]

mod api;
mod assets;
mod camera;
pub mod cli;
mod doors;
mod live;
mod robots;
mod session;
mod system;

use std::net::{SocketAddr, ToSocketAddrs};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use axum::Router;
use axum::routing::{get, post};
use penelope_protocol::client::Client;
use penelope_protocol::net::conn::ClientConfig;
use penelope_protocol::proto::Role;

use crate::cli::usage;

/// Options of `penelope web`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The naming service, HOST:PORT.
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:7300")]
    pub naming: String,
    /// Where the page is served, HOST:PORT. Any address but loopback needs --secret-file.
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:8080")]
    pub listen: String,
    /// A file holding the shared secret of the system (owner-readable only), as given to
    /// `penelope node`: the server talks to the nodes with it, and a browser must type it once
    /// at the login page (then holds a login cookie).
    #[arg(long, value_name = "FILE")]
    pub secret_file: Option<PathBuf>,
    /// The role the server speaks to the nodes with, for every browser behind it: `reader`
    /// (the default: list, watch and stop; an e-stop is always allowed), `operator` (also run
    /// objects: lifecycle, methods, recordings, gains) or `admin` (also create and destroy;
    /// needs --admin-secret-file at a system that has an admin secret).
    #[arg(long, value_enum, default_value_t = WebRole::Reader)]
    pub role: WebRole,
    /// A file holding the admin secret (with --secret-file and --role admin).
    #[arg(long, value_name = "FILE", requires = "secret_file")]
    pub admin_secret_file: Option<PathBuf>,
    /// Hours a login lasts.
    #[arg(long, value_name = "H", default_value_t = 12.0)]
    pub login_hours: f64,
    /// Seconds to wait for a node's answer.
    #[arg(long, value_name = "S", default_value_t = 5.0)]
    pub timeout: f64,
    /// A directory of system files (`*.toml`) the page offers to load besides the text box
    /// (default: none; `config/` of the repository holds the demo's).
    #[arg(long, value_name = "DIR")]
    pub systems: Option<PathBuf>,
    /// Names besides its listen address and `localhost` under which the page is served (a
    /// request whose `Host` names none of them is refused: DNS rebinding), `NAME` for any port
    /// or `NAME:PORT`, as a browser reaches this server (for example through a proxy).
    #[arg(long = "allow-host", value_name = "NAME")]
    pub allow_hosts: Vec<String>,
}

/// The role `penelope web` speaks to the nodes with.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum WebRole {
    /// List, describe, watch and stop.
    Reader,
    /// Also lifecycle, methods, recordings and gains.
    Operator,
    /// Also create and destroy objects.
    Admin,
}

/// What every request handler shares.
pub(crate) struct WebState {
    /// The system, through the client library.
    pub client: Client,
    /// The logins.
    pub sessions: session::Sessions,
    /// Where system files offered by name live.
    pub systems: Option<PathBuf>,
    /// The recordings stopped from the page: the only files it lets a browser download.
    pub recordings: Mutex<Vec<PathBuf>>,
    /// Live sockets open now (at most [`live::MAX_SOCKETS`]).
    pub live_sockets: std::sync::atomic::AtomicUsize,
}

/// Runs `penelope web` until interrupted.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let resolve = |what: &str, text: &str| -> anyhow::Result<SocketAddr> {
        text.to_socket_addrs()
            .ok()
            .and_then(|mut a| a.next())
            .ok_or_else(|| usage(format!("--{what}: `{text}` is not HOST:PORT")))
    };
    let naming = resolve("naming", &args.naming)?;
    let listen = resolve("listen", &args.listen)?;
    if !(args.timeout.is_finite() && args.timeout > 0.0) {
        return Err(usage(format!(
            "--timeout must be > 0 s, got {}",
            args.timeout
        )));
    }
    if !(args.login_hours.is_finite() && args.login_hours > 0.0 && args.login_hours <= 24.0 * 30.0)
    {
        return Err(usage(format!(
            "--login-hours must be in (0, 720], got {}",
            args.login_hours
        )));
    }
    let secret = crate::cli::read_secret(args.secret_file.as_deref())?;
    // As every server of the system: loopback alone may go without the secret.
    if !listen.ip().is_loopback() && secret.is_none() {
        return Err(usage(format!(
            "--listen {listen} is not a loopback address: give --secret-file (browsers must \
             prove the shared secret at the login page)"
        )));
    }
    let admin_secret = crate::cli::read_secret(args.admin_secret_file.as_deref())?;
    if admin_secret.is_some() && args.role != WebRole::Admin {
        return Err(usage("--admin-secret-file is only for --role admin"));
    }
    let mut config = ClientConfig::new("penelope-web");
    config.role = match args.role {
        WebRole::Reader => Role::Reader,
        WebRole::Operator => Role::Operator,
        WebRole::Admin => Role::Admin,
    };
    config.timeout = Duration::from_secs_f64(args.timeout);
    config.admin_secret = admin_secret;
    let secret = secret.map(|s| {
        config.secret = Some(s.clone());
        s.bytes().to_vec()
    });
    // Lazy: the page comes up (and says the naming service is unreachable) before the system.
    let client = Client::lazy(naming, config);
    let state = Arc::new(WebState {
        client,
        sessions: session::Sessions::new(
            secret,
            Duration::from_secs_f64(args.login_hours * 3600.0),
        ),
        systems: args.systems,
        recordings: Mutex::new(Vec::new()),
        live_sockets: std::sync::atomic::AtomicUsize::new(0),
    });
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    runtime.block_on(serve(state, listen, naming, &args.allow_hosts))
}

/// The routes: `/login` open to all, everything else behind [`session::guard`]; all of them
/// only under a name of this server ([`doors::named_host`]).
fn router(state: Arc<WebState>, hosts: Arc<doors::Hosts>) -> Router {
    let guarded = Router::new()
        .route("/", get(assets::index))
        .route("/assets/{file}", get(assets::file))
        .route("/api/tree", get(api::tree))
        .route("/api/kinds", get(api::kinds))
        .route("/api/object", get(api::describe))
        .route("/api/create", post(api::create))
        .route("/api/destroy", post(api::destroy))
        .route("/api/call", post(api::call))
        .route("/api/estop", post(api::estop_all))
        .route("/api/systems", get(system::systems))
        .route("/api/system", post(system::load_system))
        .route("/api/record", post(system::record))
        .route("/api/recording", get(system::recording))
        .route("/api/live", get(live::socket))
        .route("/api/camera", get(camera::socket))
        .route("/api/robot", get(robots::robot))
        .route("/logout", post(session::logout))
        .route_layer(axum::middleware::from_fn_with_state(
            state.clone(),
            session::guard,
        ));
    Router::new()
        .route("/login", get(session::login_page).post(session::login))
        .merge(guarded)
        // Every request, the login's too: no state change from another site.
        .layer(axum::middleware::from_fn(session::same_origin))
        // Outermost: the same-origin check compares `Origin` with `Host`, which a rebound
        // page meets unless `Host` must name this server.
        .layer(axum::middleware::from_fn_with_state(
            hosts,
            doors::named_host,
        ))
        .with_state(state)
}

async fn serve(
    state: Arc<WebState>,
    listen: SocketAddr,
    naming: SocketAddr,
    allow_hosts: &[String],
) -> anyhow::Result<ExitCode> {
    let listener = tokio::net::TcpListener::bind(listen)
        .await
        .map_err(|e| anyhow::anyhow!("cannot listen on {listen}: {e}"))?;
    let bound = listener.local_addr()?;
    let hosts = Arc::new(doors::Hosts::new(bound, allow_hosts)?);
    // The readiness line tests and scripts wait for: said once the socket accepts.
    println!(
        "penelope web: serving http://{bound}/ (naming service {naming}{}); Ctrl-C stops it",
        if state.sessions.needs_login() {
            ", login with the shared secret"
        } else {
            ""
        }
    );
    tokio::select! {
        () = doors::serve(listener, router(state, hosts)) => {}
        _ = tokio::signal::ctrl_c() => {}
    }
    Ok(ExitCode::SUCCESS)
}
