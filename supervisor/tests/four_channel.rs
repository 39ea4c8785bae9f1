//! Lawrence's four-channel master (`controller/four-channel-master`) on the demo's task: set as
//! force-position or as position-error, the whole system runs the same telemetry as the
//! classical master half, tick for tick, to the last bit (both robots, plant truth included).

use penelope_supervisor::objects::clock::ClockMode;
use penelope_supervisor::runs::{DEMO_SYSTEM, RunOptions, RunOutput, run};
use penelope_supervisor::system::SystemFile;

/// The demo with its active master half, `controllers.display`, of kind `kind` (and `keys`).
fn with_master(kind: &str, keys: &str) -> RunOutput {
    let text = DEMO_SYSTEM.replacen(
        "kind = \"force-display\"",
        &format!("kind = \"{kind}\"\n{keys}"),
        1,
    );
    let system = SystemFile::parse(&text).expect("a valid system file");
    let options = RunOptions {
        clock: ClockMode::Simulated,
        ..RunOptions::default()
    };
    run(&system, &options, &mut |_| {}).expect("the system runs")
}

/// Every tick of both robots equal. `channel_energy` is left out: the classical force display
/// runs the channel's two-port observer, the general law does not.
fn assert_same(a: &RunOutput, b: &RunOutput) {
    for (side, x, y) in [
        ("master", &a.master, &b.master),
        ("slave", &a.slave, &b.slave),
    ] {
        assert_eq!(x.len(), y.len(), "{side} ticks");
        assert!(x.len() > 19_000, "{side}: {} ticks", x.len());
        for (k, (p, q)) in x.iter().zip(y).enumerate() {
            let (mut p, mut q) = (*p, *q);
            p.sample.channel_energy = None;
            q.sample.channel_energy = None;
            assert_eq!(p, q, "{side} tick {k}");
        }
    }
    let pushed = a
        .master
        .iter()
        .filter(|t| t.sample.commanded_wrench.force.norm() > 1.0)
        .count();
    assert!(
        pushed > 1000,
        "a run that displayed nothing compares nothing: {pushed}"
    );
}

#[test]
fn set_as_force_position_it_runs_the_force_displays_task_bit_for_bit() {
    let classic = with_master("force-display", "");
    let general = with_master("four-channel-master", "c2 = 1.0\nc4 = 0.0");
    assert_same(&classic, &general);
}

#[test]
fn set_as_position_error_it_runs_the_position_error_masters_task_bit_for_bit() {
    let classic = with_master("position-error-master", "");
    let general = with_master(
        "four-channel-master",
        "c2 = 0.0\nc4 = 1.0\ndamping = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]",
    );
    assert_same(&classic, &general);
    // And both channels at once is another law: the runs part.
    let both = with_master("four-channel-master", "c2 = 1.0\nc4 = 1.0");
    assert_ne!(
        both.master[5000].sample.effort,
        classic.master[5000].sample.effort
    );
}
