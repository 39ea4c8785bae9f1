//! Force sensors: the probe model of `sensor/virtual`, where a feed gets its wrench, and the
//! sensor feed.

use crate::dataplane::sensor_stream::{Probe, SensorSubscriber};
use crate::objects::error::ObjectError;
use crate::objects::runtime::RobotKinematics;
use nalgebra::Vector3;
use penelope_drivers::sim::environment::Environment;
use penelope_hal::{Frame, JacobianFrame, Kinematics, Pose, Timestamp, Twist, Wrench};
use penelope_rt_core::cell::{ArcLatestReader, ArcLatestWriter, Stamped};
use penelope_rt_core::clock::MonotonicClock;
use penelope_rt_core::telemetry::TelemetrySample;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The state of a `sensor/virtual`: an environment pushed by a probe.
#[derive(Clone, Debug)]
pub struct VirtualSensor {
    environment: Environment,
    bias: Wrench,
    last_raw: Wrench,
    probes: u64,
}

impl VirtualSensor {
    /// A sensor over `environment`, no bias.
    pub fn new(environment: Environment) -> Self {
        VirtualSensor {
            environment,
            bias: Wrench::zero(Frame::Base),
            last_raw: Wrench::zero(Frame::Base),
            probes: 0,
        }
    }

    /// The wrench the environment applies to a probe at `pose` moving at `velocity` (base frame,
    /// N and N·m about the probe point), minus the bias. Also the new [`read`](Self::read).
    pub fn measure(&mut self, pose: &Pose, velocity: Vector3<f64>) -> Wrench {
        use penelope_drivers::sim::Interaction;
        let twist = Twist {
            linear: velocity,
            angular: Vector3::zeros(),
            frame: Frame::Base,
        };
        self.last_raw = self
            .environment
            .wrench_on_tool(Timestamp::ZERO, pose, &twist);
        self.probes += 1;
        self.read()
    }

    /// The wrench at the last probe, minus the bias.
    pub fn read(&self) -> Wrench {
        Wrench {
            force: self.last_raw.force - self.bias.force,
            torque: self.last_raw.torque - self.bias.torque,
            frame: Frame::Base,
        }
    }

    /// Takes the wrench at the last probe as the zero.
    pub fn bias(&mut self) {
        self.bias = self.last_raw;
    }

    /// Probes so far.
    pub fn probes(&self) -> u64 {
        self.probes
    }
}

/// Where a controller's sensor feed gets its wrench.
pub enum SensorSource {
    /// A sensor on another node, read over the data plane: the feed's probe goes out in a
    /// subscription each period, and the newest sample the publisher sent comes back.
    Stream(Box<SensorSubscriber>),
    /// A `sensor/virtual` on this node.
    Local(Arc<Mutex<VirtualSensor>>),
}

impl SensorSource {
    /// One measurement for a probe at `pose` moving at `velocity`, at `now_ns` on this node's
    /// clock: for a local sensor, measured now; for a stream, the newest sample that arrived
    /// since the last call (`None`: nothing new).
    ///
    /// # Errors
    /// [`ObjectError::Internal`] for a local sensor whose state is poisoned.
    pub fn measure(
        &mut self,
        pose: &Pose,
        velocity: Vector3<f64>,
        now_ns: i64,
    ) -> Result<Option<Wrench>, ObjectError> {
        match self {
            SensorSource::Stream(subscriber) => {
                let probe = Probe {
                    pose: *pose,
                    velocity,
                };
                Ok(subscriber.poll(now_ns, Some(&probe)).map(|s| s.wrench))
            }
            SensorSource::Local(s) => {
                let mut s = s
                    .lock()
                    .map_err(|_| ObjectError::Poisoned("sensor state"))?;
                Ok(Some(s.measure(pose, velocity)))
            }
        }
    }
}

/// Counters of a sensor feed.
#[derive(Debug, Default)]
pub struct FeedStats {
    /// Wrenches published.
    pub ok: AtomicU64,
    /// Failed measurements.
    pub failed: AtomicU64,
}

/// What a sensor feed needs each period: where the wrench comes from, the robot's model, the
/// loop's newest sample, and the cell the loop reads the wrench from.
pub struct SensorFeed {
    /// Where the wrench comes from.
    pub source: SensorSource,
    /// The robot's kinematics (probe pose and velocity from the sample).
    pub model: RobotKinematics,
    /// The loop's newest sample.
    pub state: ArcLatestReader<TelemetrySample>,
    /// The loop's wrench cell.
    pub out: ArcLatestWriter<Stamped<Wrench>>,
    /// Counters.
    pub stats: Arc<FeedStats>,
    /// The controller's name, for the log.
    pub controller: String,
}

impl SensorFeed {
    /// One measurement: the tool pose and velocity of the newest sample go to the source, and
    /// the wrench, stamped `stamp` (when it reached this node), into the loop's cell. A
    /// failing or silent source publishes nothing, so the loop's wrench goes stale.
    pub fn step(&mut self, stamp: Timestamp) {
        let Some(s) = self.state.latest() else { return };
        let pose = self.model.forward(&s.q);
        let v = self.model.jacobian(&s.q, JacobianFrame::Base) * s.qd;
        let now_ns = i64::try_from(stamp.as_nanos()).unwrap_or(i64::MAX);
        match self
            .source
            .measure(&pose, Vector3::new(v[0], v[1], v[2]), now_ns)
        {
            Ok(None) => {}
            Ok(Some(w)) if w.is_finite() => {
                self.out.write(Stamped { stamp, value: w });
                self.stats.ok.fetch_add(1, Ordering::Relaxed);
            }
            Ok(Some(_)) | Err(_) => {
                if self.stats.failed.fetch_add(1, Ordering::Relaxed) == 0 {
                    log::warn!(
                        "controller `{}`: sensor measurement failed; the wrench goes stale",
                        self.controller
                    );
                }
            }
        }
    }
}

/// Runs a sensor feed until `stop`, every `period`, stamping on `CLOCK_MONOTONIC`; it never
/// blocks the loop.
pub fn run_sensor_feed(feed: &mut SensorFeed, period: Duration, stop: &AtomicBool) {
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(period);
        feed.step(MonotonicClock::read());
    }
}

/// What the control loop asks of a sensor it reads in its own thread, its error reduced to a
/// kind (the loop only counts a failed read as a sensor error and goes on without a wrench).
pub trait LoopSensorRead: Send {
    /// The newest wrench at `now`, in the sensor frame.
    ///
    /// # Errors
    /// The kind of the sensor's own error.
    fn read_wrench(&mut self, now: Timestamp) -> Result<Wrench, penelope_hal::ErrorKind>;
    /// Where the sensor sits on the flange.
    fn sensor_mount(&self) -> Pose;
}

impl<S: penelope_hal::ForceSensor + Send> LoopSensorRead for S {
    fn read_wrench(&mut self, now: Timestamp) -> Result<Wrench, penelope_hal::ErrorKind> {
        penelope_hal::Sensor::read(self, now).map_err(|e| penelope_hal::Error::kind(&e))
    }

    fn sensor_mount(&self) -> Pose {
        penelope_hal::ForceSensor::mount(self)
    }
}

/// A sensor read in the control loop's own thread, its type erased: a sensor kind's module
/// gives one ([`LoopSensorReader::new`]) and the loop reads it without knowing the kind.
///
/// # Real-time
/// One dynamic call per read, no allocation (the box is made when the loop is built).
pub struct LoopSensorReader(Box<dyn LoopSensorRead>);

impl LoopSensorReader {
    /// The reader of `sensor`.
    pub fn new(sensor: impl LoopSensorRead + 'static) -> LoopSensorReader {
        LoopSensorReader(Box::new(sensor))
    }

    /// Where the sensor sits on the flange.
    pub fn mount(&self) -> Pose {
        self.0.sensor_mount()
    }
}

impl penelope_hal::Sensor for LoopSensorReader {
    type Error = penelope_hal::ErrorKind;
    type Reading = Wrench;

    fn read(&mut self, now: Timestamp) -> Result<Wrench, penelope_hal::ErrorKind> {
        self.0.read_wrench(now)
    }
}
