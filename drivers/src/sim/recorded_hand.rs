//! A recorded hand: the operator's hand played back from a recording, as the motion it gave the
//! handle.
//!
//! A scripted hand ([`operator`](super::operator)) is an impedance that pulls the handle toward
//! a target; what a recording holds is the result, the master's true state every control tick.
//! Played back, the hand is infinitely stiff: at every board read the plant's state (joint
//! positions and velocities, the hand's wrench on the tool and the energy bookkeeping) is set to
//! the recorded state of that instant, and the clutch button to its recorded state. The master's
//! motors still get their commands and the plant still integrates between reads, but the handle
//! ends each tick where the recording says: the master's controller meets exactly the motion it
//! met when the recording was made, whatever it commands now.
//!
//! Past the recording's end the hand holds the handle still at its last recorded pose (zero
//! velocity), as a hand resting on a handle would, and the clutch keeps its last state.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use penelope_hal::{JointVector, Pose, Timestamp, Twist, Wrench};

use super::Interaction;

/// The master's true state at one recorded tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RecordedState {
    /// When (the plant's clock, as the recording's truth says).
    pub time: Timestamp,
    /// Joint positions, rad.
    pub position: JointVector,
    /// Joint velocities, rad/s.
    pub velocity: JointVector,
    /// The hand's wrench on the tool (base frame), as last evaluated.
    pub wrench: Wrench,
    /// Kinetic energy, J.
    pub kinetic_energy: f64,
    /// Work done on the robot by the hand since the start, J.
    pub interaction_work: f64,
    /// Whether the clutch was held.
    pub clutch: bool,
}

/// What a recorded hand sets the plant to at one read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImposedState {
    /// Joint positions, rad.
    pub position: JointVector,
    /// Joint velocities, rad/s.
    pub velocity: JointVector,
    /// The wrench on the tool.
    pub wrench: Wrench,
    /// Kinetic energy, J.
    pub kinetic_energy: f64,
    /// Work done by the surroundings, J.
    pub interaction_work: f64,
}

/// A recording played back as a hand: the states in time order, a cursor, and the clutch.
#[derive(Clone, Debug)]
pub struct RecordedHand {
    states: Arc<[RecordedState]>,
    /// Index of the last state at or before the last lookup (lookups move forward only).
    cursor: usize,
    clutch: Arc<AtomicBool>,
}

impl RecordedHand {
    /// A hand playing `states` (in time order; loaded beforehand, not in the control thread),
    /// publishing its clutch to `clutch`.
    pub fn new(states: Arc<[RecordedState]>, clutch: Arc<AtomicBool>) -> Self {
        RecordedHand {
            states,
            cursor: 0,
            clutch,
        }
    }

    /// The recorded states.
    pub fn states(&self) -> &[RecordedState] {
        &self.states
    }

    /// The index of the last state at or before `now`, if any. Moves the cursor forward;
    /// time going back (a new loop on the same body) starts the search over.
    ///
    /// # Real-time
    /// No allocation; amortised constant time (the cursor only moves forward, one step per
    /// state passed).
    fn index_at(&mut self, now: Timestamp) -> Option<usize> {
        let states = &self.states;
        let first = states.first()?;
        if now < first.time {
            return None;
        }
        if states[self.cursor].time > now {
            self.cursor = 0;
        }
        // Bounded by the number of states.
        while self.cursor + 1 < states.len() && states[self.cursor + 1].time <= now {
            self.cursor += 1;
        }
        Some(self.cursor)
    }

    /// The state the plant takes at `now`: the recorded one at or just before it; after the
    /// last, the last pose at rest. `None` before the first (the plant runs on its own).
    ///
    /// # Real-time
    /// No allocation; amortised constant time; one atomic store (the clutch).
    pub fn imposed(&mut self, now: Timestamp) -> Option<ImposedState> {
        let i = self.index_at(now)?;
        let s = self.states[i];
        self.clutch.store(s.clutch, Ordering::Relaxed);
        let ended = i + 1 == self.states.len() && now > s.time;
        Some(if ended {
            ImposedState {
                position: s.position,
                velocity: JointVector::zeros(),
                wrench: s.wrench,
                kinetic_energy: 0.0,
                interaction_work: s.interaction_work,
            }
        } else {
            ImposedState {
                position: s.position,
                velocity: s.velocity,
                wrench: s.wrench,
                kinetic_energy: s.kinetic_energy,
                interaction_work: s.interaction_work,
            }
        })
    }
}

impl Interaction for RecordedHand {
    /// Between reads the plant feels the hand's recorded wrench of that instant (the state is
    /// set at the next read anyway).
    ///
    /// # Real-time
    /// No allocation; amortised constant time.
    fn wrench_on_tool(&mut self, now: Timestamp, _tool: &Pose, _twist: &Twist) -> Wrench {
        match self.index_at(now) {
            Some(i) => self.states[i].wrench,
            None => Wrench::zero(penelope_hal::Frame::Base),
        }
    }

    fn imposed_state(&mut self, now: Timestamp) -> Option<ImposedState> {
        self.imposed(now)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use penelope_hal::Frame;

    fn state(ms: u64, x: f64, clutch: bool) -> RecordedState {
        RecordedState {
            time: Timestamp::from_nanos(ms * 1_000_000),
            position: JointVector::repeat(x),
            velocity: JointVector::repeat(1.0),
            wrench: Wrench::zero(Frame::Base),
            kinetic_energy: 2.0,
            interaction_work: x,
            clutch,
        }
    }

    #[test]
    fn the_hand_plays_each_tick_then_rests_at_its_last_pose() {
        let clutch = Arc::new(AtomicBool::new(false));
        let states: Arc<[RecordedState]> = vec![
            state(1, 0.1, false),
            state(2, 0.2, true),
            state(3, 0.3, false),
        ]
        .into();
        let mut hand = RecordedHand::new(states, clutch.clone());
        assert_eq!(hand.imposed(Timestamp::from_nanos(500_000)), None);
        let at = |ms: u64| Timestamp::from_nanos(ms * 1_000_000);
        assert_eq!(hand.imposed(at(1)).unwrap().position[0], 0.1);
        assert_eq!(hand.imposed(at(2)).unwrap().position[0], 0.2);
        assert!(clutch.load(Ordering::Relaxed));
        let held = hand.imposed(at(3)).unwrap();
        assert_eq!((held.position[0], held.velocity[0]), (0.3, 1.0));
        assert!(!clutch.load(Ordering::Relaxed));
        let after = hand.imposed(at(9)).unwrap();
        assert_eq!((after.position[0], after.velocity[0]), (0.3, 0.0));
        assert_eq!(after.kinetic_energy, 0.0);
        // Time going back (a new loop) starts over.
        assert_eq!(hand.imposed(at(1)).unwrap().position[0], 0.1);
    }
}
