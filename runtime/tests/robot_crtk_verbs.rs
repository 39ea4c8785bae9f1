//! The CRTK verbs on a simulated PUMA 560 under a joint PID, on the simulated clock: `move_jp`
//! and `move_cp` reach their goals and `is_busy` says when; `servo_jp` streamed at one target
//! per control tick is tracked; a stream that stops holds the loop (reference stale) and then
//! runs on, still, without a fault; every refusal is typed.

use std::time::Duration;

use penelope_hal::{NamedPose, Transition};
use penelope_protocol::proto::{
    CallError, Method, OperatingStateMsg, PoseMsg, Reply, RobotMethod, SetpointsMsg, WireError,
};
use penelope_runtime::objects::clock::ClockMode;
use penelope_runtime::objects::runtime::MAX_SERVO_STEP_RAD;
use penelope_runtime::objects::{Creator, CreatorConfig};

mod common;
use common::{arm_controller, max_error, ok, puma_on_sim_board};

/// The joint PID's gains: its defaults, with an integral term.
const PID: &str = "ki = [8000.0, 8000.0, 8000.0, 800.0, 800.0, 800.0]\n\
                   integral_limit = [30.0, 30.0, 30.0, 3.0, 3.0, 3.0]";

/// One control tick of the joint PID (its default period).
const TICK: Duration = Duration::from_millis(1);

fn robot(c: &Creator, m: RobotMethod) -> Result<Reply, WireError> {
    c.call_object("arm", Method::Robot(m))
        .map_err(WireError::from)
}

fn joints_of(r: Reply) -> Vec<f64> {
    match r {
        Reply::Joints(q) => q,
        other => panic!("expected joints, got {other:?}"),
    }
}

fn measured(c: &Creator) -> Vec<f64> {
    joints_of(robot(c, RobotMethod::JointPositions).unwrap())
}

fn state(c: &Creator) -> OperatingStateMsg {
    match robot(c, RobotMethod::OperatingState).unwrap() {
        Reply::OperatingState(s) => s,
        other => panic!("expected an operating state, got {other:?}"),
    }
}

fn setpoints(c: &Creator) -> SetpointsMsg {
    match robot(c, RobotMethod::Setpoints).unwrap() {
        Reply::Setpoints(s) => s,
        other => panic!("expected setpoints, got {other:?}"),
    }
}

fn fk(c: &Creator, q: Option<Vec<f64>>) -> PoseMsg {
    match robot(c, RobotMethod::ForwardKinematics { q }).unwrap() {
        Reply::Pose(p) => p,
        other => panic!("expected a pose, got {other:?}"),
    }
}

fn advance(c: &Creator, by: Duration) {
    c.advance(by).unwrap();
}

/// A node on the simulated clock with a PUMA 560 `arm` on one simulated board, a joint PID
/// `pid` holding it at its start pose (a step to the start pose), not active yet; returns the
/// creator and the start pose.
fn puma() -> (Creator, Vec<f64>) {
    let mut config = CreatorConfig::new("crtk");
    config.clock = ClockMode::Simulated;
    config.rt.priority = None;
    let c = puma_on_sim_board(config);
    let start = joints_of(ok(
        &c,
        "arm",
        Method::Robot(RobotMethod::NamedPose {
            pose: NamedPose::Start,
        }),
    ));
    let goal = start
        .iter()
        .map(|x| x.to_string())
        .collect::<Vec<_>>()
        .join(", ");
    c.create("trajectory/step", "hold", &format!("goal = [{goal}]"))
        .unwrap();
    ok(&c, "hold", Method::Transition(Transition::Configure));
    // An integral term, so that joint friction leaves no steady-state error at the goal.
    arm_controller(&c, "controller/joint-pid", "pid", PID, "hold");
    (c, start)
}

/// [`puma`], activated and run for 200 ms.
fn running_puma() -> (Creator, Vec<f64>) {
    let (c, start) = puma();
    ok(&c, "pid", Method::Transition(Transition::Activate));
    advance(&c, Duration::from_millis(200));
    assert_eq!(state(&c).state, "ENABLED");
    (c, start)
}

/// Advances in `step`s until `done`, at most `limit` of simulated time; returns the time taken.
fn advance_until(
    c: &Creator,
    step: Duration,
    limit: Duration,
    mut done: impl FnMut(&Creator) -> bool,
) -> Duration {
    let mut t = Duration::ZERO;
    while !done(c) {
        assert!(t < limit, "not done after {t:?} of simulated time");
        advance(c, step);
        t += step;
    }
    t
}

#[test]
fn move_jp_reaches_its_goal_within_a_milliradian_and_is_busy_until_it_does() {
    let (c, start) = running_puma();
    assert!(!state(&c).is_busy, "nothing moves yet");
    let goal: Vec<f64> = start
        .iter()
        .zip([0.3, -0.2, 0.25, 0.4, -0.3, 0.5])
        .map(|(q, d)| q + d)
        .collect();
    robot(
        &c,
        RobotMethod::MoveJoints {
            q: goal.clone(),
            duration_s: 1.0,
        },
    )
    .unwrap();
    let s = state(&c);
    assert!(s.is_busy && s.is_homed, "{s:?}");
    let took = advance_until(&c, Duration::from_millis(5), Duration::from_secs(4), |c| {
        !state(c).is_busy
    });
    let error = max_error(&measured(&c), &goal);
    println!(
        "move_jp: busy for {:.3} s of a 1 s move, {:.3} mrad from the goal",
        took.as_secs_f64(),
        error * 1e3
    );
    assert!(
        took >= Duration::from_secs(1),
        "not busy to the end: {took:?}"
    );
    assert!(error < 1e-3, "{:.3} mrad from the goal", error * 1e3);
    assert_eq!(state(&c).state, "ENABLED");
    // The setpoint is the goal, and its pose the goal's tool pose.
    let sp = setpoints(&c);
    assert!(max_error(sp.joints.as_ref().unwrap(), &goal) < 1e-9);
    let want = fk(&c, Some(goal.clone()));
    let got = sp.pose.unwrap();
    assert!(max_error(&got.position, &want.position) < 1e-9);
    assert!(sp.time_ns > 1_000_000_000);
}

#[test]
fn move_cp_puts_the_tool_within_a_millimetre_of_the_pose() {
    let (c, _) = running_puma();
    let here = fk(&c, None);
    let target = PoseMsg {
        position: [
            here.position[0] + 0.05,
            here.position[1] - 0.04,
            here.position[2] - 0.03,
        ],
        ..here
    };
    robot(
        &c,
        RobotMethod::MoveTool {
            pose: target,
            duration_s: 1.0,
        },
    )
    .unwrap();
    assert!(state(&c).is_busy);
    advance_until(&c, Duration::from_millis(5), Duration::from_secs(4), |c| {
        !state(c).is_busy
    });
    let reached = fk(&c, None);
    let error = max_error(&reached.position, &target.position);
    println!("move_cp: {:.3} mm from the pose", error * 1e3);
    assert!(error < 1e-3, "{:.3} mm from the pose", error * 1e3);
}

#[test]
fn servo_jp_at_one_target_per_control_tick_is_tracked_and_cancels_a_move() {
    let (c, start) = running_puma();
    // A move under way; the first servo target cancels it.
    let far: Vec<f64> = start.iter().map(|q| q + 0.3).collect();
    robot(
        &c,
        RobotMethod::MoveJoints {
            q: far,
            duration_s: 3.0,
        },
    )
    .unwrap();
    advance(&c, Duration::from_millis(100));
    assert!(state(&c).is_busy);
    // From the current reference, a sine of 0.1 rad at 0.5 Hz on every joint: at most 0.3 mrad
    // per tick, well inside the step limit.
    let from = setpoints(&c).joints.unwrap();
    let target = |k: u32| -> Vec<f64> {
        let t = f64::from(k) * TICK.as_secs_f64();
        let d = 0.1 * (std::f64::consts::PI * t).sin();
        from.iter().map(|q| q + d).collect()
    };
    let mut worst: f64 = 0.0;
    let mut squares = 0.0;
    let mut counted = 0.0;
    let (mut lowest, mut highest) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut sent = Vec::new();
    for k in 1..=2000u32 {
        let q = target(k);
        robot(&c, RobotMethod::ServoJoints { q: q.clone() }).unwrap();
        sent.push(q);
        advance(&c, TICK);
        if k == 5 {
            assert!(!state(&c).is_busy, "the servo target cancelled the move");
        }
        let s = state(&c);
        assert_eq!(s.state, "ENABLED", "tick {k}: {s:?}");
        // After the first half second (the cancelled move's momentum gone), the error to the
        // newest target: the PID's lag behind a moving reference.
        if k > 500 {
            let q = measured(&c);
            let e = max_error(&q, &sent[k as usize - 1]);
            worst = worst.max(e);
            squares += e * e;
            counted += 1.0;
            lowest = lowest.min(q[0] - from[0]);
            highest = highest.max(q[0] - from[0]);
        }
    }
    let rms = (squares / counted).sqrt();
    println!(
        "servo_jp: tracking error at most {:.1} mrad, RMS {:.1} mrad; joint 0 swept {:.1} of \
         the 200 mrad the targets sweep",
        worst * 1e3,
        rms * 1e3,
        (highest - lowest) * 1e3
    );
    // It follows: the whole sweep, with a lag far smaller than the motion.
    assert!(highest - lowest > 0.18, "swept {:.3} rad", highest - lowest);
    assert!(worst < 0.04, "tracking error {:.1} mrad", worst * 1e3);
    assert!(rms < 0.02, "RMS tracking error {:.1} mrad", rms * 1e3);
    // The setpoint is a target sent (the newest, or the one before it).
    let sp = setpoints(&c).joints.unwrap();
    let last = sent.len() - 1;
    assert!(
        max_error(&sp, &sent[last]) < 1e-12 || max_error(&sp, &sent[last - 1]) < 1e-12,
        "the setpoint is not a target sent"
    );
}

#[test]
fn a_servo_stream_that_stops_holds_the_loop_then_runs_on_still() {
    let (c, start) = running_puma();
    let mut last = start.clone();
    for k in 1..=100 {
        last = start.iter().map(|q| q + 0.0002 * f64::from(k)).collect();
        robot(&c, RobotMethod::ServoJoints { q: last.clone() }).unwrap();
        advance(&c, TICK);
    }
    assert_eq!(state(&c).state, "ENABLED");
    // The stream stops: past the 50 ms reference watchdog the loop holds (PAUSED).
    let paused_after = advance_until(&c, TICK, Duration::from_millis(200), |c| {
        state(c).state == "PAUSED"
    });
    println!("servo stream stopped: paused after {paused_after:?}");
    assert!(
        paused_after >= Duration::from_millis(45),
        "{paused_after:?}"
    );
    // Then the communication task holds where the robot is with fresh references: the loop
    // runs on, still, and never reaches the reference-timeout fault.
    advance_until(&c, TICK, Duration::from_millis(100), |c| {
        state(c).state == "ENABLED"
    });
    let here = measured(&c);
    for _ in 0..100 {
        advance(&c, Duration::from_millis(10));
        let s = state(&c);
        assert_eq!(s.state, "ENABLED", "{s:?}");
    }
    let drift = max_error(&measured(&c), &here);
    println!(
        "held for 1 s: drift {:.3} mrad, {:.3} mrad from the last target",
        drift * 1e3,
        max_error(&here, &last) * 1e3
    );
    assert!(drift < 2e-3, "drifted {:.3} mrad", drift * 1e3);
    assert!(max_error(&here, &last) < 0.03);
    // A new stream takes over again.
    let next: Vec<f64> = here.iter().map(|q| q + 0.01).collect();
    robot(&c, RobotMethod::ServoJoints { q: next.clone() }).unwrap();
    advance(&c, Duration::from_millis(20));
    assert!(max_error(&setpoints(&c).joints.unwrap(), &next) < 1e-12);
}

fn bad(r: Result<Reply, WireError>, what: &str, says: &str) {
    match r {
        Err(WireError::Call(CallError::BadArgument(m))) => {
            assert!(m.contains(says), "{what}: {m:?} does not say {says:?}")
        }
        other => panic!("{what}: expected BadArgument, got {other:?}"),
    }
}

fn not_ready(r: Result<Reply, WireError>, what: &str) {
    assert!(
        matches!(r, Err(WireError::Call(CallError::NotReady(_)))),
        "{what}: expected NotReady, got {r:?}"
    );
}

#[test]
fn every_refusal_is_typed() {
    let (c, start) = puma();
    // No active controller: moves, servo targets and setpoints are not ready; the state says
    // DISABLED.
    let here = fk(&c, None);
    for (what, m) in [
        (
            "move_jp",
            RobotMethod::MoveJoints {
                q: start.clone(),
                duration_s: 1.0,
            },
        ),
        (
            "move_cp",
            RobotMethod::MoveTool {
                pose: here,
                duration_s: 1.0,
            },
        ),
        ("servo_jp", RobotMethod::ServoJoints { q: start.clone() }),
        ("servo_cp", RobotMethod::ServoTool { pose: here }),
        ("setpoints", RobotMethod::Setpoints),
    ] {
        not_ready(robot(&c, m), what);
    }
    let s = state(&c);
    assert_eq!(
        (s.state.as_str(), s.is_busy, s.is_homed),
        ("DISABLED", false, true)
    );

    ok(&c, "pid", Method::Transition(Transition::Activate));
    advance(&c, Duration::from_millis(100));
    let mv = |q: Vec<f64>, duration_s: f64| robot(&c, RobotMethod::MoveJoints { q, duration_s });
    bad(mv(start[..5].to_vec(), 1.0), "five joints", "expected 6");
    let mut nan = start.clone();
    nan[2] = f64::NAN;
    bad(mv(nan.clone(), 1.0), "a NaN", "NaN");
    let mut beyond = start.clone();
    beyond[1] = 10.0;
    bad(mv(beyond.clone(), 1.0), "past a limit", "joint limits");
    for d in [0.0, -1.0, f64::NAN, f64::INFINITY, 3600.5] {
        bad(mv(start.clone(), d), "a bad duration", "duration");
    }
    // Too fast for the joints' velocity limits (the loop would fault on the way): refused,
    // saying how long it must take.
    let work = joints_of(ok(
        &c,
        "arm",
        Method::Robot(RobotMethod::NamedPose {
            pose: NamedPose::Work,
        }),
    ));
    bad(mv(work.clone(), 0.5), "too fast", "velocity limit");
    let far = PoseMsg {
        position: [5.0, 0.0, 0.0],
        ..here
    };
    bad(
        robot(
            &c,
            RobotMethod::MoveTool {
                pose: far,
                duration_s: 1.0,
            },
        ),
        "an unreachable pose",
        "cannot reach",
    );
    let skewed = PoseMsg {
        n: [1.0, 1.0, 0.0],
        ..here
    };
    assert!(matches!(
        robot(
            &c,
            RobotMethod::MoveTool {
                pose: skewed,
                duration_s: 1.0
            }
        ),
        Err(WireError::Call(CallError::BadArgument(_)))
    ));
    // Servo: the same checks, and the step limit.
    bad(
        robot(&c, RobotMethod::ServoJoints { q: nan }),
        "servo NaN",
        "NaN",
    );
    bad(
        robot(&c, RobotMethod::ServoJoints { q: beyond }),
        "servo past a limit",
        "joint limits",
    );
    bad(
        robot(&c, RobotMethod::ServoTool { pose: far }),
        "servo an unreachable pose",
        "cannot reach",
    );
    let mut jump = start.clone();
    jump[0] += MAX_SERVO_STEP_RAD * 1.5;
    bad(
        robot(&c, RobotMethod::ServoJoints { q: jump }),
        "a servo jump",
        "step limit",
    );
    let mut step = start.clone();
    step[0] += MAX_SERVO_STEP_RAD * 0.5;
    robot(&c, RobotMethod::ServoJoints { q: step }).unwrap();
    // None of the refused calls moved the arm or made it busy.
    advance(&c, Duration::from_millis(100));
    let s = state(&c);
    assert_eq!((s.state.as_str(), s.is_busy), ("ENABLED", false));
    assert!(max_error(&measured(&c), &start) < MAX_SERVO_STEP_RAD);
}

#[test]
fn the_communication_task_drops_a_servo_target_past_the_step_limit_itself() {
    // A target that crossed the node's check in flight (here: written straight into the
    // motion port) is checked again where the reference is published.
    let (c, start) = puma();
    let mut d = c.detach_loop("pid").expect("the loop builds");
    let mut q0 = penelope_hal::JointVector::zeros();
    q0.as_mut_slice()[..6].copy_from_slice(&start);
    // Steps the loop over ticks `from..to`; the last tick's joint reference.
    let run = |d: &mut penelope_runtime::objects::DetachedLoop, from: u64, to: u64| {
        let mut reference = None;
        for i in from..to {
            let now = penelope_hal::Timestamp::from_nanos(i * 1_000_000);
            if i % 2 == 0 {
                d.comm.tick(now);
            }
            d.control.tick(now);
            while let Some(r) = d.telemetry.pop() {
                reference = Some(r.sample.reference_q);
            }
        }
        reference.expect("the loop ticked")
    };
    run(&mut d, 1, 200);
    let mut jump = q0;
    jump[1] += MAX_SERVO_STEP_RAD * 2.0;
    d.motion
        .servo(penelope_runtime::objects::runtime::ServoTarget { q: jump });
    let r = run(&mut d, 200, 300);
    assert_eq!(d.motion.status().servo_dropped(), 1);
    assert!(
        (r[1] - start[1]).abs() < 1e-9,
        "the reference moved to {}",
        r[1]
    );
    // A target within the limit is taken.
    let mut step = q0;
    step[1] += MAX_SERVO_STEP_RAD * 0.5;
    d.motion
        .servo(penelope_runtime::objects::runtime::ServoTarget { q: step });
    let r = run(&mut d, 300, 310);
    assert_eq!(d.motion.status().servo_dropped(), 1);
    assert!((r[1] - step[1]).abs() < 1e-12);
}
