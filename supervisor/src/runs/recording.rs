//! A task run from recordings: a system file applied with its controllers recorded from their
//! first tick ([`apply_recorded`]), the report's input taken from the recordings of a task run
//! by separate processes ([`from_recordings`]), and a run written as one recording
//! ([`write_run`]). The recordings themselves are the runtime's
//! ([`penelope_runtime::objects::recording`]).

use std::path::Path;

use penelope_hal::{Timestamp, Transition};
use penelope_protocol::proto::{Call, Method};
use penelope_runtime::objects::recording::mcap_log::{McapLog, McapTotals};
use penelope_runtime::objects::recording::ros2_log::Ros2Log;
use penelope_runtime::objects::recording::scene::{self, SceneWriter};
use penelope_runtime::objects::recording::{
    DEFAULT_SCENE_HZ, LIFECYCLE_CAPACITY, RecordProfile, Recorder, Recording, RecordingError,
    RecordingSources, SceneConfig, SceneRobot,
};
use penelope_runtime::objects::tick::TickRecord;

use super::{RECORD_CAPACITY, RunError, RunOptions, RunOutput, find_task};
use crate::node::Node;
use crate::system::SystemFile;

/// Applies `file` to `node` as [`SystemFile::apply`] does, but starts recording each
/// controller the file activates on this node (to `path`) before activating it, so the
/// recording holds every tick from the first; the robots they drive are drawn in 3D at
/// `scene_hz` of tick time ([`penelope_runtime::objects::recording::scene`]), in recording
/// profile `profile` ([`RecordProfile`]).
///
/// # Errors
/// [`RunError`] when the file is refused, a controller cannot be recorded or activated, the
/// scene rate is out of range, or the file cannot be created.
pub fn apply_recorded(
    node: &Node,
    file: &SystemFile,
    path: &Path,
    scene_hz: f64,
    profile: RecordProfile,
) -> Result<(Vec<penelope_protocol::proto::ObjectInfo>, Recorder), RunError> {
    let mut deferred = file.clone();
    let mut to_activate = Vec::new();
    for o in &mut deferred.objects {
        if o.active && (o.node.is_empty() || o.node == node.name()) {
            to_activate.push(o.name.clone());
        }
        o.active = false;
    }
    // The file's objects are created and configured before the recorder starts: their
    // transitions wait in this reader.
    let lifecycle = node.creator().lifecycle_events(LIFECYCLE_CAPACITY);
    let created = deferred.apply(node)?;
    let node_error = |what: String| move |error| RunError::Node { what, error };
    let mut streams = Vec::new();
    for name in &to_activate {
        let stream = node
            .creator()
            .record_ticks(name, RECORD_CAPACITY)
            .map_err(|e| node_error(format!("recording `{name}`"))(e.into()))?;
        streams.push((name.clone(), stream));
    }
    // The links of this node's channels to other nodes.
    let mut links = Vec::new();
    for o in deferred.objects_on(node.name()) {
        if o.kind == "trajectory/teleop"
            && let Ok(Some(source)) = node.creator().link_source(&o.name)
        {
            links.push((o.name.clone(), source));
        }
    }
    let scene = node
        .creator()
        .scene_for(&to_activate, scene_hz)
        .map_err(|e| RunError::Task(e.to_string()))?;
    let sources = RecordingSources {
        node: node.name(),
        streams,
        links,
        lifecycle: Some(lifecycle),
        clock: node.creator().common_clock(),
        node_time: node.creator().node_time(),
        scene,
    };
    // The node's cameras' frames too (configured above; their frames come once a loop runs).
    let cameras = node.creator().camera_taps();
    let recorder = Recorder::start_with_cameras(profile, path, None, sources, cameras)
        .map_err(|e| RunError::Task(e.to_string()))?;
    for name in &to_activate {
        node.call(Call::Object {
            object: name.clone(),
            method: Method::Transition(Transition::Activate),
        })
        .map_err(node_error(format!("activating `{name}`")))?;
    }
    Ok((created, recorder))
}

/// The report's input from recordings of a task run by separate processes: the master's and
/// the slave's ticks from the recordings that hold them, their times moved onto the common
/// clock (each recording's last `/clock` offset: hosts' clocks count from their own boots),
/// from the master's first tick (the task's start: its hand begins there) for the task's
/// duration (`options.duration`, else the operator's script); `None` when a recording does
/// not reach that far yet.
///
/// # Errors
/// [`RunError::Task`] when the file has no task or no recording holds its controllers.
pub fn from_recordings(
    file: &SystemFile,
    options: &RunOptions,
    recordings: &[Recording],
) -> Result<Option<RunOutput>, RunError> {
    let task = find_task(file, options)?;
    let mut info = task.info;
    let find = |node: &str, controller: &str| {
        recordings
            .iter()
            .filter(|r| node.is_empty() || r.node == node)
            .find_map(|r| {
                let shift = r.clock_offset_ns.unwrap_or(0);
                r.controllers.get(controller).map(|ticks| {
                    ticks
                        .iter()
                        .map(|t| {
                            let mut t = *t;
                            t.sample.time = Timestamp::from_nanos(
                                t.sample.time.as_nanos().saturating_add_signed(shift),
                            );
                            t
                        })
                        .collect::<Vec<TickRecord>>()
                })
            })
            .ok_or_else(|| {
                RunError::Task(format!(
                    "no recording holds controller `{controller}` of node `{node}`"
                ))
            })
    };
    let master = find(&task.node_of.0, &info.controllers.0)?;
    let slave = find(&task.node_of.1, &info.controllers.1)?;
    let dropped_of = |node: &str, controller: &str| {
        recordings
            .iter()
            .filter(|r| node.is_empty() || r.node == node)
            .find_map(|r| r.dropped.get(controller).copied())
            .unwrap_or(0)
    };
    let dropped = (
        dropped_of(&task.node_of.0, &info.controllers.0),
        dropped_of(&task.node_of.1, &info.controllers.1),
    );
    let (master, slave) = (&master[..], &slave[..]);
    let Some(first) = master.first() else {
        return Ok(None);
    };
    let start = first.sample.time;
    let end = start + task.duration;
    let reached = |ticks: &[TickRecord]| ticks.last().is_some_and(|t| t.sample.time >= end);
    if !reached(master) || !reached(slave) {
        return Ok(None);
    }
    info.start = start;
    let within = |ticks: &[TickRecord]| -> Vec<TickRecord> {
        ticks
            .iter()
            .filter(|t| t.sample.time >= start && t.sample.time < end)
            .copied()
            .collect()
    };
    Ok(Some(RunOutput {
        master: within(master),
        slave: within(slave),
        info,
        dropped,
    }))
}

/// The 3D scene of a run: the master and the slave side by side in the file's order, the
/// slave's environment and wrist sensor, at the default rate.
fn run_scene(info: &super::RunInfo) -> SceneConfig {
    let ((master, master_row), (slave, slave_row)) = &info.robots;
    let (master_ctl, slave_ctl) = &info.controllers;
    let contacts = info
        .environment
        .shapes()
        .iter()
        .map(|c| scene::contact_shape_msg(&c.shape))
        .collect();
    let master = SceneRobot {
        robot: master.clone(),
        controller: master_ctl.clone(),
        model: info.master_model.float().clone(),
        placement: penelope_scene::default_placement(*master_row),
        contacts: Vec::new(),
        sensor_mount: None,
    };
    let slave = SceneRobot {
        robot: slave.clone(),
        controller: slave_ctl.clone(),
        model: info.slave_model.float().clone(),
        placement: penelope_scene::default_placement(*slave_row),
        contacts,
        sensor_mount: Some(info.sensor_mount),
    };
    SceneConfig {
        robots: vec![master, slave],
        rate_hz: DEFAULT_SCENE_HZ,
    }
}

/// Writes run `output` to `path`: both controllers' ticks (what the pump's recorder streams
/// gave the run, cut to the run's duration as its CSV files are), their safety events, and
/// what the streams lost; with `recipe`, a `run` metadata record saying how to run it again
/// ([`RunRecipe`](super::rerun::RunRecipe)). (`penelope demo`'s `run.mcap`.)
///
/// # Errors
/// [`RecordingError`] when the file cannot be written.
pub fn write_run(
    path: &Path,
    output: &RunOutput,
    recipe: Option<&super::rerun::RunRecipe>,
) -> Result<McapTotals, RecordingError> {
    let mut log = McapLog::create(path, &output.info.system)?;
    if let Some(r) = recipe {
        log.metadata(super::rerun::RECIPE, r.to_metadata())?;
    }
    let (master, slave) = &output.info.controllers;
    let m = log.add_controller(master)?;
    let s = log.add_controller(slave)?;
    let mut scene = SceneWriter::new(run_scene(&output.info), &[master.clone(), slave.clone()]);
    scene.describe(&mut log, output.info.start.as_nanos())?;
    // In time order, as a reader plays them.
    let (mut a, mut b) = (
        output.master.iter().peekable(),
        output.slave.iter().peekable(),
    );
    loop {
        let next = match (a.peek(), b.peek()) {
            (Some(x), Some(y)) if x.sample.time <= y.sample.time => a.next().map(|t| (m, t)),
            (Some(_), Some(_)) | (None, Some(_)) => b.next().map(|t| (s, t)),
            (Some(_), None) => a.next().map(|t| (m, t)),
            (None, None) => None,
        };
        let Some((index, tick)) = next else { break };
        log.tick(index, tick)?;
        scene.tick(&mut log, index, tick)?;
    }
    log.finish(&[output.dropped.0, output.dropped.1])
}

/// Writes run `output` to `path` in the ROS 2 profile
/// ([`penelope_runtime::objects::recording::ros2_log`]): both robots' ROS 2 topic sets at the
/// scene's default rate, in time order. (`penelope demo --record-profile ros2`'s
/// `run-ros2.mcap`, beside `run.mcap`.)
///
/// # Errors
/// [`RecordingError`] when the file cannot be written.
pub fn write_run_ros2(path: &Path, output: &RunOutput) -> Result<McapTotals, RecordingError> {
    let (master, slave) = &output.info.controllers;
    let mut log = Ros2Log::create(
        path,
        &output.info.system,
        run_scene(&output.info),
        &[master.clone(), slave.clone()],
    )?;
    let mut ticks: Vec<(usize, &TickRecord)> = output
        .master
        .iter()
        .map(|t| (0, t))
        .chain(output.slave.iter().map(|t| (1, t)))
        .collect();
    // In time order, the master's first at a tie, as `write_run` writes them.
    ticks.sort_by_key(|(index, t)| (t.sample.time, *index));
    for (index, tick) in ticks {
        log.tick(index, tick)?;
    }
    log.finish(&[output.dropped.0, output.dropped.1])
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    #[test]
    fn recordings_of_hosts_whose_clocks_disagree_are_aligned_on_the_common_clock() {
        // The master's host booted 5,000 s before the naming host's, the slave's 9,000 s:
        // the same instants read 5,000 s and 9,000 s later on their clocks.
        let file = SystemFile::parse(include_str!("../../../config/demo-two-nodes.toml")).unwrap();
        let options = RunOptions {
            duration: Some(std::time::Duration::from_secs(1)),
            ..RunOptions::default()
        };
        let on_host = |node: &str, controller: &str, boot_s: u64| {
            let ticks = (0..1500u64)
                .map(|k| {
                    let mut t = TickRecord::default();
                    t.sample.seq = k + 1;
                    t.sample.time = Timestamp::from_nanos((boot_s * 1000 + k) * 1_000_000);
                    t
                })
                .collect();
            Recording {
                node: node.into(),
                controllers: BTreeMap::from([(controller.to_string(), ticks)]),
                clock_offset_ns: Some(-((boot_s * 1_000_000_000) as i64)),
                ..Recording::default()
            }
        };
        let read = [
            on_host("master", "display", 5000),
            on_host("slave", "follow", 9000),
        ];
        let out = from_recordings(&file, &options, &read)
            .unwrap()
            .expect("both reach 1 s");
        assert_eq!((out.master.len(), out.slave.len()), (1000, 1000));
        for (m, s) in out.master.iter().zip(&out.slave) {
            assert_eq!(m.sample.time, s.sample.time, "one time line");
        }
        assert_eq!(out.master[0].sample.time, Timestamp::ZERO);
        // Without the offsets, the slave's ticks lie 4,000 s after the task: none of them.
        let unaligned = read.map(|r| Recording {
            clock_offset_ns: None,
            ..r
        });
        let out = from_recordings(&file, &options, &unaligned)
            .unwrap()
            .unwrap();
        assert!(out.slave.is_empty());
    }
}
