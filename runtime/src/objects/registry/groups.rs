//! `controller/joint-groups`: the paper's joint subsets of one robot driven by different
//! controllers. The members are ordinary joint-space controllers, each with its robot and its
//! own trajectory; the group runs them in one loop (one board, one safety layer) and merges
//! their commands and references joint by joint.

use super::trajectories::{build_trajectory, spec_is_tool};
use crate::objects::error::ObjectError;
use crate::objects::registry::{ControllerConfig, Kind, bad_arg, not_ready};
use crate::objects::runtime::{ControlLaw, TrajectoryFeed};
use crate::objects::{KindState, Registry, kinds};
use penelope_drivers::model::SerialRobotModel;
use penelope_hal::{JointSet, JointVector, LifecycleState};
use penelope_protocol::proto::Class;

/// A group member, ready for the group's loop.
pub(super) struct Member {
    /// The member controller's name.
    pub name: String,
    /// Its joints.
    pub joints: JointSet,
    /// Its law.
    pub law: ControlLaw,
    /// Its trajectory's name.
    pub trajectory: String,
    /// Its trajectory, ready to start.
    pub feed: TrajectoryFeed,
}

impl Registry {
    /// Checks a joint-groups controller's relations at configure: every member exists, is a
    /// joint-space law, and drives the same robot; the group's robot is theirs.
    pub(super) fn configure_groups(
        &mut self,
        name: &str,
        groups: &kinds::JointGroupsConfig,
    ) -> Result<(), ObjectError> {
        let c = self.controller_mut(name)?;
        if let Some(t) = &c.trajectory {
            return Err(bad_arg(format!(
                "`{name}` is a joint-groups controller: each member follows its own trajectory, \
                 the group none (it has `{t}`)"
            )));
        }
        if c.sensor.is_some() {
            return Err(bad_arg(format!(
                "`{name}` is a joint-groups controller: its members are joint-space laws, which \
                 use no force sensor"
            )));
        }
        let mut robot = c.robot.clone();
        for g in &groups.groups {
            let member = &g.controller;
            if member == name {
                return Err(bad_arg(format!("`{name}` lists itself as a group member")));
            }
            let kind = self.expect_class(member, Class::Controller)?.kind;
            if !matches!(kind, Kind::JOINT_PID | Kind::JOINT_POSITION) {
                return Err(bad_arg(format!(
                    "group member `{member}` is a {}: a member is a controller/joint-pid or \
                     controller/joint-position",
                    kind.as_str()
                )));
            }
            self.configure_controller(member)?;
            let theirs = self
                .controller_mut(member)?
                .robot
                .clone()
                .unwrap_or_default();
            match &robot {
                None => robot = Some(theirs),
                Some(r) if *r != theirs => {
                    return Err(bad_arg(format!(
                        "group member `{member}` drives robot `{theirs}`; the group drives `{r}`"
                    )));
                }
                Some(_) => {}
            }
        }
        self.controller_mut(name)?.robot = robot;
        Ok(())
    }

    /// The members of a joint-groups controller, each built for `model`: configured and
    /// idle, on `robot`, following a configured trajectory (not a teleoperation channel).
    pub(super) fn group_members(
        &self,
        groups: &kinds::JointGroupsConfig,
        robot: &str,
        model: &SerialRobotModel,
        hold: (JointVector, JointVector),
    ) -> Result<Vec<Member>, ObjectError> {
        let mut members = Vec::new();
        for g in &groups.groups {
            let member = &g.controller;
            let o = self.get(member)?;
            if o.state != LifecycleState::Inactive || !o.users.is_empty() {
                return Err(not_ready(format!(
                    "group member `{member}` must be configured and not running (it is {})",
                    o.shown_state()
                )));
            }
            let kind = o.kind.as_str();
            let KindState::Controller(c) = &o.body else {
                return Err(ObjectError::internal("controller body"));
            };
            if c.robot.as_deref() != Some(robot) {
                return Err(bad_arg(format!(
                    "group member `{member}` does not drive `{robot}`"
                )));
            }
            let trajectory = c.trajectory.clone().unwrap_or_default();
            let t = self.get(&trajectory)?;
            if t.state == LifecycleState::Unconfigured {
                return Err(not_ready(format!(
                    "trajectory `{trajectory}` of group member `{member}` is not configured"
                )));
            }
            let KindState::Trajectory(spec) = &t.body else {
                return Err(bad_arg(format!(
                    "group member `{member}` follows `{trajectory}`, a {}: group members follow \
                     joint or tool trajectories",
                    t.kind.as_str()
                )));
            };
            members.push(Member {
                name: member.clone(),
                joints: kinds::JointGroupsConfig::joint_set(g),
                law: super::laws::node_law(&c.config, kind, model, hold)?,
                feed: TrajectoryFeed::new(
                    build_trajectory(&spec.spec, model, kind)?,
                    spec_is_tool(&spec.spec),
                ),
                trajectory,
            });
        }
        Ok(members)
    }

    /// The running joint-groups controller that runs `member`, and the member's index in it.
    pub(super) fn running_group_of(&self, member: &str) -> Option<(String, u8)> {
        self.objects.get(member)?.users.iter().find_map(|user| {
            let KindState::Controller(c) = &self.objects.get(user)?.body else {
                return None;
            };
            let ControllerConfig::Groups(g) = &c.config else {
                return None;
            };
            c.running.as_ref()?;
            let index = g.groups.iter().position(|g| g.controller == member)?;
            Some((user.clone(), index as u8))
        })
    }
}
