//! Running a recorded run again: `penelope recording rerun FILE`.
//!
//! `penelope demo` writes, beside the ticks in `run.mcap`, a `run` metadata record
//! ([`RunRecipe`]): the system file's text and the run's options (duration, seed, law, scale,
//! master kinematics, clock). [`rerun`] runs that system again on the simulated clock with the
//! recording in place of its inputs:
//!
//! - the operator's hand that held the master (`sensor/operator-hand`) becomes a
//!   `sensor/operator-replay` of the master controller's channel: the master moves, and its
//!   clutch is held, as recorded;
//! - the slave controller's force sensor (`sensor/virtual`) becomes a `sensor/replay` of the
//!   slave controller's sensed `wrench`: the slave's law meets the recorded contact forces.
//!
//! and compares every tick of both controllers with the recording, signal by signal
//! ([`compare`]). The controllers, the channel and the slave's plant run again for real. On the
//! simulated clock the run is deterministic, so an unchanged system gives the recording back bit
//! for bit; a changed gain (`--config` with another file) shows where and by how much it
//! changes the run, against the same operator and the same contact forces.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::Serialize;

use super::{
    MasterKinematics, RunError, RunOptions, find_task, task_error, with_master_kinematics,
};
use crate::system::{SystemFile, SystemFileError};
use penelope_runtime::objects::clock::ClockMode;
use penelope_runtime::objects::recording::mcap_log::{CONTROLLER_TOPIC, summarize};
use penelope_runtime::objects::recording::{RecordingError, read_recording};
use penelope_runtime::objects::tick::TickRecord;

/// The name of the metadata record that holds a run's [`RunRecipe`].
pub const RECIPE: &str = "run";

/// How a run was made: enough to make it again.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunRecipe {
    /// The system file's text.
    pub system: String,
    /// `--kinematics` (`float`, `fpga`), if given.
    pub kinematics: Option<String>,
    /// `--law`, if given.
    pub law: Option<String>,
    /// `--scale`, if given.
    pub scale: Option<f64>,
    /// The seed.
    pub seed: u64,
    /// The run's length, ns.
    pub duration_ns: u64,
    /// `simulated` or `real-time`.
    pub clock: String,
}

impl RunRecipe {
    /// The recipe of a run of `system` with `options` and the master's `kinematics`.
    pub fn new(
        system: &str,
        options: &RunOptions,
        kinematics: Option<&str>,
        duration: Duration,
    ) -> Self {
        RunRecipe {
            system: system.to_string(),
            kinematics: kinematics.map(str::to_string),
            law: options.law.map(|l| l.as_str().to_string()),
            scale: options.scale,
            seed: options.seed,
            duration_ns: u64::try_from(duration.as_nanos()).unwrap_or(u64::MAX),
            clock: match options.clock {
                ClockMode::Simulated => "simulated",
                ClockMode::RealTime => "real-time",
            }
            .to_string(),
        }
    }

    /// As a metadata record's entries.
    pub fn to_metadata(&self) -> BTreeMap<String, String> {
        let mut m = BTreeMap::from([
            ("system".to_string(), self.system.clone()),
            ("seed".to_string(), self.seed.to_string()),
            ("duration_ns".to_string(), self.duration_ns.to_string()),
            ("clock".to_string(), self.clock.clone()),
        ]);
        if let Some(k) = &self.kinematics {
            m.insert("kinematics".into(), k.clone());
        }
        if let Some(l) = &self.law {
            m.insert("law".into(), l.clone());
        }
        if let Some(s) = self.scale {
            // Shortest text that parses back to the same f64.
            m.insert("scale".into(), format!("{s:?}"));
        }
        m
    }

    /// From a metadata record's entries.
    ///
    /// # Errors
    /// [`RerunError::BadRecipe`] for a missing or malformed entry.
    pub fn from_metadata(m: &BTreeMap<String, String>) -> Result<RunRecipe, RerunError> {
        let get = |k: &str| {
            m.get(k)
                .cloned()
                .ok_or_else(|| RerunError::BadRecipe(format!("no `{k}`")))
        };
        let number = |k: &str| -> Result<u64, RerunError> {
            get(k)?
                .parse()
                .map_err(|_| RerunError::BadRecipe(format!("`{k}` is not a number")))
        };
        let scale = match m.get("scale") {
            Some(s) => Some(
                s.parse::<f64>()
                    .map_err(|_| RerunError::BadRecipe("`scale` is not a number".into()))?,
            ),
            None => None,
        };
        Ok(RunRecipe {
            system: get("system")?,
            kinematics: m.get("kinematics").cloned(),
            law: m.get("law").cloned(),
            scale,
            seed: number("seed")?,
            duration_ns: number("duration_ns")?,
            clock: get("clock")?,
        })
    }

    /// The run options it stands for, on the simulated clock.
    ///
    /// # Errors
    /// [`RerunError::BadRecipe`] for an unknown law.
    pub fn options(&self) -> Result<RunOptions, RerunError> {
        let law = match &self.law {
            Some(l) => Some(
                super::Law::from_name(l)
                    .ok_or_else(|| RerunError::BadRecipe(format!("unknown law `{l}`")))?,
            ),
            None => None,
        };
        Ok(RunOptions {
            duration: Some(Duration::from_nanos(self.duration_ns)),
            law,
            scale: self.scale,
            seed: self.seed,
            clock: ClockMode::Simulated,
        })
    }
}

/// Why a recording cannot be run again.
#[derive(Debug, thiserror::Error)]
pub enum RerunError {
    /// The recording cannot be read.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// It has no `run` record (not written by `penelope demo`) and no system file was given.
    #[error(
        "{0}: no `run` metadata record (it is not a `penelope demo` recording): pass the system \
         file with --config, and the run's options are the defaults"
    )]
    NoRecipe(PathBuf),
    /// The `run` record is malformed.
    #[error("the recording's `run` record: {0}")]
    BadRecipe(String),
    /// It was recorded on the real-time clock: its tick times cannot be met again.
    #[error(
        "{0}: recorded on the real-time clock; only a simulated-clock run (`penelope demo \
         --sim-clock`) can be run again tick for tick"
    )]
    RealTime(PathBuf),
    /// The system file does not parse.
    #[error("the system file: {0}")]
    System(#[from] SystemFileError),
    /// The run failed.
    #[error(transparent)]
    Run(#[from] RunError),
}

/// `file` with its inputs replaced by the recording at `recording`: the hand holding `master`
/// by a `sensor/operator-replay` of `/controllers/<master_ctl>`, and the `sensor/virtual`
/// named `slave_sensor` by a `sensor/replay` of `/controllers/<slave_ctl>`'s `wrench`.
fn replayed_system(
    file: &SystemFile,
    recording: &Path,
    (master, master_ctl): (&str, &str),
    (slave_sensor, slave_ctl): (Option<&str>, &str),
) -> Result<SystemFile, RunError> {
    let mut file = file.clone();
    let path = toml::Value::String(recording.display().to_string());
    for o in &mut file.objects {
        let table: toml::Table = o
            .config
            .parse()
            .map_err(|e| task_error(format!("{}: {e}", o.name)))?;
        let robot = table.get("robot").and_then(toml::Value::as_str);
        if o.kind == "sensor/operator-hand" && robot == Some(master) {
            let mut t = toml::Table::new();
            t.insert("robot".into(), master.into());
            t.insert("file".into(), path.clone());
            t.insert(
                "topic".into(),
                format!("{CONTROLLER_TOPIC}{master_ctl}").into(),
            );
            o.kind = "sensor/operator-replay".into();
            o.config = t.to_string();
        } else if o.kind == "sensor/virtual" && Some(o.name.as_str()) == slave_sensor {
            let mut t = toml::Table::new();
            t.insert("file".into(), path.clone());
            t.insert(
                "topic".into(),
                format!("{CONTROLLER_TOPIC}{slave_ctl}").into(),
            );
            t.insert("field".into(), "wrench".into());
            if let Some(m) = table.get("mount_xyz") {
                t.insert("mount_xyz".into(), m.clone());
            }
            o.kind = "sensor/replay".into();
            o.config = t.to_string();
        }
    }
    Ok(file)
}

/// How one signal of one controller differs between the recording and the rerun.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SignalDiff {
    /// The signal: a field of the tick (`sample.q`, `truth.base_wrench`, `clutch`, ...).
    pub signal: String,
    /// Ticks where any of its values differ (bit for bit).
    pub differing_ticks: u64,
    /// The largest absolute difference of its numbers (0 when only non-numbers differ).
    pub max_abs_diff: f64,
    /// The first differing tick's sequence number.
    pub first_seq: u64,
}

/// How one controller's ticks differ.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ControllerDiff {
    /// The controller.
    pub controller: String,
    /// Ticks in the recording.
    pub recorded: u64,
    /// Ticks in the rerun.
    pub rerun: u64,
    /// Ticks compared (both have them).
    pub compared: u64,
    /// Ticks with any difference (bit for bit).
    pub differing_ticks: u64,
    /// The signals that differ, in tick field order.
    pub signals: Vec<SignalDiff>,
}

impl ControllerDiff {
    /// Whether the rerun gave the recording back bit for bit.
    pub fn identical(&self) -> bool {
        self.differing_ticks == 0 && self.recorded == self.rerun
    }
}

/// What a rerun found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Rerun {
    /// The recording.
    pub recording: PathBuf,
    /// Where the system file came from: `recording` or the `--config` path.
    pub system_from: String,
    /// Per controller.
    pub controllers: Vec<ControllerDiff>,
}

impl Rerun {
    /// Whether every controller's ticks came back bit for bit.
    pub fn identical(&self) -> bool {
        self.controllers.iter().all(ControllerDiff::identical)
    }
}

/// Leaves of a tick's serde form, `(signal, path, value)`; the signal is the path's first two
/// levels (`sample.q`).
fn leaves(prefix: &str, v: &serde_json::Value, out: &mut Vec<(String, serde_json::Value)>) {
    match v {
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                let p = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                leaves(&p, x, out);
            }
        }
        serde_json::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                leaves(&format!("{prefix}[{i}]"), x, out);
            }
        }
        _ => out.push((prefix.to_string(), v.clone())),
    }
}

fn signal_of(path: &str) -> String {
    let cut = |s: &str| s.find(['.', '[']).map_or(s.len(), |i| i);
    let first = cut(path);
    match path[first..].strip_prefix('.') {
        Some(rest) => format!("{}.{}", &path[..first], &rest[..cut(rest)]),
        None => path[..first].to_string(),
    }
}

/// Compares controller `name`'s recorded ticks with a rerun's, tick by tick (by index: both
/// count from the first tick), value by value, bit for bit.
pub fn compare(name: &str, recorded: &[TickRecord], rerun: &[TickRecord]) -> ControllerDiff {
    let mut signals: Vec<SignalDiff> = Vec::new();
    let mut differing_ticks = 0;
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for (r, n) in recorded.iter().zip(rerun) {
        a.clear();
        b.clear();
        leaves("", &serde_json::to_value(r).unwrap_or_default(), &mut a);
        leaves("", &serde_json::to_value(n).unwrap_or_default(), &mut b);
        let mut tick_differs = false;
        let mut seen: Vec<String> = Vec::new();
        let longest = a.len().max(b.len());
        for i in 0..longest {
            let (pa, va) = a.get(i).map_or(("", None), |(p, v)| (p.as_str(), Some(v)));
            let (pb, vb) = b.get(i).map_or(("", None), |(p, v)| (p.as_str(), Some(v)));
            let path = if pa.is_empty() { pb } else { pa };
            let (same, diff) = match (va, vb) {
                (Some(x), Some(y)) if pa == pb => match (x.as_f64(), y.as_f64()) {
                    (Some(p), Some(q)) if x.is_f64() || y.is_f64() => {
                        (p.to_bits() == q.to_bits(), (p - q).abs())
                    }
                    _ => (x == y, 0.0),
                },
                _ => (false, 0.0),
            };
            if same {
                continue;
            }
            tick_differs = true;
            let signal = signal_of(path);
            let entry = match signals.iter_mut().position(|s| s.signal == signal) {
                Some(i) => &mut signals[i],
                None => {
                    signals.push(SignalDiff {
                        signal: signal.clone(),
                        differing_ticks: 0,
                        max_abs_diff: 0.0,
                        first_seq: r.sample.seq,
                    });
                    signals.last_mut().expect("just pushed")
                }
            };
            if !seen.contains(&signal) {
                entry.differing_ticks += 1;
                seen.push(signal);
            }
            if diff.is_finite() {
                entry.max_abs_diff = entry.max_abs_diff.max(diff);
            }
        }
        if tick_differs {
            differing_ticks += 1;
        }
    }
    ControllerDiff {
        controller: name.to_string(),
        recorded: recorded.len() as u64,
        rerun: rerun.len() as u64,
        compared: recorded.len().min(rerun.len()) as u64,
        differing_ticks,
        signals,
    }
}

/// Runs the recorded run at `recording` again against its recorded operator and contact
/// forces (see the [module](self)), with the system file `config` (its text and where it came
/// from) instead of the recorded one if given, and compares.
///
/// # Errors
/// [`RerunError`]: the recording cannot be read, has no recipe and no `config` was given, was
/// recorded on the real-time clock, or the run fails.
pub fn rerun(
    recording: &Path,
    config: Option<(&str, &str)>,
    on_progress: &mut dyn FnMut(&super::Progress),
) -> Result<Rerun, RerunError> {
    let recording = std::path::absolute(recording).map_err(|source| RecordingError::Io {
        path: recording.to_path_buf(),
        source,
    })?;
    let summary = summarize(&recording)?;
    let recipe = summary
        .metadata
        .get(RECIPE)
        .map(RunRecipe::from_metadata)
        .transpose()?;
    if recipe.as_ref().is_some_and(|r| r.clock != "simulated") {
        return Err(RerunError::RealTime(recording));
    }
    let recorded = read_recording(&recording)?;
    let (text, system_from, options, kinematics) = match (&recipe, config) {
        (_, Some((text, from))) => (
            text.to_string(),
            from.to_string(),
            match &recipe {
                Some(r) => r.options()?,
                None => RunOptions {
                    duration: Some(
                        Duration::from_nanos(summary.duration_ns()) + Duration::from_millis(1),
                    ),
                    ..RunOptions::default()
                },
            },
            recipe.as_ref().and_then(|r| r.kinematics.clone()),
        ),
        (Some(r), None) => (
            r.system.clone(),
            "recording".to_string(),
            r.options()?,
            r.kinematics.clone(),
        ),
        (None, None) => return Err(RerunError::NoRecipe(recording)),
    };
    let mut system = SystemFile::parse(&text)?;
    if let Some(k) = kinematics.as_deref().and_then(MasterKinematics::from_name) {
        system = with_master_kinematics(&system, k)?;
    }
    let found = find_task(&system, &options)?;
    let (master_ctl, slave_ctl) = found.info.controllers.clone();
    let (_, teleop) = super::teleop_channel(&found.file)?;
    let slave_sensor = found
        .file
        .objects
        .iter()
        .find(|o| o.name == slave_ctl)
        .and_then(|o| o.sensor.clone());
    let replayed = replayed_system(
        &system,
        &recording,
        (&teleop.master, &master_ctl),
        (slave_sensor.as_deref(), &slave_ctl),
    )?;
    let output = super::run(&replayed, &options, on_progress)?;
    let empty = Vec::new();
    let get = |name: &str| recorded.controllers.get(name).unwrap_or(&empty);
    Ok(Rerun {
        recording,
        system_from,
        controllers: vec![
            compare(&master_ctl, get(&master_ctl), &output.master),
            compare(&slave_ctl, get(&slave_ctl), &output.slave),
        ],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_difference_is_found_in_its_signal_with_its_size() {
        let mut a = vec![TickRecord::default(); 4];
        for (i, t) in a.iter_mut().enumerate() {
            t.sample.seq = i as u64 + 1;
        }
        let mut b = a.clone();
        assert!(compare("c", &a, &b).identical());
        b[2].sample.q[1] = 0.25;
        b[3].sample.q[0] = -0.5;
        b[3].clutch = Some(true);
        b[1].sample.effort[0] = -0.0; // a different bit pattern, the same number
        let d = compare("c", &a, &b);
        assert_eq!(d.differing_ticks, 3);
        let q = d.signals.iter().find(|s| s.signal == "sample.q").unwrap();
        assert_eq!(
            (q.differing_ticks, q.max_abs_diff, q.first_seq),
            (2, 0.5, 3)
        );
        let effort = d
            .signals
            .iter()
            .find(|s| s.signal == "sample.effort")
            .unwrap();
        assert_eq!((effort.differing_ticks, effort.max_abs_diff), (1, 0.0));
        assert!(d.signals.iter().any(|s| s.signal == "clutch"));
        let shorter = compare("c", &a, &a[..3]);
        assert!(!shorter.identical());
        assert_eq!(shorter.differing_ticks, 0);
    }

    #[test]
    fn a_recipe_round_trips_through_metadata() {
        let r = RunRecipe::new(
            "name = \"x\"",
            &RunOptions {
                scale: Some(0.1 + 0.2),
                ..RunOptions::default()
            },
            Some("fpga"),
            Duration::from_millis(1500),
        );
        assert_eq!(RunRecipe::from_metadata(&r.to_metadata()).unwrap(), r);
        assert!(RunRecipe::from_metadata(&BTreeMap::new()).is_err());
    }
}
