//! A force sensor published on the data plane: the node that owns the sensor serves it from one
//! endpoint, and any number of readers on any nodes subscribe to it, so reading a sensor from
//! several hosts adds no request load on it and no reader makes a TCP call per sample.
//!
//! ```text
//!  reader (a controller's sensor feed)            publisher (the sensor's node)
//!  ──────────────────────────────────             ─────────────────────────────
//!  Subscribe { probe } every feed period  ──────>  subscriber table (bounded, expiring)
//!  (or every RENEW_EVERY without a probe)          each period: measure at the newest probe
//!                                         <──────  Sample { wrench }, the same datagram to
//!  newest wins (StreamReceiver)                    every subscriber (one sequence number)
//! ```
//!
//! - [`table`]: who is subscribed, with the newest probe of each; bounded and expiring;
//! - [`publisher`]: the sensor node's thread that serves the table;
//! - [`subscriber`]: a reader's end.
//!
//! Every datagram is a [`frame`](super::frame) datagram: authenticated with the system's key
//! when it has one, numbered by a [`StreamSender`](super::stream::StreamSender) in a random
//! session, and judged newest-wins by a [`StreamReceiver`](super::stream::StreamReceiver) (at
//! the reader for samples, at the publisher per subscriber for subscriptions), which is also the
//! replay protection.
//!
//! A probe is what a `sensor/virtual` in probe mode needs: the reader's tool pose and linear
//! velocity in the sensor's base frame. The publisher measures at the newest probe any
//! subscriber sent, so every reader sees the same samples; a reader without a probe (a monitor,
//! the paper's second reader) just receives.

use std::time::Duration;

use nalgebra::Vector3;
use penelope_hal::Pose;
use serde::{Deserialize, Serialize};

use super::frame::{DatagramKey, DirectedKeys, StreamId};
use penelope_protocol::proto::{PoseMsg, WrenchMsg};

pub mod publisher;
pub mod subscriber;
pub mod table;

pub use publisher::{Measure, PublisherStats, SensorPublisher};
pub use subscriber::{SensorSubscriber, SubscriberStats, WrenchSample};
pub use table::{Admission, Refusal, SubscriberTable};

/// The stream of a sensor's samples, publisher to readers. A sensor's stream is told apart
/// from another sensor's by the publisher's address (one endpoint per sensor), not by this id.
pub const SENSOR_SAMPLES: StreamId = StreamId(16);

/// The keys of the publisher of the sensor named `sensor` (its name on its node, the last part
/// of its naming path): samples go out under `sensor -> readers`, subscriptions come in under
/// `readers -> sensor` ([`DatagramKey::for_direction`], channel `"sensor"`), so another sensor's
/// or a teleoperation channel's datagrams do not verify.
pub fn sensor_publisher_keys(system: &DatagramKey, sensor: &str) -> DirectedKeys {
    system.directed("sensor", sensor, "readers")
}

/// The keys of a reader of the sensor at naming `path` (or named `path`): the publisher's,
/// crosswise ([`sensor_publisher_keys`]).
pub fn sensor_reader_keys(system: &DatagramKey, path: &str) -> DirectedKeys {
    let sensor = path
        .trim_end_matches('/')
        .rsplit('/')
        .next()
        .unwrap_or(path);
    system.directed("sensor", "readers", sensor)
}
/// The stream of a reader's subscriptions (and probes), reader to publisher.
pub const SENSOR_SUBSCRIPTIONS: StreamId = StreamId(17);
/// A reader without a probe renews its subscription this often.
pub const RENEW_EVERY: Duration = Duration::from_millis(200);
/// A subscriber not heard from for this long is dropped (five renewals missed).
pub const SUBSCRIBER_TIMEOUT: Duration = Duration::from_secs(1);
/// Subscribers a publisher serves at once; beyond, subscriptions are refused and counted.
pub const MAX_SUBSCRIBERS: usize = 16;

/// Where a reader's probe is: its tool pose and linear velocity in the sensor's base frame
/// (checked finite and orthonormal).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Probe {
    /// The tool pose, base frame.
    pub pose: Pose,
    /// The tool's linear velocity, base frame, m/s.
    pub velocity: Vector3<f64>,
}

/// A probe as it crosses the wire.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
struct ProbeMsg {
    pose: PoseMsg,
    velocity: [f64; 3],
}

impl From<&Probe> for ProbeMsg {
    fn from(p: &Probe) -> Self {
        ProbeMsg {
            pose: PoseMsg::from(&p.pose),
            velocity: [p.velocity.x, p.velocity.y, p.velocity.z],
        }
    }
}

impl ProbeMsg {
    /// The probe, or `None` for a NaN, an infinity or a pose that is not a rotation.
    fn to_probe(self) -> Option<Probe> {
        let pose = self.pose.to_pose().ok()?;
        let velocity = Vector3::from(self.velocity);
        velocity
            .iter()
            .all(|x| x.is_finite())
            .then_some(Probe { pose, velocity })
    }
}

/// What crosses a sensor stream (the header carries stream, session, sequence and send time).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
enum SensorDatagram {
    /// Reader to publisher: keep (or start) sending me samples; measure at this probe.
    Subscribe {
        /// The reader's probe, if it has one.
        probe: Option<ProbeMsg>,
    },
    /// Reader to publisher: stop sending me samples.
    Unsubscribe,
    /// Publisher to readers: the wrench measured at the header's send time (the sensor node's
    /// clock), base frame, N and N·m.
    Sample {
        /// The wrench.
        wrench: WrenchMsg,
    },
}

/// Signed nanoseconds of a timestamp (the data plane's clock values).
fn nanos(t: penelope_hal::Timestamp) -> i64 {
    i64::try_from(t.as_nanos()).unwrap_or(i64::MAX)
}

#[cfg(test)]
mod key_tests {
    use super::*;

    #[test]
    fn a_reader_holds_its_sensors_keys_crosswise_and_no_other_stream_shares_them() {
        let system = DatagramKey::from_secret(b"lab");
        let publisher = sensor_publisher_keys(&system, "wrist");
        for path in ["/lab-b/sensors/wrist", "wrist", "/lab-b/sensors/wrist/"] {
            let reader = sensor_reader_keys(&system, path);
            assert_eq!(
                format!(
                    "{:?}",
                    (publisher.send.tag_of(b"x"), reader.send.tag_of(b"x"))
                ),
                format!(
                    "{:?}",
                    (reader.receive.tag_of(b"x"), publisher.receive.tag_of(b"x"))
                ),
                "{path}"
            );
        }
        let other = sensor_reader_keys(&system, "/lab-b/sensors/ankle");
        assert_ne!(other.receive.tag_of(b"x"), publisher.send.tag_of(b"x"));
        let teleop = system.directed("teleop", "wrist", "readers");
        assert_ne!(teleop.send.tag_of(b"x"), publisher.send.tag_of(b"x"));
        assert_ne!(system.tag_of(b"x"), publisher.send.tag_of(b"x"));
    }
}
