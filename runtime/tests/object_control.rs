//! The creator in-process (no network): a PUMA 560 on two simulated boards driven by a joint PID
//! along a trajectory and by GoTo, with telemetry through an outbox, and destroying a board the
//! running loop uses (refused, then forced).

use std::time::Duration;

use penelope_hal::{NamedPose, Transition};
use penelope_protocol::proto::{
    BoardMethod, Call, CallError, ControllerMethod, CreatorCall, Method, Reply, RobotMethod,
    ServerMsg, WireError,
};
use penelope_protocol::service::{OutboxReceiver, Service, Session};
use penelope_runtime::objects::{Creator, CreatorConfig};

mod common;

use common::*;

#[test]
fn a_puma_on_two_boards_follows_its_trajectory_streams_telemetry_and_goes_to_work() {
    // SCHED_FIFO where the process may use it (else normal priority, said in `describe`).
    let c = Creator::new(CreatorConfig::new("lab"));
    let (s, rx) = session(1);
    let (start, goal) = a_puma_with_a_ramp_from_its_start_pose(&c, &s);
    // Before activation: the measured state is the simulated body's start pose.
    let q0 = joints(call(
        &c,
        &s,
        ("robot", Method::Robot(RobotMethod::JointPositions)),
    ));
    assert!(max_error(&q0, &start) < 1e-6);

    let subscription = subscribe_and_activate(&c, &s);
    settles_at_the_goal(&c, &s, &goal);
    telemetry_arrived_decimated_and_in_order(&rx, subscription);
    let work = goes_to_work(&c, &s);
    a_forced_destroy_stops_the_loop_where_it_is(&c, &s, &work);
    c.closed(&s);
    assert_eq!(c.subscription_count(), 0);
}

/// The PUMA on two boards, its PID following a 0.6 s ramp from the start pose to a goal a few
/// tenths of a radian away; returns the start pose and the goal.
fn a_puma_with_a_ramp_from_its_start_pose(c: &Creator, s: &Session) -> (Vec<f64>, Vec<f64>) {
    create(c, s, "robot/puma560", "probe-model", "");
    let start = joints(call(
        c,
        s,
        (
            "probe-model",
            Method::Robot(RobotMethod::NamedPose {
                pose: NamedPose::Start,
            }),
        ),
    ));
    let goal: Vec<f64> = start
        .iter()
        .zip([0.2, -0.1, 0.1, 0.2, 0.1, 0.2])
        .map(|(q, d)| q + d)
        .collect();
    let goal_text = format!(
        "goal = [{}]\nduration_s = 0.6",
        goal.iter()
            .map(|x| x.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    puma_on_two_boards(c, s, "trajectory/ramp", &goal_text);
    (start, goal)
}

/// Subscribes to the PID's telemetry (one tick in ten) and activates it: everything it uses
/// shows active.
fn subscribe_and_activate(c: &Creator, s: &Session) -> u64 {
    let Ok(Reply::Subscribed { subscription }) = c.call(
        s,
        Call::Subscribe {
            object: "pid".into(),
            decimation: 10,
        },
    ) else {
        panic!("subscribe")
    };
    let info = lifecycle(c, s, "pid", Transition::Activate).unwrap();
    assert!(matches!(info, Reply::Object(o) if o.state == penelope_hal::LifecycleState::Active));
    for used in ["robot", "b1", "b2", "traj"] {
        assert_eq!(
            c.info(used).unwrap().state,
            penelope_hal::LifecycleState::Active,
            "{used} shows active while the loop runs"
        );
    }
    subscription
}

/// The ramp ends after 0.6 s; the robot settles at the goal.
fn settles_at_the_goal(c: &Creator, s: &Session, goal: &[f64]) {
    wait_for("the goal", Duration::from_secs(5), || {
        try_joints(call(
            c,
            s,
            ("robot", Method::Robot(RobotMethod::JointPositions)),
        ))
        .is_some_and(|q| max_error(&q, goal) < 0.02)
    });
    let Ok(Reply::Status(status)) = ctl(c, s, "pid", ControllerMethod::Status) else {
        panic!("status")
    };
    assert!(status.running && status.ticks > 100);
    let last = status.last.unwrap();
    assert!(last.state == "running", "state {}", last.state);
    assert!(max_error(&last.q, goal) < 0.03);
}

/// Telemetry batches arrived, samples decimated and in order.
fn telemetry_arrived_decimated_and_in_order(rx: &OutboxReceiver, subscription: u64) {
    let mut seqs = Vec::new();
    while let Ok(m) = rx.rx.try_recv() {
        if let ServerMsg::Telemetry(b) = m {
            assert_eq!(b.subscription, subscription);
            seqs.extend(b.samples.iter().map(|r| r.seq));
        }
    }
    assert!(seqs.len() > 20, "{} samples", seqs.len());
    assert!(seqs.windows(2).all(|w| w[1] > w[0]), "increasing seq");
    assert!(seqs.iter().all(|q| q % 10 == 0), "decimated by 10");
}

/// GoTo work, through the active controller; returns the work pose.
fn goes_to_work(c: &Creator, s: &Session) -> Vec<f64> {
    let work = joints(call(
        c,
        s,
        (
            "robot",
            Method::Robot(RobotMethod::NamedPose {
                pose: NamedPose::Work,
            }),
        ),
    ));
    call(
        c,
        s,
        (
            "robot",
            Method::Robot(RobotMethod::GoTo {
                pose: NamedPose::Work,
                duration_s: 2.0,
            }),
        ),
    )
    .unwrap();
    wait_for("the work pose", Duration::from_secs(10), || {
        try_joints(call(
            c,
            s,
            ("robot", Method::Robot(RobotMethod::JointPositions)),
        ))
        .is_some_and(|q| max_error(&q, &work) < 0.02)
    });
    assert!(matches!(
        call(c, s, ("b1", Method::Board(BoardMethod::AmplifiersEnabled))),
        Ok(Reply::Flag(true))
    ));
    work
}

/// Destroy is refused while active, then forced: the loop stops, amplifiers off, and the
/// body keeps its pose.
fn a_forced_destroy_stops_the_loop_where_it_is(c: &Creator, s: &Session, work: &[f64]) {
    match c.call(
        s,
        Call::Creator(CreatorCall::Destroy {
            name: "b2".into(),
            force: false,
        }),
    ) {
        Err(WireError::Call(CallError::InUse { dependents, .. })) => {
            assert_eq!(dependents, vec!["pid".to_string()])
        }
        other => panic!("expected InUse, got {other:?}"),
    }
    c.call(
        s,
        Call::Creator(CreatorCall::Destroy {
            name: "b2".into(),
            force: true,
        }),
    )
    .unwrap();
    assert!(c.info("b2").is_none());
    let Ok(Reply::Status(status)) = ctl(c, s, "pid", ControllerMethod::Status) else {
        panic!("status")
    };
    assert!(!status.running);
    assert_eq!(status.state, penelope_hal::LifecycleState::Inactive);
    assert_eq!(
        c.info("robot").unwrap().state,
        penelope_hal::LifecycleState::Inactive
    );
    assert!(matches!(
        call(c, s, ("b1", Method::Board(BoardMethod::AmplifiersEnabled))),
        Ok(Reply::Flag(false))
    ));
    // The body kept its pose across the stop.
    let q = joints(call(
        c,
        s,
        ("robot", Method::Robot(RobotMethod::JointPositions)),
    ));
    assert!(max_error(&q, work) < 0.05);
}
