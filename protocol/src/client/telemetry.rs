//! A subscription on a connection of its own: the control ticks of a running loop
//! ([`TelemetryStream`]), the link records of a channel linked to another node
//! ([`LinkStream`]) or the frames of a camera ([`FrameStream`]).
//!
//! The node pushes batches as the loop runs (or, for a link, every 100 ms) and drops batches,
//! never queues them without bound, when this side reads too slowly
//! ([`Subscription::dropped`] counts them).

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use super::{parse_address, unexpected};
use crate::net::conn::{ClientConfig, Connection, Pushed, RpcError};
use crate::proto::{
    Call, CallError, CameraFrame, Class, LinkRecord, ObjectRef, Reply, TelemetryRecord, WireError,
    object_path,
};

/// What a subscription streams, record by record: a control tick or a link record.
pub trait Streamed: Sized {
    /// The class of object whose subscription streams these (a subscription to another class
    /// is refused before anything is sent).
    const CLASS: Class;

    /// Whether an object of `class` streams these.
    fn streamed_by(class: Class) -> bool;

    /// `pushed`'s subscription, its count of dropped batches and its records, if it carries
    /// this kind of record.
    fn unpack(pushed: Pushed) -> Option<(u64, u64, Vec<Self>)>;

    /// The sending node's common-clock offset that `pushed` carries, ns (`None`: it carries
    /// none, as records already on the common clock or link records).
    fn common_offset(_pushed: &Pushed) -> Option<i64> {
        None
    }
}

impl Streamed for TelemetryRecord {
    const CLASS: Class = Class::Controller;

    /// A controller, or a robot (the node finds the controller driving it).
    fn streamed_by(class: Class) -> bool {
        matches!(class, Class::Controller | Class::Robot)
    }

    fn unpack(pushed: Pushed) -> Option<(u64, u64, Vec<Self>)> {
        match pushed {
            Pushed::Telemetry(b) => Some((b.subscription, b.dropped, b.samples)),
            Pushed::Link(_) | Pushed::Frames(_) => None,
        }
    }

    fn common_offset(pushed: &Pushed) -> Option<i64> {
        match pushed {
            Pushed::Telemetry(b) => Some(b.common_offset_ns),
            Pushed::Link(_) | Pushed::Frames(_) => None,
        }
    }
}

impl Streamed for LinkRecord {
    const CLASS: Class = Class::Trajectory;

    /// A `trajectory/teleop` channel (the node refuses other trajectories, and a channel with
    /// no link to another node).
    fn streamed_by(class: Class) -> bool {
        class == Class::Trajectory
    }

    fn unpack(pushed: Pushed) -> Option<(u64, u64, Vec<Self>)> {
        match pushed {
            Pushed::Link(b) => Some((b.subscription, b.dropped, b.records)),
            Pushed::Telemetry(_) | Pushed::Frames(_) => None,
        }
    }
}

impl Streamed for CameraFrame {
    const CLASS: Class = Class::Sensor;

    /// A sensor (the node refuses a sensor that is not a camera).
    fn streamed_by(class: Class) -> bool {
        class == Class::Sensor
    }

    fn unpack(pushed: Pushed) -> Option<(u64, u64, Vec<Self>)> {
        match pushed {
            Pushed::Frames(b) => Some((b.subscription, b.dropped, b.frames)),
            Pushed::Telemetry(_) | Pushed::Link(_) => None,
        }
    }
}

/// The control ticks of a controller (or of the robot it drives).
pub type TelemetryStream = Subscription<TelemetryRecord>;

/// The frames of a camera (`sensor/sim-camera`, `sensor/camera`), stamped on the common clock.
pub type FrameStream = Subscription<CameraFrame>;

/// The link records of a `trajectory/teleop` channel whose end on that node is linked to
/// another node: its clock offset, delay, jitter, losses and counters, every 100 ms.
pub type LinkStream = Subscription<LinkRecord>;

/// The records of one object, one after the other. Unsubscribes (and closes its connection)
/// when dropped.
///
/// As an [`Iterator`], it waits up to [`Subscription::timeout`] for each record, yields
/// `Err(RpcError::Timeout)` when none came and ends after a transport error.
#[derive(Debug)]
pub struct Subscription<R> {
    conn: Connection,
    subscription: u64,
    path: String,
    pending: VecDeque<R>,
    dropped: u64,
    common_offset_ns: i64,
    timeout: Duration,
    broken: bool,
}

impl<R: Streamed> Subscription<R> {
    /// Opens a connection to the node of `reference` and subscribes to the object, one record
    /// in `decimation`.
    ///
    /// # Errors
    /// [`CallError::WrongClass`] for an object that does not stream `R` (nothing is sent), the
    /// node's refusal or a transport error.
    pub(crate) fn open(
        reference: &ObjectRef,
        config: &ClientConfig,
        decimation: u32,
    ) -> Result<Self, RpcError> {
        if !R::streamed_by(reference.class) {
            return Err(RpcError::Remote(WireError::Call(CallError::WrongClass {
                name: reference.name.clone(),
                expected: R::CLASS,
                found: reference.class,
            })));
        }
        let address = parse_address(reference)?;
        let mut conn = Connection::connect(address, config)?;
        let subscription = match conn.call(Call::Subscribe {
            object: reference.name.clone(),
            decimation: decimation.max(1),
        })? {
            Reply::Subscribed { subscription } => subscription,
            other => return Err(unexpected("a subscription", &other)),
        };
        Ok(Subscription {
            conn,
            subscription,
            path: object_path(&reference.node, reference.class, &reference.name),
            pending: VecDeque::new(),
            dropped: 0,
            common_offset_ns: 0,
            timeout: config.timeout,
            broken: false,
        })
    }

    /// The subscription's id on its connection.
    pub fn subscription(&self) -> u64 {
        self.subscription
    }

    /// The naming path of the object watched.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// Batches the node dropped so far because this side read too slowly.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// The node's common-clock offset as its newest batch gave it, ns: a telemetry record's
    /// time on the system's common clock is `time_ns` plus this ([`Subscription::to_common`]).
    /// Zero before the first batch, and for records that carry none.
    pub fn common_offset_ns(&self) -> i64 {
        self.common_offset_ns
    }

    /// A time of the node's clock (`time_ns` of a telemetry record) on the common clock.
    pub fn to_common(&self, node_ns: u64) -> u64 {
        node_ns.saturating_add_signed(self.common_offset_ns)
    }

    /// How long the iterator waits for one record.
    pub fn timeout(&self) -> Duration {
        self.timeout
    }

    /// Sets how long the iterator waits for one record.
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// The next record, waiting at most `timeout`; `Ok(None)` if none came in time.
    ///
    /// # Errors
    /// A transport error (the node went away); the stream is then finished.
    pub fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<R>, RpcError> {
        if let Some(record) = self.pending.pop_front() {
            return Ok(Some(record));
        }
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.conn.next_pushed(left) {
                Ok(Some(pushed)) => {
                    if pushed.subscription() == self.subscription
                        && let Some(offset) = R::common_offset(&pushed)
                    {
                        self.common_offset_ns = offset;
                    }
                    if let Some((subscription, dropped, records)) = R::unpack(pushed)
                        && subscription == self.subscription
                    {
                        self.dropped = self.dropped.max(dropped);
                        self.pending.extend(records);
                        if let Some(record) = self.pending.pop_front() {
                            return Ok(Some(record));
                        }
                    }
                }
                Ok(None) | Err(RpcError::Timeout) => return Ok(None),
                Err(e) => {
                    self.broken = true;
                    return Err(e);
                }
            }
            if left.is_zero() {
                return Ok(None);
            }
        }
    }
}

impl<R: Streamed> Iterator for Subscription<R> {
    type Item = Result<R, RpcError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.broken {
            return None;
        }
        match self.recv_timeout(self.timeout) {
            Ok(Some(record)) => Some(Ok(record)),
            Ok(None) => Some(Err(RpcError::Timeout)),
            Err(e) => Some(Err(e)),
        }
    }
}

impl<R> Drop for Subscription<R> {
    fn drop(&mut self) {
        if !self.broken {
            // Best effort: the node also drops the subscription when the connection closes.
            let _ = self.conn.call(Call::Unsubscribe {
                subscription: self.subscription,
            });
        }
    }
}
