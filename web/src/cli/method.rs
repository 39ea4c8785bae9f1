//! `penelope ctl call PATH METHOD [ARGS...]`: the method words, parsed into a [`Method`].

use nalgebra::Vector3;
use penelope_hal::{NamedPose, Pose};
use penelope_protocol::proto::{
    BoardMethod, ControllerMethod, JointAxis, Joints, Method, PoseMsg, Reply, RobotMethod,
    SensorMethod, TrajectoryMethod, WrenchMsg, parse_transition,
};

use crate::cli::usage;

/// How a reply is labelled in human output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Hint {
    /// What the values are (`joint positions`).
    pub label: &'static str,
    /// Their unit (`rad`).
    pub unit: &'static str,
}

const fn hint(label: &'static str, unit: &'static str) -> Hint {
    Hint { label, unit }
}

/// The methods, with their arguments and what they return: `ctl call --help` and `ctl help`.
pub const METHODS: &str = "\
Every object:
  describe                          kind, state, relations
  configure | activate | deactivate | cleanup | shutdown | reset
Robots (Q: joint values in rad, space- or comma-separated, or a pose name nest|start|work;
        omitted: the measured joints):
  joint-positions | joint-velocities | joint-accelerations | operational | tool-wrench
  fk [Q]                            forward kinematics: tool pose (m, versors n o a, roll-pitch-yaw)
  jacobian [Q]                      geometric Jacobian, base frame, rows vx vy vz wx wy wz
  jacobian-inverse LAMBDA [Q]       damped least-squares inverse (LAMBDA around 0.01)
  ik X Y Z [NX NY NZ OX OY OZ [AX AY AZ]]
                                    inverse kinematics, every branch within the limits; without
                                    versors, the current tool orientation is kept
  tau FX FY FZ TX TY TZ [Q]         joint torques (N m) balancing a base-frame tool wrench (N, N m)
  gravity [Q] | inertia [Q]         gravity torques (N m), inertia matrix (kg m^2)
  counts-to-radians C...            encoder counts to rad;  radians-to-counts Q: the reverse
  named-pose nest|start|work        the joints of a named pose
  go-to nest|start|work SECONDS     move there through the robot's active controller
  move-jp Q SECONDS                 CRTK move_jp: a smooth move to the joints Q (rad)
  move-cp X Y Z [N O [A]] SECONDS   CRTK move_cp: a smooth move to a tool pose (as ik)
  servo-jp Q | servo-cp X Y Z [N O [A]]
                                    CRTK servo: jump the reference there (at most 0.05 rad a joint)
  setpoints | operating-state       the reference followed now; DISABLED|ENABLED|PAUSED|FAULT, busy
  map-joints BOARD J:A [J:A...]     drive joint J by axis A of BOARD (0-based)
Boards:
  axis-count | read-encoders | amplifiers-enabled
  rearm                             leave a fault the board latched (a lost Galil line)
Sensors:
  read | bias                       newest wrench (N, N m); take the current reading as zero
  set-probe X Y Z [VX VY VZ]        probe position (m) and velocity (m/s) of a virtual sensor
  measure X Y Z [VX VY VZ]          the wrench for that probe, in one round trip
  stream                            where the sensor is published on the data plane
Controllers:
  set-robot NAME | set-trajectory NAME | set-sensor NAME-OR-PATH
  set-gains TOML                    e.g. set-gains 'kp = [100, 100, 100, 10, 10, 10]'
  status | estop | rearm
Trajectories:
  reference T                       the reference T seconds after the start
  duration                          total duration (s)";

/// Looks up something the arguments refer to (the joints of a named pose, the current tool
/// pose) on the object being called.
pub type Lookup<'a> = dyn FnMut(RobotMethod) -> anyhow::Result<Reply> + 'a;

/// A finite number.
fn number(word: &str, what: &str) -> anyhow::Result<f64> {
    match word.parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        _ => Err(usage(format!("{what}: `{word}` is not a finite number"))),
    }
}

/// Numbers, each word possibly comma-separated.
fn numbers(words: &[String], what: &str) -> anyhow::Result<Vec<f64>> {
    words
        .iter()
        .flat_map(|w| w.split(',').filter(|s| !s.is_empty()))
        .map(|w| number(w, what))
        .collect()
}

/// Exactly `N` numbers.
fn fixed<const N: usize>(words: &[String], what: &str) -> anyhow::Result<[f64; N]> {
    let v = numbers(words, what)?;
    v.try_into()
        .map_err(|v: Vec<f64>| usage(format!("{what}: expected {N} numbers, got {}", v.len())))
}

fn named_pose(word: &str) -> anyhow::Result<NamedPose> {
    NamedPose::parse(word).ok_or_else(|| {
        usage(format!(
            "`{word}` is not a named pose (nest, start or work)"
        ))
    })
}

/// Optional joint values: none (measured), a pose name, or numbers.
fn joints(words: &[String], lookup: &mut Lookup<'_>) -> anyhow::Result<Option<Joints>> {
    match words {
        [] => Ok(None),
        [word] if NamedPose::parse(word).is_some() => {
            let pose = named_pose(word)?;
            match lookup(RobotMethod::NamedPose { pose })? {
                Reply::Joints(q) => Ok(Some(q)),
                other => anyhow::bail!("expected joint values for `{word}`, got {other:?}"),
            }
        }
        _ => Ok(Some(numbers(words, "joint value")?)),
    }
}

/// A probe pose (identity orientation) and velocity from `X Y Z [VX VY VZ]`.
fn probe(words: &[String]) -> anyhow::Result<(PoseMsg, [f64; 3])> {
    let v = numbers(words, "probe")?;
    let (p, vel) = match v.len() {
        3 => ([v[0], v[1], v[2]], [0.0; 3]),
        6 => ([v[0], v[1], v[2]], [v[3], v[4], v[5]]),
        n => {
            return Err(usage(format!(
                "probe: expected X Y Z [VX VY VZ], got {n} numbers"
            )));
        }
    };
    let pose = Pose::translation(p[0], p[1], p[2]);
    Ok((PoseMsg::from(&pose), vel))
}

/// A target pose from `X Y Z [N O [A]]`; without versors, the current tool orientation.
fn target(words: &[String], lookup: &mut Lookup<'_>) -> anyhow::Result<PoseMsg> {
    let v = numbers(words, "pose")?;
    let (n, o, a) = match v.len() {
        3 => match lookup(RobotMethod::ForwardKinematics { q: None })? {
            Reply::Pose(p) => (p.n, p.o, p.a),
            other => anyhow::bail!("expected the current tool pose, got {other:?}"),
        },
        9 | 12 => {
            let n = Vector3::new(v[3], v[4], v[5]);
            let o = Vector3::new(v[6], v[7], v[8]);
            let a = if v.len() == 12 {
                Vector3::new(v[9], v[10], v[11])
            } else {
                n.cross(&o)
            };
            (n.into(), o.into(), a.into())
        }
        k => {
            return Err(usage(format!(
                "ik: expected X Y Z, X Y Z NX NY NZ OX OY OZ or X Y Z N O A (3, 9 or 12 numbers), got {k}"
            )));
        }
    };
    let msg = PoseMsg {
        position: [v[0], v[1], v[2]],
        n,
        o,
        a,
    };
    msg.to_pose().map_err(|e| usage(format!("ik: {e}")))?;
    Ok(msg)
}

fn no_args(name: &str, args: &[String]) -> anyhow::Result<()> {
    if args.is_empty() {
        Ok(())
    } else {
        Err(usage(format!(
            "`{name}` takes no arguments, got `{}`",
            args.join(" ")
        )))
    }
}

fn one<'a>(name: &str, what: &str, args: &'a [String]) -> anyhow::Result<&'a str> {
    match args {
        [a] => Ok(a),
        _ => Err(usage(format!("`{name}` takes one argument: {what}"))),
    }
}

/// Parses `METHOD ARGS...` into the method and how to label its reply.
///
/// # Errors
/// A usage error naming what is wrong; `lookup`'s errors.
pub fn parse(
    name: &str,
    args: &[String],
    lookup: &mut Lookup<'_>,
) -> anyhow::Result<(Method, Hint)> {
    if let Some(t) = parse_transition(name) {
        no_args(name, args)?;
        return Ok((Method::Transition(t), hint("", "")));
    }
    if name == "describe" {
        no_args(name, args)?;
        return Ok((Method::Describe, hint("", "")));
    }
    if let Some(parsed) = robot_state_method(name, args)? {
        return Ok(parsed);
    }
    if let Some(parsed) = robot_model_method(name, args, lookup)? {
        return Ok(parsed);
    }
    if let Some(parsed) = robot_joint_method(name, args, lookup)? {
        return Ok(parsed);
    }
    if let Some(parsed) = board_method(name, args)? {
        return Ok(parsed);
    }
    if let Some(parsed) = sensor_method(name, args)? {
        return Ok(parsed);
    }
    if let Some(parsed) = controller_method(name, args)? {
        return Ok(parsed);
    }
    if let Some(parsed) = trajectory_method(name, args)? {
        return Ok(parsed);
    }
    Err(usage(format!(
        "unknown method `{name}`; the methods are:\n{METHODS}"
    )))
}

/// The robot's measured-state methods (no arguments);
/// `None` when `name` is not one of them.
fn robot_state_method(name: &str, args: &[String]) -> anyhow::Result<Option<(Method, Hint)>> {
    let none = hint("", "");
    let robot = |m: RobotMethod, h: Hint| Ok(Some((Method::Robot(m), h)));
    match name {
        "joint-positions" | "q" => {
            no_args(name, args)?;
            robot(RobotMethod::JointPositions, hint("joint positions", "rad"))
        }
        "joint-velocities" | "qd" => {
            no_args(name, args)?;
            robot(
                RobotMethod::JointVelocities,
                hint("joint velocities", "rad/s"),
            )
        }
        "joint-accelerations" | "qdd" => {
            no_args(name, args)?;
            robot(
                RobotMethod::JointAccelerations,
                hint("joint accelerations", "rad/s²"),
            )
        }
        "operational" => {
            no_args(name, args)?;
            robot(RobotMethod::Operational, none)
        }
        "tool-wrench" => {
            no_args(name, args)?;
            robot(RobotMethod::ToolWrench, none)
        }
        _ => Ok(None),
    }
}

/// The robot's model methods: kinematics and dynamics at given or measured joints;
/// `None` when `name` is not one of them.
fn robot_model_method(
    name: &str,
    args: &[String],
    lookup: &mut Lookup<'_>,
) -> anyhow::Result<Option<(Method, Hint)>> {
    let none = hint("", "");
    let robot = |m: RobotMethod, h: Hint| Ok(Some((Method::Robot(m), h)));
    match name {
        "fk" | "forward-kinematics" => {
            let q = joints(args, lookup)?;
            robot(RobotMethod::ForwardKinematics { q }, none)
        }
        "jacobian" => {
            let q = joints(args, lookup)?;
            robot(RobotMethod::Jacobian { q }, hint("jacobian", ""))
        }
        "jacobian-inverse" => {
            let Some((lambda, rest)) = args.split_first() else {
                return Err(usage("`jacobian-inverse` needs LAMBDA [Q]"));
            };
            let damping = number(lambda, "damping")?;
            if damping < 0.0 {
                return Err(usage("damping must be >= 0"));
            }
            let q = joints(rest, lookup)?;
            robot(
                RobotMethod::JacobianInverse { q, damping },
                hint("jacobian-inverse", ""),
            )
        }
        "ik" | "inverse-kinematics" => {
            let pose = target(args, lookup)?;
            robot(RobotMethod::InverseKinematics { pose }, none)
        }
        "tau" | "wrench-to-torques" => {
            if args.len() < 6 {
                return Err(usage(format!("`{name}` needs FX FY FZ TX TY TZ [Q]")));
            }
            let w: [f64; 6] = fixed(&args[..6], "wrench")?;
            let q = joints(&args[6..], lookup)?;
            let wrench = WrenchMsg {
                force: [w[0], w[1], w[2]],
                torque: [w[3], w[4], w[5]],
            };
            robot(
                RobotMethod::WrenchToTorques { wrench, q },
                hint("joint torques", "N·m"),
            )
        }
        "gravity" => {
            let q = joints(args, lookup)?;
            robot(RobotMethod::Gravity { q }, hint("gravity torques", "N·m"))
        }
        "inertia" => {
            let q = joints(args, lookup)?;
            robot(RobotMethod::Inertia { q }, hint("inertia", "kg·m²"))
        }
        _ => Ok(None),
    }
}

/// The robot's joint-space methods: unit conversions, named poses, moves, the joint map;
/// `None` when `name` is not one of them.
fn robot_joint_method(
    name: &str,
    args: &[String],
    lookup: &mut Lookup<'_>,
) -> anyhow::Result<Option<(Method, Hint)>> {
    let none = hint("", "");
    let robot = |m: RobotMethod, h: Hint| Ok(Some((Method::Robot(m), h)));
    match name {
        "counts-to-radians" => {
            let counts = args
                .iter()
                .flat_map(|w| w.split(',').filter(|s| !s.is_empty()))
                .map(|w| {
                    w.parse::<i64>()
                        .map_err(|_| usage(format!("`{w}` is not an encoder count")))
                })
                .collect::<anyhow::Result<Vec<_>>>()?;
            robot(
                RobotMethod::CountsToRadians { counts },
                hint("joint positions", "rad"),
            )
        }
        "radians-to-counts" => {
            let q = joints(args, lookup)?.ok_or_else(|| usage("`radians-to-counts` needs Q"))?;
            robot(
                RobotMethod::RadiansToCounts { q },
                hint("encoder", "counts"),
            )
        }
        "named-pose" => {
            let pose = named_pose(one(name, "nest, start or work", args)?)?;
            robot(
                RobotMethod::NamedPose { pose },
                hint("joint positions", "rad"),
            )
        }
        "go-to" => {
            let [pose, secs] = args else {
                return Err(usage(
                    "`go-to` needs a pose (nest, start, work) and SECONDS",
                ));
            };
            let pose = named_pose(pose)?;
            let duration_s = number(secs, "duration")?;
            if duration_s <= 0.0 {
                return Err(usage("the duration must be > 0 s"));
            }
            robot(RobotMethod::GoTo { pose, duration_s }, none)
        }
        "move-jp" | "move-cp" => {
            let Some((secs, goal)) = args.split_last() else {
                return Err(usage(format!("`{name}` needs a goal and SECONDS")));
            };
            let duration_s = number(secs, "duration")?;
            if duration_s <= 0.0 {
                return Err(usage("the duration must be > 0 s"));
            }
            if name == "move-jp" {
                let q = joints(goal, lookup)?
                    .ok_or_else(|| usage("`move-jp` needs Q (joint values or a pose name)"))?;
                robot(RobotMethod::MoveJoints { q, duration_s }, none)
            } else {
                let pose = target(goal, lookup)?;
                robot(RobotMethod::MoveTool { pose, duration_s }, none)
            }
        }
        "servo-jp" => {
            let q = joints(args, lookup)?.ok_or_else(|| usage("`servo-jp` needs Q"))?;
            robot(RobotMethod::ServoJoints { q }, none)
        }
        "servo-cp" => {
            let pose = target(args, lookup)?;
            robot(RobotMethod::ServoTool { pose }, none)
        }
        "setpoints" | "setpoint" => {
            no_args(name, args)?;
            robot(RobotMethod::Setpoints, none)
        }
        "operating-state" => {
            no_args(name, args)?;
            robot(RobotMethod::OperatingState, none)
        }
        "map-joints" => {
            let Some((board, pairs)) = args.split_first() else {
                return Err(usage("`map-joints` needs BOARD J:A [J:A...]"));
            };
            if pairs.is_empty() {
                return Err(usage("`map-joints` needs at least one J:A pair"));
            }
            let joints = pairs
                .iter()
                .map(|p| {
                    let parsed = p
                        .split_once(':')
                        .and_then(|(j, a)| Some((j.parse::<u8>().ok()?, a.parse::<u8>().ok()?)));
                    parsed
                        .map(|(joint, axis)| JointAxis { joint, axis })
                        .ok_or_else(|| usage(format!("`{p}` is not JOINT:AXIS (0-based integers)")))
                })
                .collect::<anyhow::Result<Vec<_>>>()?;
            robot(
                RobotMethod::MapJoints {
                    board: board.clone(),
                    joints,
                },
                none,
            )
        }
        _ => Ok(None),
    }
}

/// The board methods;
/// `None` when `name` is not one of them.
fn board_method(name: &str, args: &[String]) -> anyhow::Result<Option<(Method, Hint)>> {
    match name {
        "axis-count" => {
            no_args(name, args)?;
            Ok(Some((
                Method::Board(BoardMethod::AxisCount),
                hint("axes", ""),
            )))
        }
        "read-encoders" | "encoders" => {
            no_args(name, args)?;
            Ok(Some((
                Method::Board(BoardMethod::ReadEncoders),
                hint("encoders", "counts"),
            )))
        }
        "amplifiers-enabled" | "amplifiers" => {
            no_args(name, args)?;
            Ok(Some((
                Method::Board(BoardMethod::AmplifiersEnabled),
                hint("amplifiers enabled", ""),
            )))
        }
        _ => Ok(None),
    }
}

/// The sensor methods;
/// `None` when `name` is not one of them.
fn sensor_method(name: &str, args: &[String]) -> anyhow::Result<Option<(Method, Hint)>> {
    let none = hint("", "");
    match name {
        "read" => {
            no_args(name, args)?;
            Ok(Some((Method::Sensor(SensorMethod::Read), none)))
        }
        "bias" => {
            no_args(name, args)?;
            Ok(Some((Method::Sensor(SensorMethod::Bias), none)))
        }
        "set-probe" => {
            let (pose, velocity) = probe(args)?;
            Ok(Some((
                Method::Sensor(SensorMethod::SetProbe { pose, velocity }),
                none,
            )))
        }
        "measure" => {
            let (pose, velocity) = probe(args)?;
            Ok(Some((
                Method::Sensor(SensorMethod::Measure { pose, velocity }),
                none,
            )))
        }
        "stream" => {
            no_args(name, args)?;
            Ok(Some((Method::Sensor(SensorMethod::Stream), none)))
        }
        _ => Ok(None),
    }
}

/// The controller methods;
/// `None` when `name` is not one of them.
fn controller_method(name: &str, args: &[String]) -> anyhow::Result<Option<(Method, Hint)>> {
    let none = hint("", "");
    match name {
        "set-robot" => {
            let robot = one(name, "the robot's name", args)?.to_string();
            Ok(Some((
                Method::Controller(ControllerMethod::SetRobot { robot }),
                none,
            )))
        }
        "set-trajectory" => {
            let trajectory = one(name, "the trajectory's name", args)?.to_string();
            Ok(Some((
                Method::Controller(ControllerMethod::SetTrajectory { trajectory }),
                none,
            )))
        }
        "set-sensor" => {
            let sensor = one(name, "the sensor's name or naming path", args)?.to_string();
            Ok(Some((
                Method::Controller(ControllerMethod::SetSensor { sensor }),
                none,
            )))
        }
        "set-gains" => {
            let gains = args.join(" ");
            gains
                .parse::<toml::Table>()
                .map_err(|e| usage(format!("set-gains: not TOML: {}", e.message())))?;
            Ok(Some((
                Method::Controller(ControllerMethod::SetGains { gains }),
                none,
            )))
        }
        "estop" | "e-stop" => {
            no_args(name, args)?;
            Ok(Some((Method::Controller(ControllerMethod::EStop), none)))
        }
        "rearm" => {
            no_args(name, args)?;
            Ok(Some((Method::Controller(ControllerMethod::Rearm), none)))
        }
        "status" => {
            no_args(name, args)?;
            Ok(Some((Method::Controller(ControllerMethod::Status), none)))
        }
        _ => Ok(None),
    }
}

/// The trajectory methods;
/// `None` when `name` is not one of them.
fn trajectory_method(name: &str, args: &[String]) -> anyhow::Result<Option<(Method, Hint)>> {
    let none = hint("", "");
    match name {
        "reference" => {
            let t_s = number(one(name, "the time T in seconds", args)?, "time")?;
            Ok(Some((
                Method::Trajectory(TrajectoryMethod::Reference { t_s }),
                none,
            )))
        }
        "duration" => {
            no_args(name, args)?;
            Ok(Some((Method::Trajectory(TrajectoryMethod::Duration), none)))
        }
        _ => Ok(None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn words(s: &str) -> Vec<String> {
        s.split_whitespace().map(String::from).collect()
    }

    fn no_lookup(_: RobotMethod) -> anyhow::Result<Reply> {
        anyhow::bail!("no lookup in this test")
    }

    #[test]
    fn methods_parse_with_their_arguments() {
        let mut lookup = no_lookup;
        let (m, _) = parse("fk", &words("0 -0.5,1 0 0 0"), &mut lookup).unwrap();
        assert_eq!(
            m,
            Method::Robot(RobotMethod::ForwardKinematics {
                q: Some(vec![0.0, -0.5, 1.0, 0.0, 0.0, 0.0])
            })
        );
        let (m, _) = parse("map-joints", &words("galil 0:0 1:2"), &mut lookup).unwrap();
        assert!(
            matches!(m, Method::Robot(RobotMethod::MapJoints { ref joints, .. }) if joints.len() == 2 && joints[1].axis == 2)
        );
        let (m, _) = parse("go-to", &words("work 2.0"), &mut lookup).unwrap();
        assert_eq!(
            m,
            Method::Robot(RobotMethod::GoTo {
                pose: NamedPose::Work,
                duration_s: 2.0
            })
        );
        let (m, _) = parse("move-jp", &words("0,0.1 -0.2 1.5"), &mut lookup).unwrap();
        assert_eq!(
            m,
            Method::Robot(RobotMethod::MoveJoints {
                q: vec![0.0, 0.1, -0.2],
                duration_s: 1.5
            })
        );
        let (m, _) = parse("move-cp", &words("0.5 0 0.2 1 0 0 0 -1 0 3"), &mut lookup).unwrap();
        let Method::Robot(RobotMethod::MoveTool { pose, duration_s }) = m else {
            panic!("{m:?}")
        };
        assert_eq!(
            (pose.position, pose.a, duration_s),
            ([0.5, 0.0, 0.2], [0.0, 0.0, -1.0], 3.0)
        );
        let (m, _) = parse("servo-jp", &words("0.1 0.2"), &mut lookup).unwrap();
        assert_eq!(
            m,
            Method::Robot(RobotMethod::ServoJoints { q: vec![0.1, 0.2] })
        );
        let (m, _) = parse("operating-state", &[], &mut lookup).unwrap();
        assert_eq!(m, Method::Robot(RobotMethod::OperatingState));
        let (m, _) = parse("setpoints", &[], &mut lookup).unwrap();
        assert_eq!(m, Method::Robot(RobotMethod::Setpoints));
        let (m, _) = parse("ik", &words("0.5 0 0.2 1 0 0 0 -1 0"), &mut lookup).unwrap();
        let Method::Robot(RobotMethod::InverseKinematics { pose }) = m else {
            panic!("{m:?}")
        };
        assert_eq!(pose.a, [0.0, 0.0, -1.0]);
        assert!(parse("activate", &[], &mut lookup).is_ok());
    }

    #[test]
    fn a_named_pose_is_looked_up_and_bad_input_is_a_usage_error() {
        let mut lookup = |m: RobotMethod| {
            assert_eq!(
                m,
                RobotMethod::NamedPose {
                    pose: NamedPose::Work
                }
            );
            Ok(Reply::Joints(vec![0.0; 6]))
        };
        let (m, _) = parse("gravity", &words("work"), &mut lookup).unwrap();
        assert_eq!(
            m,
            Method::Robot(RobotMethod::Gravity {
                q: Some(vec![0.0; 6])
            })
        );
        let mut lookup = no_lookup;
        for (name, args) in [
            ("fk", "0 nan 0"),
            ("fk", "0 inf"),
            ("go-to", "work -1"),
            ("go-to", "home 1"),
            ("move-jp", ""),
            ("move-jp", "2"),
            ("move-jp", "0 0 0 0"),
            ("move-jp", "0 0 0 nan"),
            ("move-cp", "0.5 0 0.2"),
            ("move-cp", "1 2 3"),
            ("servo-jp", ""),
            ("servo-cp", "1 2"),
            ("operating-state", "now"),
            ("map-joints", "b 0-1"),
            ("frobnicate", ""),
            ("status", "now"),
            ("ik", "1 2"),
            ("ik", "0 0 0 1 1 0 0 1 0"),
            ("set-gains", "kp = ["),
        ] {
            let err = parse(name, &words(args), &mut lookup).unwrap_err();
            assert!(
                err.downcast_ref::<crate::cli::UsageError>().is_some(),
                "{name} {args}: {err}"
            );
        }
    }
}
