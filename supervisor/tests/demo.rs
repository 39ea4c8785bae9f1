//! The teleoperation demo on a simulated clock, run through the node runtime (its system file
//! applied to an in-process node's creator): what issues 4 and 12 promise, checked.

use std::time::Duration;

use penelope_runtime::objects::clock::ClockMode;
use penelope_supervisor::runs::report::{Report, report};
use penelope_supervisor::runs::{DEMO_SYSTEM, Law, RunOptions, RunOutput, run};
use penelope_supervisor::system::SystemFile;

fn demo() -> SystemFile {
    SystemFile::parse(DEMO_SYSTEM).expect("config/demo.toml is a valid system file")
}

fn simulate(law: Law, seed: u64, duration: Option<Duration>) -> (RunOutput, Report) {
    let options = RunOptions {
        duration,
        law: Some(law),
        scale: None,
        seed,
        clock: ClockMode::Simulated,
    };
    let out = run(&demo(), &options, &mut |_| {}).expect("the demo system builds and runs");
    let r = report(&out);
    (out, r)
}

#[test]
fn free_motion_tracking_is_under_two_millimetres_rms_for_both_laws() {
    for law in [Law::ForcePosition, Law::PositionError] {
        let (_, r) = simulate(law, 1, None);
        assert!(r.faults.is_empty(), "{law:?}: faults {:?}", r.faults);
        assert!(
            r.tracking.samples > 5_000,
            "{law:?}: too few free-motion ticks: {}",
            r.tracking.samples
        );
        assert!(
            r.tracking.rms_mm < 2.0,
            "{law:?}: tracking RMS {} mm",
            r.tracking.rms_mm
        );
        assert!(
            r.tracking.max_mm < 5.0,
            "{law:?}: tracking max {} mm",
            r.tracking.max_mm
        );
    }
}

#[test]
fn in_steady_contact_the_master_displays_the_gain_times_the_mapped_sensor_force() {
    let (_, r) = simulate(Law::ForcePosition, 1, None);
    let c = &r.contact;
    assert!(c.samples > 500, "steady-contact ticks: {}", c.samples);
    assert!(
        c.sensed_force_n > 5.0,
        "the slave must press on the wall, sensed {} N",
        c.sensed_force_n
    );
    assert!(
        c.display_error_pct < 5.0,
        "the motors display {} N, {}% off the expected {} N",
        c.displayed_force_n,
        c.display_error_pct,
        c.expected_display_n
    );
    // The force the operator's hand actually feels (the plant's statics) also matches.
    let hand_error = (c.hand_force_n - c.expected_display_n).abs() / c.expected_display_n * 100.0;
    assert!(
        hand_error < 5.0,
        "hand feels {} N, expected {} N",
        c.hand_force_n,
        c.expected_display_n
    );
    // The sensor tracks the true contact force (bias tared, noise filtered).
    assert!((c.sensed_force_n - c.true_contact_force_n).abs() < 0.05 * c.true_contact_force_n);
}

#[test]
fn tapping_does_not_build_up_energy_with_default_gains() {
    for law in [Law::ForcePosition, Law::PositionError] {
        let (_, r) = simulate(law, 1, None);
        let peaks = &r.energy.tap_cycle_peaks_j;
        assert!(peaks.len() >= 5, "{law:?}: tap cycles {}", peaks.len());
        assert!(
            peaks.iter().all(|e| e.is_finite() && *e > 0.0),
            "{law:?}: {peaks:?}"
        );
        assert!(
            r.energy.growth_ratio <= 1.05,
            "{law:?}: energy grows: {peaks:?}"
        );
    }
}

#[test]
fn clutch_re_anchoring_never_jumps() {
    let (out, r) = simulate(Law::ForcePosition, 1, None);
    assert!(r.clutch.normal_max_step_mm > 0.0);
    assert!(
        r.clutch.max_step_mm <= r.clutch.normal_max_step_mm,
        "clutch step {} mm exceeds the normal per-tick motion {} mm",
        r.clutch.max_step_mm,
        r.clutch.normal_max_step_mm
    );
    // While the clutch is held the slave holds: the hand moved 2 cm up, the slave not at all.
    let (a, b) = (Duration::from_millis(8_600), Duration::from_millis(9_400));
    let held: Vec<_> = out
        .slave
        .iter()
        .filter(|s| (s.sample.time - out.info.start) >= a && (s.sample.time - out.info.start) < b)
        .map(|s| s.sample.reference_position)
        .collect();
    let spread = held
        .iter()
        .map(|p| (p - held[0]).norm())
        .fold(0.0f64, f64::max);
    assert!(
        spread < 1e-4,
        "the slave reference moved {spread} m while clutched"
    );
}

#[test]
fn the_simulated_clock_is_bit_for_bit_reproducible_and_the_seed_matters() {
    let short = Some(Duration::from_secs(13));
    let (a, _) = simulate(Law::ForcePosition, 7, short);
    let (b, _) = simulate(Law::ForcePosition, 7, short);
    assert_eq!(a.master.len(), b.master.len());
    assert!(
        a.master == b.master && a.slave == b.slave,
        "same seed, different telemetry"
    );
    let (c, _) = simulate(Law::ForcePosition, 8, short);
    assert!(
        a.slave != c.slave,
        "a different seed must change the sensor noise and so the telemetry"
    );
}

#[test]
fn a_bad_configuration_is_a_clear_error_not_a_crash() {
    let text = DEMO_SYSTEM.replace("kind = \"puma200\"", "kind = \"puma999\"");
    // Refused when the file is read, or when a node creates the robot: by name either way.
    let err = match SystemFile::parse(&text) {
        Err(e) => e.to_string(),
        Ok(f) => run(&f, &RunOptions::default(), &mut |_| {})
            .err()
            .expect("unknown model")
            .to_string(),
    };
    assert!(err.contains("puma999"), "{err}");
    let options = RunOptions {
        scale: Some(f64::NAN),
        ..RunOptions::default()
    };
    assert!(run(&demo(), &options, &mut |_| {}).is_err());
}

#[test]
fn the_report_gives_both_end_to_end_latencies_within_a_communication_and_a_control_period() {
    // On the simulated clock the communication task steps at its period (no early wakes):
    // a sample waits at most one communication period to cross and one control period to be
    // used, and the limit is the receiving loop's next tick.
    let (out, r) = simulate(Law::ForcePosition, 1, None);
    let bound = (out.info.comm_period + out.info.control_period).as_secs_f64() * 1e6;
    let tick = out.info.control_period.as_secs_f64() * 1e6;
    for (what, e) in [
        ("motion->command", &r.latency.motion_to_command),
        ("contact->force", &r.latency.contact_to_force),
    ] {
        eprintln!("{what}: {e:?}");
        assert!(e.latency.samples > 1000, "{what}: {e:?}");
        assert!(e.latency.p99_us <= bound, "{what}: {e:?}");
        assert!(e.latency.max_us <= bound, "{what}: {e:?}");
        // Both loops tick at the same instants: the next tick is one control period on.
        assert!((e.limit.p50_us - tick).abs() < 1.0, "{what}: {e:?}");
    }
}
