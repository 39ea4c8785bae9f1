//! A node's recording draws its robots in 3D: the description of each robot its recorded
//! controllers drive, once; `/tf` with every link frame at the rate asked (of tick time), the
//! root placed in the world; `/scene` with the contact shapes of its simulated board. A rate
//! out of range is refused before any file is made; rate 0 writes the descriptions only.

mod common;

use common::{call, create, ctl, lifecycle, map, session};
use penelope_hal::Transition;
use penelope_protocol::proto::{
    Call, CallError, ControllerMethod, CreatorCall, Method, Reply, RobotMethod, WireError,
};
use penelope_protocol::service::Service;
use penelope_runtime::objects::clock::ClockMode;
use penelope_runtime::objects::{Creator, CreatorConfig};
use std::collections::BTreeMap;
use std::time::Duration;

fn sim_creator() -> Creator {
    let mut config = CreatorConfig::new("lab");
    config.clock = ClockMode::Simulated;
    config.rt.priority = None;
    config.records = Some(std::env::temp_dir());
    Creator::new(config)
}

/// Records one simulated second of a PUMA 560 held by a joint PID on a simulated board with a
/// wall, at `scene_hz`: the messages by topic.
fn record_a_second(scene_hz: f64, tag: &str) -> BTreeMap<String, Vec<(u64, serde_json::Value)>> {
    let c = sim_creator();
    let (s, _rx) = session(1);
    // Another robot made first: the PUMA stands second in the row (y = 1 m).
    create(&c, &s, "robot/frhc", "master", "");
    create(&c, &s, "robot/puma560", "arm", "");
    create(
        &c,
        &s,
        "board/sim",
        "b",
        "axes = 6\n[[shapes]]\nkind = \"plane\"\npoint = [0.7, 0.0, 0.0]\nnormal = [-1.0, 0.0, 0.0]\n",
    );
    map(
        &c,
        &s,
        "arm",
        "b",
        &[(0, 0), (1, 1), (2, 2), (3, 3), (4, 4), (5, 5)],
    );
    for o in ["b", "arm"] {
        lifecycle(&c, &s, o, Transition::Configure).unwrap();
    }
    create(
        &c,
        &s,
        "trajectory/step",
        "hold",
        "goal = [0, 0.3, 0.2, 0, 0.1, 0]",
    );
    lifecycle(&c, &s, "hold", Transition::Configure).unwrap();
    create(&c, &s, "controller/joint-pid", "pid", "");
    ctl(
        &c,
        &s,
        "pid",
        ControllerMethod::SetRobot {
            robot: "arm".into(),
        },
    )
    .unwrap();
    ctl(
        &c,
        &s,
        "pid",
        ControllerMethod::SetTrajectory {
            trajectory: "hold".into(),
        },
    )
    .unwrap();
    lifecycle(&c, &s, "pid", Transition::Configure).unwrap();
    let name = format!("scene-{}-{tag}.mcap", std::process::id());
    let path = std::env::temp_dir().join(&name);
    let _ = std::fs::remove_file(&path);
    c.record_start_with(&name, &["pid".to_string()], scene_hz)
        .unwrap();
    lifecycle(&c, &s, "pid", Transition::Activate).unwrap();
    c.advance(Duration::from_secs(1)).unwrap();
    lifecycle(&c, &s, "pid", Transition::Deactivate).unwrap();
    c.record_stop().unwrap();
    // The description the robot gives is the one recorded.
    let described = call(&c, &s, ("arm", Method::Robot(RobotMethod::Description))).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let _ = std::fs::remove_file(&path);
    let mut topics: BTreeMap<String, Vec<(u64, serde_json::Value)>> = BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m.channel.schema.as_ref().unwrap();
        if m.channel.topic.starts_with("/controllers/") {
            continue;
        }
        let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
        // The schema the channel carries is the scene crate's (Foxglove's, vendored).
        if let Some(text) = penelope_scene::schema(&schema.name) {
            assert_eq!(schema.data.as_ref(), text.as_bytes(), "{}", schema.name);
        }
        topics
            .entry(m.channel.topic.clone())
            .or_default()
            .push((m.log_time, v));
    }
    let penelope_protocol::proto::Reply::RobotDescription(d) = described else {
        panic!("no description");
    };
    let recorded = &topics["/robot_description/arm"][0].1;
    assert_eq!(recorded["urdf"], d.urdf);
    assert_eq!(recorded["frames"], serde_json::json!(d.frames));
    topics
}

#[test]
fn a_recording_draws_its_robots_at_the_rate_asked() {
    let topics = record_a_second(50.0, "50");
    assert_eq!(topics["/robot_description/arm"].len(), 1);
    assert!(
        !topics.contains_key("/robot_description/master"),
        "not recorded: not drawn"
    );
    let tf = &topics["/tf"];
    // 1 s of ticks at 50 Hz: 50 drawings (the first tick's and every 20 ms after), give or
    // take the tick the run ends on.
    assert!((50..=51).contains(&tf.len()), "{} /tf messages", tf.len());
    for pair in tf.windows(2) {
        assert_eq!(
            pair[1].0 - pair[0].0,
            20_000_000,
            "20 ms of tick time apart"
        );
    }
    let first = &tf[0].1["transforms"];
    assert_eq!(first[0]["parent_frame_id"], "world");
    assert_eq!(first[0]["child_frame_id"], "arm/base_link");
    assert_eq!(
        first[0]["translation"]["y"], 1.0,
        "second robot made: 1 m along y"
    );
    let frames: Vec<&str> = first.as_array().unwrap()[1..]
        .iter()
        .map(|t| t["child_frame_id"].as_str().unwrap())
        .collect();
    assert_eq!(
        frames,
        [
            "arm/link1",
            "arm/link2",
            "arm/link3",
            "arm/link4",
            "arm/link5",
            "arm/link6",
            "arm/tool"
        ]
    );
    // The arm moves to its goal: its tool's transform changes over the second.
    let tool = |m: &serde_json::Value| m["transforms"][7]["translation"].clone();
    assert_ne!(tool(&tf[0].1), tool(&tf[tf.len() - 1].1));
    let scene = &topics["/scene"];
    assert_eq!(scene.len(), tf.len());
    let wall = &scene[0].1["entities"][0];
    assert_eq!(wall["id"], "arm/contact0");
    assert_eq!(wall["frame_id"], "arm/base_link");
    assert_eq!(wall["cubes"].as_array().unwrap().len(), 1);
}

#[test]
fn rate_zero_writes_descriptions_only_and_a_bad_rate_is_refused() {
    let topics = record_a_second(0.0, "0");
    assert_eq!(topics["/robot_description/arm"].len(), 1);
    assert!(!topics.contains_key("/tf") && !topics.contains_key("/scene"));
    let c = sim_creator();
    let (session, _rx) = session(2);
    for bad in [-1.0, f64::NAN, 1e6] {
        let name = format!("scene-bad-{}.mcap", std::process::id());
        assert!(c.record_start_with(&name, &[], bad).is_err(), "{bad}");
        // The same through the wire's call: a bad argument.
        let reply = c.call(
            &session,
            Call::Creator(CreatorCall::RecordStartScene {
                path: name.clone(),
                objects: vec![],
                scene_hz: bad,
            }),
        );
        assert!(
            matches!(reply, Err(WireError::Call(CallError::BadArgument(_)))),
            "{bad}: {reply:?}"
        );
        assert!(
            !std::env::temp_dir().join(&name).exists(),
            "no file for a refused call"
        );
    }
    // A good rate through the call starts the recording.
    let name = format!("scene-call-{}.mcap", std::process::id());
    let reply = c.call(
        &session,
        Call::Creator(CreatorCall::RecordStartScene {
            path: name.clone(),
            objects: vec![],
            scene_hz: 25.0,
        }),
    );
    assert!(matches!(reply, Ok(Reply::Recording { .. })), "{reply:?}");
    c.record_stop().unwrap();
    let _ = std::fs::remove_file(std::env::temp_dir().join(&name));
}
