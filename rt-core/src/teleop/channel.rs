//! The teleop channel: a [`Trajectory`] whose references come from the other side of the link.
//!
//! The communication thread pushes each [`TeleopSample`] it receives with
//! [`TeleopChannel::receive`]; the channel keeps the newest (by sequence number), maps it through
//! its [`WorkspaceMapping`] in the configured [`ChannelDirection`], and hands it out as an
//! ordinary reference. The watchdog judges freshness with [`TeleopChannel::age`].
//!
//! # Wiring the demo (position-forward / force-back)
//!
//! - master control thread: publishes the master tool pose (forward kinematics) into a cell;
//! - master comm thread: `master_channel.track_master(now, &pose, clutch)`, then sends
//!   `TeleopSample { sequence, sent: now, clutch, reference: Reference::Cartesian(..) }`;
//! - slave comm thread: `slave_channel.receive(sample)` (a `MasterToSlave` channel, started with
//!   the slave's measured tool pose), then `slave_channel.reference(now)` into the slave's
//!   reference cell: a `Reference::Cartesian` in the slave base with a velocity feed-forward;
//! - slave control thread: [`SlaveTracking`](super::SlaveTracking) follows it; the slave comm
//!   thread sends back the sensor wrench in the slave base (`Reference::Wrench`, or
//!   `Reference::Hybrid` with the slave pose for position-error or both);
//! - master comm thread: `master_channel.receive(sample)` (a `SlaveToMaster` channel, started with
//!   the master's tool pose), `reference(now)`: a `Reference::Wrench` in the master base, scaled by
//!   `k_f`, rotated by `R_ms^T`, faded while the clutch is held; the master's
//!   [`ForceDisplay`](super::ForceDisplay) displays it.
//!
//! # Anchoring
//!
//! [`start`](Trajectory::start) takes the local robot's tool pose (`Reference::Cartesian` or
//! `Hybrid`). The mapping is anchored with it and the first remote pose that arrives (or the
//! latest one already received), so the local reference starts exactly at the local pose. Both
//! sides anchor on the same pair when both arms are at rest while the link starts; otherwise call
//! [`WorkspaceMapping::anchor`] on both sides through [`TeleopChannel::mapping_mut`].
//!
//! # Clutch
//!
//! The master's clutch button travels in every sample ([`TeleopSample::clutch`]): the
//! `MasterToSlave` channel holds the slave reference while it is set and re-anchors on release.
//! On the master, [`TeleopChannel::track_master`] feeds the same states and poses to the
//! `SlaveToMaster` channel's mapping, which fades the force feedback out and in, and re-anchors
//! identically (for the inverse pose mapping of position-error).

use core::fmt;
use core::time::Duration;

use nalgebra::{UnitQuaternion, Vector3, Vector6};
use penelope_hal::{
    CartesianReference, Error, ErrorKind, Frame, HybridReference, JointReference, JointVector,
    Pose, Reference, Timestamp, Trajectory, TrajectoryError, Twist, Wrench,
};

use super::mapping::{MappingConfig, WorkspaceMapping};
use super::passivity::PortEnergy;
use super::wave::WaveSample;
use super::{TeleopConfigError, bottom, lowpass_gain, stack, top};

/// One reference sent over the link.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TeleopSample {
    /// The sender's sequence number; larger is newer.
    pub sequence: u64,
    /// When the sender took the sample, on the receiver's clock (the communication thread
    /// corrects the sender's stamp by the clock offset the heartbeats estimate; on one host the
    /// clocks are the same).
    pub sent: Timestamp,
    /// The master's clutch (indexing) button: held = `true`. Slaves leave it `false`.
    pub clutch: bool,
    /// The payload: master tool pose (`Cartesian`), slave wrench (`Wrench`), both (`Hybrid`), or
    /// joint positions (`Joint`, passed through unmapped for kinematically identical pairs).
    /// Poses and wrenches are in the sender's base frame (wrenches about the tool origin).
    pub reference: Reference,
    /// What passivity-preserving laws add (a wave, energy counters); empty for the others.
    /// The channel itself ignores it: the communication thread hands it to the law's
    /// transform.
    pub port: PortPayload,
    /// Sent on a safety event of the sender's loop that the previous sample did not carry (a
    /// force sensor's fault, say): the receiving communication thread hands it to its loop at
    /// once instead of at its next period. The channel itself ignores it.
    pub urgent: bool,
}

/// The passivity payload of a [`TeleopSample`]: small, `Copy`, no_std.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PortPayload {
    /// The wave of a wave-variable law ([`WaveMaster`](super::WaveMaster),
    /// [`WaveSlave`](super::WaveSlave)), with the sender's running totals.
    pub wave: Option<WaveSample>,
    /// The sender's two-port energy counters
    /// ([`TwoPortObserver`](super::TwoPortObserver)).
    pub energy: Option<PortEnergy>,
}

impl TeleopSample {
    /// A sample with the clutch released.
    pub fn new(sequence: u64, sent: Timestamp, reference: Reference) -> Self {
        TeleopSample {
            sequence,
            sent,
            clutch: false,
            reference,
            port: PortPayload::default(),
            urgent: false,
        }
    }
}

/// Which way the channel maps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ChannelDirection {
    /// On the slave: master poses in, slave poses out (wrenches in are mapped master -> slave).
    #[default]
    MasterToSlave,
    /// On the master: slave wrenches (and poses) in, master wrenches (and poses) out.
    SlaveToMaster,
}

/// Where the velocity feed-forward of pose and joint references comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VelocityFeedForward {
    /// Differences of consecutive samples (by their send stamps) through a first-order low-pass
    /// with corner `cutoff_hz`.
    Estimate {
        /// Low-pass corner, Hz (> 0).
        cutoff_hz: f64,
    },
    /// The twist or joint velocity carried in the sample, mapped.
    FromSample,
    /// No velocity feed-forward.
    Zero,
}

/// The channel's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChannelConfig {
    /// Which way to map.
    pub direction: ChannelDirection,
    /// The workspace mapping.
    pub mapping: MappingConfig,
    /// The velocity feed-forward.
    pub velocity: VelocityFeedForward,
    /// Consecutive samples further apart than this (send stamps) restart the velocity estimate
    /// at zero instead of differentiating across the gap.
    pub max_velocity_gap: Duration,
}

impl Default for ChannelConfig {
    /// Master to slave, default mapping, velocity estimated with a 60 Hz low-pass (about 3 ms of
    /// lag; lower it for a noisy master), 50 ms gap.
    fn default() -> Self {
        ChannelConfig {
            direction: ChannelDirection::MasterToSlave,
            mapping: MappingConfig::default(),
            velocity: VelocityFeedForward::Estimate { cutoff_hz: 60.0 },
            max_velocity_gap: Duration::from_millis(50),
        }
    }
}

/// Why a sample was not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReceiveError {
    /// Its sequence number is not newer than the latest taken (late or duplicated datagram).
    Stale,
    /// It holds NaN or infinity.
    NonFinite,
    /// Its wrench is in a frame the channel cannot map (only base-frame wrenches travel).
    UnsupportedFrame,
}

impl fmt::Display for ReceiveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ReceiveError::Stale => "sample older than the latest one",
            ReceiveError::NonFinite => "sample holds NaN or infinity",
            ReceiveError::UnsupportedFrame => "sample wrench is not in the base frame",
        })
    }
}

impl Error for ReceiveError {
    fn kind(&self) -> ErrorKind {
        match self {
            ReceiveError::Stale => ErrorKind::Communication,
            ReceiveError::NonFinite => ErrorKind::NonFinite,
            ReceiveError::UnsupportedFrame => ErrorKind::InvalidInput,
        }
    }
}

/// What the channel has taken and refused.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ChannelStats {
    /// Samples taken.
    pub accepted: u64,
    /// Samples dropped as not newer than the latest.
    pub stale: u64,
    /// Samples refused as non-finite or in an unsupported frame.
    pub rejected: u64,
}

/// The position part of a sample, for differentiation.
#[derive(Clone, Copy, Debug)]
enum Position {
    Joint(JointVector),
    Pose(Pose),
}

fn position_of(r: &Reference) -> Option<Position> {
    match r {
        Reference::Joint(j) => Some(Position::Joint(j.position)),
        Reference::Cartesian(c) => Some(Position::Pose(c.pose)),
        Reference::Hybrid(h) => Some(Position::Pose(h.motion.pose)),
        Reference::Wrench(_) => None,
    }
}

fn pose_of(r: &Reference) -> Option<&CartesianReference> {
    match r {
        Reference::Cartesian(c) => Some(c),
        Reference::Hybrid(h) => Some(&h.motion),
        _ => None,
    }
}

/// First-order filtered finite differences of the raw (unmapped) sample stream.
#[derive(Clone, Copy, Debug)]
struct VelocityEstimator {
    last: Option<(Timestamp, Position)>,
    /// `[v; omega]` (base frame) or joint velocities.
    velocity: Vector6<f64>,
}

impl VelocityEstimator {
    const fn new() -> Self {
        VelocityEstimator {
            last: None,
            velocity: Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        }
    }

    fn update(&mut self, at: Timestamp, p: Position, cutoff_hz: f64, max_gap: Duration) {
        let previous = self.last.replace((at, p));
        let Some((t0, p0)) = previous else {
            self.velocity = Vector6::zeros();
            return;
        };
        let gap = at.saturating_since(t0);
        let dt = gap.as_secs_f64();
        let raw = match (p0, p) {
            _ if dt <= 0.0 || gap > max_gap => None,
            (Position::Joint(a), Position::Joint(b)) => Some((b - a) / dt),
            (Position::Pose(a), Position::Pose(b)) => {
                let v = (b.translation.vector - a.translation.vector) / dt;
                let w = (b.rotation * a.rotation.inverse()).scaled_axis() / dt;
                Some(stack(&v, &w))
            }
            _ => None,
        };
        match raw {
            Some(raw) => self.velocity += (raw - self.velocity) * lowpass_gain(cutoff_hz, dt),
            None => self.velocity = Vector6::zeros(),
        }
    }
}

/// A streamed trajectory fed from the other side of a teleoperation link. Kind `"teleop"`.
///
/// [`reference`](Trajectory::reference) answers [`TrajectoryError::NotStarted`] before
/// [`start`](Trajectory::start) (or while a pose cannot be mapped for want of anchors) and
/// [`TrajectoryError::NoData`] before the first sample; afterwards it keeps answering with the
/// latest sample however old: freshness is the watchdog's call, from [`age`](Self::age).
///
/// # Real-time
/// `receive` (communication thread), `reference`, `track_master` and `age`: no allocation, no
/// locks, constant time, no panics. The channel itself is not shared between threads: the
/// communication thread owns it and publishes `reference(now)` into the control thread's cell.
#[derive(Clone, Copy, Debug)]
pub struct TeleopChannel {
    config: ChannelConfig,
    mapping: WorkspaceMapping,
    started: bool,
    /// The local pose waiting for the first remote pose to anchor the mapping.
    pending_anchor: Option<Pose>,
    latest: Option<TeleopSample>,
    /// MasterToSlave: the clutch-aware slave pose of the latest sample.
    mapped: Option<Pose>,
    /// SlaveToMaster: the latest local master pose (`track_master` or `start`).
    local_master: Option<Pose>,
    estimator: VelocityEstimator,
    stats: ChannelStats,
}

impl TeleopChannel {
    /// A channel with nothing received.
    ///
    /// # Errors
    /// [`TeleopConfigError`] for an invalid mapping or velocity filter.
    pub fn new(config: ChannelConfig) -> Result<Self, TeleopConfigError> {
        if let VelocityFeedForward::Estimate { cutoff_hz } = config.velocity {
            if !cutoff_hz.is_finite() {
                return Err(TeleopConfigError::NonFinite {
                    parameter: "velocity.cutoff_hz",
                });
            }
            if cutoff_hz <= 0.0 {
                return Err(TeleopConfigError::OutOfRange {
                    parameter: "velocity.cutoff_hz",
                });
            }
        }
        Ok(TeleopChannel {
            config,
            mapping: WorkspaceMapping::new(config.mapping)?,
            started: false,
            pending_anchor: None,
            latest: None,
            mapped: None,
            local_master: None,
            estimator: VelocityEstimator::new(),
            stats: ChannelStats::default(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &ChannelConfig {
        &self.config
    }

    /// The workspace mapping (anchors, clutch state, force scale).
    pub fn mapping(&self) -> &WorkspaceMapping {
        &self.mapping
    }

    /// The workspace mapping, to anchor it explicitly.
    pub fn mapping_mut(&mut self) -> &mut WorkspaceMapping {
        &mut self.mapping
    }

    /// Takes a sample from the other side if it is newer than the latest one (newest wins).
    ///
    /// # Errors
    /// [`ReceiveError`]; the sample is then dropped and the channel unchanged but for its
    /// [`stats`](Self::stats).
    pub fn receive(&mut self, sample: TeleopSample) -> Result<(), ReceiveError> {
        if !sample.reference.is_finite() {
            self.stats.rejected += 1;
            return Err(ReceiveError::NonFinite);
        }
        let wrench_frame = match &sample.reference {
            Reference::Wrench(w) => Some(w.frame),
            Reference::Hybrid(h) => Some(h.wrench.frame),
            _ => None,
        };
        if matches!(wrench_frame, Some(f) if !matches!(f, Frame::Base | Frame::Master)) {
            self.stats.rejected += 1;
            return Err(ReceiveError::UnsupportedFrame);
        }
        if self.latest.is_some_and(|l| sample.sequence <= l.sequence) {
            self.stats.stale += 1;
            return Err(ReceiveError::Stale);
        }
        if let (Some(p), VelocityFeedForward::Estimate { cutoff_hz }) =
            (position_of(&sample.reference), self.config.velocity)
        {
            self.estimator
                .update(sample.sent, p, cutoff_hz, self.config.max_velocity_gap);
        }
        self.latest = Some(sample);
        self.stats.accepted += 1;
        self.anchor_if_pending();
        self.map_latest();
        Ok(())
    }

    /// Anchors the mapping once both the local pose (from `start`) and a remote pose are known.
    fn anchor_if_pending(&mut self) {
        let (Some(local), Some(remote)) = (
            self.pending_anchor,
            self.latest.as_ref().and_then(|s| pose_of(&s.reference)),
        ) else {
            return;
        };
        match self.config.direction {
            ChannelDirection::MasterToSlave => self.mapping.anchor(&remote.pose, &local),
            ChannelDirection::SlaveToMaster => self.mapping.anchor(&local, &remote.pose),
        }
        self.pending_anchor = None;
    }

    /// MasterToSlave: runs the clutch-aware mapping on the latest sample.
    fn map_latest(&mut self) {
        if self.config.direction != ChannelDirection::MasterToSlave {
            return;
        }
        let Some(s) = self.latest else { return };
        if let Some(c) = pose_of(&s.reference) {
            self.mapped = self.mapping.update(s.sent, &c.pose, s.clutch).ok();
        }
    }

    /// On the master (`SlaveToMaster`): the master's own tool pose and clutch button, each
    /// communication period, before sending the same pose and state to the slave. Drives the
    /// force fade and keeps the inverse mapping's anchors in step with the slave's. Ignored by a
    /// `MasterToSlave` channel (its clutch comes in the samples).
    pub fn track_master(&mut self, now: Timestamp, master: &Pose, clutch: bool) {
        if self.config.direction != ChannelDirection::SlaveToMaster {
            return;
        }
        self.local_master = Some(*master);
        if self.pending_anchor.is_some() {
            self.pending_anchor = Some(*master);
        }
        // Tracks the clutch and the fade even before anchoring; the pose itself is not needed.
        let _ = self.mapping.update(now, master, clutch);
    }

    /// The latest sample taken, as received.
    pub fn latest(&self) -> Option<&TeleopSample> {
        self.latest.as_ref()
    }

    /// The sequence number of the latest sample taken.
    pub fn latest_sequence(&self) -> Option<u64> {
        self.latest.map(|s| s.sequence)
    }

    /// How old the latest sample is at `now` (`now - sent`, zero if `sent` is in the future);
    /// `None` before the first sample.
    pub fn age(&self, now: Timestamp) -> Option<Duration> {
        self.latest.map(|s| now.saturating_since(s.sent))
    }

    /// Counters of taken and refused samples.
    pub fn stats(&self) -> ChannelStats {
        self.stats
    }

    /// The current velocity estimate of the raw stream (`[v; omega]` in the sender's base frame,
    /// or joint velocities).
    pub fn estimated_velocity(&self) -> Vector6<f64> {
        self.estimator.velocity
    }

    /// Forgets everything received (a new session: sequence numbers may restart) and the anchors.
    pub fn reset(&mut self) {
        self.latest = None;
        self.mapped = None;
        self.local_master = None;
        self.pending_anchor = None;
        self.started = false;
        self.estimator = VelocityEstimator::new();
        self.mapping.reset();
    }

    /// The raw velocity of the latest sample per the configured source.
    fn raw_velocity(&self, sample: &TeleopSample) -> Vector6<f64> {
        match self.config.velocity {
            VelocityFeedForward::Estimate { .. } => self.estimator.velocity,
            VelocityFeedForward::Zero => Vector6::zeros(),
            VelocityFeedForward::FromSample => match &sample.reference {
                Reference::Joint(j) => j.velocity,
                Reference::Cartesian(c) => c.twist.to_vector(),
                Reference::Hybrid(h) => h.motion.twist.to_vector(),
                Reference::Wrench(_) => Vector6::zeros(),
            },
        }
    }

    fn joint_out(&self, sample: &TeleopSample, j: &JointReference) -> Reference {
        Reference::Joint(JointReference {
            position: j.position,
            velocity: self.raw_velocity(sample),
            acceleration: match self.config.velocity {
                VelocityFeedForward::FromSample => j.acceleration,
                _ => JointVector::zeros(),
            },
        })
    }

    /// The mapped motion part at `now`.
    fn motion_out(
        &self,
        now: Timestamp,
        sample: &TeleopSample,
        c: &CartesianReference,
    ) -> Result<CartesianReference, TrajectoryError> {
        let raw_v = self.raw_velocity(sample);
        let raw_twist = Twist {
            linear: top(&raw_v),
            angular: bottom(&raw_v),
            frame: Frame::Base,
        };
        match self.config.direction {
            ChannelDirection::MasterToSlave => {
                let pose = self.mapped.ok_or(TrajectoryError::NotStarted)?;
                let twist = if self.mapping.is_clutched() {
                    Twist::default()
                } else {
                    self.mapping.twist_to_slave(&raw_twist)
                };
                Ok(CartesianReference { pose, twist })
            }
            ChannelDirection::SlaveToMaster => {
                let pose = self
                    .mapping
                    .slave_to_master(&c.pose)
                    .map_err(|_| TrajectoryError::NotStarted)?;
                let twist = self.mapping.twist_to_master(&raw_twist);
                // While the clutch fades the feedback, blend toward the master's own pose so a
                // position-error master's spring fades too.
                let k = self.mapping.force_scale(now);
                match self.local_master {
                    Some(m) if k < 1.0 => Ok(CartesianReference {
                        pose: blend(&m, &pose, k),
                        twist: Twist {
                            linear: twist.linear * k,
                            angular: twist.angular * k,
                            frame: Frame::Base,
                        },
                    }),
                    _ => Ok(CartesianReference { pose, twist }),
                }
            }
        }
    }

    fn wrench_out(&self, now: Timestamp, w: &Wrench) -> Wrench {
        match self.config.direction {
            ChannelDirection::MasterToSlave => self.mapping.wrench_to_slave(w),
            ChannelDirection::SlaveToMaster => {
                let k = self.mapping.force_scale(now);
                let m = self.mapping.wrench_to_master(w);
                Wrench {
                    force: m.force * k,
                    torque: m.torque * k,
                    frame: Frame::Base,
                }
            }
        }
    }
}

/// `a` moved toward `b` by `k` (0 = `a`, 1 = `b`): positions linearly, orientations by slerp.
fn blend(a: &Pose, b: &Pose, k: f64) -> Pose {
    let p: Vector3<f64> = a.translation.vector + (b.translation.vector - a.translation.vector) * k;
    let delta = (b.rotation * a.rotation.inverse()).scaled_axis() * k;
    Pose::from_parts(
        p.into(),
        UnitQuaternion::from_scaled_axis(delta) * a.rotation,
    )
}

impl Trajectory for TeleopChannel {
    fn kind(&self) -> &'static str {
        "teleop"
    }

    /// Starts with the local robot's reference: its tool pose anchors the mapping (see the type
    /// docs). A joint or wrench `from` starts the channel without anchoring (joint and wrench
    /// samples need no anchors; pose samples then answer `NotStarted` until
    /// [`WorkspaceMapping::anchor`] is called).
    fn start(&mut self, _now: Timestamp, from: &Reference) {
        self.started = true;
        let local = if from.is_finite() {
            pose_of(from).map(|c| c.pose)
        } else {
            None
        };
        if let Some(local) = local {
            self.pending_anchor = Some(local);
            if self.config.direction == ChannelDirection::SlaveToMaster {
                self.local_master = Some(local);
            }
            self.anchor_if_pending();
            self.map_latest();
        }
    }

    fn reference(&mut self, now: Timestamp) -> Result<Reference, TrajectoryError> {
        if !self.started {
            return Err(TrajectoryError::NotStarted);
        }
        let sample = self.latest.ok_or(TrajectoryError::NoData)?;
        Ok(match &sample.reference {
            Reference::Joint(j) => self.joint_out(&sample, j),
            Reference::Cartesian(c) => Reference::Cartesian(self.motion_out(now, &sample, c)?),
            Reference::Wrench(w) => Reference::Wrench(self.wrench_out(now, w)),
            Reference::Hybrid(h) => Reference::Hybrid(HybridReference {
                motion: self.motion_out(now, &sample, &h.motion)?,
                wrench: self.wrench_out(now, &h.wrench),
                force_axes: h.force_axes,
            }),
        })
    }

    fn is_finished(&self, _now: Timestamp) -> bool {
        false
    }
}
