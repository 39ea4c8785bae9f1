//! The wave-variable law (`controller/wave-master`, `controller/wave-slave`) and the passivity
//! observers in telemetry, on the demo's task and simulated clock (issue 14). Zero delay here:
//! the delayed runs come with the delay channel.

use penelope_runtime::objects::clock::ClockMode;
use penelope_supervisor::runs::report::{Report, report};
use penelope_supervisor::runs::{DEMO_SYSTEM, Law, RunOptions, RunOutput, run};
use penelope_supervisor::system::SystemFile;

fn simulate(law: Law) -> (RunOutput, Report) {
    let file = SystemFile::parse(DEMO_SYSTEM).expect("config/demo.toml is a valid system file");
    let options = RunOptions {
        law: Some(law),
        clock: ClockMode::Simulated,
        ..RunOptions::default()
    };
    let out = run(&file, &options, &mut |_| {}).expect("the demo system builds and runs");
    let r = report(&out);
    (out, r)
}

#[test]
fn the_wave_law_completes_the_demo_task_with_zero_delay() {
    let (out, r) = simulate(Law::Wave);
    eprintln!(
        "wave: tracking rms {:.3} mm max {:.3} mm, against master rms {:.3} mm max {:.3} mm; \
         contact sensed {:.2} N displayed {:.2} N; drag {:?}; energy growth {:.3}; \
         port min master {:?} J slave {:?} J",
        r.tracking.rms_mm,
        r.tracking.max_mm,
        r.tracking.against_master_rms_mm,
        r.tracking.against_master_max_mm,
        r.contact.sensed_force_n,
        r.contact.displayed_force_n,
        r.drag,
        r.energy.growth_ratio,
        r.energy.master_port_min_j,
        r.energy.slave_port_min_j,
    );
    assert_eq!(out.info.law, Law::Wave);
    assert!(r.faults.is_empty(), "faults {:?}", r.faults);
    assert!(
        r.tracking.samples > 5_000,
        "free-motion ticks: {}",
        r.tracking.samples
    );
    // The demo's tracking bound, 2 mm RMS, against the wave's own pose (measured 0.11 mm) and,
    // stricter, against the master's mapped pose at the same instant (measured 1.11 mm RMS,
    // 1.84 mm max: the line's damping b lags the slave a little behind the hand).
    assert!(
        r.tracking.rms_mm < 2.0,
        "tracking RMS {} mm",
        r.tracking.rms_mm
    );
    assert!(
        r.tracking.against_master_rms_mm < 2.0,
        "against the master: RMS {} mm",
        r.tracking.against_master_rms_mm
    );
    // The slave presses on the wall and the operator feels it (measured 8.77 N both: the line
    // maps force with the position scale, 1, not the channel's force gain).
    assert!(
        r.contact.sensed_force_n > 2.0,
        "sensed {} N",
        r.contact.sensed_force_n
    );
    assert!(
        r.contact.displayed_force_n > 1.0,
        "displayed {} N",
        r.contact.displayed_force_n
    );
    // Energy does not build up while tapping.
    assert!(
        r.energy.growth_ratio < 1.5,
        "growth {}",
        r.energy.growth_ratio
    );
}

#[test]
fn every_law_reports_its_port_energy_in_the_recorded_ticks() {
    for law in [Law::ForcePosition, Law::PositionError, Law::Wave] {
        let (out, r) = simulate(law);
        for (side, ticks) in [("master", &out.master), ("slave", &out.slave)] {
            let with = ticks
                .iter()
                .filter(|t| t.sample.port_energy.is_some())
                .count();
            assert!(
                with * 10 > ticks.len() * 9,
                "{law:?} {side}: {with} of {} ticks carry the observer's energy",
                ticks.len()
            );
            assert!(
                ticks
                    .iter()
                    .filter_map(|t| t.sample.port_energy)
                    .all(f64::is_finite)
            );
        }
        assert!(r.energy.master_port_min_j.is_some() && r.energy.slave_port_min_j.is_some());
        eprintln!(
            "{law:?}: port min master {:?} J slave {:?} J",
            r.energy.master_port_min_j, r.energy.slave_port_min_j
        );
    }
}

/// The demo with `passivity = ...` on its force display.
fn with_passivity(word: &str) -> SystemFile {
    let text = DEMO_SYSTEM.replacen(
        "kind = \"force-display\"",
        &format!("passivity = \"{word}\"\nkind = \"force-display\""),
        1,
    );
    SystemFile::parse(&text).expect("a valid system file")
}

#[test]
fn the_force_display_takes_the_two_port_controller_from_its_config() {
    let options = RunOptions {
        law: Some(Law::ForcePosition),
        clock: ClockMode::Simulated,
        ..RunOptions::default()
    };
    let out = run(&with_passivity("impedance"), &options, &mut |_| {}).expect("runs");
    let r = report(&out);
    eprintln!(
        "force-position with the master's two-port controller: tracking rms {:.3} mm, channel \
         min master {:?} J slave {:?} J",
        r.tracking.rms_mm, r.energy.master_channel_min_j, r.energy.slave_channel_min_j
    );
    assert!(r.faults.is_empty(), "faults {:?}", r.faults);
    assert!(
        r.tracking.rms_mm < 2.0,
        "tracking RMS {} mm",
        r.tracking.rms_mm
    );
    // The master port's observer, fed by the slave's counters, is held by its controller at the
    // port's allowed initial energy, -10 mJ (measured -0.0100 J, against -0.046 J without it:
    // the display's filter makes the channel slightly active even without delay).
    let min = r
        .energy
        .master_channel_min_j
        .expect("the two-port observer's energy");
    assert!(min > -0.012, "master port energy went down to {min} J");
    // Without the controller, in the paper's decoupled mode (`handoff = "periodic"`: a sample
    // waits for the communication period), the observer sees the channel go active. With the
    // default event-driven handoff the channel's delay is one control tick at most and the
    // observer sees it stay passive to within a microjoule (-1.4e-7 J measured).
    let periodic = DEMO_SYSTEM
        .replacen(
            "kind = \"force-display\"",
            "passivity = \"off\"\nkind = \"force-display\"",
            1,
        )
        .replacen(
            "kind = \"teleop\"",
            "handoff = \"periodic\"\nkind = \"teleop\"",
            1,
        );
    let periodic = SystemFile::parse(&periodic).expect("a valid system file");
    let plain = report(&run(&periodic, &options, &mut |_| {}).expect("runs"));
    let min_plain = plain
        .energy
        .master_channel_min_j
        .expect("observed without the controller");
    assert!(min_plain < -0.03, "without the controller: {min_plain} J");
    let event = report(&run(&with_passivity("off"), &options, &mut |_| {}).expect("runs"));
    let min_event = event
        .energy
        .master_channel_min_j
        .expect("observed without the controller");
    eprintln!("without the controller: periodic {min_plain} J, event-driven {min_event} J");
    assert!(
        min_event > min_plain,
        "event-driven {min_event} J, periodic {min_plain} J"
    );
    // A force display has impedance causality: the admittance form is refused.
    assert!(run(&with_passivity("admittance"), &options, &mut |_| {}).is_err());
}
