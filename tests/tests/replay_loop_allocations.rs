//! The replay kinds' per-tick path allocates nothing: the demo's teleoperation pair with the
//! operator's hand replayed (`sensor/operator-replay`: the FRHC's recorded motion imposed on its
//! plant every tick) and the slave's wrist sensor replayed (`sensor/replay`, read in the control
//! loop), built by the creator exactly as `activate` builds them and stepped on a simulated
//! clock for 100,000 control ticks: the first 19,000 counted ones play the recording, the rest
//! run past its end (the hand holding the last pose, the sensor reporting its end).
//!
//! The recording is a 20 s simulated run of the demo's system, made first (its allocations are
//! not counted: the counting allocator counts only the stepping windows of this thread).

use std::time::Duration;

use penelope_hal::Timestamp;
use penelope_runtime::objects::{Creator, CreatorConfig};
use penelope_supervisor::runs::recording::write_run;
use penelope_supervisor::runs::{DEMO_SYSTEM, RunOptions, run};
use penelope_supervisor::system::SystemFile;
use penelope_testkit::alloc::CountingAllocator;
use penelope_tests::papers_task::connect_and_configure;
use penelope_tests::{assert_pair_ran, step_teleop_pair};

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

#[test]
fn a_hundred_thousand_replayed_teleoperation_ticks_allocate_nothing() {
    let dir = std::env::temp_dir().join(format!("penelope-replay-alloc-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("run.mcap");
    let system = SystemFile::parse(DEMO_SYSTEM).unwrap();
    let options = RunOptions {
        duration: Some(Duration::from_secs(20)),
        ..RunOptions::default()
    };
    let output = run(&system, &options, &mut |_| {}).expect("the demo runs");
    write_run(&file, &output, None).expect("run.mcap");
    let file = format!("{:?}", file.display().to_string());

    let mut config = CreatorConfig::new("alloc");
    config.rt.priority = None;
    let c = Creator::new(config);
    a_teleoperation_pair_replaying(&c, &file);
    let mut master = c.detach_loop("display").expect("the master's loop builds");
    let mut slave = c.detach_loop("follow").expect("the slave's loop builds");
    assert!(
        slave.wrench.is_none(),
        "the replayed sensor is read in the loop, not fed through a cell"
    );
    let mut feed = |_: Timestamp| {};
    step_teleop_pair(&mut master, &mut slave, 1..1001, &mut feed);
    let allocated = step_teleop_pair(&mut master, &mut slave, 1001..101_001, &mut feed);
    assert_eq!(
        allocated, 0,
        "the replayed teleoperation loops allocated or freed {allocated} times"
    );
    assert_pair_ran(&master, &slave, 101_000, 50_000);
    // The hand played: the master's true pose at the end is the recording's last one.
    let last = output.master.last().and_then(|t| t.truth).expect("truth");
    let q = master.control.control_loop().last_sample().q;
    for j in 0..6 {
        assert!(
            (q[j] - last.joints.position[j]).abs() < 1e-3,
            "joint {j}: {} against the recording's {}",
            q[j],
            last.joints.position[j]
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// On `c`: the demo's teleoperation pair with the operator's hand and the wrist sensor
/// replayed from the recording `file` (a quoted path), all configured.
fn a_teleoperation_pair_replaying(c: &Creator, file: &str) {
    let wall =
        "[[shapes]]\nkind = \"plane\"\npoint = [0.350868, 0.127, 0.2902]\nstiffness = 4000.0";
    for (kind, name, cfg) in [
        ("robot/frhc", "frhc", "start = \"start\"".to_string()),
        ("board/sim", "frhc-io", String::new()),
        (
            "sensor/operator-replay",
            "hand",
            format!("robot = \"frhc\"\nfile = {file}\ntopic = \"/controllers/display\""),
        ),
        ("robot/puma200", "puma", "start = \"start\"".to_string()),
        ("board/sim", "puma-io", wall.to_string()),
        (
            "sensor/replay",
            "wrist",
            format!("file = {file}\ntopic = \"/controllers/follow\"\nmount_xyz = [0.0, 0.0, 0.02]"),
        ),
        (
            "trajectory/teleop",
            "link",
            "master = \"frhc\"\nslave = \"puma\"\nforce_gain = 0.5".to_string(),
        ),
        ("controller/force-display", "display", String::new()),
        ("controller/slave-tracking", "follow", String::new()),
    ] {
        c.create(kind, name, &cfg)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    // Sensors (the recordings are read here) before the robots, as a system file does.
    connect_and_configure(c);
}
