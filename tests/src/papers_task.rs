//! The paper's task made of objects on one in-process node, as `ctl` would make it: an FRHC held
//! by the scripted operator's hand, a PUMA 200 over a wall with a wrist sensor, the channel
//! between them (`trajectory/teleop`, named `link`) and the two halves of position-forward /
//! force-back (`display` on the master, `follow` on the slave); and its loops stepped on a
//! simulated clock.

use penelope_hal::{Frame, Timestamp, Transition};
use penelope_protocol::proto::{
    ControllerMethod, JointAxis, Method, PoseMsg, Reply, RobotMethod, SensorMethod,
};
use penelope_rt_core::cell::Stamped;
use penelope_rt_core::telemetry::TelemetrySample;
use penelope_runtime::objects::{Creator, CreatorConfig, DetachedLoop};

/// Creates `kind` `name` with `config` (TOML), panicking with the reason on an error.
pub fn create(c: &Creator, kind: &str, name: &str, config: &str) {
    c.create(kind, name, config)
        .unwrap_or_else(|e| panic!("create {name}: {e}"));
}

/// Calls `method` on `name`, panicking with the reason on an error.
pub fn ok(c: &Creator, name: &str, method: Method) -> Reply {
    c.call_object(name, method)
        .unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// Maps the six joints of `robot` to the first six axes of `board`.
pub fn map_all(c: &Creator, robot: &str, board: &str) {
    ok(
        c,
        robot,
        Method::Robot(RobotMethod::MapJoints {
            board: board.into(),
            joints: (0..6).map(|j| JointAxis { joint: j, axis: j }).collect(),
        }),
    );
}

/// Binds `controller` to `robot`, `trajectory` and, if given, `sensor`.
pub fn relate(c: &Creator, controller: &str, robot: &str, trajectory: &str, sensor: Option<&str>) {
    let mut methods = vec![
        ControllerMethod::SetRobot {
            robot: robot.into(),
        },
        ControllerMethod::SetTrajectory {
            trajectory: trajectory.into(),
        },
    ];
    if let Some(s) = sensor {
        methods.push(ControllerMethod::SetSensor { sensor: s.into() });
    }
    for m in methods {
        ok(c, controller, Method::Controller(m));
    }
}

/// The task's objects, configured (not active) on a node `lab` at normal priority; the wall
/// 4 cm below the slave's tool at its start pose.
pub fn papers_task() -> Creator {
    let mut config = CreatorConfig::new("lab");
    config.rt.priority = None;
    let c = Creator::new(config);
    create(&c, "robot/puma200", "puma", "");
    let start = match ok(
        &c,
        "puma",
        Method::Robot(RobotMethod::NamedPose {
            pose: penelope_hal::NamedPose::Start,
        }),
    ) {
        Reply::Joints(q) => q,
        other => panic!("named pose answered {other:?}"),
    };
    let tool = match ok(
        &c,
        "puma",
        Method::Robot(RobotMethod::ForwardKinematics { q: Some(start) }),
    ) {
        Reply::Pose(p) => p.position,
        other => panic!("fk answered {other:?}"),
    };
    let wall = format!(
        "[[shapes]]\nkind = \"plane\"\npoint = [{}, {}, {}]\nnormal = [0.0, 0.0, 1.0]\n\
         stiffness = 4000.0\ndamping = 20.0\n",
        tool[0],
        tool[1],
        tool[2] - 0.04
    );
    create(&c, "board/sim", "puma-io", &wall);
    create(&c, "sensor/virtual", "wrist", &wall);
    create(&c, "robot/frhc", "frhc", "");
    create(&c, "board/sim", "frhc-io", "");
    create(&c, "sensor/operator-hand", "hand", "robot = \"frhc\"");
    create(
        &c,
        "trajectory/teleop",
        "link",
        "master = \"frhc\"\nslave = \"puma\"\nforce_gain = 0.5",
    );
    create(&c, "controller/force-display", "display", "");
    create(&c, "controller/slave-tracking", "follow", "");
    connect_and_configure(&c);
    c
}

/// Connects the task's objects, created already: each robot mapped onto its board (`frhc` on
/// `frhc-io`, `puma` on `puma-io`), `display` and `follow` bound to their robots and the
/// channel `link` (`follow` with the sensor `wrist`), and configures every one in a system
/// file's order (boards and sensors before robots, the channel before its laws).
pub fn connect_and_configure(c: &Creator) {
    map_all(c, "frhc", "frhc-io");
    map_all(c, "puma", "puma-io");
    relate(c, "display", "frhc", "link", None);
    relate(c, "follow", "puma", "link", Some("wrist"));
    for name in [
        "frhc-io", "puma-io", "wrist", "hand", "frhc", "puma", "link", "display", "follow",
    ] {
        ok(c, name, Method::Transition(Transition::Configure));
    }
}

/// Steps both sides of the task every control tick for `seconds` of simulated time: control
/// every 1 ms, communication every 2 ms (the master's only until `master_silent_after`
/// seconds), the wrist sensor's feed done here as its thread would; `at(tick, now, slave)` runs
/// before each control tick. Returns the master's and the slave's telemetry.
pub fn step_papers_task(
    c: &Creator,
    seconds: f64,
    master_silent_after: f64,
    mut at: impl FnMut(u64, Timestamp, &mut DetachedLoop),
) -> (Vec<TelemetrySample>, Vec<TelemetrySample>) {
    let mut master = c.detach_loop("display").expect("the master's loop builds");
    let mut slave = c.detach_loop("follow").expect("the slave's loop builds");
    let mut wrench = slave.wrench.take().expect("a sensor is bound");
    let (mut m_rows, mut s_rows) = (Vec::new(), Vec::new());
    for i in 1..=(seconds * 1000.0) as u64 {
        let now = Timestamp::from_nanos(i * 1_000_000);
        if i % 2 == 1 {
            if (i as f64) < master_silent_after * 1000.0 {
                master.comm.tick(now);
            }
            slave.comm.tick(now);
            if let Some(s) = slave.probe.latest() {
                let pose = match ok(
                    c,
                    "puma",
                    Method::Robot(RobotMethod::ForwardKinematics {
                        q: Some(s.q.iter().take(6).copied().collect()),
                    }),
                ) {
                    Reply::Pose(p) => p,
                    other => panic!("fk answered {other:?}"),
                };
                let measured = ok(
                    c,
                    "wrist",
                    Method::Sensor(SensorMethod::Measure {
                        pose: PoseMsg { ..pose },
                        velocity: [0.0; 3],
                    }),
                );
                if let Reply::Wrench(w) = measured {
                    wrench.write(Stamped {
                        stamp: now,
                        value: w.to_wrench(Frame::Base).unwrap(),
                    });
                }
            }
        }
        at(i, now, &mut slave);
        master.control.tick(now);
        slave.control.tick(now);
        while let Some(s) = master.telemetry.pop().map(|t| t.sample) {
            m_rows.push(s);
        }
        while let Some(s) = slave.telemetry.pop().map(|t| t.sample) {
            s_rows.push(s);
        }
    }
    (m_rows, s_rows)
}

/// The demo's two teleoperation loops as objects, configured (not active) on `config`'s node:
/// an FRHC held by the scripted hand under force display (`display`), a PUMA 200 with a wrist
/// sensor following against a wall 10 cm up (`follow`), the channel `link` between them with
/// `link_settings` (TOML lines) added to its master and slave.
pub fn wall_pair(config: CreatorConfig, link_settings: &str) -> Creator {
    let c = Creator::new(config);
    let wall = "[[shapes]]\nkind = \"plane\"\npoint = [0, 0, 0.1]";
    let link = format!("master = \"frhc\"\nslave = \"puma\"\n{link_settings}");
    for (kind, name, cfg) in [
        ("robot/frhc", "frhc", ""),
        ("board/sim", "frhc-io", ""),
        ("sensor/operator-hand", "hand", "robot = \"frhc\""),
        ("robot/puma200", "puma", ""),
        ("board/sim", "puma-io", wall),
        ("sensor/virtual", "wrist", wall),
        ("trajectory/teleop", "link", link.as_str()),
        ("controller/force-display", "display", ""),
        ("controller/slave-tracking", "follow", ""),
    ] {
        create(&c, kind, name, cfg);
    }
    map_all(&c, "frhc", "frhc-io");
    map_all(&c, "puma", "puma-io");
    relate(&c, "display", "frhc", "link", None);
    relate(&c, "follow", "puma", "link", Some("wrist"));
    for name in [
        "frhc-io", "puma-io", "wrist", "hand", "frhc", "puma", "link", "display", "follow",
    ] {
        ok(&c, name, Method::Transition(Transition::Configure));
    }
    c
}
