#![doc = include_str!("../README.md")]
//!
//! # Layers
//! - [`wire`]: the Foxglove WebSocket protocol's messages and frames (pure data).
//! - [`hub`]: the channels served and the clients connected; bounded queues per client, so a
//!   slow client loses messages (counted) and never holds up a reader.
//! - [`sources`]: which objects the nodes have, and one reader thread per stream, subscribed
//!   through the protocol (the node decimates; no real-time thread sees the gateway).
//! - [`cameras`]: each camera's frames, calibration, and the force measured at each frame's
//!   capture instant drawn on it.
//! - [`robots`]: each robot's description, place, transforms and scene (`penelope-scene`
//!   builds the messages, the node's model gives the frames).
//! - [`clock`]: message times on the system's common clock (simulated time on a simulated node).
//! - [`topics`]: the topics and their JSON Schemas, as in the recordings.
//! - [`server`]: the WebSocket itself (origins, client cap, requests, the e-stop service).

#![warn(missing_docs)]

pub mod cameras;
pub mod clock;
pub mod hub;
pub mod robots;
pub mod server;
pub mod sources;
pub mod topics;
pub mod wire;

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use penelope_protocol::client::Client;
use penelope_protocol::net::conn::ClientConfig;
use penelope_protocol::proto::Role;

use crate::hub::Hub;
use crate::server::ServerState;
use crate::sources::{DISCOVERY_PERIOD, Shared, Sources};

/// The default rate of every controller's messages, per second.
pub const DEFAULT_RATE_HZ: f64 = 100.0;
/// How often the server's time goes to the clients.
const TIME_PERIOD: Duration = Duration::from_millis(100);
/// How often `/penelope/gateway` is published.
const STATS_PERIOD: Duration = Duration::from_secs(1);
/// How often at most a client that loses messages is told so.
const NOTICE_PERIOD: Duration = Duration::from_secs(5);

/// How `penelope foxglove` runs.
#[derive(Clone, Debug)]
pub struct Config {
    /// The naming service.
    pub naming: SocketAddr,
    /// Where Foxglove connects (loopback only).
    pub listen: SocketAddr,
    /// How the gateway talks to the nodes: its name, the shared secret, timeouts. Its role is
    /// always [`Role::Reader`]: it watches and stops, which is all it needs.
    pub client: ClientConfig,
    /// Messages per second per controller at most.
    pub rate_hz: f64,
    /// Whether the global e-stop is offered as a service.
    pub estop: bool,
    /// Browser origins allowed besides loopback pages and Foxglove's app (`*`: any).
    pub allowed_origins: Vec<String>,
}

/// Why `penelope foxglove` cannot start.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An option out of range.
    #[error("{0}")]
    Usage(String),
    /// The listening socket or the runtime.
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

impl Config {
    /// Checks the options.
    ///
    /// # Errors
    /// [`Error::Usage`] naming the option.
    pub fn check(&self) -> Result<(), Error> {
        if !self.listen.ip().is_loopback() {
            return Err(Error::Usage(format!(
                "--listen {}: the Foxglove WebSocket protocol has no authentication, so this \
                 server listens on loopback only; from another host, forward the port \
                 (`ssh -L 8765:127.0.0.1:8765 HOST`)",
                self.listen
            )));
        }
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0 && self.rate_hz <= 10_000.0) {
            return Err(Error::Usage(format!(
                "--rate must be in (0, 10000] messages per second, got {}",
                self.rate_hz
            )));
        }
        Ok(())
    }
}

/// Runs the gateway until `stop` is set (or Ctrl-C): prints its readiness line once it accepts
/// connections.
///
/// # Errors
/// [`Error`]: bad options, or the address cannot be listened on.
pub fn run(mut config: Config, stop: Arc<AtomicBool>) -> Result<(), Error> {
    config.check()?;
    config.client.role = Role::Reader;
    let client = Client::lazy(config.naming, config.client.clone());
    let session = format!(
        "{}",
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_millis())
    );
    let hub = Arc::new(Hub::new("penelope", &session));
    if config.estop {
        hub.set_services(vec![server::estop_service()]);
    }
    let gateway_channel = hub.add_channel(
        topics::GATEWAY_TOPIC,
        "penelope.GatewayStats",
        topics::GATEWAY_SCHEMA,
    );
    let schema = |name| penelope_scene::schema(name).unwrap_or("{}");
    let tf = hub.add_channel(
        penelope_scene::TOPIC_TF,
        penelope_scene::FRAME_TRANSFORMS,
        schema(penelope_scene::FRAME_TRANSFORMS),
    );
    let scene = hub.add_channel(
        penelope_scene::TOPIC_SCENE,
        penelope_scene::SCENE_UPDATE,
        schema(penelope_scene::SCENE_UPDATE),
    );
    let shared = Arc::new(Shared {
        client: client.clone(),
        hub: hub.clone(),
        rate_hz: config.rate_hz,
        latest_ns: AtomicU64::new(0),
        scene_channels: (tf, scene),
        robots: std::sync::Mutex::new(std::collections::HashMap::new()),
    });
    let state = Arc::new(ServerState {
        hub: hub.clone(),
        client,
        estop: config.estop,
        origins: config.allowed_origins.clone(),
        connected: AtomicUsize::new(0),
        estops: AtomicUsize::new(0),
    });
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    let listener = runtime
        .block_on(tokio::net::TcpListener::bind(config.listen))
        .map_err(|e| Error::Usage(format!("cannot listen on {}: {e}", config.listen)))?;
    let bound = listener.local_addr()?;
    let keeper = {
        let stop = stop.clone();
        std::thread::Builder::new()
            .name("fox-keeper".into())
            .spawn(move || keep(&shared, gateway_channel, &stop))?
    };
    // The readiness line tests and scripts wait for: said once the socket accepts.
    println!(
        "penelope foxglove: serving ws://{bound} ({}; naming service {}; {} msg/s per controller{}); Ctrl-C stops it",
        wire::SUBPROTOCOLS[0],
        config.naming,
        config.rate_hz,
        if config.estop { "; e-stop service" } else { "" }
    );
    let app = server::router(state).into_make_service_with_connect_info::<SocketAddr>();
    let stopped = stop.clone();
    runtime.block_on(async move {
        let until_stopped = async move {
            while !stopped.load(Ordering::Acquire) {
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
        };
        tokio::select! {
            r = axum::serve(listener, app) => { let _ = r; }
            _ = tokio::signal::ctrl_c() => {}
            () = until_stopped => {}
        }
    });
    stop.store(true, Ordering::Release);
    let _ = keeper.join();
    runtime.shutdown_timeout(Duration::from_secs(1));
    Ok(())
}

/// The housekeeping thread: finds the nodes' objects, sends the server's time, publishes the
/// gateway's counters; ends the readers when stopped.
fn keep(shared: &Arc<Shared>, gateway_channel: u32, stop: &AtomicBool) {
    let mut sources = Sources::new(shared.clone());
    let mut last_discovery: Option<Instant> = None;
    let mut last_stats = Instant::now();
    let mut last_time = 0;
    let mut complained = false;
    let mut told = std::collections::HashMap::new();
    while !stop.load(Ordering::Acquire) {
        if last_discovery.is_none_or(|t| t.elapsed() >= DISCOVERY_PERIOD) {
            last_discovery = Some(Instant::now());
            match sources.discover() {
                Ok(()) => complained = false,
                Err(e) if !complained => {
                    complained = true;
                    eprintln!(
                        "penelope foxglove: the naming service did not answer: {e} (asking again)"
                    );
                }
                Err(_) => {}
            }
        }
        let now = shared.latest_ns.load(Ordering::Acquire);
        if now > last_time {
            last_time = now;
            shared.hub.broadcast_time(now);
        }
        if last_stats.elapsed() >= STATS_PERIOD {
            last_stats = Instant::now();
            let (clients, evicted) = shared.hub.stats();
            for (id, text) in hub::notices(&clients, &mut told, Instant::now(), NOTICE_PERIOD) {
                let status = wire::status(wire::Level::Warning, &text);
                shared.hub.send_control(id, hub::Outgoing::Text(status));
            }
            let message = topics::gateway(&clients, evicted, &sources.stats()).to_string();
            shared
                .hub
                .publish(gateway_channel, last_time, message.as_bytes());
        }
        std::thread::sleep(TIME_PERIOD);
    }
    // Dropping the sources stops and joins every reader (each unsubscribes).
    drop(sources);
}
