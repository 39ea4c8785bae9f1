//! A virtual operator: a hand, modelled as an impedance, that holds the master's handle and
//! follows a script of motions while feeling what the master displays.
//!
//! The hand's target moves along the script; the hand pushes on the handle with
//! `F = K (p_target - p) + B (v_target - v)` and holds the handle's orientation with a rotational
//! spring-damper. When the master's motors push back (force reflection), the handle lags the
//! target and the hand "feels" it as a larger spring force: that is what [`HandImpedance`] models.

use core::f64::consts::PI;
use core::time::Duration;

use heapless::Vec as FixedVec;
use nalgebra::{Unit, UnitQuaternion, Vector3};
use penelope_hal::{Frame, Pose, Timestamp, Twist, Wrench};

use super::Interaction;

/// The largest number of segments in one script.
pub const MAX_SEGMENTS: usize = 32;

/// A human hand's mechanical impedance while grasping a handle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HandImpedance {
    /// Translational stiffness, N/m (a relaxed grasp is 100-500 N/m).
    pub stiffness: f64,
    /// Translational damping, N·s/m.
    pub damping: f64,
    /// Rotational stiffness, N·m/rad.
    pub rotational_stiffness: f64,
    /// Rotational damping, N·m·s/rad.
    pub rotational_damping: f64,
}

impl Default for HandImpedance {
    fn default() -> Self {
        HandImpedance {
            stiffness: 400.0,
            damping: 12.0,
            rotational_stiffness: 2.0,
            rotational_damping: 0.05,
        }
    }
}

/// What the hand does during one segment (positions in the master's base frame, metres,
/// relative to where the segment starts unless stated).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Motion {
    /// Keep the target still.
    Hold,
    /// Move the target to `anchor + offset` along a minimum-jerk path (a reach).
    MoveTo {
        /// Destination relative to the script's anchor, m.
        offset: Vector3<f64>,
    },
    /// Oscillate along `axis` about the segment's start, the amplitude faded in and out over
    /// `fade` at both ends so the hand never jerks.
    Sine {
        /// Direction of motion.
        axis: Unit<Vector3<f64>>,
        /// Amplitude, m.
        amplitude: f64,
        /// Frequency, Hz.
        frequency: f64,
        /// Fade-in and fade-out time.
        fade: Duration,
    },
    /// Repeated pushes along `direction` to `depth` beyond the segment's start:
    /// `depth (1 - cos(2 pi f t)) / 2`, a tapping motion.
    Tap {
        /// Direction of the pushes.
        direction: Unit<Vector3<f64>>,
        /// Depth of each push, m.
        depth: f64,
        /// Taps per second, Hz.
        frequency: f64,
    },
}

/// One step of a script.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// A short name for reports ("reach", "sweep", "push", ...).
    pub label: &'static str,
    /// What the hand does.
    pub motion: Motion,
    /// How long it lasts.
    pub duration: Duration,
    /// Whether the operator holds the clutch (indexing) button during this segment.
    pub clutch: bool,
}

/// A sequence of segments, starting at a hand anchor.
#[derive(Clone, Debug, PartialEq)]
pub struct OperatorScript {
    segments: FixedVec<Segment, MAX_SEGMENTS>,
    starts: FixedVec<Vector3<f64>, MAX_SEGMENTS>,
}

/// More segments than [`MAX_SEGMENTS`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScriptTooLong;

impl OperatorScript {
    /// A script made of `segments`, played in order.
    ///
    /// # Errors
    /// [`ScriptTooLong`] beyond [`MAX_SEGMENTS`].
    pub fn new(segments: &[Segment]) -> Result<Self, ScriptTooLong> {
        let mut script = OperatorScript {
            segments: FixedVec::new(),
            starts: FixedVec::new(),
        };
        let mut position = Vector3::zeros();
        for s in segments {
            script.segments.push(*s).map_err(|_| ScriptTooLong)?;
            script.starts.push(position).map_err(|_| ScriptTooLong)?;
            position = end_position(&s.motion, position);
        }
        Ok(script)
    }

    /// The segments.
    pub fn segments(&self) -> &[Segment] {
        &self.segments
    }

    /// Total duration.
    pub fn duration(&self) -> Duration {
        self.segments.iter().map(|s| s.duration).sum()
    }

    /// The segment active `elapsed` after the start, with its index and the time into it
    /// (the last segment holds after the end).
    pub fn segment_at(&self, elapsed: Duration) -> Option<(usize, &Segment, Duration)> {
        let mut t0 = Duration::ZERO;
        for (i, s) in self.segments.iter().enumerate() {
            if elapsed < t0 + s.duration || i + 1 == self.segments.len() {
                return Some((i, s, elapsed.saturating_sub(t0)));
            }
            t0 += s.duration;
        }
        None
    }

    /// The hand target's offset from the anchor (m) and its velocity (m/s), `elapsed` after the
    /// start.
    pub fn target(&self, elapsed: Duration) -> (Vector3<f64>, Vector3<f64>) {
        let Some((i, seg, tau)) = self.segment_at(elapsed) else {
            return (Vector3::zeros(), Vector3::zeros());
        };
        let start = self.starts[i];
        let tau = tau.min(seg.duration);
        let t = tau.as_secs_f64();
        let total = seg.duration.as_secs_f64().max(1e-9);
        match seg.motion {
            Motion::Hold => (start, Vector3::zeros()),
            Motion::MoveTo { offset } => {
                let (s, ds) = minimum_jerk(t / total);
                (
                    start + (offset - start) * s,
                    (offset - start) * (ds / total),
                )
            }
            Motion::Sine {
                axis,
                amplitude,
                frequency,
                fade,
            } => {
                let w = 2.0 * PI * frequency;
                let (e, de) = fade_envelope(t, total, fade.as_secs_f64());
                let (sin, cos) = (w * t).sin_cos();
                let p = axis.into_inner() * (amplitude * e * sin);
                let v = axis.into_inner() * (amplitude * (de * sin + e * w * cos));
                (start + p, v)
            }
            Motion::Tap {
                direction,
                depth,
                frequency,
            } => {
                let w = 2.0 * PI * frequency;
                let (sin, cos) = (w * t).sin_cos();
                let p = direction.into_inner() * (depth * 0.5 * (1.0 - cos));
                let v = direction.into_inner() * (depth * 0.5 * w * sin);
                (start + p, v)
            }
        }
    }

    /// Whether the clutch is held `elapsed` after the start.
    pub fn clutch(&self, elapsed: Duration) -> bool {
        self.segment_at(elapsed).is_some_and(|(_, s, _)| s.clutch)
    }
}

fn end_position(motion: &Motion, start: Vector3<f64>) -> Vector3<f64> {
    match motion {
        Motion::MoveTo { offset } => *offset,
        // Sine fades out to zero; a tap ends after whole periods only if the script says so: the
        // next segment starts from the nominal start either way (the hand returns).
        Motion::Hold | Motion::Sine { .. } | Motion::Tap { .. } => start,
    }
}

/// Minimum-jerk profile `s(x) = 10x³ - 15x⁴ + 6x⁵` on `x` in [0, 1], and `ds/dx`.
fn minimum_jerk(x: f64) -> (f64, f64) {
    let x = x.clamp(0.0, 1.0);
    let s = x * x * x * (10.0 - 15.0 * x + 6.0 * x * x);
    let ds = 30.0 * x * x * (1.0 - x) * (1.0 - x);
    (s, ds)
}

/// An envelope rising from 0 to 1 over `fade` seconds (minimum jerk), falling back over the last
/// `fade` seconds of `total`; and its time derivative.
fn fade_envelope(t: f64, total: f64, fade: f64) -> (f64, f64) {
    if fade <= 0.0 {
        return (1.0, 0.0);
    }
    let fade = fade.min(total / 2.0);
    if t < fade {
        let (s, ds) = minimum_jerk(t / fade);
        (s, ds / fade)
    } else if t > total - fade {
        let (s, ds) = minimum_jerk((total - t) / fade);
        (s, -ds / fade)
    } else {
        (1.0, 0.0)
    }
}

/// The operator: a script, a hand impedance, and where the script is anchored.
#[derive(Clone, Debug)]
pub struct VirtualOperator {
    script: OperatorScript,
    hand: HandImpedance,
    anchor: Pose,
    start: Timestamp,
    last_force: Wrench,
}

impl VirtualOperator {
    /// An operator whose script starts at `start` from the handle pose `anchor` (the master's
    /// tool pose in its base frame), holding the handle with `hand`.
    pub fn new(
        script: OperatorScript,
        hand: HandImpedance,
        anchor: Pose,
        start: Timestamp,
    ) -> Self {
        VirtualOperator {
            script,
            hand,
            anchor,
            start,
            last_force: Wrench::zero(Frame::Base),
        }
    }

    /// The script.
    pub fn script(&self) -> &OperatorScript {
        &self.script
    }

    /// The hand target's position (m, master base frame) and velocity (m/s) at `now`.
    pub fn hand_target(&self, now: Timestamp) -> (Vector3<f64>, Vector3<f64>) {
        let (offset, velocity) = self.script.target(now - self.start);
        (self.anchor.translation.vector + offset, velocity)
    }

    /// Whether the operator holds the clutch at `now`.
    pub fn clutch(&self, now: Timestamp) -> bool {
        self.script.clutch(now - self.start)
    }

    /// The label of the script segment playing at `now`.
    pub fn phase(&self, now: Timestamp) -> &'static str {
        self.script
            .segment_at(now - self.start)
            .map_or("", |(_, s, _)| s.label)
    }

    /// The wrench the hand applied at the last evaluation (master base frame).
    pub fn last_force(&self) -> Wrench {
        self.last_force
    }
}

impl Interaction for VirtualOperator {
    fn wrench_on_tool(&mut self, now: Timestamp, tool: &Pose, twist: &Twist) -> Wrench {
        let (target, target_velocity) = self.hand_target(now);
        let p = tool.translation.vector;
        let force = (target - p) * self.hand.stiffness
            + (target_velocity - twist.linear) * self.hand.damping;
        let rotation_error: UnitQuaternion<f64> = self.anchor.rotation * tool.rotation.inverse();
        let torque = rotation_error.scaled_axis() * self.hand.rotational_stiffness
            - twist.angular * self.hand.rotational_damping;
        self.last_force = Wrench {
            force,
            torque,
            frame: Frame::Base,
        };
        self.last_force
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn script() -> OperatorScript {
        OperatorScript::new(&[
            Segment {
                label: "reach",
                motion: Motion::MoveTo {
                    offset: Vector3::new(0.05, 0.0, 0.0),
                },
                duration: Duration::from_secs(1),
                clutch: false,
            },
            Segment {
                label: "sweep",
                motion: Motion::Sine {
                    axis: Vector3::y_axis(),
                    amplitude: 0.03,
                    frequency: 1.0,
                    fade: Duration::from_millis(500),
                },
                duration: Duration::from_secs(3),
                clutch: false,
            },
            Segment {
                label: "index",
                motion: Motion::Hold,
                duration: Duration::from_secs(1),
                clutch: true,
            },
        ])
        .unwrap()
    }

    #[test]
    fn the_target_is_continuous_and_its_velocity_is_its_derivative() {
        let s = script();
        let dt = 1e-4;
        let mut previous = s.target(Duration::ZERO).0;
        for k in 1..50_000 {
            let t = Duration::from_secs_f64(k as f64 * dt);
            let (p, v) = s.target(t);
            let numeric = (p - previous) / dt;
            assert!((p - previous).norm() < 1e-3, "jump at {t:?}");
            assert!(
                (numeric - v).norm() < 2e-2,
                "velocity mismatch at {t:?}: {numeric} vs {v}"
            );
            previous = p;
        }
        assert!((s.target(Duration::from_secs(1)).0 - Vector3::new(0.05, 0.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn the_clutch_follows_the_script() {
        let s = script();
        assert!(!s.clutch(Duration::from_millis(3_900)));
        assert!(s.clutch(Duration::from_millis(4_100)));
        assert!(s.clutch(Duration::from_secs(100)), "the last segment holds");
    }

    #[test]
    fn the_hand_pulls_the_handle_toward_its_target() {
        let mut op = VirtualOperator::new(
            script(),
            HandImpedance::default(),
            Pose::identity(),
            Timestamp::ZERO,
        );
        let at = Pose::translation(-0.01, 0.0, 0.0);
        let w = op.wrench_on_tool(Timestamp::ZERO, &at, &Twist::default());
        assert!(
            (w.force.x - 4.0).abs() < 1e-9,
            "400 N/m * 1 cm = 4 N, got {}",
            w.force.x
        );
        assert!(w.torque.norm() < 1e-12);
    }
}
