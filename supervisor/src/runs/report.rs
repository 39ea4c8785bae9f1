//! The report of a teleoperation run: what a person wants to know after the demo.
//!
//! Every figure is computed from the recorded telemetry (the control loops' samples and the
//! simulated plants' ground truth), per phase of the operator's script.

use std::collections::BTreeMap;
use std::time::Duration;

use nalgebra::Vector3;
use penelope_hal::{Kinematics, Timestamp};
use penelope_rt_core::telemetry::ReferenceKind;
use serde::Serialize;

use super::{RunInfo, RunOutput};
use penelope_drivers::sim::scripts::{CONTACT_PHASE, FREE_MOTION_PHASES, INDEX_PHASE, TAP_PHASE};
use penelope_rt_core::teleop::WorkspaceMapping;
use penelope_runtime::objects::clock::ClockMode;
use penelope_runtime::objects::teleop::sensor_to_base;
use penelope_runtime::objects::tick::TickRecord;

/// Position tracking in free motion.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct TrackingReport {
    /// RMS distance between the slave's tool and its own reference (the mapped master pose as
    /// the slave received it), mm.
    pub rms_mm: f64,
    /// Largest distance, mm.
    pub max_mm: f64,
    /// RMS distance between the slave's tool and the master's mapped pose at the same instant
    /// (the transport lag shows here), mm.
    pub against_master_rms_mm: f64,
    /// Largest such distance, mm.
    pub against_master_max_mm: f64,
    /// Control ticks measured.
    pub samples: usize,
}

/// Forces in steady contact (the second half of the contact phase).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ContactReport {
    /// Mean contact force the wrist sensor measured, magnitude, N.
    pub sensed_force_n: f64,
    /// Mean force the master should display: force gain x mapped sensed force, magnitude, N.
    pub expected_display_n: f64,
    /// Mean force the master's motors produce at the handle (their torques less gravity,
    /// through `J^-T`, from the plant's applied torques), magnitude, N.
    pub displayed_force_n: f64,
    /// Mean force the master's law commanded, magnitude, N.
    pub commanded_force_n: f64,
    /// `|displayed - expected| / |expected|` of the mean vectors, percent.
    pub display_error_pct: f64,
    /// Mean force the operator's hand felt (pushed with), magnitude, N.
    pub hand_force_n: f64,
    /// Mean true contact force on the slave (simulation ground truth), magnitude, N.
    pub true_contact_force_n: f64,
    /// Control ticks measured.
    pub samples: usize,
}

/// What the operator feels in free motion: the master's drag.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct DragReport {
    /// RMS hand force in free motion, N.
    pub rms_n: f64,
    /// Largest hand force in free motion, N.
    pub max_n: f64,
}

/// Energy during tapping.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct EnergyReport {
    /// Peak mechanical energy (kinetic energy of both arms + energy stored in the wall) in each
    /// tap cycle, J.
    pub tap_cycle_peaks_j: Vec<f64>,
    /// Last cycle's peak over the largest earlier peak (above 1 would mean energy building up).
    pub growth_ratio: f64,
    /// Work the operator's hand did on the master during the tapping, J.
    pub operator_work_j: f64,
    /// The lowest energy the master law's passivity observer read over the run, J (negative:
    /// the law gave out more than it took); `None` when the law has no observer.
    pub master_port_min_j: Option<f64>,
    /// The same for the slave law.
    pub slave_port_min_j: Option<f64>,
    /// The lowest energy of the channel's two-port observer at the master port, J (what the
    /// slave put in minus what the master gave out: negative, the channel with its delays gave
    /// out energy that never entered it); `None` when the law runs none (position-error, wave).
    pub master_channel_min_j: Option<f64>,
    /// The same at the slave port.
    pub slave_channel_min_j: Option<f64>,
}

/// The lowest value of `energy` over `ticks`, if any tick had one.
fn min_energy(ticks: &[TickRecord], energy: fn(&TickRecord) -> Option<f64>) -> Option<f64> {
    ticks.iter().filter_map(energy).reduce(f64::min)
}

/// Indexing (clutch) behaviour.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ClutchReport {
    /// Largest step of the slave reference between two control ticks while the clutch was held
    /// and just after release, mm.
    pub max_step_mm: f64,
    /// Largest step of the slave reference between two control ticks in normal free motion, mm.
    pub normal_max_step_mm: f64,
}

/// Timing of one loop.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct LoopTiming {
    /// Thread name.
    pub name: String,
    /// Period, µs.
    pub period_us: f64,
    /// Ticks run.
    pub ticks: u64,
    /// Ticks whose body ended past the next deadline.
    pub overruns: u64,
    /// Wake-up latency, µs: min, p50, p99, p99.9, max.
    pub latency_us: [f64; 5],
    /// Execution time of the body, µs: mean, max.
    pub exec_us: [f64; 2],
    /// Whether the loop ran on the real clock (latencies are measured only there).
    pub realtime: bool,
}

/// The kinematics the master computed with and, on its FPGA board, the board's modelled
/// latency per tick ([`penelope_runtime::objects::fpga_board`]).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct KinematicsReport {
    /// `float` (on the host) or `fpga` (on the master's `board/fpga`).
    pub master: String,
    /// Cycles at 40 MHz of one forward kinematics on the board (0: float).
    pub fk_cycles: u32,
    /// Encoder latch to the pose and Jacobian frames on the host, µs (0: float).
    pub fk_latency_us: f64,
    /// Cycles of one forward kinematics plus force transformation on the board (0: float).
    pub fk_force_cycles: u32,
    /// The law's wrench written to `tau = J^T F` on the host, µs (0: float).
    pub fk_force_latency_us: f64,
    /// Encoder latch to the tick's command on the motors, µs (0: float).
    pub command_delay_us: f64,
}

fn kinematics_report(info: &RunInfo) -> KinematicsReport {
    use penelope_runtime::objects::fpga_board::{FK, FK_FORCE, command_delay_ns};
    if info.master_model.is_fpga_board() {
        KinematicsReport {
            master: "fpga".into(),
            fk_cycles: FK.cycles,
            fk_latency_us: FK.latency_ns() as f64 / 1e3,
            fk_force_cycles: FK_FORCE.cycles,
            fk_force_latency_us: FK_FORCE.latency_ns() as f64 / 1e3,
            command_delay_us: command_delay_ns() as f64 / 1e3,
        }
    } else {
        KinematicsReport {
            master: "float".into(),
            fk_cycles: 0,
            fk_latency_us: 0.0,
            fk_force_cycles: 0,
            fk_force_latency_us: 0.0,
            command_delay_us: 0.0,
        }
    }
}

/// The whole report.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Report {
    /// Lab name.
    pub lab: String,
    /// Law.
    pub law: String,
    /// Clock: "real-time" or "simulated".
    pub clock: String,
    /// Seed.
    pub seed: u64,
    /// Length of the run, s.
    pub duration_s: f64,
    /// Position scale.
    pub scale: f64,
    /// Force gain.
    pub force_gain: f64,
    /// The master's kinematics (float, or its FPGA board's, with the board's latency).
    pub kinematics: KinematicsReport,
    /// Free-motion tracking.
    pub tracking: TrackingReport,
    /// Steady contact.
    pub contact: ContactReport,
    /// Free-motion drag.
    pub drag: DragReport,
    /// Energy while tapping.
    pub energy: EnergyReport,
    /// Clutch.
    pub clutch: ClutchReport,
    /// End-to-end latency each way beside its limit (the wait for the receiving tick: the
    /// demo's channel is a pair of cells on one node).
    pub latency: LatencyReport,
    /// Per-thread timing (real-time runs; empty on a simulated clock).
    pub timing: Vec<LoopTiming>,
    /// Safety events per robot: `robot/event -> count`.
    pub safety_events: BTreeMap<String, u64>,
    /// Faults seen (robot: cause).
    pub faults: Vec<String>,
    /// Telemetry samples dropped because the logger fell behind.
    pub dropped_samples: usize,
}

fn phase_of(info: &RunInfo, t: Timestamp) -> &'static str {
    info.script
        .segment_at(t - info.start)
        .map_or("", |(_, s, _)| s.label)
}

fn phase_window(info: &RunInfo, label: &str) -> Option<(Duration, Duration)> {
    let mut t0 = Duration::ZERO;
    for s in info.script.segments() {
        if s.label == label {
            return Some((t0, t0 + s.duration));
        }
        t0 += s.duration;
    }
    None
}

fn rms(values: impl Iterator<Item = f64>) -> (f64, f64, usize) {
    let (mut sum, mut max, mut n) = (0.0, 0.0f64, 0usize);
    for v in values {
        sum += v * v;
        max = max.max(v.abs());
        n += 1;
    }
    (if n > 0 { (sum / n as f64).sqrt() } else { 0.0 }, max, n)
}

fn mean_vector(values: impl Iterator<Item = Vector3<f64>>) -> (Vector3<f64>, usize) {
    let (mut sum, mut n) = (Vector3::zeros(), 0usize);
    for v in values {
        sum += v;
        n += 1;
    }
    (if n > 0 { sum / n as f64 } else { sum }, n)
}

fn in_window(info: &RunInfo, s: &TickRecord, window: (Duration, Duration)) -> bool {
    let t = s.sample.time - info.start;
    t >= window.0 && t < window.1
}

/// Mechanical energy of the coupled system at each slave tick: both arms' kinetic energy plus
/// the energy stored in the environment, the master taken at its latest tick not after the
/// slave's (the two control threads tick on their own deadlines, and overruns skip ticks, so
/// samples are matched by time, not by index).
fn coupled_energy(out: &RunOutput) -> Vec<(Duration, f64)> {
    let info = &out.info;
    let mut master = out
        .master
        .iter()
        .filter_map(|m| m.truth.map(|t| (m.sample.time, t)))
        .peekable();
    let mut current = None;
    let mut series = Vec::with_capacity(out.slave.len());
    for s in &out.slave {
        while let Some(&(t, truth)) = master.peek() {
            if t > s.sample.time {
                break;
            }
            current = Some(truth);
            master.next();
        }
        if let (Some(ts), Some(tm)) = (s.truth, current) {
            let stored = info
                .environment
                .stored_energy(&ts.tool_pose.translation.vector);
            series.push((
                s.sample.time - info.start,
                ts.kinetic_energy + tm.kinetic_energy + stored,
            ));
        }
    }
    series
}

/// The force the master's motors produce at the handle in tick `s`: the plant's applied joint
/// torques less gravity, through `J^-T` (`None` near a singularity).
pub fn motor_force(info: &RunInfo, s: &TickRecord) -> Option<Vector3<f64>> {
    use penelope_hal::{Dynamics, JacobianFrame};
    let q = s.sample.q;
    let n = info.master_dynamics.joint_count().min(6);
    let tau = s.truth.map_or(s.sample.effort, |t| t.joints.effort);
    let g = info.master_dynamics.gravity(&q);
    let j = info.master_model.jacobian(&q, JacobianFrame::Base);
    let jt = j.columns(0, n).transpose();
    let rhs = (tau - g).rows(0, n).into_owned();
    // J^T F = tau - g, solved for F (least squares for fewer than six joints).
    let f = jt.svd(true, true).solve(&rhs, 1e-9).ok()?;
    Some(Vector3::new(f[0], f[1], f[2]))
}

/// The master's tool position mapped into the slave's frame at each master tick, replaying the
/// channel's mapping (anchored at the start, re-anchored at each clutch release).
fn mapped_master(out: &RunOutput) -> Vec<(Timestamp, Vector3<f64>)> {
    let info = &out.info;
    let (Some(m0), Some(s0)) = (out.master.first(), out.slave.first()) else {
        return Vec::new();
    };
    let Ok(mut mapping) = WorkspaceMapping::new(info.mapping) else {
        return Vec::new();
    };
    mapping.anchor(
        &info.master_model.forward(&m0.sample.q),
        &info.slave_model.forward(&s0.sample.q),
    );
    out.master
        .iter()
        .filter_map(|m| {
            let pose = info.master_model.forward(&m.sample.q);
            let clutch = info.script.clutch(m.sample.time - info.start);
            let mapped = mapping.update(m.sample.time, &pose, clutch).ok()?;
            Some((m.sample.time, mapped.translation.vector))
        })
        .collect()
}

/// Wake-up latency and execution time of one control loop, from what it noted each tick.
fn loop_timing(name: &str, info: &RunInfo, rows: &[TickRecord]) -> LoopTiming {
    let us = |d: Duration| d.as_secs_f64() * 1e6;
    let mut latency: Vec<f64> = rows.iter().map(|r| us(r.sample.wake_latency)).collect();
    latency.sort_by(f64::total_cmp);
    let at = |p: f64| {
        let i = ((latency.len() as f64 - 1.0) * p).round() as usize;
        latency.get(i).copied().unwrap_or(0.0)
    };
    let exec: Vec<f64> = rows.iter().map(|r| us(r.sample.exec_time)).collect();
    let period = info.control_period;
    // A deadline the loop skipped shows as a gap of more than one period between ticks.
    let overruns = rows
        .windows(2)
        .map(|w| {
            let gap = w[1].sample.time.saturating_since(w[0].sample.time);
            (gap.as_nanos() / period.as_nanos().max(1)).saturating_sub(1) as u64
        })
        .sum();
    LoopTiming {
        name: name.to_string(),
        period_us: us(period),
        ticks: rows.len() as u64,
        overruns,
        latency_us: [at(0.0), at(0.5), at(0.99), at(0.999), at(1.0)],
        exec_us: [
            exec.iter().sum::<f64>() / exec.len().max(1) as f64,
            exec.iter().copied().fold(0.0, f64::max),
        ],
        realtime: true,
    }
}

/// Whether `s` is a free-motion tick with a reference to track.
fn in_free_motion(info: &RunInfo, s: &TickRecord) -> bool {
    s.sample.reference_kind != ReferenceKind::None
        && FREE_MOTION_PHASES.contains(&phase_of(info, s.sample.time))
}

/// Tracking: the slave tool against its reference, and against the mapped master, in the
/// free-motion phases.
fn tracking_report(out: &RunOutput) -> TrackingReport {
    let info = &out.info;
    let (track_rms, track_max, track_n) = rms(out
        .slave
        .iter()
        .filter(|s| in_free_motion(info, s))
        .map(|s| (s.sample.reference_position - s.sample.tool_position).norm()));
    let mapped = mapped_master(out);
    let (lag_rms, lag_max, _) = rms(out
        .slave
        .iter()
        .filter(|s| in_free_motion(info, s))
        .filter_map(|s| {
            let m = mapped
                .iter()
                .take_while(|(t, _)| *t <= s.sample.time)
                .last()?;
            Some((m.1 - s.sample.tool_position).norm())
        }));
    TrackingReport {
        rms_mm: track_rms * 1e3,
        max_mm: track_max * 1e3,
        against_master_rms_mm: lag_rms * 1e3,
        against_master_max_mm: lag_max * 1e3,
        samples: track_n,
    }
}

/// Contact: the forces of the second half of the steady-contact phase, and how far the force
/// the master displays is from the one expected.
fn contact_report(out: &RunOutput) -> ContactReport {
    let info = &out.info;
    let contact_window = phase_window(info, CONTACT_PHASE)
        .map(|(a, b)| (a + (b - a) / 2, b))
        .unwrap_or_default();
    let slave_contact: Vec<&TickRecord> = out
        .slave
        .iter()
        .filter(|s| in_window(info, s, contact_window))
        .collect();
    let master_contact: Vec<&TickRecord> = out
        .master
        .iter()
        .filter(|s| in_window(info, s, contact_window))
        .collect();
    let slave_model = &info.slave_model;
    // The environment's push on the slave, base frame: a wrist sensor reads the robot pushing
    // in its own frame (hence the minus); a sensor read over the data plane gives the push in
    // the base frame already.
    let (pushed, contact_n) = mean_vector(slave_contact.iter().map(|s| {
        let w = &s.sample.wrench;
        if w.frame == penelope_hal::Frame::Base {
            w.force
        } else {
            let pose = slave_model.forward(&s.sample.q);
            -sensor_to_base(w, &info.sensor_mount, &pose).force
        }
    }));
    let (true_contact, _) = mean_vector(
        slave_contact
            .iter()
            .filter_map(|s| s.truth.map(|t| t.base_wrench.force)),
    );
    let (displayed, _) = mean_vector(master_contact.iter().filter_map(|s| motor_force(info, s)));
    let (commanded, _) = mean_vector(
        master_contact
            .iter()
            .map(|s| s.sample.commanded_wrench.force),
    );
    let (hand, _) = mean_vector(
        master_contact
            .iter()
            .filter_map(|s| s.truth.map(|t| t.base_wrench.force)),
    );
    // Expected display: the environment's push on the slave, rotated into the master frame and
    // scaled by the force gain (by the position scale for the wave law, whose power-preserving
    // mapping has no force gain of its own).
    let gain = if info.law == super::Law::Wave {
        info.mapping.scale
    } else {
        info.mapping.force_gain
    };
    let expected = info.rotation().inverse() * (pushed * gain);
    let display_error_pct = if expected.norm() > 1e-9 {
        (displayed - expected).norm() / expected.norm() * 100.0
    } else {
        0.0
    };
    ContactReport {
        sensed_force_n: pushed.norm(),
        expected_display_n: expected.norm(),
        displayed_force_n: displayed.norm(),
        commanded_force_n: commanded.norm(),
        display_error_pct,
        hand_force_n: hand.norm(),
        true_contact_force_n: true_contact.norm(),
        samples: contact_n,
    }
}

/// Drag: the hand force in free motion.
fn drag_report(out: &RunOutput) -> DragReport {
    let info = &out.info;
    let (drag_rms, drag_max, _) = rms(out
        .master
        .iter()
        .filter(|s| in_free_motion(info, s))
        .filter_map(|s| s.truth.map(|t| t.base_wrench.force.norm())));
    DragReport {
        rms_n: drag_rms,
        max_n: drag_max,
    }
}

/// Energy: the coupled energy's peak per whole tap cycle the run reached, whether it builds up,
/// the operator's work over the tap phase, and the lowest port and channel energies.
fn energy_report(out: &RunOutput) -> EnergyReport {
    let info = &out.info;
    let mut peaks = Vec::new();
    let mut operator_work = 0.0;
    if let Some((a, b)) = phase_window(info, TAP_PHASE) {
        peaks = tap_cycle_peaks(out, a, b);
        let work_at = |t: Duration| {
            out.master
                .iter()
                .find(|s| s.sample.time - info.start >= t)
                .and_then(|s| s.truth)
                .map(|t| t.interaction_work)
        };
        if let (Some(w0), Some(w1)) = (work_at(a), work_at(b)) {
            operator_work = w1 - w0;
        }
    }
    // The last cycle against the largest before it: above 1 means energy is building up.
    let growth_ratio = match peaks.split_last() {
        Some((last, earlier)) if !earlier.is_empty() => {
            let before = earlier.iter().copied().fold(0.0f64, f64::max);
            if before > 0.0 { last / before } else { 1.0 }
        }
        _ => 1.0,
    };
    EnergyReport {
        tap_cycle_peaks_j: peaks,
        growth_ratio,
        operator_work_j: operator_work,
        master_port_min_j: min_energy(&out.master, |t| t.sample.port_energy),
        slave_port_min_j: min_energy(&out.slave, |t| t.sample.port_energy),
        master_channel_min_j: min_energy(&out.master, |t| t.sample.channel_energy),
        slave_channel_min_j: min_energy(&out.slave, |t| t.sample.channel_energy),
    }
}

/// The coupled energy's peak in each whole tap cycle between `a` and `b` that the run reached.
fn tap_cycle_peaks(out: &RunOutput, a: Duration, b: Duration) -> Vec<f64> {
    let info = &out.info;
    let frequency = info
        .script
        .segments()
        .iter()
        .find(|s| s.label == TAP_PHASE)
        .and_then(|s| match s.motion {
            penelope_drivers::sim::operator::Motion::Tap { frequency, .. } => Some(frequency),
            _ => None,
        });
    let cycle = Duration::from_secs_f64(1.0 / frequency.unwrap_or(1.0));
    let energy = coupled_energy(out);
    let mut peaks = Vec::new();
    let mut k = a;
    // Only whole cycles the run reached.
    let run_end = out
        .slave
        .last()
        .map_or(Duration::ZERO, |s| s.sample.time - info.start);
    while k + cycle <= b.min(run_end + Duration::from_millis(1)) {
        let window = (k, k + cycle);
        let peak = energy
            .iter()
            .filter(|(t, _)| *t >= window.0 && *t < window.1)
            .map(|(_, e)| *e)
            .fold(0.0f64, f64::max);
        peaks.push(peak);
        k += cycle;
    }
    peaks
}

/// Clutch: the largest reference step while indexing, against the largest in normal sweeps.
fn clutch_report(out: &RunOutput) -> ClutchReport {
    let info = &out.info;
    let steps = |pred: &dyn Fn(&TickRecord) -> bool| {
        out.slave
            .windows(2)
            .filter(|w| pred(&w[1]))
            .map(|w| (w[1].sample.reference_position - w[0].sample.reference_position).norm())
            .fold(0.0f64, f64::max)
            * 1e3
    };
    let index_window = phase_window(info, INDEX_PHASE)
        .map(|(a, b)| (a, b + Duration::from_millis(300)))
        .unwrap_or_default();
    ClutchReport {
        max_step_mm: steps(&|s| in_window(info, s, index_window)),
        normal_max_step_mm: steps(&|s| phase_of(info, s.sample.time).starts_with("sweep")),
    }
}

/// Timing: what each control loop noted of its own wake-ups and execution (real-time runs
/// only; the simulated clock has no timing to speak of).
fn loop_timings(out: &RunOutput) -> Vec<LoopTiming> {
    let info = &out.info;
    if info.clock != ClockMode::RealTime {
        return Vec::new();
    }
    let (m, s) = &info.controllers;
    [
        (format!("master ({m})"), &out.master),
        (format!("slave ({s})"), &out.slave),
    ]
    .into_iter()
    .filter(|(_, rows)| !rows.is_empty())
    .map(|(name, rows)| loop_timing(&name, info, rows))
    .collect()
}

/// Safety: the count of each safety event per robot, and each fault where it began.
fn safety_record(out: &RunOutput) -> (BTreeMap<String, u64>, Vec<String>) {
    let info = &out.info;
    let mut safety_events = BTreeMap::new();
    let mut faults = Vec::new();
    for (robot, rows) in [("master", &out.master), ("slave", &out.slave)] {
        let mut last_fault = None;
        for s in rows.iter() {
            for e in s.sample.events.iter() {
                *safety_events
                    .entry(format!("{robot}/{}", e.as_str()))
                    .or_insert(0) += 1;
            }
            if let Some(cause) = s.sample.fault
                && s.sample.fault != last_fault
            {
                faults.push(format!(
                    "{robot} at {:.3} s: {cause}",
                    (s.sample.time - info.start).as_secs_f64()
                ));
            }
            last_fault = s.sample.fault;
        }
    }
    (safety_events, faults)
}

/// The run's end-to-end latencies ([`latency`](super::latency)).
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct LatencyReport {
    /// Master motion to slave command.
    pub motion_to_command: super::latency::EndToEnd,
    /// Slave contact to master force.
    pub contact_to_force: super::latency::EndToEnd,
}

/// The run's latencies, its channel's cells taken as no transport.
fn latency_report(out: &RunOutput) -> LatencyReport {
    let zero = std::time::Duration::ZERO;
    let (motion_to_command, contact_to_force) = super::latency::end_to_end(out, (zero, zero));
    LatencyReport {
        motion_to_command,
        contact_to_force,
    }
}

/// The run's report.
pub fn report(out: &RunOutput) -> Report {
    let info = &out.info;
    let (safety_events, faults) = safety_record(out);
    Report {
        lab: info.system.clone(),
        law: info.law.as_str().to_string(),
        clock: match info.clock {
            ClockMode::RealTime => "real-time",
            ClockMode::Simulated => "simulated",
        }
        .to_string(),
        seed: info.seed,
        duration_s: out
            .slave
            .last()
            .map_or(0.0, |s| (s.sample.time - info.start).as_secs_f64()),
        scale: info.mapping.scale,
        force_gain: info.mapping.force_gain,
        kinematics: kinematics_report(info),
        tracking: tracking_report(out),
        contact: contact_report(out),
        drag: drag_report(out),
        energy: energy_report(out),
        clutch: clutch_report(out),
        latency: latency_report(out),
        timing: loop_timings(out),
        safety_events,
        faults,
        dropped_samples: (out.dropped.0 + out.dropped.1) as usize,
    }
}
