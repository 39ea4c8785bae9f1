//! Different control laws on different joints of one robot: the paper's "a set of joints can be
//! controlled with a joint-based algorithm and the remaining joints with a different algorithm"
//! (for example a joint PID on the arm and a position servo on the wrist).

use core::fmt;

use penelope_hal::{
    ControlInput, Controller, ControllerError, ErrorKind, JointCommand, JointSet, JointState,
    JointVector, MAX_JOINTS, RobotModel, Timestamp,
};

/// Why a set of joint groups was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointGroupsError {
    /// No group, or more groups than joints.
    Count(usize),
    /// A group with no joint (its index in the list).
    EmptyGroup(usize),
    /// A joint claimed by two groups.
    Overlap(usize),
    /// Joints of the robot that no group drives (every joint needs exactly one law).
    Uncovered(JointSet),
    /// A joint index at or past the robot's joint count.
    OutOfRange(usize),
}

impl fmt::Display for JointGroupsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            JointGroupsError::Count(n) => {
                write!(f, "{n} joint groups: need between 1 and {MAX_JOINTS}")
            }
            JointGroupsError::EmptyGroup(i) => write!(f, "joint group {i} has no joint"),
            JointGroupsError::Overlap(j) => write!(f, "joint {j} is in two groups"),
            JointGroupsError::Uncovered(s) => {
                f.write_str("no group drives joint")?;
                if s.len() > 1 {
                    f.write_str("s")?;
                }
                for (k, j) in s.iter().enumerate() {
                    write!(f, "{}{j}", if k == 0 { " " } else { ", " })?;
                }
                Ok(())
            }
            JointGroupsError::OutOfRange(j) => write!(f, "joint {j} is past the robot's joints"),
        }
    }
}

impl penelope_hal::Error for JointGroupsError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::InvalidInput
    }
}

/// One controller per group of joints, run side by side in one control tick; each group's
/// command is taken on its own joints and the results merged into one [`JointCommand`]
/// ([`JointCommand::Mixed`] when some groups give torques and others position targets).
///
/// Every member sees the same [`ControlInput`]; the reference is expected to carry each group's
/// goal on that group's joints (the caller merges the groups' trajectories).
///
/// # Real-time
/// Fixed storage (at most [`MAX_JOINTS`] groups), no allocation.
#[derive(Clone, Debug)]
pub struct JointGroups<C> {
    groups: [Option<(JointSet, C)>; MAX_JOINTS],
    count: usize,
}

impl<C: Controller> JointGroups<C> {
    /// Groups for a robot of `joint_count` joints: every joint in exactly one group.
    ///
    /// # Errors
    /// [`JointGroupsError`] naming the first problem.
    pub fn new(
        joint_count: usize,
        groups: impl IntoIterator<Item = (JointSet, C)>,
    ) -> Result<Self, JointGroupsError> {
        let mut slots: [Option<(JointSet, C)>; MAX_JOINTS] = core::array::from_fn(|_| None);
        let mut count = 0;
        let mut covered = JointSet::EMPTY;
        for (i, (joints, law)) in groups.into_iter().enumerate() {
            if i >= MAX_JOINTS {
                return Err(JointGroupsError::Count(i + 1));
            }
            if joints.is_empty() {
                return Err(JointGroupsError::EmptyGroup(i));
            }
            if let Some(j) = joints.iter().find(|&j| j >= joint_count) {
                return Err(JointGroupsError::OutOfRange(j));
            }
            if let Some(j) = joints.intersection(covered).iter().next() {
                return Err(JointGroupsError::Overlap(j));
            }
            covered = covered.union(joints);
            slots[i] = Some((joints, law));
            count = i + 1;
        }
        if count == 0 {
            return Err(JointGroupsError::Count(0));
        }
        let all = JointSet::first(joint_count);
        if covered != all {
            let missing = all.iter().filter(|&j| !covered.contains(j));
            let mut uncovered = JointSet::EMPTY;
            for j in missing {
                uncovered = uncovered.with(j);
            }
            return Err(JointGroupsError::Uncovered(uncovered));
        }
        Ok(JointGroups {
            groups: slots,
            count,
        })
    }

    /// How many groups there are.
    pub fn len(&self) -> usize {
        self.count
    }

    /// Never true: [`new`](Self::new) refuses an empty list.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Group `index`: its joints and its controller.
    pub fn group(&self, index: usize) -> Option<(JointSet, &C)> {
        self.groups
            .get(index)?
            .as_ref()
            .map(|(joints, law)| (*joints, law))
    }

    /// Group `index`'s controller, to change its gains.
    pub fn group_mut(&mut self, index: usize) -> Option<(JointSet, &mut C)> {
        self.groups
            .get_mut(index)?
            .as_mut()
            .map(|(joints, law)| (*joints, law))
    }

    fn members(&mut self) -> impl Iterator<Item = &mut (JointSet, C)> {
        self.groups.iter_mut().flatten()
    }
}

impl<C: Controller> Controller for JointGroups<C> {
    fn kind(&self) -> &'static str {
        "joint-groups"
    }

    fn activate(&mut self, now: Timestamp, measured: &JointState, model: &dyn RobotModel) {
        for (_, law) in self.members() {
            law.activate(now, measured, model);
        }
    }

    fn update(&mut self, input: &ControlInput<'_>) -> Result<JointCommand, ControllerError> {
        let mut effort = JointVector::zeros();
        let mut position = JointVector::zeros();
        let mut position_joints = JointSet::EMPTY;
        let mut effort_joints = JointSet::EMPTY;
        for (joints, law) in self.members() {
            let command = law.update(input)?;
            for j in joints.iter() {
                let is_position = match command {
                    JointCommand::Effort(t) => {
                        effort[j] = t[j];
                        false
                    }
                    JointCommand::Position(q) => {
                        position[j] = q[j];
                        true
                    }
                    JointCommand::Mixed {
                        effort: t,
                        position: q,
                        position_joints: p,
                    } => {
                        if p.contains(j) {
                            position[j] = q[j];
                        } else {
                            effort[j] = t[j];
                        }
                        p.contains(j)
                    }
                };
                if is_position {
                    position_joints = position_joints.with(j);
                } else {
                    effort_joints = effort_joints.with(j);
                }
            }
        }
        Ok(if position_joints.is_empty() {
            JointCommand::Effort(effort)
        } else if effort_joints.is_empty() {
            JointCommand::Position(position)
        } else {
            JointCommand::Mixed {
                effort,
                position,
                position_joints,
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::{JointPid, JointPidGains, JointPositionServo};
    use core::time::Duration;
    use penelope_hal::{JointReference, Reference};
    use penelope_testbed::DecoupledChain;

    fn set(indices: &[usize]) -> JointSet {
        JointSet::from_indices(indices).unwrap()
    }

    fn input_at<'a>(
        state: &'a JointState,
        reference: &'a Reference,
        model: &'a DecoupledChain,
    ) -> ControlInput<'a> {
        ControlInput {
            now: Timestamp::from_nanos(1_000_000),
            period: Duration::from_millis(1),
            state,
            reference,
            wrench: None,
            model,
        }
    }

    fn state_and_reference() -> (JointState, Reference) {
        let mut state = JointState::default();
        let mut goal = JointVector::zeros();
        for j in 0..MAX_JOINTS {
            state.position[j] = 0.1 * j as f64;
            state.velocity[j] = -0.05 * j as f64;
            goal[j] = 0.3 - 0.07 * j as f64;
        }
        let reference = Reference::Joint(JointReference {
            position: goal,
            velocity: JointVector::zeros(),
            acceleration: JointVector::zeros(),
        });
        (state, reference)
    }

    #[test]
    fn two_pids_on_split_joints_equal_each_pid_on_its_own_joints() {
        let model = DecoupledChain::six_joint();
        let soft = JointPidGains::pd(JointVector::repeat(40.0), JointVector::repeat(4.0));
        let stiff = JointPidGains::pd(JointVector::repeat(400.0), JointVector::repeat(20.0));
        let (state, reference) = state_and_reference();
        let input = input_at(&state, &reference, &model);

        let mut alone_soft = JointPid::new(soft);
        let mut alone_stiff = JointPid::new(stiff);
        let mut groups = JointGroups::new(
            6,
            [
                (set(&[0, 1, 2]), JointPid::new(soft)),
                (set(&[3, 4, 5]), JointPid::new(stiff)),
            ],
        )
        .unwrap();
        for law in [&mut alone_soft, &mut alone_stiff] {
            law.activate(Timestamp::ZERO, &state, &model);
        }
        groups.activate(Timestamp::ZERO, &state, &model);

        let JointCommand::Effort(a) = alone_soft.update(&input).unwrap() else {
            panic!("a PID gives torques")
        };
        let JointCommand::Effort(b) = alone_stiff.update(&input).unwrap() else {
            panic!("a PID gives torques")
        };
        let JointCommand::Effort(merged) = groups.update(&input).unwrap() else {
            panic!("two PIDs give torques")
        };
        for j in 0..3 {
            assert_eq!(merged[j], a[j], "joint {j}");
        }
        for j in 3..6 {
            assert_eq!(merged[j], b[j], "joint {j}");
        }
        assert_ne!(
            a[4], b[4],
            "the two gain sets must differ for the test to mean anything"
        );
        assert_eq!(groups.kind(), "joint-groups");
    }

    #[test]
    fn a_pid_and_a_position_servo_give_a_mixed_command() {
        let model = DecoupledChain::six_joint();
        let (state, reference) = state_and_reference();
        let input = input_at(&state, &reference, &model);
        let mut groups = JointGroups::new(
            6,
            [
                (
                    set(&[0, 1, 2]),
                    Member::Pid(JointPid::new(JointPidGains::pd(
                        JointVector::repeat(100.0),
                        JointVector::repeat(5.0),
                    ))),
                ),
                (
                    set(&[3, 4, 5]),
                    Member::Servo(JointPositionServo::new(JointVector::repeat(f64::INFINITY))),
                ),
            ],
        )
        .unwrap();
        groups.activate(Timestamp::ZERO, &state, &model);
        let command = groups.update(&input).unwrap();
        let JointCommand::Mixed {
            effort,
            position,
            position_joints,
        } = command
        else {
            panic!("expected a mixed command, got {command:?}")
        };
        assert_eq!(position_joints, set(&[3, 4, 5]));
        let Reference::Joint(goal) = reference else {
            unreachable!()
        };
        for j in 3..6 {
            assert_eq!(
                position[j], goal.position[j],
                "the servo's target, joint {j}"
            );
        }
        for j in 0..3 {
            assert!(effort[j] != 0.0, "the PID's torque on joint {j}");
        }
    }

    #[test]
    fn bad_groups_are_refused_with_the_joint_named() {
        let pid = || {
            JointPid::new(JointPidGains::pd(
                JointVector::repeat(1.0),
                JointVector::zeros(),
            ))
        };
        let err = |r: Result<JointGroups<JointPid>, _>| r.err().unwrap();
        assert_eq!(
            err(JointGroups::new(
                6,
                [(set(&[0, 1, 2]), pid()), (set(&[2, 3, 4, 5]), pid())]
            )),
            JointGroupsError::Overlap(2)
        );
        let uncovered = err(JointGroups::new(6, [(set(&[0, 1, 2]), pid())]));
        assert_eq!(uncovered, JointGroupsError::Uncovered(set(&[3, 4, 5])));
        assert_eq!(uncovered.to_string(), "no group drives joints 3, 4, 5");
        assert_eq!(
            err(JointGroups::new(3, [(set(&[0, 1, 2, 3]), pid())])),
            JointGroupsError::OutOfRange(3)
        );
        assert_eq!(
            err(JointGroups::new(
                6,
                [(JointSet::EMPTY, pid()), (JointSet::first(6), pid())]
            )),
            JointGroupsError::EmptyGroup(0)
        );
        assert_eq!(
            err(JointGroups::new(6, core::iter::empty())),
            JointGroupsError::Count(0)
        );
    }

    /// Two different laws in one group list.
    enum Member {
        Pid(JointPid),
        Servo(JointPositionServo),
    }

    impl Controller for Member {
        fn kind(&self) -> &'static str {
            match self {
                Member::Pid(c) => c.kind(),
                Member::Servo(c) => c.kind(),
            }
        }
        fn activate(&mut self, now: Timestamp, measured: &JointState, model: &dyn RobotModel) {
            match self {
                Member::Pid(c) => c.activate(now, measured, model),
                Member::Servo(c) => c.activate(now, measured, model),
            }
        }
        fn update(&mut self, input: &ControlInput<'_>) -> Result<JointCommand, ControllerError> {
            match self {
                Member::Pid(c) => c.update(input),
                Member::Servo(c) => c.update(input),
            }
        }
    }
}
