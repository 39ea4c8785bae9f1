//! The Zenoh bridge: a node's telemetry, safety events and link statistics published on Zenoh
//! key expressions `penelope/<node>/<object>/<stream>`, its object tree answered as a
//! queryable, and operator poses taken from a Zenoh key as the master side of a
//! `trajectory/teleop` channel — so that an operator station, a lab's dashboards or a ROS 2
//! system that speaks Zenoh (rmw_zenoh) reach a node without our own protocol.
//!
//! # Layers
//! - [`encoding`]: the key expressions and the bytes (documented in `docs/zenoh.md`);
//! - the channels fed from Zenoh are the runtime's
//!   ([`BridgedChannels`](penelope_runtime::objects::bridged::BridgedChannels)): the creator
//!   registers them when it configures one, the bridge feeds their cells;
//! - `session.rs` (feature `zenoh`): the Zenoh session, its publishers, subscribers and
//!   queryable, and the bridge's thread.
//!
//! # Real time
//! Nothing here runs in a loop's thread. Ticks reach the bridge the way they reach a recording:
//! the telemetry pump hands every tick to a bounded stream ([`penelope_runtime::objects::Creator::record_ticks`]);
//! a bridge that falls behind loses ticks (counted), never the loop. Operator poses reach the
//! loop the way the data plane's samples do: the bridge writes a lock-free latest-value cell
//! that the channel's communication thread reads each tick
//! ([`penelope_runtime::objects::teleop_end::TeleopLink::bridged`]); a malformed payload is refused and
//! counted before it reaches the cell.
//!
//! # Scope of the network
//! A node connects to the router or peer it is told (`--zenoh ENDPOINT`), and listens nowhere;
//! multicast scouting is off. A Zenoh configuration file (`--zenoh-config FILE`) is passed
//! through as it is, and decides what it mentions: scouting when it mentions `multicast`,
//! listening when it mentions `listen`.
//!
//! # Authentication and access control
//! An endpoint off loopback (to connect to or listen on), or multicast scouting, is refused
//! unless the configuration file sets Zenoh's user-password authentication
//! (`transport.auth.usrpwd`: `user` and `password`, and a `dictionary_file` when it listens):
//! off loopback, whoever may publish on a channel's reference key drives its slave. With
//! [`ZenohSettings::operators`], the session's access control lets every authenticated
//! participant subscribe and query, and only those users put.

pub mod encoding;
#[cfg(feature = "zenoh")]
mod session;

use std::path::PathBuf;

#[cfg(feature = "zenoh")]
pub use session::ZenohBridge;

/// How a node reaches Zenoh: `zenoh = "tcp/127.0.0.1:7447"` (an endpoint) or
/// `zenoh = { connect = "tcp/127.0.0.1:7447", config = "zenoh.json5" }` in its `[nodes.<name>]`
/// table, or `penelope node --zenoh ENDPOINT --zenoh-config FILE`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ZenohSettings {
    /// The router or peer to connect to, a Zenoh endpoint (`tcp/127.0.0.1:7447`).
    pub connect: Option<String>,
    /// Zenoh's own configuration file (JSON5), passed through.
    pub config: Option<PathBuf>,
    /// The Zenoh users (user-password authentication, `transport.auth.usrpwd` in the
    /// configuration file) that may publish on this node: operator poses into its channels.
    /// When set, the bridge's session enforces Zenoh access control: every participant may
    /// subscribe and query, only these may put (docs/zenoh.md).
    pub operators: Vec<String>,
}

impl<'de> serde::Deserialize<'de> for ZenohSettings {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Table {
            connect: Option<String>,
            config: Option<PathBuf>,
            #[serde(default)]
            operators: Vec<String>,
        }
        #[derive(serde::Deserialize)]
        #[serde(
            untagged,
            expecting = "an endpoint (\"tcp/127.0.0.1:7447\") or a table \
                                     { connect = ENDPOINT, config = FILE, operators = [USER] }"
        )]
        enum Either {
            Endpoint(String),
            Table(Table),
        }
        Ok(match Either::deserialize(d)? {
            Either::Endpoint(e) => ZenohSettings {
                connect: Some(e),
                config: None,
                operators: Vec::new(),
            },
            Either::Table(t) => ZenohSettings {
                connect: t.connect,
                config: t.config,
                operators: t.operators,
            },
        })
    }
}

/// Why a node's Zenoh bridge could not start.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ZenohError {
    /// This build has no Zenoh bridge.
    #[error("this penelope was built without the Zenoh bridge: build it with `--features zenoh`")]
    NotBuilt,
    /// The configuration file could not be read, or an endpoint or setting was refused.
    #[error("Zenoh configuration: {0}")]
    Config(String),
    /// The session could not be opened, or a key could not be declared.
    #[error("Zenoh session: {0}")]
    Session(String),
}

/// What a node's bridge did so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BridgeStats {
    /// Controllers whose ticks it publishes.
    pub controllers: u64,
    /// Key expressions it takes operator poses from.
    pub reference_keys: u64,
    /// Controllers' ticks published.
    pub ticks: u64,
    /// Ticks the bridge lost because it fell behind the loops.
    pub ticks_dropped: u64,
    /// Safety events published.
    pub events: u64,
    /// Link statistics published.
    pub link_records: u64,
    /// Feedback samples (bridged channels' ends) published.
    pub feedback: u64,
    /// Operator poses taken, over every bridged channel's key.
    pub poses_taken: u64,
    /// Payloads refused on those keys (malformed).
    pub poses_refused: u64,
    /// Queries of the object tree answered.
    pub queries: u64,
    /// The ROS 2 presence's (zero without one).
    pub ros2: crate::ros2::Ros2Stats,
}

/// A node's Zenoh bridge, in a build without the `zenoh` feature: it never starts.
#[cfg(not(feature = "zenoh"))]
#[derive(Debug)]
pub struct ZenohBridge(());

#[cfg(not(feature = "zenoh"))]
impl ZenohBridge {
    /// Refuses: this build has no Zenoh.
    ///
    /// # Errors
    /// Always [`ZenohError::NotBuilt`].
    pub fn start(
        _node: &str,
        _creator: std::sync::Weak<penelope_runtime::objects::Creator>,
        _settings: &ZenohSettings,
        _ros2: Option<crate::ros2::Ros2Settings>,
    ) -> Result<ZenohBridge, ZenohError> {
        Err(ZenohError::NotBuilt)
    }

    /// What it did (nothing).
    pub fn stats(&self) -> BridgeStats {
        BridgeStats::default()
    }

    /// Stops it (nothing to stop).
    pub fn stop(self) {}
}
