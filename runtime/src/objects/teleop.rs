//! Teleoperation as objects: the channel between a master and a slave (`trajectory/teleop`,
//! the paper's Trajectory object that links the two sides), and the communication-thread end
//! each side runs. (The operator's hand that holds a simulated master, `sensor/operator-hand`,
//! is in [`operator_hand`](super::operator_hand).)
//!
//! ```text
//!  master comm: pose + clutch ──master_to_slave cell──> slave comm: TeleopChannel (MasterToSlave)
//!  master comm: TeleopChannel (SlaveToMaster) <──slave_to_master cell── slave comm: pose + wrench
//! ```
//!
//! One channel object holds both directions; a controller on its master robot takes the master
//! end, a controller on its slave robot the slave end. Each end is a pair of lock-free latest-
//! value cells (newest wins, as on the UDP data plane between nodes); the communication thread
//! that holds it gives it back when its loop stops, so the channel can be used again.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use nalgebra::UnitQuaternion;
use penelope_hal::{
    CartesianReference, Frame, HybridReference, Kinematics, Pose, Reference, Timestamp, Twist,
    Wrench,
};
use penelope_rt_core::cell::Stamped;
use penelope_rt_core::safety::{EventSet, SafetyEvent};
use penelope_rt_core::telemetry::TelemetrySample;
use penelope_rt_core::teleop::{
    ChannelConfig, ChannelDirection, MappingConfig, PortPayload, TeleopChannel, TeleopSample,
};
use serde::{Deserialize, Serialize};

use super::kinematics::RobotKinematics;
use super::reference::ReferenceOut;
use super::teleop_passivity::{PortLaw, TwoPortEnd};
use super::teleop_wave::WaveEnd;
use crate::objects::error::ObjectError;

/// `trajectory/teleop` configuration.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct TeleopConfig {
    /// The master robot (a name on this node; with `zenoh_reference`, the station's name).
    pub master: String,
    /// The slave robot.
    pub slave: String,
    /// Slave motion = scale x master motion, 1e-3..=1e3.
    pub scale: f64,
    /// Displayed force = force_gain x mapped sensor force, 0..=1e3.
    pub force_gain: f64,
    /// Displayed moment = torque_gain x mapped sensor moment, 0..=1e3.
    pub torque_gain: f64,
    /// Master base frame -> slave base frame, roll, pitch, yaw, degrees.
    pub rotation_rpy_deg: [f64; 3],
    /// When the master and the slave are on different nodes, the same channel is created on
    /// both, each node holding the end of its own robot; samples cross on the data plane (UDP,
    /// one stream per direction, newest wins; authenticated when the nodes have a secret,
    /// required off loopback): this node's address for the channel, host:port (with `peer`).
    pub listen: Option<String>,
    /// The other node's data-plane address for the channel (with `listen`).
    pub peer: Option<String>,
    /// Faults injected (tests and experiments): on another node's channel, into what this end
    /// sends; with both ends on this node, into each direction through a seeded delay line,
    /// samples arriving delay + U(0, jitter) later (to within one T_com), some lost; the same
    /// draws on the simulated clock for the same fault_seed. One-way values: the round trip is
    /// twice delay_ms.
    pub faults: Option<crate::dataplane::faults::FaultConfig>,
    /// The seed of the injected faults (both directions draw from it).
    pub fault_seed: u64,
    /// Silence before the link to another node counts as lost and the robot goes neutral
    /// (slave holds, master no force), ms, 0..=10000 (0: two T_com). Above the link's jitter:
    /// each loss re-anchors the motion.
    pub link_timeout_ms: u64,
    /// When the master is an operator station that speaks Zenoh (docs/zenoh.md; the node runs
    /// a Zenoh bridge, `penelope node --zenoh ENDPOINT`): the key its poses come from; the
    /// slave is a robot here. Not with `listen`, `peer` or `faults`.
    pub zenoh_reference: Option<String>,
    /// When a sample crosses: `event` (each control tick's new sample is sent at once and
    /// handed to the other side's loop as it arrives; the communication period is then only
    /// the floor when nothing is new), or `periodic` (the paper's decoupled mode: samples
    /// leave and are handed on at the communication period `T_com`). A wave-variable law's
    /// transform steps once per period either way.
    pub handoff: Handoff,
}

/// When a teleoperation channel's samples cross ([`TeleopConfig::handoff`]).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize, schemars::JsonSchema,
)]
#[serde(rename_all = "lowercase")]
pub enum Handoff {
    /// As they are made: the control tick's new sample wakes the communication thread, which
    /// sends it at once (at most one send per control tick); the receiving thread hands it to
    /// its loop at once. The period is the floor when nothing is new.
    #[default]
    Event,
    /// At the communication period (`T_com`), as in the paper's decoupled threads.
    Periodic,
}

impl Default for TeleopConfig {
    fn default() -> Self {
        TeleopConfig {
            master: String::new(),
            slave: String::new(),
            scale: 1.0,
            force_gain: 0.5,
            torque_gain: 0.5,
            rotation_rpy_deg: [0.0; 3],
            listen: None,
            peer: None,
            faults: None,
            fault_seed: 1,
            link_timeout_ms: 0,
            zenoh_reference: None,
            handoff: Handoff::Event,
        }
    }
}

impl crate::objects::config::KindConfig for TeleopConfig {
    fn example() -> Self {
        TeleopConfig {
            master: "frhc".into(),
            slave: "puma".into(),
            listen: Some("127.0.0.1:7410".into()),
            peer: Some("127.0.0.1:7411".into()),
            faults: Some(crate::dataplane::faults::FaultConfig {
                delay_ms: 50.0,
                jitter_ms: 5.0,
                loss: 0.01,
                outages: vec![crate::dataplane::faults::OutageWindow {
                    from_s: 10.0,
                    to_s: 12.0,
                }],
                ..Default::default()
            }),
            zenoh_reference: Some("station/hand/pose".into()),
            ..Self::default()
        }
    }
}

impl TeleopConfig {
    /// Checks the keys.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<(), ObjectError> {
        let bad = |message: String| ObjectError::BadConfig {
            kind: kind.into(),
            message,
        };
        if self.master.is_empty() || self.slave.is_empty() {
            return Err(bad("needs `master` and `slave` (robot names)".into()));
        }
        if self.master == self.slave {
            return Err(bad("`master` and `slave` are the same robot".into()));
        }
        for (key, v, lo, hi) in [
            ("scale", self.scale, 1e-3, 1e3),
            ("force_gain", self.force_gain, 0.0, 1e3),
            ("torque_gain", self.torque_gain, 0.0, 1e3),
        ] {
            if !(v.is_finite() && v >= lo && v <= hi) {
                return Err(bad(format!("`{key}` = {v} is outside {lo}..={hi}")));
            }
        }
        if self.rotation_rpy_deg.iter().any(|a| !a.is_finite()) {
            return Err(bad("`rotation_rpy_deg` must be finite".into()));
        }
        let plane = self.data_plane(kind)?;
        if let Some(key) = &self.zenoh_reference {
            crate::objects::bridged::check_key(key)
                .map_err(|why| bad(format!("`zenoh_reference` = {key:?}: {why}")))?;
            if plane.is_some() || self.faults.is_some() {
                return Err(bad(
                    "`zenoh_reference` takes the master's poses from Zenoh: leave out `listen`, \
                     `peer` and `faults`"
                        .into(),
                ));
            }
        }
        if self.link_timeout_ms > 10_000 {
            return Err(bad(format!(
                "`link_timeout_ms` = {} is outside 0..=10000",
                self.link_timeout_ms
            )));
        }
        if let Some(f) = &self.faults {
            f.validate().map_err(|e| bad(format!("`faults`: {e}")))?;
            // On one node both ends read one clock: there is no other clock to be off.
            if plane.is_none() && f.clock_offset_us != 0.0 {
                return Err(bad(
                    "`faults.clock_offset_us` offsets the clock of an end on another node: \
                     it needs `listen` and `peer`"
                        .into(),
                ));
            }
        }
        Ok(())
    }

    /// The data-plane addresses `(listen, peer)` of a channel that crosses to another node, or
    /// `None` for a channel on this node.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`] for only one of the two, or an address that does not parse.
    pub fn data_plane(
        &self,
        kind: &str,
    ) -> Result<Option<(std::net::SocketAddr, std::net::SocketAddr)>, ObjectError> {
        let bad = |message: String| ObjectError::BadConfig {
            kind: kind.into(),
            message,
        };
        let parse = |key: &str, v: &str| {
            v.parse::<std::net::SocketAddr>()
                .map_err(|e| bad(format!("`{key}` = {v:?}: {e} (host:port, an IP address)")))
        };
        match (&self.listen, &self.peer) {
            (None, None) => Ok(None),
            (Some(l), Some(p)) => Ok(Some((parse("listen", l)?, parse("peer", p)?))),
            _ => Err(bad(
                "`listen` and `peer` go together (a channel to another node)".into(),
            )),
        }
    }

    /// How long the link may be silent before it counts as lost, for a communication period
    /// `comm_period`.
    pub fn link_timeout(&self, comm_period: Duration) -> Duration {
        match self.link_timeout_ms {
            0 => comm_period * 2,
            ms => Duration::from_millis(ms),
        }
    }

    /// The workspace mapping.
    pub fn mapping(&self) -> MappingConfig {
        let [r, p, y] = self.rotation_rpy_deg.map(f64::to_radians);
        MappingConfig {
            scale: self.scale,
            rotation: UnitQuaternion::from_euler_angles(r, p, y),
            force_gain: self.force_gain,
            torque_gain: self.torque_gain,
            // A node's sensors report the world pushing on the robot (`sensor/virtual`), which
            // is what the operator should feel: no sign change.
            negate_wrench: false,
            ..MappingConfig::default()
        }
    }
}

pub use super::teleop_end::{Side, TeleopEnd, TeleopLink};

/// The communication-thread end of one side: publishes this robot's state to the other side,
/// feeds the other side's samples into this side's [`TeleopChannel`], and the channel's
/// reference into the loop's reference cell.
pub struct TeleopComm {
    end: TeleopEnd,
    channel: TeleopChannel,
    model: RobotKinematics,
    /// The clutch button of the operator's hand on this (master) robot, if one holds it.
    clutch: Option<Arc<AtomicBool>>,
    /// The mount of a wrist sensor in the loop (its readings are in the sensor frame).
    sensor_mount: Option<Pose>,
    started: bool,
    sequence: u64,
    /// When the newest sample of the other side arrived (this node's clock): the stamp of the
    /// references, so that a silent other side makes them stale and the loop's watchdog acts.
    received_at: Option<Timestamp>,
    /// For an end linked to another node: how long the other side may be silent before the
    /// link counts as lost and this robot goes neutral (a slave holds, a master displays no
    /// force) without waiting for the loop's watchdog.
    link_timeout: Option<Duration>,
    /// While the link is lost: the pose this robot had when it was (a slave holds it); neutral
    /// references until the other side is heard again.
    /// Since the slave's loop latched a fault or an e-stop, until it runs again: the channel
    /// restarts from the slave's pose every tick.
    reanchoring: bool,
    lost_at: Option<Pose>,
    /// The wave-variable transform, when the law is a wave half (`controller/wave-*`).
    wave: Option<WaveEnd>,
    /// The two-port passivity observer (and controller), when the law is a force-position half.
    two_port: Option<TwoPortEnd>,
    /// A master's end sends the operator's wrench beside its pose ([`Self::with_hand_wrench`]).
    hand_wrench: bool,
    /// The loop's safety events when this end last sent: a sample whose loop shows one more
    /// is urgent ([`TeleopSample::urgent`]).
    events_sent: EventSet,
    /// A sample of the other side read on an early wake but not urgent: handed to the
    /// channel at the next tick, as if read then.
    pending: Option<TeleopSample>,
    /// Samples cross as they are made ([`Handoff::Event`]; not for a wave end).
    event_driven: bool,
    /// The time of the loop's sample this end last sent: a sample is sent once at most.
    sent_sample: Option<Timestamp>,
    /// When the last sample went out: a periodic tick sends when nothing went out for a
    /// control period (the floor while the loop is silent).
    sent_at: Option<Timestamp>,
    /// The loop's control period.
    control_period: Duration,
    /// Control ticks in one communication period (the early-wake cap scales with them).
    ticks_per_period: u32,
    /// When the channel's reference was last handed to the loop: a two-port controller steps
    /// with the time since, so a second hand-on at the same instant (possible only on the
    /// simulated clock) waits for the next wake rather than step it by zero.
    handed_at: Option<Timestamp>,
}

impl TeleopComm {
    /// The end `end` with the channel's `mapping`, for a robot computed with `model`.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`] for a mapping the channel refuses.
    pub fn new(
        end: TeleopEnd,
        mapping: MappingConfig,
        model: RobotKinematics,
    ) -> Result<Self, ObjectError> {
        let direction = match end.side {
            Side::Master => ChannelDirection::SlaveToMaster,
            Side::Slave => ChannelDirection::MasterToSlave,
        };
        let channel = TeleopChannel::new(ChannelConfig {
            direction,
            mapping,
            ..ChannelConfig::default()
        })
        .map_err(|e| ObjectError::BadConfig {
            kind: "trajectory/teleop".into(),
            message: format!("{e:?}"),
        })?;
        Ok(TeleopComm {
            sequence: end.sent(),
            end,
            channel,
            model,
            clutch: None,
            sensor_mount: None,
            started: false,
            received_at: None,
            link_timeout: None,
            lost_at: None,
            reanchoring: false,
            wave: None,
            two_port: None,
            hand_wrench: false,
            events_sent: EventSet::EMPTY,
            pending: None,
            event_driven: false,
            sent_sample: None,
            sent_at: None,
            control_period: Duration::ZERO,
            ticks_per_period: 1,
            handed_at: None,
        })
    }

    /// Makes samples cross as `handoff` says, for a loop ticking every `control_period` and a
    /// communication thread every `comm_period`. Event-driven handoff rings the other end's doorbell with every
    /// sample on cells, and takes [`MAX_EARLY_WAKES`](penelope_rt_core::wake::MAX_EARLY_WAKES)
    /// early wakes per control tick. A wave-variable end stays periodic: its transform steps
    /// once per communication period (call this after [`with_port_law`](Self::with_port_law)).
    pub fn with_handoff(
        mut self,
        handoff: Handoff,
        control_period: Duration,
        comm_period: Duration,
    ) -> Self {
        self.event_driven = handoff == Handoff::Event && self.wave.is_none();
        let ticks = comm_period
            .as_nanos()
            .div_ceil(control_period.as_nanos().max(1));
        self.ticks_per_period = u32::try_from(ticks.max(1)).unwrap_or(u32::MAX);
        self.control_period = control_period;
        self.end.wake_peer_with_every_sample(self.event_driven);
        self
    }

    /// Whether samples cross as they are made ([`Handoff::Event`]).
    pub fn is_event_driven(&self) -> bool {
        self.event_driven
    }

    /// The side of the channel this end runs.
    pub fn side(&self) -> Side {
        self.end.side
    }

    /// Samples this end has sent so far (its sequence number).
    pub fn samples_sent(&self) -> u64 {
        self.sequence
    }

    /// Runs what the law's half needs in this end: the wave-variable transform (a
    /// `controller/wave-*` half), or the two-port passivity observer and controller (a
    /// force-position half).
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`] for settings the transform or the controller refuses. An end
    /// linked to another node is fine: the data plane's sample carries the wave and the energy
    /// counters.
    pub fn with_port_law(
        mut self,
        law: PortLaw,
        mapping: &MappingConfig,
    ) -> Result<Self, ObjectError> {
        match law {
            PortLaw::Plain => {}
            PortLaw::Wave(config) => {
                self.wave = Some(WaveEnd::new(self.end.side, config, mapping)?);
            }
            PortLaw::TwoPort(config) => {
                self.two_port = Some(TwoPortEnd::new(self.end.side, config, mapping)?);
            }
            PortLaw::Observer => {
                self.two_port = Some(TwoPortEnd::observer(self.end.side, mapping)?);
            }
        }
        Ok(self)
    }

    /// Reads the master's clutch button from `clutch` (an operator's hand), if any.
    pub fn with_clutch(mut self, clutch: Option<Arc<AtomicBool>>) -> Self {
        self.clutch = clutch;
        self
    }

    /// Makes the master's end send the operator's wrench on the handle (its loop's sensor,
    /// turned into the base frame at the tool) beside its pose, as a `Reference::Hybrid`: what
    /// a four-channel slave's `C_3` adds. Without a handle sensor the master sends its pose
    /// alone.
    pub fn with_hand_wrench(mut self, send: bool) -> Self {
        self.hand_wrench = send && self.end.side == Side::Master;
        self
    }

    /// Tells the slave's end that its loop reads a wrist sensor mounted at `mount` in the tool
    /// frame (readings in the sensor frame, the robot pushing on the world).
    pub fn with_sensor_mount(mut self, mount: Option<Pose>) -> Self {
        self.sensor_mount = mount;
        self
    }

    /// Goes neutral when an end linked to another node hears nothing for `timeout` (ends on
    /// cells ignore it).
    pub fn with_link_timeout(mut self, timeout: Duration) -> Self {
        self.link_timeout = self.end.is_remote().then_some(timeout);
        self
    }

    /// Starts (or starts again) the channel from this robot's tool pose `pose`.
    fn start_channel(&mut self, now: Timestamp, pose: &Pose) {
        penelope_hal::Trajectory::start(
            &mut self.channel,
            now,
            &Reference::Cartesian(CartesianReference {
                pose: *pose,
                twist: Twist::default(),
            }),
        );
    }

    /// What wakes the communication thread of this end before its period
    /// ([`TeleopEnd::wake_on`]).
    ///
    /// # Errors
    /// The OS's, when the socket's descriptor cannot be duplicated.
    pub fn wake_on(&self) -> std::io::Result<Option<penelope_rt_core::wake::WakeOn>> {
        let wake = self.end.wake_on()?;
        Ok(match wake {
            Some(w) if self.event_driven => Some(w.per_period(self.ticks_per_period)),
            other => other,
        })
    }

    /// The end, given back when the loop stops.
    pub fn into_end(mut self) -> TeleopEnd {
        self.end.set_sent(self.sequence);
        self.end
    }

    /// The channel's counters (accepted, stale, rejected samples).
    pub fn channel(&self) -> &TeleopChannel {
        &self.channel
    }

    /// The world's wrench on the robot in `sample`, base frame, about the tool point (what the
    /// channel carries). A feed's is that already; a wrist sensor's is in its own frame with
    /// the opposite sign; a tool-frame wrench is rotated.
    fn contact(&self, sample: &TelemetrySample, pose: &Pose) -> Wrench {
        let w = sample.wrench;
        match (w.frame, self.sensor_mount) {
            (Frame::Base, _) => w,
            (Frame::Sensor, Some(mount)) => {
                let at_tool = sensor_to_base(&w, &mount, pose);
                Wrench {
                    force: -at_tool.force,
                    torque: -at_tool.torque,
                    frame: Frame::Base,
                }
            }
            _ => Wrench {
                force: pose.rotation * w.force,
                torque: pose.rotation * w.torque,
                frame: Frame::Base,
            },
        }
    }

    /// One wave-variable tick: receive the other side's wave, run this side's transform, send
    /// its wave with this robot's pose (and wrench), publish the transform's reference. Stamped
    /// now: the transform itself handles a silent other side passively (a master feels the
    /// damping `b`, a slave holds).
    fn wave_tick(
        &mut self,
        now: Timestamp,
        sample: &TelemetrySample,
        pose: &Pose,
        out: &mut ReferenceOut,
    ) {
        let mut restored = false;
        if let Some(received) = self.take_received(now) {
            if self.lost_at.take().is_some() {
                // Heard again: the line starts afresh from where this robot is (the slave's
                // pose, the master's position), as at the law's start, so nothing jumps.
                restored = self.end.note_link(false);
                if let Some(wave) = self.wave.as_mut() {
                    wave.restart();
                }
            }
            if let (Some(w), Some(wave)) = (received.port.wave, self.wave.as_mut()) {
                wave.receive(received.sequence, &w);
                if let Reference::Cartesian(m) = &received.reference {
                    wave.hear_master(&m.pose.translation.vector);
                }
            }
            self.received_at = Some(now);
        }
        let clutch = self
            .clutch
            .as_ref()
            .is_some_and(|c| c.load(Ordering::Relaxed));
        let contact = self.contact(sample, pose);
        let urgent = self.note_events(sample.events);
        let Some(wave) = self.wave.as_mut() else {
            return;
        };
        let at = |pose: &Pose| CartesianReference {
            pose: *pose,
            twist: Twist::default(),
        };
        let (reference, sent, clutch, own) = match self.end.side {
            Side::Master => {
                let (r, w) = wave.master_tick(now, &self.model, sample, clutch);
                let mut sent = *pose;
                sent.translation.vector =
                    wave.indexed_master_position(&pose.translation.vector, clutch);
                (r, w, clutch, Reference::Cartesian(at(&sent)))
            }
            Side::Slave => {
                let (r, w) = wave.slave_tick(now, pose, &contact);
                let own = Reference::Hybrid(HybridReference {
                    motion: at(pose),
                    wrench: contact,
                    force_axes: [true; 6],
                });
                (r, w, false, own)
            }
        };
        self.sequence += 1;
        self.end.publish(TeleopSample {
            clutch,
            port: PortPayload {
                wave: Some(sent),
                energy: None,
            },
            urgent,
            ..TeleopSample::new(self.sequence, now, own)
        });
        out.set_channel_energy(wave.channel_energy());
        // Lost as the other laws' links are (silent for the link timeout): neutral and fresh,
        // the slave holding where it was, the master displaying no force; raised once.
        if let (Some(timeout), Some(at)) = (self.link_timeout, self.received_at)
            && now.saturating_since(at) >= timeout
        {
            let held = *self.lost_at.get_or_insert(*pose);
            let lost = self.end.note_link(true);
            out.write(Stamped {
                stamp: now,
                value: neutral(self.end.side, &held, pose),
            });
            if lost {
                out.raise(SafetyEvent::LinkLost);
            }
            self.end.publish_stats();
            return;
        }
        // Stamped with the arrival of the newest wave, so the loop's watchdog sees a silent
        // other side; before the first one the transform runs on its missing-wave policy (the
        // line starts at rest), fresh.
        if reference.is_finite() {
            out.write(Stamped {
                stamp: self.received_at.unwrap_or(now),
                value: reference,
            });
            if restored {
                out.raise(SafetyEvent::LinkRestored);
            }
        }
        self.end.publish_stats();
    }

    /// Sends this robot's sample (a master its pose and clutch, a slave its pose and contact
    /// wrench), urgent when its loop shows a safety event the last one sent did not; returns
    /// the contact wrench (zero on a master).
    ///
    /// # Real-time
    /// Kinematics and the end's bounded send; no allocation.
    fn send_own(&mut self, now: Timestamp, sample: &TelemetrySample, pose: &Pose) -> Wrench {
        self.sequence += 1;
        self.sent_sample = Some(sample.time);
        self.sent_at = Some(now);
        let contact = match self.end.side {
            Side::Master => Wrench::default(),
            Side::Slave => self.contact(sample, pose),
        };
        let (clutch, reference) = match self.end.side {
            Side::Master => {
                let clutch = self
                    .clutch
                    .as_ref()
                    .is_some_and(|c| c.load(Ordering::Relaxed));
                self.channel.track_master(now, pose, clutch);
                let motion = CartesianReference {
                    pose: *pose,
                    twist: Twist::default(),
                };
                let reference = if self.hand_wrench {
                    Reference::Hybrid(HybridReference {
                        motion,
                        wrench: self.contact(sample, pose),
                        // Information for the slave's C3, not a force-control request: every
                        // axis stays motion-controlled for a hybrid-aware slave.
                        force_axes: [false; 6],
                    })
                } else {
                    Reference::Cartesian(motion)
                };
                (clutch, reference)
            }
            Side::Slave => (
                false,
                Reference::Hybrid(HybridReference {
                    motion: CartesianReference {
                        pose: *pose,
                        twist: Twist::default(),
                    },
                    wrench: contact,
                    // A failed sensor's sample carries no wrench (no force axis): the master
                    // displays zero at once rather than fading out what the sensor last said.
                    force_axes: [!sample.events.contains(SafetyEvent::SensorError); 6],
                }),
            ),
        };
        let urgent = self.note_events(sample.events);
        self.end.publish(TeleopSample {
            clutch,
            port: PortPayload {
                wave: None,
                energy: self.two_port.as_ref().map(TwoPortEnd::counters),
            },
            urgent,
            ..TeleopSample::new(self.sequence, now, reference)
        });
        contact
    }

    /// Notes the loop's safety events at a send; `true` when one is new since the last send.
    fn note_events(&mut self, events: EventSet) -> bool {
        let new = events.gained_since(self.events_sent);
        self.events_sent = events;
        new
    }

    /// The other side's newest sample: what arrives now, else what an early wake left.
    fn take_received(&mut self, now: Timestamp) -> Option<TeleopSample> {
        let arrived = self.end.take_newest(now);
        let pending = self.pending.take();
        arrived.or(pending)
    }

    /// An early wake at `now` (a doorbell or the socket, between ticks): this robot's sample
    /// goes out at once if its loop shows a new safety event, and an urgent sample of the other
    /// side is handed to the loop at once, as a tick would (its reference written, a two-port
    /// observer integrating up to now). What else arrived waits for the tick. A wave-variable
    /// end does neither: its transform runs once per period.
    ///
    /// With event-driven handoff every new sample of the loop goes out (once: a sample already
    /// sent is not sent again, so sends never outnumber control ticks however often the thread
    /// wakes), and every sample of the other side is handed on at once.
    ///
    /// # Real-time
    /// As [`tick`](Self::tick).
    pub fn early(
        &mut self,
        now: Timestamp,
        state: Option<TelemetrySample>,
        out: &mut ReferenceOut,
    ) {
        let (Some(sample), true, None) = (state, self.started, self.wave.as_ref()) else {
            return;
        };
        let pose = self.model.forward(&sample.q);
        let fresh = self.sent_sample.is_none_or(|t| sample.time > t);
        if fresh && (self.event_driven || sample.events.gained_since(self.events_sent)) {
            self.send_own(now, &sample, &pose);
        }
        let Some(received) = self.take_received(now) else {
            return;
        };
        self.pending = Some(received);
        let later = self.handed_at.is_none_or(|t| now > t);
        if received.urgent || (self.event_driven && later) {
            let contact = match self.end.side {
                Side::Master => Wrench::default(),
                Side::Slave => self.contact(&sample, &pose),
            };
            self.hand_on(now, &sample, &pose, &contact, out);
        }
    }

    /// One communication tick at `now`, with the loop's newest sample `state`: send, receive,
    /// publish the reference into `out`.
    ///
    /// # Real-time
    /// No allocation, no locks: cell reads and writes, kinematics, the channel's bounded work.
    pub fn tick(&mut self, now: Timestamp, state: Option<TelemetrySample>, out: &mut ReferenceOut) {
        let Some(sample) = state else {
            return; // nothing measured yet: the channel starts from the measured pose
        };
        let pose = self.model.forward(&sample.q);
        if self.wave.is_some() {
            self.wave_tick(now, &sample, &pose, out);
            return;
        }
        if !self.started {
            self.start_channel(now, &pose);
            self.started = true;
        }
        self.reanchor_after_a_latch(now, &sample, &pose);
        // Event-driven, the sample went out when it was made: the tick sends only a sample not
        // yet sent, or, when nothing went out for a control period (the loop missed a tick),
        // the last one again: the floor that keeps the link heard while the loop is silent
        // (silence at most a communication and a control period, under the link's timeout of
        // two communication periods).
        let fresh = self.sent_sample.is_none_or(|t| sample.time > t);
        let quiet = self
            .sent_at
            .is_none_or(|t| now.saturating_since(t) > self.control_period);
        let contact = if !self.event_driven || fresh || quiet {
            self.send_own(now, &sample, &pose)
        } else {
            match self.end.side {
                Side::Master => Wrench::default(),
                Side::Slave => self.contact(&sample, &pose),
            }
        };
        self.hand_on(now, &sample, &pose, &contact, out);
    }

    /// A slave whose loop latched a fault or an e-stop lost the motion it was following: from
    /// then until its loop runs again (re-armed and activated: it holds where it is until a
    /// reference starts there), the channel restarts every tick from where the slave is, as
    /// when a link comes back, so the re-armed slave neither moves by itself nor jumps: it
    /// follows the master's motion from its own pose with the offset re-anchored.
    ///
    /// # Real-time
    /// Constant time: the channel's reset and start.
    fn reanchor_after_a_latch(&mut self, now: Timestamp, sample: &TelemetrySample, pose: &Pose) {
        use penelope_rt_core::safety::SafetyState;
        if self.end.side != Side::Slave {
            return;
        }
        match sample.state {
            SafetyState::Fault | SafetyState::EStop => self.reanchoring = true,
            SafetyState::Running => self.reanchoring = false,
            SafetyState::Inactive | SafetyState::Holding => {}
        }
        if self.reanchoring {
            self.channel.reset();
            self.start_channel(now, pose);
            if let Some(t) = self.two_port.as_mut() {
                t.restart_motion();
            }
        }
    }

    /// Takes what the other side sent (or what an early wake left) into the channel, goes
    /// neutral when the link is lost, and writes the channel's reference for the loop.
    fn hand_on(
        &mut self,
        now: Timestamp,
        sample: &TelemetrySample,
        pose: &Pose,
        contact: &Wrench,
        out: &mut ReferenceOut,
    ) {
        let received = self.take_received(now);
        self.handed_at = Some(now);
        let mut restored = false;
        if let Some(received) = received {
            if self.lost_at.take().is_some() {
                // Heard again: resume from where this robot is, re-anchored as after the
                // clutch, so nothing jumps.
                restored = self.end.note_link(false);
                self.channel.reset();
                self.start_channel(now, pose);
                if let Some(t) = self.two_port.as_mut() {
                    t.restart_motion();
                }
            }
            if let Some(t) = self.two_port.as_mut() {
                t.receive(received.port.energy.as_ref());
            }
            if self.channel.receive(received).is_ok() {
                // (A stale or malformed sample is counted by the channel and dropped.)
                self.received_at = Some(now);
            }
        }
        if let (Some(timeout), Some(at)) = (self.link_timeout, self.received_at)
            && now.saturating_since(at) >= timeout
        {
            let held = *self.lost_at.get_or_insert(*pose);
            let lost = self.end.note_link(true);
            self.end.publish_stats();
            // Neutral and fresh: the slave holds where it was, the master displays no force.
            out.write(Stamped {
                stamp: now,
                value: neutral(self.end.side, &held, pose),
            });
            // A safety event of the loop, raised after the reference it goes with.
            if lost {
                out.raise(SafetyEvent::LinkLost);
            }
            return;
        }
        // Stamped with the arrival of what it is made of: when the other side goes silent the
        // reference ages, and the loop holds (slave) or displays zero force (master).
        if let Some(stamp) = self.received_at
            && let Ok(r) = penelope_hal::Trajectory::reference(&mut self.channel, now)
            && r.is_finite()
        {
            let r = match self.two_port.as_mut() {
                Some(t) => {
                    let r = t.tick(now, r, &self.model, sample, contact);
                    if let Some(e) = t.energy() {
                        out.set_channel_energy(e);
                    }
                    r
                }
                None => r,
            };
            out.write(Stamped { stamp, value: r });
        }
        if restored {
            out.raise(SafetyEvent::LinkRestored);
        }
        self.end.publish_stats();
    }
}

/// What a side follows while its link is lost: the slave the pose it had when the link was
/// lost (it holds), the master its present pose and no wrench (a position-error master's
/// spring is slack, a force display shows nothing).
fn neutral(side: Side, held: &Pose, now: &Pose) -> Reference {
    let at = |pose: &Pose| CartesianReference {
        pose: *pose,
        twist: Twist::default(),
    };
    match side {
        Side::Slave => Reference::Cartesian(at(held)),
        Side::Master => Reference::Hybrid(HybridReference {
            motion: at(now),
            wrench: Wrench {
                frame: Frame::Base,
                ..Wrench::default()
            },
            force_axes: [true; 6],
        }),
    }
}

pub use penelope_rt_core::teleop::sensor_to_base;

pub use super::operator_hand::{HandConfig, HandObj};

pub use super::teleop_laws::{
    ForceDisplayToml, FourChannelSlaveToml, FourChannelToml, PositionErrorToml, SlaveTrackingToml,
};
