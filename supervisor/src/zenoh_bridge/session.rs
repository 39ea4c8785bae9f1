//! The bridge's Zenoh session and its thread (feature `zenoh`): Zenoh's sync API (`Wait`) from
//! one thread of normal priority, and Zenoh's own runtime threads for the callbacks of the
//! reference subscribers and the object-tree queryable. None of it touches a loop but through
//! the cells of [`BridgedChannels`] and the bounded tick streams of the telemetry pump.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError, Sender};
use std::sync::{Arc, Weak};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use penelope_rt_core::safety::{FaultCause, SafetyState};
use zenoh::Wait;
use zenoh::bytes::Encoding;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::CongestionControl;
use zenoh::query::{Query, Queryable};

use super::encoding::{self, EVENTS, FEEDBACK, LINK, TELEMETRY, objects_key, stream_key};
use super::{BridgeStats, ZenohError, ZenohSettings};
use crate::ros2::Ros2Settings;
use crate::ros2::presence::{self, Ros2Presence};
use penelope_protocol::proto::Class;
use penelope_runtime::objects::Creator;
use penelope_runtime::objects::bridged::BridgedChannels;
use penelope_runtime::objects::link_source::LinkSource;
use penelope_runtime::objects::tick::TickStream;

/// How often the bridge drains the tick streams and publishes.
const DRAIN_EVERY: Duration = Duration::from_millis(5);
/// How often it looks for new controllers, channels and reference keys, and publishes links'
/// statistics.
const DISCOVER_EVERY: Duration = Duration::from_millis(100);
/// Ticks a controller's stream holds for the bridge (four seconds at 1 kHz): beyond, the
/// bridge fell behind and ticks are dropped (counted).
const TICK_STREAM_CAPACITY: usize = 4096;

/// The bridge's counters, shared with the callbacks.
#[derive(Default)]
struct Counters {
    controllers: AtomicU64,
    reference_keys: AtomicU64,
    ticks: AtomicU64,
    events: AtomicU64,
    link_records: AtomicU64,
    feedback: AtomicU64,
    poses_taken: AtomicU64,
    poses_refused: AtomicU64,
    queries: AtomicU64,
}

/// A node's running Zenoh bridge. Stopped (its thread joined, its session closed) by
/// [`stop`](Self::stop) or when dropped.
pub struct ZenohBridge {
    session: zenoh::Session,
    counters: Arc<Counters>,
    /// Ticks lost by the bridge's streams (summed by its thread).
    dropped: Arc<AtomicU64>,
    ros2: Option<Arc<presence::Counters>>,
    stop: Option<(Sender<()>, JoinHandle<()>)>,
    _queryable: Queryable<()>,
}

impl std::fmt::Debug for ZenohBridge {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ZenohBridge")
            .field("zid", &self.session.zid())
            .finish_non_exhaustive()
    }
}

/// The session's configuration: `settings`' file passed through, the endpoint to connect to,
/// and — unless the file says otherwise — no multicast scouting and no listening.
fn config(settings: &ZenohSettings) -> Result<zenoh::Config, ZenohError> {
    let cfg = |e: zenoh::Error| ZenohError::Config(e.to_string());
    let (mut config, text) = match &settings.config {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .map_err(|e| ZenohError::Config(format!("{}: {e}", path.display())))?;
            let config = zenoh::Config::from_json5(&text)
                .map_err(|e| ZenohError::Config(format!("{}: {e}", path.display())))?;
            (config, text)
        }
        None => (zenoh::Config::default(), String::new()),
    };
    if !text.contains("multicast") {
        config
            .insert_json5("scouting/multicast/enabled", "false")
            .map_err(cfg)?;
    }
    if !text.contains("listen") {
        config.insert_json5("listen/endpoints", "[]").map_err(cfg)?;
    }
    if let Some(endpoint) = &settings.connect {
        let list =
            serde_json::to_string(&[endpoint]).map_err(|e| ZenohError::Config(e.to_string()))?;
        config
            .insert_json5("connect/endpoints", &list)
            .map_err(|e| ZenohError::Config(format!("endpoint {endpoint:?}: {e}")))?;
    }
    let json = |key: &str| -> serde_json::Value {
        config
            .get_json(key)
            .ok()
            .and_then(|t| serde_json::from_str(&t).ok())
            .unwrap_or(serde_json::Value::Null)
    };
    let set = |v: serde_json::Value| v.as_str().is_some_and(|s| !s.is_empty());
    let user_password =
        set(json("transport/auth/usrpwd/user")) && set(json("transport/auth/usrpwd/password"));
    let dictionary = set(json("transport/auth/usrpwd/dictionary_file"));
    let mut wide = Vec::new();
    for (key, needs_dictionary) in [("connect/endpoints", false), ("listen/endpoints", true)] {
        let mut endpoints = Vec::new();
        strings(&json(key), &mut endpoints);
        for e in endpoints.into_iter().filter(|e| !loopback_endpoint(e)) {
            wide.push((e, needs_dictionary));
        }
    }
    if json("scouting/multicast/enabled") == serde_json::Value::Bool(true) {
        wide.push(("multicast scouting".into(), true));
    }
    for (what, needs_dictionary) in &wide {
        if !user_password || (*needs_dictionary && !dictionary) {
            return Err(ZenohError::Config(format!(
                "{what} is off loopback: Zenoh there needs authentication (whoever publishes \
                 on a channel's reference key drives its slave). Set transport.auth.usrpwd's \
                 `user` and `password`{} in the Zenoh configuration file (docs/zenoh.md)",
                if *needs_dictionary {
                    " and its `dictionary_file` (the users this node accepts)"
                } else {
                    ""
                }
            )));
        }
    }
    if !settings.operators.is_empty() {
        if !user_password || !dictionary {
            return Err(ZenohError::Config(
                "`operators` are Zenoh users: the configuration file needs \
                 transport.auth.usrpwd (`user`, `password`, `dictionary_file`)"
                    .into(),
            ));
        }
        if text.contains("access_control") {
            return Err(ZenohError::Config(
                "`operators` and the configuration file's own `access_control`: one of them".into(),
            ));
        }
        config
            .insert_json5("access_control", &access_control(&settings.operators))
            .map_err(cfg)?;
    }
    Ok(config)
}

/// Every string in `v` (an endpoint list, or a list per mode).
fn strings(v: &serde_json::Value, out: &mut Vec<String>) {
    match v {
        serde_json::Value::String(s) => out.push(s.clone()),
        serde_json::Value::Array(a) => a.iter().for_each(|v| strings(v, out)),
        serde_json::Value::Object(m) => m.values().for_each(|v| strings(v, out)),
        _ => {}
    }
}

/// True for an endpoint only this host can reach: TCP or UDP to 127.0.0.0/8, `::1` or
/// `localhost`, or a Unix socket.
pub(super) fn loopback_endpoint(endpoint: &str) -> bool {
    let endpoint = endpoint.split(['#', '?']).next().unwrap_or("");
    let Some((proto, address)) = endpoint.split_once('/') else {
        return false;
    };
    if proto.starts_with("unixsock") || proto == "unixpipe" {
        return true;
    }
    let host = match address.rsplit_once(':') {
        Some((host, _port)) => host.trim_start_matches('[').trim_end_matches(']'),
        None => address,
    };
    host.eq_ignore_ascii_case("localhost")
        || host
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback())
}

/// The access control of a bridge with `operators`: every participant may subscribe, query,
/// reply and receive what the node publishes; only the operators' transports may put or
/// delete (operator poses). Default deny, so a message kind not listed is refused.
fn access_control(operators: &[String]) -> String {
    serde_json::json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": [
            {
                "id": "penelope-anyone",
                "permission": "allow",
                "flows": ["ingress", "egress"],
                "messages": [
                    "declare_subscriber", "query", "declare_queryable", "reply",
                    "liveliness_token", "declare_liveliness_subscriber", "liveliness_query"
                ],
                "key_exprs": ["**"]
            },
            {
                "id": "penelope-published",
                "permission": "allow",
                "flows": ["egress"],
                "messages": ["put", "delete"],
                "key_exprs": ["**"]
            },
            {
                "id": "penelope-operator-poses",
                "permission": "allow",
                "flows": ["ingress"],
                "messages": ["put", "delete"],
                "key_exprs": ["**"]
            }
        ],
        "subjects": [
            { "id": "penelope-anyone" },
            { "id": "penelope-operators", "usernames": operators }
        ],
        "policies": [
            { "rules": ["penelope-anyone", "penelope-published"], "subjects": ["penelope-anyone"] },
            { "rules": ["penelope-operator-poses"], "subjects": ["penelope-operators"] }
        ]
    })
    .to_string()
}

impl ZenohBridge {
    /// Opens a Zenoh session as `settings` say and starts bridging node `node`'s `creator`:
    /// the object tree's queryable at once, then its controllers, channels and reference keys
    /// as they appear; with `ros2`, the node's ROS 2 presence too ([`crate::ros2`]).
    ///
    /// # Errors
    /// [`ZenohError`]: a configuration file that does not read or parse, a refused endpoint,
    /// a session that does not open.
    pub fn start(
        node: &str,
        creator: Weak<Creator>,
        settings: &ZenohSettings,
        ros2: Option<Ros2Settings>,
    ) -> Result<ZenohBridge, ZenohError> {
        let session = zenoh::open(config(settings)?)
            .wait()
            .map_err(|e| ZenohError::Session(e.to_string()))?;
        let counters = Arc::new(Counters::default());
        let queryable = declare_objects(&session, node, creator.clone(), counters.clone())?;
        let ros2 = match (ros2, creator.upgrade()) {
            (Some(ros2), Some(c)) => Some(
                Ros2Presence::start(&session, node, ros2, c.node_time().now_ns())
                    .map_err(|e| ZenohError::Session(e.to_string()))?,
            ),
            _ => None,
        };
        let dropped = Arc::new(AtomicU64::new(0));
        let (stop, stopped) = mpsc::channel::<()>();
        let mut worker = Worker {
            node: node.to_string(),
            session: session.clone(),
            creator,
            counters: counters.clone(),
            dropped: dropped.clone(),
            controllers: BTreeMap::new(),
            links: BTreeMap::new(),
            feedback: BTreeMap::new(),
            subscribers: BTreeMap::new(),
            channels: None,
            ros2,
        };
        let ros2 = worker.ros2.as_ref().map(Ros2Presence::counters);
        let thread = std::thread::Builder::new()
            .name(format!("zenoh-{node}"))
            .spawn(move || worker.run(&stopped))
            .map_err(|e| ZenohError::Session(format!("cannot spawn the bridge thread: {e}")))?;
        Ok(ZenohBridge {
            session,
            counters,
            dropped,
            ros2,
            stop: Some((stop, thread)),
            _queryable: queryable,
        })
    }

    /// What it did so far.
    pub fn stats(&self) -> BridgeStats {
        let c = &self.counters;
        let n = |a: &AtomicU64| a.load(Ordering::Relaxed);
        BridgeStats {
            controllers: n(&c.controllers),
            reference_keys: n(&c.reference_keys),
            ticks: n(&c.ticks),
            ticks_dropped: n(&self.dropped),
            events: n(&c.events),
            link_records: n(&c.link_records),
            feedback: n(&c.feedback),
            poses_taken: n(&c.poses_taken),
            poses_refused: n(&c.poses_refused),
            queries: n(&c.queries),
            ros2: self.ros2.as_ref().map(|c| c.stats()).unwrap_or_default(),
        }
    }

    /// Stops the thread (it publishes what its streams hold first) and closes the session.
    pub fn stop(mut self) {
        self.halt();
    }

    fn halt(&mut self) {
        if let Some((stop, thread)) = self.stop.take() {
            let _ = stop.send(());
            let _ = thread.join();
            if let Err(e) = self.session.close().wait() {
                log::warn!("zenoh: closing the session: {e}");
            }
        }
    }
}

impl Drop for ZenohBridge {
    fn drop(&mut self) {
        self.halt();
    }
}

/// Declares the queryable of `node`'s object tree: `penelope/<node>/objects` answers every
/// object, `penelope/<node>/objects/<name>` one, as JSON (`proto::ObjectInfo`'s serde form).
fn declare_objects(
    session: &zenoh::Session,
    node: &str,
    creator: Weak<Creator>,
    counters: Arc<Counters>,
) -> Result<Queryable<()>, ZenohError> {
    let tree = objects_key(node);
    let prefix = format!("{tree}/");
    let everything = format!("{tree}/**");
    session
        .declare_queryable(everything.clone())
        .callback(move |query: Query| {
            let Some(creator) = creator.upgrade() else {
                return;
            };
            let asked = query.key_expr().as_str();
            // One object when the query names one plainly; the whole tree otherwise.
            let one = asked
                .strip_prefix(&prefix)
                .filter(|name| penelope_protocol::proto::check_name(name).is_ok());
            let (key, body) = match one {
                Some(name) => match creator.info(name) {
                    Some(info) => (asked.to_string(), serde_json::to_vec(&info)),
                    None => return,
                },
                None => (tree.clone(), serde_json::to_vec(&creator.list())),
            };
            let Ok(body) = body else { return };
            match query
                .reply(key, body)
                .encoding(Encoding::APPLICATION_JSON)
                .wait()
            {
                Ok(()) => {
                    counters.queries.fetch_add(1, Ordering::Relaxed);
                }
                Err(e) => log::debug!("zenoh: a reply to {asked} failed: {e}"),
            }
        })
        .wait()
        .map_err(|e| ZenohError::Session(format!("queryable {everything}: {e}")))
}

/// A controller the bridge publishes.
struct ControllerStreams {
    ticks: TickStream,
    telemetry: Publisher<'static>,
    events: Publisher<'static>,
    /// The state and fault of the last tick published.
    last: Option<(SafetyState, Option<FaultCause>)>,
}

/// The bridge's thread: what it publishes and where.
struct Worker {
    node: String,
    session: zenoh::Session,
    creator: Weak<Creator>,
    counters: Arc<Counters>,
    dropped: Arc<AtomicU64>,
    controllers: BTreeMap<String, ControllerStreams>,
    links: BTreeMap<String, (LinkSource, Publisher<'static>)>,
    feedback: BTreeMap<String, Publisher<'static>>,
    /// A subscriber per reference key (several channels may share one).
    subscribers: BTreeMap<String, Subscriber<()>>,
    channels: Option<BridgedChannels>,
    ros2: Option<Ros2Presence>,
}

impl Worker {
    fn publisher(&self, object: &str, stream: &str) -> Option<Publisher<'static>> {
        let key = stream_key(&self.node, object, stream);
        // Blocking when the transport is congested slows this thread only: the loops' ticks
        // then wait in its bounded streams (and past their capacity are dropped, counted).
        self.session
            .declare_publisher(key.clone())
            .encoding(Encoding::APPLICATION_JSON)
            .congestion_control(CongestionControl::Block)
            .wait()
            .map_err(|e| log::warn!("zenoh: cannot declare {key}: {e}"))
            .ok()
    }

    fn run(&mut self, stop: &mpsc::Receiver<()>) {
        let mut discovered: Option<Instant> = None;
        loop {
            let stopping = match stop.recv_timeout(DRAIN_EVERY) {
                Err(RecvTimeoutError::Timeout) => false,
                Ok(()) | Err(RecvTimeoutError::Disconnected) => true,
            };
            let Some(creator) = self.creator.upgrade() else {
                return;
            };
            if discovered.is_none_or(|t| t.elapsed() >= DISCOVER_EVERY) {
                discovered = Some(Instant::now());
                self.discover(&creator);
                self.publish_links();
            }
            drop(creator);
            self.publish_ticks();
            self.publish_feedback();
            if let Some(ros2) = &mut self.ros2 {
                ros2.frames();
            }
            if stopping {
                return;
            }
        }
    }

    /// Starts publishing new controllers and linked channels, and subscribes to new reference
    /// keys.
    fn discover(&mut self, creator: &Arc<Creator>) {
        if let Some(ros2) = &mut self.ros2 {
            ros2.retry_pending(creator);
            ros2.add_cameras(creator);
        }
        for info in creator.list() {
            if info.class == Class::Controller && !self.controllers.contains_key(&info.name) {
                let Ok(ticks) = creator.record_ticks(&info.name, TICK_STREAM_CAPACITY) else {
                    continue;
                };
                let (Some(telemetry), Some(events)) = (
                    self.publisher(&info.name, TELEMETRY),
                    self.publisher(&info.name, EVENTS),
                ) else {
                    continue;
                };
                if let Some(ros2) = &mut self.ros2 {
                    ros2.add_controller(creator, &info.name);
                }
                self.controllers.insert(
                    info.name,
                    ControllerStreams {
                        ticks,
                        telemetry,
                        events,
                        last: None,
                    },
                );
                self.counters
                    .controllers
                    .store(self.controllers.len() as u64, Ordering::Relaxed);
            } else if info.kind == penelope_runtime::objects::kinds::Kind::TELEOP.as_str() {
                let source = creator.link_source(&info.name).ok().flatten();
                let stale = match (self.links.get(&info.name), &source) {
                    (Some((old, _)), Some(new)) => !old.same_link(new),
                    (None, Some(_)) => true,
                    _ => false,
                };
                if stale
                    && let Some(source) = source
                    && let Some(publisher) = self.publisher(&info.name, LINK)
                {
                    self.links.insert(info.name, (source, publisher));
                }
            }
        }
        let channels = self
            .channels
            .get_or_insert_with(|| creator.bridged_channels())
            .clone();
        for (channel, key) in channels.keys() {
            if !self.feedback.contains_key(&channel)
                && let Some(publisher) = self.publisher(&channel, FEEDBACK)
            {
                self.feedback.insert(channel, publisher);
            }
            if self.subscribers.contains_key(&key) {
                continue;
            }
            let (feed, counters, on) = (channels.clone(), self.counters.clone(), key.clone());
            let declared = self
                .session
                .declare_subscriber(key.clone())
                .callback(move |sample| {
                    let counter = match feed.offer(&on, &sample.payload().to_bytes()) {
                        Ok(()) => &counters.poses_taken,
                        Err(_) => &counters.poses_refused,
                    };
                    counter.fetch_add(1, Ordering::Relaxed);
                })
                .wait();
            match declared {
                Ok(subscriber) => {
                    self.subscribers.insert(key, subscriber);
                    self.counters
                        .reference_keys
                        .store(self.subscribers.len() as u64, Ordering::Relaxed);
                }
                Err(e) => log::warn!("zenoh: cannot subscribe to {key}: {e}"),
            }
        }
    }

    fn publish_ticks(&mut self) {
        let mut dropped = 0;
        for (name, c) in &mut self.controllers {
            while let Ok(record) = c.ticks.ticks.try_recv() {
                if let Some(event) = encoding::event_message(name, &record, c.last)
                    && c.events.put(event).wait().is_ok()
                {
                    self.counters.events.fetch_add(1, Ordering::Relaxed);
                }
                c.last = Some((record.sample.state, record.sample.fault));
                if let Some(ros2) = &mut self.ros2 {
                    ros2.tick(name, &record);
                }
                if let Ok(body) = encoding::tick_message(&record)
                    && c.telemetry.put(body).wait().is_ok()
                {
                    self.counters.ticks.fetch_add(1, Ordering::Relaxed);
                }
            }
            dropped += c.ticks.dropped.load(Ordering::Relaxed);
        }
        self.dropped.store(dropped, Ordering::Relaxed);
    }

    fn publish_links(&mut self) {
        let now = penelope_rt_core::clock::MonotonicClock::read().as_nanos();
        for (channel, (source, publisher)) in &self.links {
            let Some(stats) = source.latest() else {
                continue;
            };
            let record = stats.record(now);
            if let Some(ros2) = &mut self.ros2 {
                ros2.link(channel, &record);
            }
            if let Ok(body) = serde_json::to_vec(&record)
                && publisher.put(body).wait().is_ok()
            {
                self.counters.link_records.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    fn publish_feedback(&mut self) {
        let Some(channels) = &self.channels else {
            return;
        };
        for (channel, sample) in channels.feedback() {
            if let Some(ros2) = &mut self.ros2 {
                ros2.feedback(channels, &channel, &sample);
            }
            if let Some(publisher) = self.feedback.get(&channel)
                && publisher
                    .put(encoding::feedback_message(&sample))
                    .wait()
                    .is_ok()
            {
                self.counters.feedback.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}
