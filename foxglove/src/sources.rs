//! The nodes' streams: which objects there are (the nodes' creators, asked every
//! [`DISCOVERY_PERIOD`]), and one reader thread per stream, subscribed through the protocol as
//! `penelope ctl watch` is: the node's telemetry thread copies from its rings and decimates, so
//! no real-time thread ever sees the gateway.
//!
//! - every controller: its ticks on `/controllers/<name>`, at most `rate` per second (the node
//!   decimates to about that, measured from the loop's own period; the reader thins the rest);
//! - every `trajectory/teleop` channel linked to another node: its link's statistics on
//!   `/links/<channel>` (every 100 ms, as the node pushes them);
//! - every camera (a sensor whose kind is a camera): its frames, calibration, the force drawn on
//!   them and the force sample of each frame's capture instant ([`crate::cameras`]).
//!
//! A reader hands each message to the [`Hub`], which never waits; a node whose subscription the
//! gateway reads too slowly drops batches itself (counted, reported on `/penelope/gateway`).

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use penelope_protocol::client::clock::{CommonClockView, REFRESH};
use penelope_protocol::client::{Client, NodeProxy};
use penelope_protocol::net::conn::RpcError;
use penelope_protocol::proto::{Class, ObjectInfo, object_path};

use crate::cameras::{self, RobotSamples};
use crate::clock::{NodeClock, local_ns};
use crate::hub::Hub;
use crate::robots::RobotView;
use crate::topics::{self, StreamStats};

/// How often the nodes are asked for their objects.
pub const DISCOVERY_PERIOD: Duration = Duration::from_secs(2);
/// How long a reader waits before it subscribes again after a refusal (a controller that is
/// not running) or a broken stream.
const RETRY: Duration = Duration::from_secs(2);
/// How long one wait for a record lasts (a stop is seen within it).
const POLL: Duration = Duration::from_millis(200);
/// How often a reader estimates its node's clock again.
const CLOCK_REFRESH: Duration = Duration::from_secs(30);

/// What every reader shares.
pub struct Shared {
    /// The system.
    pub client: Client,
    /// Where messages go.
    pub hub: Arc<Hub>,
    /// Messages per second per controller at most.
    pub rate_hz: f64,
    /// The newest message time published, ns on the common clock (the server's time).
    pub latest_ns: AtomicU64,
    /// The `/tf` and `/scene` channels.
    pub scene_channels: (u32, u32),
    /// The robots described so far, by `node/robot`.
    pub robots: Mutex<HashMap<String, Arc<RobotView>>>,
}

/// One stream and its reader.
struct Stream {
    channel: u32,
    /// A camera's other channels (calibration, annotations, force).
    more_channels: Vec<u32>,
    /// The robot its controller drives, by `node/robot`, when it started.
    robot: Option<String>,
    stop: Arc<AtomicBool>,
    stats: Arc<Mutex<StreamStats>>,
    reader: Option<JoinHandle<()>>,
}

impl Stream {
    fn remove_channels(&self, hub: &Hub) {
        hub.remove_channel(self.channel);
        for c in &self.more_channels {
            hub.remove_channel(*c);
        }
    }
}

/// Whether an object is a camera (`sensor/sim-camera`, `sensor/camera`).
fn is_camera(info: &ObjectInfo) -> bool {
    info.class == Class::Sensor && info.kind.contains("camera")
}

impl Drop for Stream {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(r) = self.reader.take() {
            let _ = r.join();
        }
    }
}

/// The streams followed now, by `node/object`.
pub struct Sources {
    shared: Arc<Shared>,
    streams: HashMap<String, Stream>,
    /// Each robot's place in the world, by `node/robot`, in the order they were found.
    places: HashMap<String, usize>,
}

/// What a discovery found of one stream.
struct Found {
    node: String,
    address: SocketAddr,
    hosts_naming: bool,
    info: ObjectInfo,
}

impl Sources {
    /// No streams yet.
    pub fn new(shared: Arc<Shared>) -> Self {
        Sources {
            shared,
            streams: HashMap::new(),
            places: HashMap::new(),
        }
    }

    /// Every stream's counters.
    pub fn stats(&self) -> Vec<StreamStats> {
        let mut all: Vec<StreamStats> = self
            .streams
            .values()
            .map(|s| lock(&s.stats).clone())
            .collect();
        all.sort_by(|a, b| a.topic.cmp(&b.topic));
        all
    }

    /// Asks every node for its objects; starts readers for new streams and ends those of
    /// objects gone.
    ///
    /// # Errors
    /// The naming service could not be asked (the streams are kept as they are).
    pub fn discover(&mut self) -> Result<(), RpcError> {
        let nodes = self.shared.client.nodes()?;
        let mut found: Vec<(String, Found)> = Vec::new();
        let mut robots_found: Vec<String> = Vec::new();
        for node in &nodes {
            // A node that does not answer now keeps its streams (their readers retry).
            let Ok(objects) = node.list() else {
                self.keep_node(node, &mut found);
                let prefix = format!("{}/", node.name());
                robots_found.extend(
                    lock(&self.shared.robots)
                        .keys()
                        .filter(|k| k.starts_with(&prefix))
                        .cloned(),
                );
                continue;
            };
            let hosts_naming = node.info().map(|i| i.hosts_naming).unwrap_or(false);
            for info in objects.iter().filter(|o| o.class == Class::Robot) {
                let key = format!("{}/{}", node.name(), info.name);
                robots_found.push(key.clone());
                self.describe_robot(node, info, key);
            }
            for info in objects {
                let streamed = info.class == Class::Controller
                    || info.kind == "trajectory/teleop"
                    || is_camera(&info);
                if streamed {
                    found.push((
                        format!("{}/{}", node.name(), info.name),
                        Found {
                            node: node.name().to_string(),
                            address: node.address(),
                            hosts_naming,
                            info,
                        },
                    ));
                }
            }
        }
        // Robots gone: their descriptions with them.
        let gone: Vec<(String, u32)> = lock(&self.shared.robots)
            .iter()
            .filter(|(k, _)| !robots_found.contains(k))
            .map(|(k, r)| (k.clone(), r.description))
            .collect();
        for (key, channel) in gone {
            lock(&self.shared.robots).remove(&key);
            self.shared.hub.remove_channel(channel);
        }
        let keys: Vec<&String> = found.iter().map(|(k, _)| k).collect();
        let gone: Vec<String> = self
            .streams
            .keys()
            .filter(|k| !keys.contains(k))
            .cloned()
            .collect();
        for key in gone {
            if let Some(s) = self.streams.remove(&key) {
                s.remove_channels(&self.shared.hub);
            }
        }
        for (key, f) in found {
            if f.info.name.is_empty() {
                continue;
            }
            // A controller bound to another robot since its reader started: started again.
            match self.streams.get(&key) {
                Some(s) if s.robot == robot_of(&f) => continue,
                Some(_) => {
                    if let Some(s) = self.streams.remove(&key) {
                        s.remove_channels(&self.shared.hub);
                    }
                }
                None => {}
            }
            let stream = self.start(&f);
            self.streams.insert(key, stream);
        }
        Ok(())
    }

    /// Describes the robot `info` of `node` (known by `key`) unless it is already: its place
    /// is fixed the first time it is seen, its description asked until the node gives it.
    fn describe_robot(&mut self, node: &NodeProxy, info: &ObjectInfo, key: String) {
        if lock(&self.shared.robots).contains_key(&key) {
            return;
        }
        let next = self.places.len();
        let index = *self.places.entry(key.clone()).or_insert(next);
        let proxy = match self.shared.client.robot(&node.path_of(info)) {
            Ok(p) => p,
            Err(_) => return,
        };
        // Frame ids and topics are by robot name; the second of a name says its node.
        let taken = lock(&self.shared.robots)
            .values()
            .any(|r| r.name == info.name);
        let name = if taken {
            format!("{}@{}", info.name, node.name())
        } else {
            info.name.clone()
        };
        let view = RobotView::describe(
            &name,
            proxy,
            penelope_scene::default_placement(index),
            self.shared.hub.clone(),
            self.shared.scene_channels,
            self.shared.latest_ns.load(Ordering::Acquire),
        );
        // A robot not configured yet has no model to describe: asked again next time.
        if let Ok(view) = view {
            lock(&self.shared.robots).insert(key, Arc::new(view));
        }
    }

    /// Keeps the streams of a node that did not answer (marked as found).
    fn keep_node(&self, node: &NodeProxy, found: &mut Vec<(String, Found)>) {
        let prefix = format!("{}/", node.name());
        for key in self.streams.keys().filter(|k| k.starts_with(&prefix)) {
            found.push((
                key.clone(),
                Found {
                    node: node.name().to_string(),
                    address: node.address(),
                    hosts_naming: false,
                    info: ObjectInfo {
                        name: String::new(),
                        kind: String::new(),
                        class: Class::Creator,
                        state: penelope_hal::LifecycleState::Unconfigured,
                        relations: Vec::new(),
                    },
                },
            ));
        }
    }

    fn start(&self, f: &Found) -> Stream {
        if is_camera(&f.info) {
            return self.start_camera(f);
        }
        let is_link = f.info.class == Class::Trajectory;
        let prefix = if is_link {
            topics::LINK_TOPIC
        } else {
            topics::CONTROLLER_TOPIC
        };
        // Names are unique on a node; across nodes the second of a name says its node.
        let mut topic = format!("{prefix}{}", f.info.name);
        if self.shared.hub.topics().iter().any(|(_, t, _)| *t == topic) {
            topic = format!("{topic}@{}", f.node);
        }
        let (schema_name, schema) = if is_link {
            ("penelope.LinkStats", topics::LINK_SCHEMA)
        } else {
            ("penelope.Tick", topics::TICK_SCHEMA)
        };
        let channel = self.shared.hub.add_channel(&topic, schema_name, schema);
        let stop = Arc::new(AtomicBool::new(false));
        let stats = Arc::new(Mutex::new(StreamStats {
            topic: topic.clone(),
            clock: "unknown",
            ..StreamStats::default()
        }));
        let robot = robot_of(f);
        let reader_robot = robot.clone();
        let reader = Reader {
            shared: self.shared.clone(),
            robot,
            path: object_path(&f.node, f.info.class, &f.info.name),
            address: f.address,
            hosts_naming: f.hosts_naming,
            channel,
            stop: stop.clone(),
            stats: stats.clone(),
        };
        let name = format!("fox-{}", f.info.name);
        let handle = std::thread::Builder::new()
            .name(name.chars().take(15).collect())
            .spawn(move || {
                if is_link {
                    reader.follow_link();
                } else {
                    reader.follow_ticks();
                }
            })
            .ok();
        Stream {
            channel,
            more_channels: Vec::new(),
            robot: reader_robot,
            stop,
            stats,
            reader: handle,
        }
    }

    /// A camera's four channels and the reader that fills them.
    fn start_camera(&self, f: &Found) -> Stream {
        // Names are unique on a node; across nodes the second of a name says its node.
        let mut name = f.info.name.clone();
        let image_topic = format!("/{name}/image");
        if self
            .shared
            .hub
            .topics()
            .iter()
            .any(|(_, t, _)| *t == image_topic)
        {
            name = format!("{name}@{}", f.node);
        }
        let channels: Vec<u32> = cameras::topics(&name)
            .iter()
            .map(|(topic, schema_name, schema)| {
                self.shared.hub.add_channel(topic, schema_name, schema)
            })
            .collect();
        let stop = Arc::new(AtomicBool::new(false));
        let stats = Arc::new(Mutex::new(StreamStats {
            topic: format!("/{name}/image"),
            clock: "common",
            ..StreamStats::default()
        }));
        let reader = Reader {
            shared: self.shared.clone(),
            robot: None,
            path: object_path(&f.node, f.info.class, &f.info.name),
            address: f.address,
            hosts_naming: f.hosts_naming,
            channel: channels[0],
            stop: stop.clone(),
            stats: stats.clone(),
        };
        let node = f.node.clone();
        let more = channels[1..].to_vec();
        let theirs = more.clone();
        let handle = std::thread::Builder::new()
            .name(format!("fox-{}", f.info.name).chars().take(15).collect())
            .spawn(move || reader.follow_camera(&node, &theirs))
            .ok();
        Stream {
            channel: channels[0],
            more_channels: more,
            // As discovery compares it (a camera's relations may name a robot).
            robot: robot_of(f),
            stop,
            stats,
            reader: handle,
        }
    }
}

/// The robot a found controller drives, by `node/robot`.
fn robot_of(f: &Found) -> Option<String> {
    f.info
        .relations
        .iter()
        .find(|(relation, _)| relation == "robot")
        .map(|(_, robot)| format!("{}/{robot}", f.node))
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The decimation that brings a loop of period `period_ns` down to about `rate_hz` (at least 1).
pub fn decimation_for(period_ns: f64, rate_hz: f64) -> u32 {
    if !(period_ns > 0.0 && rate_hz > 0.0) {
        return 1;
    }
    let d = (1e9 / rate_hz / period_ns).floor();
    d.clamp(1.0, 100_000.0) as u32
}

/// Lets through one message per `interval_ns` of message time on average: a message is due
/// from a tenth of an interval before its slot (so a node decimating to exactly the rate is not
/// halved by jitter), and slots keep their spacing (so the early ones do not raise the rate).
#[derive(Debug)]
pub struct Thinning {
    interval_ns: u64,
    next_ns: Option<u64>,
}

impl Thinning {
    /// About `rate_hz` messages per second.
    pub fn new(rate_hz: f64) -> Self {
        Thinning {
            interval_ns: (1e9 / rate_hz) as u64,
            next_ns: None,
        }
    }

    /// Whether a message at `time_ns` goes out.
    pub fn admit(&mut self, time_ns: u64) -> bool {
        let slack = self.interval_ns / 10;
        match self.next_ns {
            // A clock that went back (a restarted loop) starts again.
            Some(next) if time_ns + slack < next && next - time_ns <= self.interval_ns => false,
            Some(next)
                if time_ns < next.saturating_add(self.interval_ns) && time_ns + slack >= next =>
            {
                self.next_ns = Some(next + self.interval_ns);
                true
            }
            _ => {
                self.next_ns = Some(time_ns + self.interval_ns);
                true
            }
        }
    }
}

struct Reader {
    shared: Arc<Shared>,
    /// The robot the controller drives, by `node/robot`.
    robot: Option<String>,
    path: String,
    address: SocketAddr,
    hosts_naming: bool,
    channel: u32,
    stop: Arc<AtomicBool>,
    stats: Arc<Mutex<StreamStats>>,
}

impl Reader {
    fn stopped(&self) -> bool {
        self.stop.load(Ordering::Acquire)
    }

    /// Waits `RETRY` (or until stopped), noting `error`.
    fn pause(&self, error: String) {
        lock(&self.stats).error = Some(error);
        let until = Instant::now() + RETRY;
        while !self.stopped() && Instant::now() < until {
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    fn clock(&self) -> Result<NodeClock, RpcError> {
        NodeClock::estimate(&self.shared.client, self.address, self.hosts_naming)
    }

    fn published(&self, common_ns: u64) {
        self.shared.latest_ns.fetch_max(common_ns, Ordering::AcqRel);
        lock(&self.stats).published += 1;
    }

    fn follow_ticks(&self) {
        let mut decimation = 1;
        while !self.stopped() {
            // Subscribed first: a controller that is not running is refused before the
            // clock's exchanges are spent on it.
            let mut stream = match self.shared.client.subscribe(&self.path, decimation) {
                Ok(s) => s,
                Err(e) => {
                    self.pause(e.to_string());
                    continue;
                }
            };
            let mut clock = match self.clock() {
                Ok(c) => c,
                Err(e) => {
                    self.pause(format!("the node's clock: {e}"));
                    continue;
                }
            };
            {
                let mut s = lock(&self.stats);
                s.error = None;
                s.decimation = decimation;
            }
            let mut thinning = Thinning::new(self.shared.rate_hz);
            let mut first: Option<(u64, u64)> = None;
            let mut clock_at = Instant::now();
            let mut seen = false;
            loop {
                if self.stopped() {
                    break;
                }
                let record = match stream.recv_timeout(POLL) {
                    Ok(Some(r)) => r,
                    Ok(None) => continue,
                    Err(e) => {
                        self.pause(e.to_string());
                        break;
                    }
                };
                if !seen {
                    seen = true;
                    clock = clock.seen_tick(record.time_ns, local_ns());
                    lock(&self.stats).clock = match clock {
                        NodeClock::Common => "common",
                        NodeClock::Offset { .. } => "offset",
                        NodeClock::Simulated => "simulated",
                    };
                }
                // The loop's period from the first two ticks: the node then decimates.
                match first {
                    None => first = Some((record.seq, record.time_ns)),
                    Some((seq0, t0)) if decimation == 1 && record.seq > seq0 => {
                        let period =
                            record.time_ns.saturating_sub(t0) as f64 / (record.seq - seq0) as f64;
                        let wanted = decimation_for(period, self.shared.rate_hz);
                        if wanted > 1 {
                            decimation = wanted;
                            break;
                        }
                        first = Some((record.seq, record.time_ns));
                    }
                    Some(_) => {}
                }
                lock(&self.stats).node_dropped = stream.dropped();
                if !thinning.admit(record.time_ns) {
                    continue;
                }
                if clock_at.elapsed() > CLOCK_REFRESH
                    && let Ok(c) = self.clock()
                {
                    clock_at = Instant::now();
                    if clock != NodeClock::Simulated {
                        clock = c;
                    }
                }
                let common = clock.to_common(record.time_ns);
                if self.shared.hub.has_subscribers(self.channel) {
                    let payload = topics::tick(&record).to_string();
                    self.shared
                        .hub
                        .publish(self.channel, common, payload.as_bytes());
                }
                let robot = self
                    .robot
                    .as_ref()
                    .and_then(|key| lock(&self.shared.robots).get(key).cloned());
                if let Some(robot) = robot
                    && let Err(e) = robot.draw(&record, common)
                {
                    lock(&self.stats).error = Some(format!("robot {}: {e}", robot.name));
                }
                self.published(common);
            }
            // Ended, or to subscribe again at the decimation measured.
            drop(stream);
        }
    }

    /// A camera's frames, each published with its calibration, its annotations and the force
    /// sample of its capture instant (`more`: the calibration, annotations and force
    /// channels).
    fn follow_camera(&self, node: &str, more: &[u32]) {
        let &[calibration_channel, annotations_channel, force_channel] = more else {
            return;
        };
        while !self.stopped() {
            let mut frames = match self.shared.client.watch_camera(&self.path, 1) {
                Ok(s) => s,
                Err(e) => {
                    // A camera not running is refused: asked again later.
                    self.pause(e.to_string());
                    continue;
                }
            };
            // The display instant on the common clock, though the gateway may run on another
            // host than the naming service's.
            let clock = match CommonClockView::follow(&self.shared.client, REFRESH) {
                Ok(c) => c,
                Err(e) => {
                    self.pause(format!("the common clock: {e}"));
                    continue;
                }
            };
            lock(&self.stats).error = None;
            let mut samples: Option<(String, RobotSamples)> = None;
            let mut tool = None;
            while !self.stopped() {
                let frame = match frames.recv_timeout(POLL) {
                    Ok(Some(f)) => f,
                    Ok(None) => continue,
                    Err(e) => {
                        self.pause(e.to_string());
                        break;
                    }
                };
                lock(&self.stats).node_dropped = frames.dropped();
                if samples.is_none()
                    && let Some(robot) = &frame.model.robot
                {
                    let path = object_path(node, Class::Robot, robot);
                    let follower = RobotSamples::follow(self.shared.client.clone(), path);
                    samples = Some((robot.clone(), follower));
                }
                let (aligned, newest) = samples
                    .as_ref()
                    .map_or((None, None), |(_, s)| s.for_frame(frame.capture_ns));
                let robot_path = frame
                    .model
                    .robot
                    .as_ref()
                    .map(|r| object_path(node, Class::Robot, r));
                let (aligned, newest) = cameras::in_base(
                    &self.shared.client,
                    robot_path.as_deref(),
                    &mut tool,
                    aligned,
                    newest,
                );
                let figures =
                    cameras::figures(clock.now_ns(), &frame, aligned.as_ref(), newest.as_ref());
                let at = frame.capture_ns;
                let hub = &self.shared.hub;
                if let Ok(text) = serde_json::to_vec(&cameras::calibration(&frame.model, at)) {
                    hub.publish(calibration_channel, at, &text);
                }
                let text = cameras::annotations(&frame, aligned.as_ref(), &figures).to_string();
                hub.publish(annotations_channel, at, text.as_bytes());
                if let (Some(a), Some((robot, _))) = (&aligned, &samples) {
                    let text = cameras::aligned_force(&frame, robot, a, &figures).to_string();
                    hub.publish(force_channel, at, text.as_bytes());
                }
                if hub.has_subscribers(self.channel)
                    && let Ok(text) = serde_json::to_vec(&cameras::image(&frame))
                {
                    hub.publish(self.channel, at, &text);
                }
                self.published(at);
            }
        }
    }

    fn follow_link(&self) {
        while !self.stopped() {
            let mut stream = match self.shared.client.watch_link(&self.path, 1) {
                Ok(s) => s,
                Err(e) => {
                    // A channel with no link to another node is refused: asked again later.
                    self.pause(e.to_string());
                    continue;
                }
            };
            let mut clock = match self.clock() {
                Ok(c) => c,
                Err(e) => {
                    self.pause(format!("the node's clock: {e}"));
                    continue;
                }
            };
            lock(&self.stats).error = None;
            let mut seen = false;
            while !self.stopped() {
                let record = match stream.recv_timeout(POLL) {
                    Ok(Some(r)) => r,
                    Ok(None) => continue,
                    Err(e) => {
                        self.pause(e.to_string());
                        break;
                    }
                };
                if !seen {
                    seen = true;
                    clock = clock.seen_tick(record.time_ns, local_ns());
                }
                lock(&self.stats).node_dropped = stream.dropped();
                let common = clock.to_common(record.time_ns);
                let payload = topics::link(&record).to_string();
                self.shared
                    .hub
                    .publish(self.channel, common, payload.as_bytes());
                self.published(common);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_node_decimates_a_loop_to_about_the_rate() {
        assert_eq!(decimation_for(1e6, 100.0), 10);
        assert_eq!(decimation_for(2e6, 100.0), 5);
        assert_eq!(decimation_for(3e6, 100.0), 3);
        assert_eq!(decimation_for(20e6, 100.0), 1);
        assert_eq!(decimation_for(0.0, 100.0), 1);
        assert_eq!(decimation_for(1e6, 0.0), 1);
    }

    #[test]
    fn thinning_passes_one_message_per_interval_with_jitter_allowed() {
        let ms = 1_000_000u64;
        // A 1 kHz loop for a second: 100 messages.
        let mut t = Thinning::new(100.0);
        let passed = (0..1000u64).filter(|k| t.admit(k * ms)).count();
        assert!((100..=101).contains(&passed), "{passed}");
        // A node already at the rate, 0.3 ms early now and then: nothing lost.
        let mut t = Thinning::new(100.0);
        let early = (0..50u64)
            .map(|k| k * 10 * ms - if k % 2 == 1 { 300_000 } else { 0 })
            .filter(|at| t.admit(*at))
            .count();
        assert_eq!(early, 50);
        // A gap (a pause of the loop) starts the slots again from the next message.
        assert!(t.admit(10_000 * ms));
        assert!(!t.admit(10_005 * ms));
        // A clock that went back (a restarted loop) starts again.
        assert!(t.admit(0));
    }
}
