//! Reset never starts motion (issue 30), for a teleoperation slave: the paper's task made of
//! objects on one node (an FRHC held by the scripted operator's hand, a PUMA 200 over a wall
//! with a wrist sensor, position-forward / force-back), stepped on a simulated clock; the slave
//! is e-stopped while the master moves on, then re-armed and activated again.

use penelope_hal::{Frame, Timestamp, Transition};
use penelope_rt_core::cell::Stamped;
use penelope_rt_core::control::ControlCommand;
use penelope_rt_core::safety::SafetyState;
use penelope_rt_core::telemetry::TelemetrySample;
use penelope_supervisor::objects::{Creator, CreatorConfig, DetachedLoop};
use penelope_supervisor::proto::{
    ControllerMethod, JointAxis, Method, PoseMsg, Reply, RobotMethod, SensorMethod,
};

fn create(c: &Creator, kind: &str, name: &str, config: &str) {
    c.create(kind, name, config)
        .unwrap_or_else(|e| panic!("create {name}: {e}"));
}

fn ok(c: &Creator, name: &str, method: Method) -> Reply {
    c.call_object(name, method)
        .unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn map_all(c: &Creator, robot: &str, board: &str) {
    ok(
        c,
        robot,
        Method::Robot(RobotMethod::MapJoints {
            board: board.into(),
            joints: (0..6).map(|j| JointAxis { joint: j, axis: j }).collect(),
        }),
    );
}

fn relate(c: &Creator, controller: &str, robot: &str, sensor: Option<&str>) {
    let mut methods = vec![
        ControllerMethod::SetRobot {
            robot: robot.into(),
        },
        ControllerMethod::SetTrajectory {
            trajectory: "link".into(),
        },
    ];
    if let Some(s) = sensor {
        methods.push(ControllerMethod::SetSensor { sensor: s.into() });
    }
    for m in methods {
        ok(c, controller, Method::Controller(m));
    }
}

/// The task's objects, configured; the wall 4 cm below the slave's tool at its start pose.
fn the_task() -> Creator {
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
    map_all(&c, "frhc", "frhc-io");
    map_all(&c, "puma", "puma-io");
    relate(&c, "display", "frhc", None);
    relate(&c, "follow", "puma", Some("wrist"));
    for name in [
        "frhc-io", "puma-io", "wrist", "hand", "frhc", "puma", "link", "display", "follow",
    ] {
        ok(&c, name, Method::Transition(Transition::Configure));
    }
    c
}

/// Every control tick of both sides for `seconds` of simulated time (communication every
/// 2 ms, control every 1 ms, the sensor feed's work done here), with `at(tick, slave)` called
/// before each control tick.
fn run(
    c: &Creator,
    seconds: f64,
    mut at: impl FnMut(u64, Timestamp, &mut DetachedLoop),
) -> (Vec<TelemetrySample>, Vec<TelemetrySample>) {
    let mut master = c.detach_loop("display").expect("the master's loop builds");
    let mut slave = c.detach_loop("follow").expect("the slave's loop builds");
    let mut wrench = slave.wrench.take().expect("a sensor is bound");
    let (mut m_rows, mut s_rows) = (Vec::new(), Vec::new());
    for i in 1..=(seconds * 1000.0) as u64 {
        let now = Timestamp::from_nanos(i * 1_000_000);
        if i % 2 == 1 {
            master.comm.tick(now);
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

fn at_ms(rows: &[TelemetrySample], ms: u64) -> &TelemetrySample {
    rows.iter()
        .find(|s| s.time.as_nanos() >= ms * 1_000_000)
        .expect("a sample at that time")
}

#[test]
fn a_rearmed_teleoperation_slave_reanchors_where_it_is_and_follows_without_a_jump() {
    const ESTOP_MS: u64 = 2_500;
    const REARM_MS: u64 = 2_800;
    let c = the_task();
    let (master, slave) = run(&c, 4.0, |i, now, slave| {
        if i == ESTOP_MS {
            slave.control.apply(now, ControlCommand::EStop);
        }
        if i == REARM_MS {
            slave.control.apply(now, ControlCommand::Rearm);
            slave.control.apply(now, ControlCommand::Activate);
        }
    });
    // Latched while the master moved on.
    assert_eq!(at_ms(&slave, ESTOP_MS + 10).state, SafetyState::EStop);
    let master_moved =
        (at_ms(&master, REARM_MS).tool_position - at_ms(&master, ESTOP_MS).tool_position).norm();
    println!(
        "the master moved {:.1} mm while the slave was e-stopped",
        master_moved * 1e3
    );
    assert!(
        master_moved > 0.005,
        "the test needs a master that moves: {master_moved} m"
    );

    // Re-armed: it runs again within a few periods (not waiting for a clutch or a link loss).
    let back = slave
        .iter()
        .find(|s| s.time.as_nanos() > REARM_MS * 1_000_000 && s.state == SafetyState::Running)
        .expect("the slave never followed again after its re-arm");
    let resumed_after = back.time.as_nanos() / 1_000_000 - REARM_MS;
    println!("re-armed slave following again {resumed_after} ms after the re-arm");
    assert!(resumed_after <= 20, "{resumed_after} ms");

    // No jump: in the 200 ms after the re-arm the slave moves no more than the master does
    // (scale 1), plus a little for its tracking; never by the offset the master built up.
    let window = |rows: &[TelemetrySample], from: u64, to: u64| {
        (at_ms(rows, to).tool_position - at_ms(rows, from).tool_position).norm()
    };
    let slave_moved = window(&slave, REARM_MS, REARM_MS + 200);
    let master_then = window(&master, REARM_MS, REARM_MS + 200);
    println!(
        "200 ms after the re-arm: slave moved {:.2} mm, master {:.2} mm (offset built while \
         stopped {:.1} mm)",
        slave_moved * 1e3,
        master_then * 1e3,
        master_moved * 1e3
    );
    assert!(
        slave_moved <= master_then + 0.003,
        "the slave jumped: {slave_moved} m against the master's {master_then} m"
    );
    // Following from where it is: over the next second its motion is the master's (scale 1).
    let slave_d = at_ms(&slave, REARM_MS + 1_000).tool_position - back.tool_position;
    let master_d = at_ms(&master, REARM_MS + 1_000).tool_position
        - at_ms(&master, back.time.as_nanos() / 1_000_000).tool_position;
    println!(
        "the second after: slave moved {:.1} mm, master {:.1} mm, difference {:.1} mm",
        slave_d.norm() * 1e3,
        master_d.norm() * 1e3,
        (slave_d - master_d).norm() * 1e3
    );
    assert!(
        (slave_d - master_d).norm() < 0.01 + 0.2 * master_d.norm(),
        "the slave does not follow the master's motion: {slave_d:?} vs {master_d:?}"
    );
    assert!(
        slave
            .iter()
            .filter(|s| s.time > back.time)
            .all(|s| s.state == SafetyState::Running),
        "the slave stopped following"
    );
}
