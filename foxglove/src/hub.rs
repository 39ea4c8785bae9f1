//! The channels served and the clients connected, between the readers of the nodes' streams
//! (threads of their own) and the clients' sockets (tasks of their own).
//!
//! A reader hands a message to [`Hub::publish`], which never waits: each subscribed client has
//! a bounded queue of data frames, and a frame that finds it full is dropped and counted for
//! that client ([`ClientStats::dropped`]). So a slow client loses messages, never holds up a
//! reader, and a reader never holds up the node's subscription. Advertisements and answers go
//! through a second bounded queue that is never thinned: a client that lets it fill is
//! disconnected (it would otherwise see channels it was never told of).

use std::collections::{BTreeMap, HashMap};
use std::net::SocketAddr;
use std::sync::{Mutex, MutexGuard, PoisonError};

use serde::Serialize;
use tokio::sync::mpsc;

use crate::wire::{self, ChannelAd, ServiceAd};

/// Data frames queued for one client before new ones are dropped: about a second of one robot
/// at the default 100 Hz on every topic.
pub const DATA_QUEUE: usize = 256;
/// Control messages queued for one client before it is disconnected.
pub const CONTROL_QUEUE: usize = 64;

/// What goes out to a client.
#[derive(Debug)]
pub enum Outgoing {
    /// A JSON operation.
    Text(String),
    /// A binary frame.
    Binary(Vec<u8>),
}

/// The two queues a client's socket task reads.
pub struct ClientQueues {
    /// The client's id in the hub.
    pub id: u64,
    /// Advertisements, answers, statuses (read first).
    pub control: mpsc::Receiver<Outgoing>,
    /// Message data and time.
    pub data: mpsc::Receiver<Outgoing>,
}

/// One client's counters, as `/penelope/gateway` reports them.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ClientStats {
    /// The hub's id of the client.
    pub id: u64,
    /// Where it connected from.
    pub address: String,
    /// Its subscriptions.
    pub subscriptions: usize,
    /// Data frames sent to its queue.
    pub queued: u64,
    /// Data frames dropped because its queue was full (it read too slowly).
    pub dropped: u64,
}

struct ClientSlot {
    address: SocketAddr,
    control: mpsc::Sender<Outgoing>,
    data: mpsc::Sender<Outgoing>,
    /// Subscription id -> channel id.
    subscriptions: HashMap<u32, u32>,
    queued: u64,
    dropped: u64,
}

#[derive(Default)]
struct Inner {
    channels: BTreeMap<u32, ChannelAd>,
    next_channel: u32,
    services: Vec<ServiceAd>,
    clients: HashMap<u64, ClientSlot>,
    next_client: u64,
    /// The last message of each latched channel (a robot's description, the walls): what a
    /// new subscriber gets at once.
    latched: HashMap<u32, (u64, Vec<u8>)>,
    /// Clients disconnected for a full control queue.
    evicted: u64,
}

/// The channels and the clients.
pub struct Hub {
    name: String,
    session: String,
    inner: Mutex<Inner>,
}

impl Hub {
    /// A hub serving as `name` (the `serverInfo` name), for the session `session`.
    pub fn new(name: &str, session: &str) -> Self {
        Hub {
            name: name.to_string(),
            session: session.to_string(),
            inner: Mutex::new(Inner {
                next_channel: 1,
                next_client: 1,
                ..Inner::default()
            }),
        }
    }

    fn lock(&self) -> MutexGuard<'_, Inner> {
        // The data are queues and counters: at worst a count off after a panic elsewhere.
        self.inner.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The services offered to every client (set before clients connect).
    pub fn set_services(&self, services: Vec<ServiceAd>) {
        self.lock().services = services;
    }

    /// Serves `topic` (its id if it is already served), advertising it to every client.
    pub fn add_channel(&self, topic: &str, schema_name: &str, schema: &str) -> u32 {
        let mut inner = self.lock();
        if let Some((id, _)) = inner.channels.iter().find(|(_, c)| c.topic == topic) {
            return *id;
        }
        let id = inner.next_channel;
        inner.next_channel += 1;
        let ad = ChannelAd::json(id, topic, schema_name, schema);
        let text = wire::advertise(std::slice::from_ref(&ad));
        inner.channels.insert(id, ad);
        control_all(&mut inner, &text);
        id
    }

    /// Stops serving channel `id`, telling every client.
    pub fn remove_channel(&self, id: u32) {
        let mut inner = self.lock();
        if inner.channels.remove(&id).is_none() {
            return;
        }
        inner.latched.remove(&id);
        for c in inner.clients.values_mut() {
            c.subscriptions.retain(|_, channel| *channel != id);
        }
        control_all(&mut inner, &wire::unadvertise(&[id]));
    }

    /// The topics served, with their channel ids.
    pub fn topics(&self) -> Vec<(u32, String, String)> {
        self.lock()
            .channels
            .values()
            .map(|c| (c.id, c.topic.clone(), c.schema_name.clone()))
            .collect()
    }

    /// Whether any client subscribes to channel `id` (a reader skips encoding otherwise).
    pub fn has_subscribers(&self, id: u32) -> bool {
        self.lock()
            .clients
            .values()
            .any(|c| c.subscriptions.values().any(|ch| *ch == id))
    }

    /// Hands `payload`, logged at `time_ns`, to every client subscribed to channel `id`.
    /// Never waits: a full queue drops the frame (counted for that client).
    pub fn publish(&self, id: u32, time_ns: u64, payload: &[u8]) {
        let mut inner = self.lock();
        for c in inner.clients.values_mut() {
            for (sub, _) in c.subscriptions.iter().filter(|(_, ch)| **ch == id) {
                let frame = wire::message_data(*sub, time_ns, payload);
                match c.data.try_send(Outgoing::Binary(frame)) {
                    Ok(()) => c.queued += 1,
                    Err(mpsc::error::TrySendError::Full(_)) => c.dropped += 1,
                    // The socket task ended; `disconnect` removes the slot.
                    Err(mpsc::error::TrySendError::Closed(_)) => {}
                }
            }
        }
    }

    /// As [`publish`](Self::publish), and kept: every later subscriber of channel `id` gets it
    /// when it subscribes (a description that rarely changes).
    pub fn publish_latched(&self, id: u32, time_ns: u64, payload: &[u8]) {
        self.publish(id, time_ns, payload);
        let mut inner = self.lock();
        if inner.channels.contains_key(&id) {
            inner.latched.insert(id, (time_ns, payload.to_vec()));
        }
    }

    /// The server's time to every client (dropped for a client whose queue is full).
    pub fn broadcast_time(&self, time_ns: u64) {
        let frame = wire::time(time_ns);
        let mut inner = self.lock();
        for c in inner.clients.values_mut() {
            if c.data.try_send(Outgoing::Binary(frame.clone())).is_err() {
                c.dropped += 1;
            }
        }
    }

    /// A new client from `address`: its queues, already holding `serverInfo` and the current
    /// advertisements.
    pub fn connect(&self, address: SocketAddr) -> ClientQueues {
        let (control, control_rx) = mpsc::channel(CONTROL_QUEUE);
        let (data, data_rx) = mpsc::channel(DATA_QUEUE);
        let mut inner = self.lock();
        let id = inner.next_client;
        inner.next_client += 1;
        let services = !inner.services.is_empty();
        let mut first = vec![wire::server_info(&self.name, &self.session, services)];
        let channels: Vec<ChannelAd> = inner.channels.values().cloned().collect();
        if !channels.is_empty() {
            first.push(wire::advertise(&channels));
        }
        if services {
            first.push(wire::advertise_services(&inner.services));
        }
        for text in first {
            // A fresh queue holds these few.
            let _ = control.try_send(Outgoing::Text(text));
        }
        inner.clients.insert(
            id,
            ClientSlot {
                address,
                control,
                data,
                subscriptions: HashMap::new(),
                queued: 0,
                dropped: 0,
            },
        );
        ClientQueues {
            id,
            control: control_rx,
            data: data_rx,
        }
    }

    /// Forgets client `id` (its socket closed); returns its counters.
    pub fn disconnect(&self, id: u64) -> Option<ClientStats> {
        let mut inner = self.lock();
        inner.clients.remove(&id).map(|c| stats(id, &c))
    }

    /// Client `id` subscribes to channel `channel` as subscription `sub`.
    ///
    /// # Errors
    /// Why not, as the client is told: no such channel, or `sub` already in use.
    pub fn subscribe(&self, id: u64, sub: u32, channel: u32) -> Result<(), String> {
        let mut inner = self.lock();
        if !inner.channels.contains_key(&channel) {
            return Err(format!("no channel {channel}"));
        }
        let c = inner
            .clients
            .get_mut(&id)
            .ok_or_else(|| "not connected".to_string())?;
        if c.subscriptions.contains_key(&sub) {
            return Err(format!("subscription id {sub} is already in use"));
        }
        c.subscriptions.insert(sub, channel);
        if let Some((time_ns, payload)) = inner.latched.get(&channel) {
            let frame = wire::message_data(sub, *time_ns, payload);
            if let Some(c) = inner.clients.get_mut(&id) {
                match c.data.try_send(Outgoing::Binary(frame)) {
                    Ok(()) => c.queued += 1,
                    Err(_) => c.dropped += 1,
                }
            }
        }
        Ok(())
    }

    /// Client `id` ends subscription `sub` (nothing if it has none such).
    pub fn unsubscribe(&self, id: u64, sub: u32) {
        if let Some(c) = self.lock().clients.get_mut(&id) {
            c.subscriptions.remove(&sub);
        }
    }

    /// A control message (an answer, a status) to client `id` alone; a client whose control
    /// queue is full is disconnected.
    pub fn send_control(&self, id: u64, message: Outgoing) {
        let mut inner = self.lock();
        let full = match inner.clients.get(&id) {
            Some(c) => matches!(
                c.control.try_send(message),
                Err(mpsc::error::TrySendError::Full(_))
            ),
            None => false,
        };
        if full {
            inner.clients.remove(&id);
            inner.evicted += 1;
        }
    }

    /// Every client's counters, and the clients disconnected so far for not reading their
    /// control messages.
    pub fn stats(&self) -> (Vec<ClientStats>, u64) {
        let inner = self.lock();
        let mut all: Vec<ClientStats> = inner.clients.iter().map(|(id, c)| stats(*id, c)).collect();
        all.sort_by_key(|c| c.id);
        (all, inner.evicted)
    }
}

/// Tells each client that loses messages so, at most once per `every`: the Foxglove app shows
/// a `status` among its problems. Remembers what each was told in `told` (by client id: drops
/// told, when).
pub fn notices(
    clients: &[ClientStats],
    told: &mut HashMap<u64, (u64, std::time::Instant)>,
    now: std::time::Instant,
    every: std::time::Duration,
) -> Vec<(u64, String)> {
    told.retain(|id, _| clients.iter().any(|c| c.id == *id));
    let mut out = Vec::new();
    for c in clients {
        let due = match told.get(&c.id) {
            Some((before, at)) => c.dropped > *before && now.duration_since(*at) >= every,
            None => c.dropped > 0,
        };
        if due {
            told.insert(c.id, (c.dropped, now));
            out.push((
                c.id,
                format!(
                    "this client reads too slowly: {} of {} messages dropped so far (the robots \
                     are not held up; subscribe to fewer topics or lower --rate)",
                    c.dropped,
                    c.dropped + c.queued
                ),
            ));
        }
    }
    out
}

fn stats(id: u64, c: &ClientSlot) -> ClientStats {
    ClientStats {
        id,
        address: c.address.to_string(),
        subscriptions: c.subscriptions.len(),
        queued: c.queued,
        dropped: c.dropped,
    }
}

/// `text` to every client's control queue; a client whose queue is full is disconnected.
fn control_all(inner: &mut Inner, text: &str) {
    let before = inner.clients.len();
    inner.clients.retain(|_, c| {
        !matches!(
            c.control.try_send(Outgoing::Text(text.to_string())),
            Err(mpsc::error::TrySendError::Full(_))
        )
    });
    inner.evicted += (before - inner.clients.len()) as u64;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn addr() -> SocketAddr {
        "127.0.0.1:1".parse().unwrap()
    }

    fn texts(rx: &mut mpsc::Receiver<Outgoing>) -> Vec<String> {
        let mut out = Vec::new();
        while let Ok(m) = rx.try_recv() {
            if let Outgoing::Text(t) = m {
                out.push(t);
            }
        }
        out
    }

    #[test]
    fn a_client_gets_server_info_then_the_channels_then_new_ones_as_they_come() {
        let hub = Hub::new("penelope", "s1");
        let tf = hub.add_channel("/tf", "foxglove.FrameTransforms", "{}");
        assert_eq!(hub.add_channel("/tf", "foxglove.FrameTransforms", "{}"), tf);
        let mut q = hub.connect(addr());
        let first = texts(&mut q.control);
        assert!(first[0].contains("serverInfo"), "{first:?}");
        assert!(first[1].contains("\"/tf\""), "{first:?}");
        let ticks = hub.add_channel("/controllers/pid", "penelope.Tick", "{}");
        assert!(texts(&mut q.control)[0].contains("/controllers/pid"));
        hub.remove_channel(ticks);
        assert!(texts(&mut q.control)[0].contains("unadvertise"));
        assert_eq!(hub.topics().len(), 1);
    }

    #[test]
    fn only_subscribers_get_data_with_their_own_subscription_id() {
        let hub = Hub::new("penelope", "s1");
        let tf = hub.add_channel("/tf", "foxglove.FrameTransforms", "{}");
        let mut a = hub.connect(addr());
        let mut b = hub.connect(addr());
        assert!(!hub.has_subscribers(tf));
        hub.subscribe(a.id, 42, tf).unwrap();
        assert!(hub.subscribe(a.id, 42, tf).is_err(), "an id in use");
        assert!(hub.subscribe(a.id, 43, 999).is_err(), "no such channel");
        assert!(hub.has_subscribers(tf));
        hub.publish(tf, 7, b"{}");
        match a.data.try_recv().unwrap() {
            Outgoing::Binary(f) => {
                assert_eq!(f[0], 1);
                assert_eq!(&f[1..5], &42u32.to_le_bytes());
            }
            other => panic!("{other:?}"),
        }
        assert!(b.data.try_recv().is_err());
        hub.unsubscribe(a.id, 42);
        hub.publish(tf, 8, b"{}");
        assert!(a.data.try_recv().is_err());
    }

    #[test]
    fn a_latched_message_reaches_each_later_subscriber_once() {
        let hub = Hub::new("penelope", "s1");
        let d = hub.add_channel("/robot_description/puma", "penelope.RobotDescription", "{}");
        hub.publish_latched(d, 5, b"{\"urdf\":1}");
        let mut a = hub.connect(addr());
        hub.subscribe(a.id, 1, d).unwrap();
        match a.data.try_recv().unwrap() {
            Outgoing::Binary(f) => assert_eq!(&f[13..], b"{\"urdf\":1}"),
            other => panic!("{other:?}"),
        }
        assert!(a.data.try_recv().is_err());
        hub.remove_channel(d);
        let d2 = hub.add_channel("/robot_description/puma", "penelope.RobotDescription", "{}");
        hub.subscribe(a.id, 2, d2).unwrap();
        assert!(
            a.data.try_recv().is_err(),
            "a removed channel's message is forgotten"
        );
    }

    #[test]
    fn a_client_that_does_not_read_loses_frames_counted_and_the_publisher_never_waits() {
        let hub = Hub::new("penelope", "s1");
        let tf = hub.add_channel("/tf", "foxglove.FrameTransforms", "{}");
        let slow = hub.connect(addr());
        let mut fast = hub.connect(addr());
        hub.subscribe(slow.id, 1, tf).unwrap();
        hub.subscribe(fast.id, 1, tf).unwrap();
        let extra = 100;
        let mut fast_got = 0;
        for t in 0..(DATA_QUEUE + extra) as u64 {
            hub.publish(tf, t, b"{}");
            while fast.data.try_recv().is_ok() {
                fast_got += 1;
            }
        }
        let (stats, evicted) = hub.stats();
        let s = stats.iter().find(|c| c.id == slow.id).unwrap();
        assert_eq!(s.queued, DATA_QUEUE as u64);
        assert_eq!(s.dropped, extra as u64);
        let f = stats.iter().find(|c| c.id == fast.id).unwrap();
        assert_eq!(f.dropped, 0);
        assert_eq!(fast_got, DATA_QUEUE + extra);
        assert_eq!(evicted, 0);
        drop(slow);
    }

    #[test]
    fn a_client_losing_messages_is_told_at_most_once_per_period() {
        let every = std::time::Duration::from_secs(5);
        let t0 = std::time::Instant::now();
        let client = |dropped| ClientStats {
            id: 3,
            address: "127.0.0.1:1".into(),
            subscriptions: 1,
            queued: 10,
            dropped,
        };
        let mut told = HashMap::new();
        assert!(notices(&[client(0)], &mut told, t0, every).is_empty());
        let first = notices(&[client(4)], &mut told, t0, every);
        assert_eq!(first.len(), 1);
        assert!(first[0].1.contains("4 of 14"), "{}", first[0].1);
        assert!(notices(&[client(9)], &mut told, t0 + every / 2, every).is_empty());
        assert_eq!(notices(&[client(9)], &mut told, t0 + every, every).len(), 1);
        assert!(
            notices(&[client(9)], &mut told, t0 + every * 3, every).is_empty(),
            "no new drops"
        );
        // A client gone is forgotten.
        assert!(notices(&[], &mut told, t0 + every * 4, every).is_empty());
        assert!(told.is_empty());
    }

    #[test]
    fn a_client_that_lets_its_control_queue_fill_is_disconnected() {
        let hub = Hub::new("penelope", "s1");
        let q = hub.connect(addr());
        for k in 0..CONTROL_QUEUE + 1 {
            hub.add_channel(&format!("/t{k}"), "x", "{}");
        }
        let (stats, evicted) = hub.stats();
        assert!(stats.is_empty());
        assert_eq!(evicted, 1);
        assert!(hub.disconnect(q.id).is_none());
    }
}
