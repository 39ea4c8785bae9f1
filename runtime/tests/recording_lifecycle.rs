//! A recording holds the node's lifecycle transitions (`/lifecycle`): every object created,
//! moved through its states and destroyed while it runs, in order, with the state each left it
//! in, stamped on the node's clock; a refused call leaves no trace.

use penelope_hal::Transition;
use penelope_runtime::objects::clock::ClockMode;
use penelope_runtime::objects::{Creator, CreatorConfig};

#[test]
fn a_recording_holds_the_nodes_lifecycle_transitions_in_order() {
    let mut config = CreatorConfig::new("lab");
    config.clock = ClockMode::Simulated;
    config.rt.priority = None;
    config.records = Some(std::env::temp_dir());
    let creator = Creator::new(config);
    let path = std::env::temp_dir().join(format!("lifecycle-{}.mcap", std::process::id()));
    let _ = std::fs::remove_file(&path);
    // Before the recording: not in it.
    creator
        .create("trajectory/step", "before", "goal = [0, 0, 0, 0, 0, 0]")
        .unwrap();
    let name = path.file_name().unwrap().to_str().unwrap();
    creator.record_start(name, &[]).unwrap();
    creator
        .create("trajectory/step", "hold", "goal = [0.1, 0, 0, 0, 0, 0]")
        .unwrap();
    creator.transition("hold", Transition::Configure).unwrap();
    // Refused: a second configure, an unknown kind. Neither is a transition.
    assert!(creator.transition("hold", Transition::Configure).is_err());
    assert!(creator.create("robot/nonesuch", "x", "").is_err());
    creator.transition("hold", Transition::Cleanup).unwrap();
    creator.destroy("hold", false).unwrap();
    creator.record_stop().unwrap();

    let bytes = std::fs::read(&path).unwrap();
    let _ = std::fs::remove_file(&path);
    let mut seen = Vec::new();
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        if message.channel.topic != "/lifecycle" {
            continue;
        }
        let schema = message.channel.schema.as_ref().expect("a schema");
        assert_eq!(
            (schema.name.as_str(), schema.encoding.as_str()),
            ("penelope.Lifecycle", "jsonschema")
        );
        let v: serde_json::Value = serde_json::from_slice(&message.data).unwrap();
        assert_eq!(v["time_ns"].as_u64(), Some(message.log_time));
        assert_eq!(v["kind"], "trajectory/step");
        seen.push(format!(
            "{} {} {}",
            v["object"].as_str().unwrap(),
            v["transition"].as_str().unwrap(),
            v["state"].as_str().unwrap()
        ));
    }
    assert_eq!(
        seen,
        [
            "hold create unconfigured",
            "hold configure inactive",
            "hold cleanup unconfigured",
            "hold destroy destroyed",
        ]
    );
}
