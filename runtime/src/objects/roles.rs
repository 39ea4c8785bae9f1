//! Who may make which call of a node's creator and objects, checked on every call before it is
//! served ([`authorize_call`]):
//! - **watch** (any role): ping, node info, the clock, kinds and lists, describing objects,
//!   reading their state, subscribing to telemetry;
//! - **stop** (any role, so any authenticated peer: safety over secrecy): a controller's
//!   e-stop, and the `deactivate` and `fault` transitions, which only ever end motion;
//! - **operate** ([`Role::Operator`], [`Role::Node`], [`Role::Admin`]): every other lifecycle
//!   transition (a re-arm among them), object methods that change something (bindings, gains,
//!   moves, biases, board re-arms), recordings, the simulated clock;
//! - **create and destroy** ([`Role::Admin`] only).
//!
//! The matches are exhaustive on purpose: a new call or method does not compile until someone
//! decides who may make it (a new stop must land under "stop").

use penelope_hal::Transition;

use crate::objects::error::ObjectError;
use penelope_protocol::proto::{
    BoardMethod, Call, ControllerMethod, CreatorCall, Method, RobotMethod, Role, SensorMethod,
    TrajectoryMethod,
};
use penelope_protocol::service::Identity;

/// What a call needs, weakest first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Needs {
    /// Reads only (or a naming call, authorized by the naming service itself).
    Watch,
    /// Ends motion: allowed to everyone who got a session.
    Stop,
    /// Changes what objects do.
    Operate,
    /// Makes or removes objects.
    Create,
}

/// What `call` needs.
pub fn needs(call: &Call) -> Needs {
    match call {
        Call::Ping { .. }
        | Call::NodeInfo
        | Call::Time
        | Call::Naming(_)
        | Call::Subscribe { .. }
        | Call::Unsubscribe { .. } => Needs::Watch,
        Call::Creator(c) => match c {
            CreatorCall::Kinds | CreatorCall::List => Needs::Watch,
            CreatorCall::EStop => Needs::Stop,
            CreatorCall::Create { .. }
            | CreatorCall::Destroy { .. }
            | CreatorCall::ApplySystem { .. } => Needs::Create,
            CreatorCall::Advance { .. }
            | CreatorCall::RecordStart { .. }
            | CreatorCall::RecordStartScene { .. }
            | CreatorCall::RecordStop => Needs::Operate,
        },
        Call::Object { method, .. } => method_needs(method),
    }
}

fn method_needs(method: &Method) -> Needs {
    match method {
        Method::Describe => Needs::Watch,
        Method::Transition(t) => match t {
            Transition::Deactivate | Transition::Fault => Needs::Stop,
            Transition::Configure
            | Transition::Activate
            | Transition::Cleanup
            | Transition::Shutdown
            | Transition::Reset => Needs::Operate,
        },
        Method::Robot(m) => match m {
            RobotMethod::JointPositions
            | RobotMethod::JointVelocities
            | RobotMethod::JointAccelerations
            | RobotMethod::Operational
            | RobotMethod::ToolWrench
            | RobotMethod::ForwardKinematics { .. }
            | RobotMethod::Jacobian { .. }
            | RobotMethod::JacobianInverse { .. }
            | RobotMethod::InverseKinematics { .. }
            | RobotMethod::WrenchToTorques { .. }
            | RobotMethod::Gravity { .. }
            | RobotMethod::Inertia { .. }
            | RobotMethod::CountsToRadians { .. }
            | RobotMethod::RadiansToCounts { .. }
            | RobotMethod::NamedPose { .. }
            | RobotMethod::Description
            | RobotMethod::LinkFrames { .. }
            | RobotMethod::Setpoints
            | RobotMethod::OperatingState => Needs::Watch,
            RobotMethod::GoTo { .. }
            | RobotMethod::MapJoints { .. }
            | RobotMethod::MoveJoints { .. }
            | RobotMethod::MoveTool { .. }
            | RobotMethod::ServoJoints { .. }
            | RobotMethod::ServoTool { .. } => Needs::Operate,
        },
        Method::Board(m) => match m {
            BoardMethod::AxisCount | BoardMethod::ReadEncoders | BoardMethod::AmplifiersEnabled => {
                Needs::Watch
            }
            BoardMethod::Rearm => Needs::Operate,
        },
        Method::Sensor(m) => match m {
            SensorMethod::Read | SensorMethod::Stream => Needs::Watch,
            // Measure moves the sensor's probe (the model's state) as well as reading.
            SensorMethod::Bias | SensorMethod::SetProbe { .. } | SensorMethod::Measure { .. } => {
                Needs::Operate
            }
        },
        Method::Controller(m) => match m {
            ControllerMethod::Status => Needs::Watch,
            ControllerMethod::EStop => Needs::Stop,
            ControllerMethod::SetRobot { .. }
            | ControllerMethod::SetTrajectory { .. }
            | ControllerMethod::SetSensor { .. }
            | ControllerMethod::SetGains { .. }
            | ControllerMethod::Rearm => Needs::Operate,
        },
        Method::Trajectory(m) => match m {
            TrajectoryMethod::Reference { .. } | TrajectoryMethod::Duration => Needs::Watch,
        },
    }
}

/// What `role` may do at most.
pub fn allowed(role: Role) -> Needs {
    match role {
        Role::Reader => Needs::Stop,
        Role::Operator | Role::Node => Needs::Operate,
        Role::Admin => Needs::Create,
    }
}

/// Whether a session of `identity` may make `call`.
///
/// # Errors
/// [`ObjectError::Forbidden`] saying what the call needs and how to get it.
pub fn authorize_call(identity: Identity, call: &Call) -> Result<(), ObjectError> {
    let need = needs(call);
    if need <= allowed(identity.role) {
        return Ok(());
    }
    let (what, how) = match need {
        Needs::Create => (
            "create or destroy objects",
            "connect as an admin (with the admin secret)",
        ),
        _ => (
            "operate objects (lifecycle, methods, recordings, gains)",
            "connect as an operator or an admin",
        ),
    };
    Err(ObjectError::Forbidden(format!(
        "a {} may not {what}: {how}",
        identity.role.name()
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn id(role: Role) -> Identity {
        Identity { role, proven: true }
    }

    #[test]
    fn each_role_may_do_what_its_rank_allows_and_everyone_may_stop() {
        let create = Call::Creator(CreatorCall::Create {
            kind: "robot/puma560".into(),
            name: "r".into(),
            config: String::new(),
        });
        let rearm = Call::Object {
            object: "pid".into(),
            method: Method::Controller(ControllerMethod::Rearm),
        };
        let estop = Call::Object {
            object: "pid".into(),
            method: Method::Controller(ControllerMethod::EStop),
        };
        let record = Call::Creator(CreatorCall::RecordStart {
            path: "x.mcap".into(),
            objects: Vec::new(),
        });
        let apply = Call::Creator(CreatorCall::ApplySystem {
            text: String::new(),
        });
        let estop_node = Call::Creator(CreatorCall::EStop);
        let list = Call::Creator(CreatorCall::List);
        for (role, may_create, may_operate) in [
            (Role::Reader, false, false),
            (Role::Operator, false, true),
            (Role::Node, false, true),
            (Role::Admin, true, true),
        ] {
            assert_eq!(
                authorize_call(id(role), &create).is_ok(),
                may_create,
                "{role:?}"
            );
            assert_eq!(
                authorize_call(id(role), &apply).is_ok(),
                may_create,
                "{role:?}"
            );
            assert_eq!(
                authorize_call(id(role), &rearm).is_ok(),
                may_operate,
                "{role:?}"
            );
            assert_eq!(
                authorize_call(id(role), &record).is_ok(),
                may_operate,
                "{role:?}"
            );
            assert!(authorize_call(id(role), &estop).is_ok(), "{role:?}");
            assert!(authorize_call(id(role), &estop_node).is_ok(), "{role:?}");
            assert!(authorize_call(id(role), &list).is_ok(), "{role:?}");
        }
        let e = authorize_call(id(Role::Reader), &create).unwrap_err();
        assert!(
            matches!(&e, ObjectError::Forbidden(why) if why.contains("admin")),
            "{e}"
        );
    }
}
