//! A simulated motion board in front of a [`RigidBodyPlant`].
//!
//! What a real board does to the signals, modelled: encoders quantise positions to whole counts
//! and velocities are differences of counts; the DAC saturates at its full scale and resolves
//! `2^bits` levels; the command written is held until the next write (sample-and-hold), while the
//! plant keeps moving; an optional on-board position loop servos `AxisCommand::Position` targets
//! at the plant's sub-step rate, as a motion controller's own servo loop does.
//!
//! The command-freshness watchdog, the rule of the Galil board's I/O thread: while
//! any axis is driven by effort with the amplifiers on, a command older than
//! [`SimBoardConfig::command_timeout`] on the plant's clock is a fault,
//! [`SimBoardError::CommandStale`]: from that instant every axis is off (zero torque, amplifiers
//! off) until [`Board::rearm`] or an explicit disable. The check is the board's own, made
//! whenever the plant is stepped, by the control thread or by anything else that steps it (the
//! supervisor's plant keeper steps it while the control thread is silent).

use penelope_hal::{
    AxisCommand, AxisState, Board, Error, ErrorKind, Frame, JointVector, MAX_AXES, RobotModel,
    Timestamp, Wrench,
};

use super::Interaction;
use super::plant::{PlantConfig, RigidBodyPlant};
use super::tap::{TapSample, TapWriter};

/// Settings of a [`SimBoard`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimBoardConfig {
    /// Encoder counts per radian of joint motion, per axis (gear ratio included).
    pub counts_per_radian: JointVector,
    /// DAC full scale per axis, expressed as joint torque, N·m: efforts beyond are clipped.
    pub effort_full_scale: JointVector,
    /// DAC resolution, bits (16 on most motion boards).
    pub dac_bits: u32,
    /// Proportional gain of the on-board position loop, N·m/rad.
    pub position_kp: JointVector,
    /// Derivative gain of the on-board position loop, N·m·s/rad.
    pub position_kd: JointVector,
    /// Corner of the first-order low-pass on the reported velocity (count differences), Hz; 0
    /// reports raw differences. Motion boards filter their velocity estimate the same way.
    pub velocity_cutoff_hz: f64,
    /// The command-freshness watchdog: with an axis driven by effort, no new command for this
    /// long (plant time) turns every axis off. `None` turns the check off.
    pub command_timeout: Option<core::time::Duration>,
    /// Power-off holding brakes: while the amplifiers are off every joint stands where it is
    /// (as most industrial arms' brakes hold them against gravity); without, an arm whose
    /// amplifiers are off falls.
    pub brake: bool,
}

/// The default [`SimBoardConfig::command_timeout`], the Galil board's
/// (`penelope_drivers::galil::DEFAULT_COMMAND_TIMEOUT`): 50 control periods at 1 kHz.
pub const DEFAULT_COMMAND_TIMEOUT: core::time::Duration = core::time::Duration::from_millis(50);

/// Invalid use of a simulated board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SimBoardError {
    /// A slice shorter than the axis count.
    WrongLength,
    /// A NaN or infinite effort.
    NonFinite,
    /// The command-freshness watchdog tripped: no new command while driving by effort for the
    /// command timeout; every axis is off until a re-arm or a disable.
    CommandStale,
}

impl Error for SimBoardError {
    fn kind(&self) -> ErrorKind {
        match self {
            SimBoardError::WrongLength => ErrorKind::InvalidInput,
            SimBoardError::NonFinite => ErrorKind::NonFinite,
            SimBoardError::CommandStale => ErrorKind::Timeout,
        }
    }
}

impl core::fmt::Display for SimBoardError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            SimBoardError::WrongLength => "slice shorter than the axis count",
            SimBoardError::NonFinite => "effort is NaN or infinite",
            SimBoardError::CommandStale => {
                "no fresh command while driving by effort: every axis off (command timeout)"
            }
        })
    }
}

/// A board driving a simulated robot, with the robot's surroundings acting on its tool.
pub struct SimBoard<M, I> {
    plant: RigidBodyPlant<M>,
    interaction: I,
    config: SimBoardConfig,
    held: [AxisCommand; MAX_AXES],
    enabled: bool,
    last_counts: [i64; MAX_AXES],
    velocity: [f64; MAX_AXES],
    last_read: Option<Timestamp>,
    tap: Option<TapWriter>,
    /// Plant time of the newest command written (or of the last re-arm).
    last_write: Timestamp,
    /// When the command-freshness watchdog tripped (plant time), until a re-arm or a disable.
    stale_at: Option<Timestamp>,
}

impl<M: RobotModel, I: Interaction> SimBoard<M, I> {
    /// A board whose axes are the joints of `model`, at rest at `q0` at time `start`, with
    /// `interaction` acting on the tool.
    pub fn new(
        model: M,
        plant: PlantConfig,
        config: SimBoardConfig,
        interaction: I,
        q0: JointVector,
        start: Timestamp,
    ) -> Self {
        let plant = RigidBodyPlant::new(model, plant, q0, start);
        let mut board = SimBoard {
            plant,
            interaction,
            config,
            held: [AxisCommand::Off; MAX_AXES],
            enabled: false,
            last_counts: [0; MAX_AXES],
            velocity: [0.0; MAX_AXES],
            last_read: None,
            tap: None,
            last_write: start,
            stale_at: None,
        };
        for j in 0..board.axis_count() {
            board.last_counts[j] = board.encoder(j);
        }
        board
    }

    /// Publishes the plant's true state to `tap` after every read (for a virtual sensor and for
    /// ground-truth telemetry).
    pub fn with_tap(mut self, tap: TapWriter) -> Self {
        self.tap = Some(tap);
        self
    }

    /// Replaces the tap (its old readers see no new samples): a board that outlives the loops
    /// that read it gets a fresh tap per loop, so readers never pile up.
    pub fn set_tap(&mut self, tap: TapWriter) {
        self.tap = Some(tap);
    }

    /// Whether the amplifiers are on (set by [`Board::set_enabled`]); off, the plant gets zero
    /// torque.
    pub fn is_enabled(&self) -> bool {
        self.enabled
    }

    /// The commands the board holds (the last written), one per axis.
    pub fn held_commands(&self) -> &[AxisCommand] {
        &self.held[..self.axis_count()]
    }

    /// The command-freshness watchdog's timeout, if it has one.
    pub fn command_timeout(&self) -> Option<core::time::Duration> {
        self.config.command_timeout
    }

    /// When the command-freshness watchdog tripped (plant time), if it did and has not been
    /// cleared by a re-arm or a disable.
    pub fn command_stale_since(&self) -> Option<Timestamp> {
        self.stale_at
    }

    /// Steps the plant to `now` with the held commands, the command-freshness watchdog
    /// included, without reading or writing: for whoever keeps a simulated world moving while
    /// its control thread is silent (the world does not stop with the host).
    ///
    /// # Real-time
    /// No allocation; as [`Board::read_axes`].
    pub fn step_to(&mut self, now: Timestamp) {
        self.advance(now);
    }

    /// The plant (ground truth).
    pub fn plant(&self) -> &RigidBodyPlant<M> {
        &self.plant
    }

    /// The interaction acting on the tool.
    pub fn interaction(&self) -> &I {
        &self.interaction
    }

    fn encoder(&self, axis: usize) -> i64 {
        let q = self.plant.snapshot().joints.position[axis];
        // Floor, as an incremental encoder counts whole lines passed.
        libm::floor(q * self.config.counts_per_radian[axis]) as i64
    }

    fn dac(&self, axis: usize, effort: f64) -> f64 {
        let full = self.config.effort_full_scale[axis];
        let clipped = effort.clamp(-full, full);
        let levels = (1u64 << self.config.dac_bits.min(52)) as f64;
        let step = 2.0 * full / levels;
        if step > 0.0 && step.is_finite() {
            libm::round(clipped / step) * step
        } else {
            clipped
        }
    }

    /// Integrates the plant to `now` with the held commands, then takes the state the tool's
    /// surroundings impose, if they do (a recorded hand).
    fn advance(&mut self, now: Timestamp) {
        if let Some(deadline) = self.stale_deadline()
            && now > deadline
        {
            // What really happened: the old torque until the deadline, then nothing.
            self.integrate(deadline);
            self.held = [AxisCommand::Off; MAX_AXES];
            self.enabled = false;
            self.stale_at = Some(deadline);
        }
        self.integrate(now);
        if let Some(state) = self.interaction.imposed_state(now) {
            self.plant.impose(&state);
        }
    }

    /// When the held commands go stale: amplifiers on, an axis driven by effort, a timeout set.
    fn stale_deadline(&self) -> Option<Timestamp> {
        let timeout = self.config.command_timeout?;
        let torque = self.enabled
            && self.held[..self.axis_count()]
                .iter()
                .any(|c| matches!(c, AxisCommand::Effort(_)));
        torque.then(|| self.last_write + timeout)
    }

    /// Integrates the plant to `now` with the held commands.
    fn integrate(&mut self, now: Timestamp) {
        let n = self.axis_count();
        if self.config.brake && !self.enabled {
            // The brakes hold: time passes, the joints stand.
            let q = self.plant.snapshot().joints.position;
            self.plant
                .advance_to(now, &JointVector::zeros(), &mut self.interaction);
            for (j, position) in q.iter().enumerate().take(n) {
                self.plant.hold_joint(j, *position);
            }
            return;
        }
        let needs_servo = self.enabled
            && self.held[..n]
                .iter()
                .any(|c| matches!(c, AxisCommand::Position(_)));
        if !needs_servo {
            let tau = self.held_efforts();
            self.plant.advance_to(now, &tau, &mut self.interaction);
            return;
        }
        // The on-board servo recomputes its torque every sub-step.
        while self.plant.snapshot().time < now {
            let step_end =
                (self.plant.snapshot().time + core::time::Duration::from_micros(200)).min(now);
            let mut tau = self.held_efforts();
            let state = self.plant.snapshot().joints;
            for j in 0..n {
                if let AxisCommand::Position(target) = self.held[j] {
                    let target_rad = target as f64 / self.config.counts_per_radian[j];
                    let effort = self.config.position_kp[j] * (target_rad - state.position[j])
                        - self.config.position_kd[j] * state.velocity[j];
                    tau[j] = self.dac(j, effort);
                }
            }
            self.plant.advance_to(step_end, &tau, &mut self.interaction);
        }
    }

    fn held_efforts(&self) -> JointVector {
        let mut tau = JointVector::zeros();
        if !self.enabled {
            return tau;
        }
        for j in 0..self.axis_count() {
            if let AxisCommand::Effort(e) = self.held[j] {
                tau[j] = self.dac(j, e);
            }
        }
        tau
    }

    fn publish(&mut self) {
        let Some(tap) = self.tap.as_mut() else { return };
        let snapshot = self.plant.snapshot();
        let pose = self.plant.model().forward(&snapshot.joints.position);
        let base = snapshot.interaction;
        let rotation_t = pose.rotation.inverse();
        let tool_wrench = Wrench {
            force: rotation_t * base.force,
            torque: rotation_t * base.torque,
            frame: Frame::Tool,
        };
        tap.publish(TapSample {
            time: snapshot.time,
            joints: snapshot.joints,
            tool_pose: pose,
            base_wrench: base,
            tool_wrench,
            kinetic_energy: snapshot.kinetic_energy,
            interaction_work: snapshot.interaction_work,
        });
    }
}

impl<M: RobotModel, I: Interaction> Board for SimBoard<M, I> {
    type Error = SimBoardError;

    fn axis_count(&self) -> usize {
        self.plant.model().joint_count().min(MAX_AXES)
    }

    /// # Real-time
    /// No allocation; integrates the plant up to `now` (time proportional to the elapsed time).
    fn read_axes(&mut self, now: Timestamp, out: &mut [AxisState]) -> Result<(), SimBoardError> {
        let n = self.axis_count();
        if out.len() < n {
            return Err(SimBoardError::WrongLength);
        }
        self.advance(now);
        if self.stale_at.is_some() {
            self.publish();
            return Err(SimBoardError::CommandStale);
        }
        let dt = self
            .last_read
            .map(|t| (now - t).as_secs_f64())
            .unwrap_or(0.0);
        let gain = if self.config.velocity_cutoff_hz > 0.0 && dt > 0.0 {
            let tau = 1.0 / (2.0 * core::f64::consts::PI * self.config.velocity_cutoff_hz);
            dt / (tau + dt)
        } else {
            1.0
        };
        for (j, axis) in out.iter_mut().enumerate().take(n) {
            let counts = self.encoder(j);
            if dt > 0.0 {
                let raw = (counts - self.last_counts[j]) as f64 / dt;
                self.velocity[j] += gain * (raw - self.velocity[j]);
            }
            let velocity = self.velocity[j];
            let effort = match self.held[j] {
                AxisCommand::Effort(e) if self.enabled => self.dac(j, e),
                _ => self.plant.snapshot().joints.effort[j],
            };
            let following_error = match self.held[j] {
                AxisCommand::Position(target) => target - counts,
                _ => 0,
            };
            *axis = AxisState {
                position: counts,
                velocity,
                effort,
                following_error,
                enabled: self.enabled,
            };
            self.last_counts[j] = counts;
        }
        self.last_read = Some(now);
        self.publish();
        Ok(())
    }

    /// # Real-time
    /// No allocation; integrates the plant up to `now` with the previous commands first.
    fn write_axes(
        &mut self,
        now: Timestamp,
        commands: &[AxisCommand],
    ) -> Result<(), SimBoardError> {
        let n = self.axis_count();
        if commands.len() < n {
            return Err(SimBoardError::WrongLength);
        }
        if commands[..n]
            .iter()
            .any(|c| matches!(c, AxisCommand::Effort(e) if !e.is_finite()))
        {
            return Err(SimBoardError::NonFinite);
        }
        self.advance(now);
        if self.stale_at.is_some() {
            return Err(SimBoardError::CommandStale);
        }
        self.held[..n].copy_from_slice(&commands[..n]);
        self.last_write = self.plant.snapshot().time.max(now);
        Ok(())
    }

    /// Turning the amplifiers off also clears a tripped command watchdog (nothing is driven
    /// any more); turning them on while it is tripped is refused.
    fn set_enabled(&mut self, enabled: bool) -> Result<(), SimBoardError> {
        if !enabled {
            self.stale_at = None;
        } else if self.stale_at.is_some() {
            return Err(SimBoardError::CommandStale);
        }
        self.enabled = enabled;
        self.last_write = self.plant.snapshot().time;
        Ok(())
    }

    /// Clears a tripped command watchdog: every axis stays off until the next command.
    fn rearm(&mut self) -> Result<(), SimBoardError> {
        self.stale_at = None;
        self.last_write = self.plant.snapshot().time;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::puma560;
    use crate::sim::FreeSpace;
    use crate::sim::plant::PlantConfig;
    use core::time::Duration;

    fn ms(k: u64) -> Timestamp {
        Timestamp::from_nanos(k * 1_000_000)
    }

    /// A board of 1000 counts/rad and 100 N·m full scale, with the given watchdog and brakes.
    fn config(command_timeout: Option<Duration>, brake: bool) -> SimBoardConfig {
        SimBoardConfig {
            counts_per_radian: JointVector::repeat(1000.0),
            effort_full_scale: JointVector::repeat(100.0),
            dac_bits: 16,
            position_kp: JointVector::repeat(100.0),
            position_kd: JointVector::repeat(1.0),
            velocity_cutoff_hz: 0.0,
            command_timeout,
            brake,
        }
    }

    #[test]
    fn a_stale_effort_command_turns_every_axis_off_at_the_timeout_on_the_plants_clock() {
        let config = config(Some(DEFAULT_COMMAND_TIMEOUT), false);
        let mut b = SimBoard::new(
            puma560(),
            PlantConfig::default(),
            config,
            FreeSpace,
            JointVector::zeros(),
            ms(0),
        );
        let mut out = [AxisState::default(); 6];
        b.set_enabled(true).unwrap();
        b.write_axes(ms(1), &[AxisCommand::Effort(3.0); 6]).unwrap();
        // Fresh enough up to the timeout.
        b.read_axes(ms(50), &mut out).unwrap();
        assert_eq!(out[0].effort, b.dac(0, 3.0));
        // One step past it: tripped at exactly the last command plus the timeout.
        assert_eq!(
            b.read_axes(ms(60), &mut out),
            Err(SimBoardError::CommandStale)
        );
        assert_eq!(b.command_stale_since(), Some(ms(51)));
        assert!(!b.is_enabled());
        assert!(b.held_commands().iter().all(|c| *c == AxisCommand::Off));
        assert_eq!(b.plant().snapshot().joints.effort, JointVector::zeros());
        // Refused until re-armed: no command, no re-enable.
        assert_eq!(
            b.write_axes(ms(61), &[AxisCommand::Effort(3.0); 6]),
            Err(SimBoardError::CommandStale)
        );
        assert_eq!(b.set_enabled(true), Err(SimBoardError::CommandStale));
        b.rearm().unwrap();
        b.set_enabled(true).unwrap();
        b.read_axes(ms(62), &mut out).unwrap();
        assert!(b.held_commands().iter().all(|c| *c == AxisCommand::Off));
        // Position targets alone never go stale (the board's servo holds them).
        b.write_axes(ms(63), &[AxisCommand::Position(0); 6])
            .unwrap();
        b.read_axes(ms(63) + Duration::from_secs(1), &mut out)
            .unwrap();
        assert_eq!(b.command_stale_since(), None);
    }

    #[test]
    fn brakes_hold_an_arm_whose_amplifiers_are_off_and_let_go_when_they_are_on() {
        let board = |brake| {
            let config = config(None, brake);
            let model = puma560();
            let q0 = model.named_pose(penelope_hal::NamedPose::Start);
            (
                SimBoard::new(model, PlantConfig::default(), config, FreeSpace, q0, ms(0)),
                q0,
            )
        };
        let mut out = [AxisState::default(); 6];
        // Under gravity, amplifiers off: without brakes the arm falls, with them it stands.
        let (mut free, q0) = board(false);
        free.read_axes(ms(500), &mut out).unwrap();
        let fell = (free.plant().snapshot().joints.position - q0).amax();
        assert!(fell > 0.05, "no gravity to hold against: {fell} rad");
        let (mut braked, q0) = board(true);
        braked.read_axes(ms(500), &mut out).unwrap();
        let snapshot = braked.plant().snapshot();
        assert_eq!(snapshot.joints.position, q0);
        assert_eq!(snapshot.joints.velocity, JointVector::zeros());
        assert_eq!(snapshot.time, ms(500));
        // Amplifiers on with no torque: the brakes release and gravity acts.
        braked.set_enabled(true).unwrap();
        braked.read_axes(ms(1000), &mut out).unwrap();
        assert!((braked.plant().snapshot().joints.position - q0).amax() > 0.05);
    }
}
