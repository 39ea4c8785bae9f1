//! The delay experiment: a system file's teleoperation task (the demo's: free motion, steady
//! contact with a stiff wall, tapping on it) run for each law and each round-trip delay on the
//! simulated clock, with a verdict on its stability and the figures a control engineer compares
//! laws by.
//!
//! # The delay
//! A round-trip delay `T` is split half each way: the channel gets `faults = { delay_ms = T/2,
//! jitter_ms = J }` in both directions (the one-node channel's seeded delay line, see
//! [`penelope_runtime::objects::delay_line`]), so a sample of the master's reaches the slave `T/2 +
//! U(0, J)` later (to within one communication period) and the slave's wrench comes back as
//! late. `T = 0` with no jitter runs the channel without faults: the demo as it is.
//!
//! # Stable or not
//! A run is stable when all of these hold (each number is in its [`DelayRun`]):
//!
//! 1. **no fault**: no safety fault stopped either robot;
//! 2. **no energy build-up while tapping**: [`EnergyReport::growth_ratio`] (the last tap cycle's
//!    peak mechanical energy of both arms and the wall over the largest earlier one) at most
//!    [`MAX_GROWTH_RATIO`];
//! 3. **no limit cycle in steady contact**: while the operator holds the master still against
//!    the wall (the second half of the contact phase), the true contact force's standard
//!    deviation over its mean (at least 1 N) at most [`MAX_CONTACT_RIPPLE`]: a slave bouncing on
//!    the wall shows as a ripple near or above 1;
//! 4. **no limit cycle at rest**: when the operator holds still in free space at the end (the
//!    rest phase), the slave's tool stays within [`MAX_REST_MOTION_MM`] RMS of where it is on
//!    average (a displacement, not a speed: the wrist's sub-millimetre chatter at 1 kHz makes
//!    a finite-difference speed of about 10 mm/s even when nothing moves);
//! 5. **tracking does not blow up**: the slave stays within [`MAX_TRACKING_MM`] of its own
//!    reference in free motion, and every figure is finite.
//!
//! The thresholds sit far from what a stable run shows (zero delay: growth about 1, ripple a few
//! percent, rest motion under 0.1 mm, tracking under 5 mm), so that noise does not flip a
//! verdict; each failed criterion is named in [`DelayRun::reasons`].
//!
//! [`EnergyReport::growth_ratio`]: super::report::EnergyReport::growth_ratio

use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use penelope_drivers::sim::scripts::CONTACT_PHASE;
use serde::Serialize;

use super::report::{Report, report};
use super::{Law, RunError, RunOptions, RunOutput, run, set_key, task_error};
use crate::system::SystemFile;
use penelope_runtime::objects::clock::ClockMode;

/// Largest growth ratio of the tap cycles' peak energy of a stable run.
pub const MAX_GROWTH_RATIO: f64 = 1.25;
/// Largest contact-force ripple (standard deviation over mean) in steady contact.
pub const MAX_CONTACT_RIPPLE: f64 = 0.25;
/// Largest RMS slave tool displacement about its mean while the operator rests in free
/// space, mm.
pub const MAX_REST_MOTION_MM: f64 = 2.0;
/// Largest distance between the slave's tool and its reference in free motion, mm (ten times
/// the demo's bound of 5 mm).
pub const MAX_TRACKING_MM: f64 = 50.0;

/// The phase in which the operator holds still in free space at the end of the demo's script.
const REST_PHASE: &str = "rest";

/// What to run.
#[derive(Clone, Debug, PartialEq)]
pub struct DelayPlan {
    /// The laws, in order.
    pub laws: Vec<Law>,
    /// Round-trip delays, ms (half each way).
    pub round_trip_ms: Vec<f64>,
    /// Jitter of each direction, ms: every sample `U(0, jitter)` later still.
    pub jitter_ms: f64,
    /// The wall's stiffness, N/m (default: the file's).
    pub wall_stiffness: Option<f64>,
    /// Seed of the delay lines and the sensor noise.
    pub seed: u64,
    /// Length of each run (default: the operator's script).
    pub duration: Option<Duration>,
    /// Runs at once, at least 1.
    pub jobs: usize,
}

impl Default for DelayPlan {
    fn default() -> Self {
        DelayPlan {
            laws: Law::ALL.to_vec(),
            round_trip_ms: vec![0.0, 10.0, 50.0, 100.0, 200.0],
            jitter_ms: 0.0,
            wall_stiffness: None,
            seed: 1,
            duration: None,
            jobs: 1,
        }
    }
}

/// One law at one delay: the verdict and the figures.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct DelayRun {
    /// The law's name.
    pub law: String,
    /// Round-trip delay, ms.
    pub delay_ms: f64,
    /// Delay of each direction, ms (half the round trip).
    pub one_way_ms: f64,
    /// Jitter of each direction, ms.
    pub jitter_ms: f64,
    /// The wall's stiffness, N/m (the file's if not set).
    pub wall_stiffness: Option<f64>,
    /// Stable by every criterion of the module's docs.
    pub stable: bool,
    /// The criteria it failed, with their numbers (empty when stable).
    pub reasons: Vec<String>,
    /// Peak energy per tap cycle, J.
    pub tap_cycle_peaks_j: Vec<f64>,
    /// The last tap cycle's peak over the largest earlier one.
    pub energy_growth: f64,
    /// Contact-force standard deviation over its mean in steady contact.
    pub contact_ripple: f64,
    /// RMS slave tool displacement about its mean while the operator rests in free space, mm.
    pub rest_motion_mm: f64,
    /// Free-motion tracking, slave tool against its own (delayed) reference: RMS, mm.
    pub tracking_rms_mm: f64,
    /// The same, largest, mm.
    pub tracking_max_mm: f64,
    /// Free-motion tracking against the master's mapped pose at the same instant (the delay
    /// shows here): RMS, mm.
    pub against_master_rms_mm: f64,
    /// Force tracking in steady contact: displayed force against force gain x sensed force,
    /// percent.
    pub force_error_pct: f64,
    /// Free-motion drag the operator feels, RMS, N.
    pub drag_rms_n: f64,
    /// Largest true contact force on the slave over the run, N.
    pub max_contact_force_n: f64,
    /// The lowest energy of the channel's two-port observer at the master port, J (`None`
    /// for laws that run none).
    pub master_channel_min_j: Option<f64>,
    /// The same at the slave port, J.
    pub slave_channel_min_j: Option<f64>,
    /// Safety faults seen (robot at time: cause).
    pub faults: Vec<String>,
    /// Wall-clock time the run took, s.
    pub wall_time_s: f64,
}

/// The system file `file` with the plan's delay, jitter and wall for one run.
///
/// # Errors
/// [`RunError::Task`] when the file has no teleoperation channel, or a configuration is not
/// TOML.
pub fn delayed_system(
    file: &SystemFile,
    round_trip_ms: f64,
    jitter_ms: f64,
    wall_stiffness: Option<f64>,
    seed: u64,
) -> Result<SystemFile, RunError> {
    let mut file = file.clone();
    let mut channels = 0;
    for o in &mut file.objects {
        if o.kind == "trajectory/teleop" {
            channels += 1;
            if round_trip_ms > 0.0 || jitter_ms > 0.0 {
                let mut faults = toml::Table::new();
                faults.insert("delay_ms".into(), toml::Value::Float(round_trip_ms / 2.0));
                faults.insert("jitter_ms".into(), toml::Value::Float(jitter_ms));
                set_key(o, "faults", toml::Value::Table(faults))?;
                set_key(o, "fault_seed", toml::Value::Integer(seed as i64))?;
            }
        }
        // The plant's shapes, and a virtual sensor's own copy of them if it has one: the
        // same wall for both.
        if let (Some(k), "board/sim" | "sensor/virtual") = (wall_stiffness, o.kind.as_str()) {
            let mut table: toml::Table = o
                .config
                .parse()
                .map_err(|e| task_error(format!("{}: {e}", o.name)))?;
            if let Some(toml::Value::Array(shapes)) = table.get_mut("shapes") {
                for shape in shapes.iter_mut() {
                    if let toml::Value::Table(s) = shape {
                        s.insert("stiffness".into(), toml::Value::Float(k));
                    }
                }
            }
            o.config = table.to_string();
        }
    }
    if channels == 0 {
        return Err(task_error("the system has no trajectory/teleop channel"));
    }
    Ok(file)
}

/// Runs `law` at `round_trip_ms` on the simulated clock and judges it.
///
/// # Errors
/// The errors of [`delayed_system`] and [`run`].
pub fn run_one(
    file: &SystemFile,
    plan: &DelayPlan,
    law: Law,
    round_trip_ms: f64,
) -> Result<DelayRun, RunError> {
    let started = Instant::now();
    let system = delayed_system(
        file,
        round_trip_ms,
        plan.jitter_ms,
        plan.wall_stiffness,
        plan.seed,
    )?;
    let options = RunOptions {
        duration: plan.duration,
        law: Some(law),
        scale: None,
        seed: plan.seed,
        clock: ClockMode::Simulated,
    };
    let out = run(&system, &options, &mut |_| {})?;
    let r = report(&out);
    let mut judged = judge(&out, &r);
    judged.law = law.as_str().to_string();
    judged.delay_ms = round_trip_ms;
    judged.one_way_ms = round_trip_ms / 2.0;
    judged.jitter_ms = plan.jitter_ms;
    judged.wall_stiffness = plan.wall_stiffness;
    judged.wall_time_s = started.elapsed().as_secs_f64();
    Ok(judged)
}

/// Every law at every delay of `plan`, at most `plan.jobs` at once (each run has its own
/// nodes and simulated clock, so runs in parallel give the same results as one by one);
/// `on_done` is called from the worker thread as each run ends. Runs come back in plan order:
/// law by law, delay by delay.
///
/// # Errors
/// The first run's error, if any failed to run (an unstable run is not an error).
pub fn run_plan(
    file: &SystemFile,
    plan: &DelayPlan,
    on_done: &(dyn Fn(&DelayRun) + Sync),
) -> Result<Vec<DelayRun>, RunError> {
    let cases: Vec<(Law, f64)> = plan
        .laws
        .iter()
        .flat_map(|&l| plan.round_trip_ms.iter().map(move |&d| (l, d)))
        .collect();
    let results: Vec<Mutex<Option<Result<DelayRun, RunError>>>> =
        cases.iter().map(|_| Mutex::new(None)).collect();
    let next = AtomicUsize::new(0);
    let jobs = plan.jobs.clamp(1, cases.len().max(1));
    // Each run has its own nodes and clock; a bounded pool takes the cases in order.
    std::thread::scope(|scope| {
        for _ in 0..jobs {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(&(law, delay)) = cases.get(i) else {
                        break;
                    };
                    let result = run_one(file, plan, law, delay);
                    if let Ok(r) = &result {
                        on_done(r);
                    }
                    if let Ok(mut slot) = results[i].lock() {
                        *slot = Some(result);
                    }
                }
            });
        }
    });
    results
        .into_iter()
        .map(|slot| {
            slot.into_inner()
                .ok()
                .flatten()
                .unwrap_or_else(|| Err(task_error("a run did not finish")))
        })
        .collect()
}

/// The verdict and figures of one run (law and delay left for the caller to fill in).
pub fn judge(out: &RunOutput, r: &Report) -> DelayRun {
    let contact_ripple = contact_ripple(out);
    let rest_motion_mm = rest_motion_mm(out);
    let max_contact_force_n = out
        .slave
        .iter()
        .filter_map(|s| s.truth.map(|t| t.base_wrench.force.norm()))
        .fold(0.0f64, f64::max);
    let reasons = instability_reasons(r, contact_ripple, rest_motion_mm, max_contact_force_n);
    DelayRun {
        law: r.law.clone(),
        delay_ms: 0.0,
        one_way_ms: 0.0,
        jitter_ms: 0.0,
        wall_stiffness: None,
        stable: reasons.is_empty(),
        reasons,
        tap_cycle_peaks_j: r.energy.tap_cycle_peaks_j.clone(),
        energy_growth: r.energy.growth_ratio,
        contact_ripple,
        rest_motion_mm,
        tracking_rms_mm: r.tracking.rms_mm,
        tracking_max_mm: r.tracking.max_mm,
        against_master_rms_mm: r.tracking.against_master_rms_mm,
        force_error_pct: r.contact.display_error_pct,
        drag_rms_n: r.drag.rms_n,
        max_contact_force_n,
        master_channel_min_j: r.energy.master_channel_min_j,
        slave_channel_min_j: r.energy.slave_channel_min_j,
        faults: r.faults.clone(),
        wall_time_s: 0.0,
    }
}

/// Where the script's phase `label` starts and ends, from the run's start.
fn phase_window(out: &RunOutput, label: &str) -> Option<(Duration, Duration)> {
    let mut t0 = Duration::ZERO;
    for s in out.info.script.segments() {
        if s.label == label {
            return Some((t0, t0 + s.duration));
        }
        t0 += s.duration;
    }
    None
}

/// Steady contact: the true contact force's spread about its mean over the second half of the
/// contact phase, relative to the mean (at least 1 N).
fn contact_ripple(out: &RunOutput) -> f64 {
    let elapsed = |t: penelope_hal::Timestamp| t.saturating_since(out.info.start);
    let forces: Vec<f64> = phase_window(out, CONTACT_PHASE)
        .map(|(a, b)| {
            let from = a + (b - a) / 2;
            out.slave
                .iter()
                .filter(|s| (from..b).contains(&elapsed(s.sample.time)))
                .filter_map(|s| s.truth.map(|t| t.base_wrench.force.norm()))
                .collect()
        })
        .unwrap_or_default();
    if forces.is_empty() {
        0.0
    } else {
        let n = forces.len() as f64;
        let mean = forces.iter().sum::<f64>() / n;
        let var = forces.iter().map(|f| (f - mean).powi(2)).sum::<f64>() / n;
        var.sqrt() / mean.max(1.0)
    }
}

/// Rest: the slave's true tool position about its mean over the rest phase, mm RMS.
fn rest_motion_mm(out: &RunOutput) -> f64 {
    let elapsed = |t: penelope_hal::Timestamp| t.saturating_since(out.info.start);
    let rest: Vec<nalgebra::Vector3<f64>> = phase_window(out, REST_PHASE)
        .map(|(a, b)| {
            out.slave
                .iter()
                .filter(|s| (a..b).contains(&elapsed(s.sample.time)))
                .filter_map(|s| s.truth.map(|t| t.tool_pose.translation.vector))
                .collect()
        })
        .unwrap_or_default();
    if rest.is_empty() {
        0.0
    } else {
        let n = rest.len() as f64;
        let mean = rest.iter().sum::<nalgebra::Vector3<f64>>() / n;
        (rest.iter().map(|p| (p - mean).norm_squared()).sum::<f64>() / n).sqrt() * 1e3
    }
}

/// Why a run is not stable, one reason per criterion it fails; empty when it is stable.
fn instability_reasons(
    r: &Report,
    contact_ripple: f64,
    rest_motion_mm: f64,
    max_contact_force_n: f64,
) -> Vec<String> {
    let mut reasons = Vec::new();
    if !r.faults.is_empty() {
        reasons.push(format!("faults: {}", r.faults.join("; ")));
    }
    let growth = r.energy.growth_ratio;
    if !within(growth, MAX_GROWTH_RATIO) {
        reasons.push(format!(
            "tap energy grows: last/largest earlier cycle peak {growth:.2} > {MAX_GROWTH_RATIO} \
             (peaks {:.3?} J)",
            r.energy.tap_cycle_peaks_j
        ));
    }
    if !within(contact_ripple, MAX_CONTACT_RIPPLE) {
        reasons.push(format!(
            "limit cycle in steady contact: force ripple {contact_ripple:.2} > \
             {MAX_CONTACT_RIPPLE}"
        ));
    }
    if !within(rest_motion_mm, MAX_REST_MOTION_MM) {
        reasons.push(format!(
            "limit cycle at rest: the slave moves {rest_motion_mm:.2} mm RMS > \
             {MAX_REST_MOTION_MM} mm"
        ));
    }
    if !within(r.tracking.max_mm, MAX_TRACKING_MM) {
        reasons.push(format!(
            "tracking blows up: {:.1} mm from its reference > {MAX_TRACKING_MM} mm",
            r.tracking.max_mm
        ));
    }
    let figures = [
        r.tracking.rms_mm,
        r.tracking.against_master_rms_mm,
        r.contact.display_error_pct,
        r.drag.rms_n,
        max_contact_force_n,
    ];
    if figures.iter().any(|v| !v.is_finite()) {
        reasons.push("a figure is not finite".to_string());
    }
    reasons
}

/// `value` is a number no larger than `limit` (NaN is not: a figure that is not a number
/// fails its criterion).
fn within(value: f64, limit: f64) -> bool {
    value.partial_cmp(&limit).is_some_and(|o| o.is_le())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runs::DEMO_SYSTEM;
    use penelope_runtime::objects::kinds::SimBoardConfig;
    use penelope_runtime::objects::teleop::TeleopConfig;

    fn object<'a>(file: &'a SystemFile, kind: &str) -> &'a crate::system::ObjectSpec {
        file.objects.iter().find(|o| o.kind == kind).unwrap()
    }

    #[test]
    fn a_round_trip_is_split_half_each_way_and_the_wall_is_set() {
        let demo = SystemFile::parse(DEMO_SYSTEM).unwrap();
        let file = delayed_system(&demo, 200.0, 5.0, Some(1500.0), 9).unwrap();
        let link: TeleopConfig = penelope_runtime::objects::config::parse(
            "trajectory/teleop",
            &object(&file, "trajectory/teleop").config,
        )
        .unwrap();
        let faults = link.faults.expect("faults on the channel");
        assert_eq!((faults.delay_ms, faults.jitter_ms), (100.0, 5.0));
        assert_eq!(link.fault_seed, 9);
        let board = file
            .objects
            .iter()
            .filter(|o| o.kind == "board/sim")
            .map(|o| {
                penelope_runtime::objects::config::parse::<SimBoardConfig>(&o.kind, &o.config)
                    .unwrap()
            })
            .find(|b| !b.shapes.is_empty())
            .expect("the demo's wall");
        assert!(board.shapes.iter().all(|s| s.stiffness == 1500.0));
        // No delay, no jitter: the channel as it was, plain cells.
        let plain = delayed_system(&demo, 0.0, 0.0, None, 9).unwrap();
        assert_eq!(plain, demo);
    }

    #[test]
    fn within_refuses_what_is_not_a_number() {
        assert!(within(1.0, 1.25) && within(1.25, 1.25));
        assert!(!within(1.3, 1.25) && !within(f64::NAN, 1.25));
    }
}
