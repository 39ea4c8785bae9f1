//! The run's telemetry as CSV, one row per control tick.

use std::path::Path;

use penelope_drivers::sim::operator::OperatorScript;
use penelope_hal::Timestamp;
use penelope_runtime::objects::tick::TickRecord;

/// Writes one robot's ticks: time since `start` (the run's first tick), the phase of the
/// operator's `script`, safety state, joints, references, wrenches, the plant's ground truth and
/// loop timing. Units in the column names. (`tools/tests/demo_by_ctl.rs` writes a node's ticks
/// with this same function, to compare them with the demo's files byte for byte.)
pub fn write_telemetry(
    path: &Path,
    start: Timestamp,
    script: &OperatorScript,
    rows: &[TickRecord],
) -> anyhow::Result<()> {
    let mut w = csv::Writer::from_path(path)?;
    let mut header: Vec<String> = vec![
        "time_s".into(),
        "phase".into(),
        "state".into(),
        "controller".into(),
    ];
    for name in ["q_rad", "qd_rad_s", "effort_nm"] {
        header.extend((1..=6).map(|j| format!("{name}{j}")));
    }
    for name in [
        "ref_m",
        "tool_m",
        "sensor_force_n",
        "sensor_torque_nm",
        "commanded_force_n",
        "true_tool_m",
        "true_force_n",
    ] {
        header.extend(["x", "y", "z"].iter().map(|a| format!("{name}_{a}")));
    }
    header.extend(
        [
            "kinetic_energy_j",
            "interaction_work_j",
            "port_energy_j",
            "channel_energy_j",
            "wake_latency_us",
            "exec_us",
            "events",
        ]
        .iter()
        .map(|s| s.to_string()),
    );
    w.write_record(&header)?;
    let mut record: Vec<String> = Vec::with_capacity(header.len());
    for s in rows {
        let t = &s.sample;
        record.clear();
        let elapsed = t.time - start;
        record.push(format!("{:.6}", elapsed.as_secs_f64()));
        record.push(
            script
                .segment_at(elapsed)
                .map_or("", |(_, seg, _)| seg.label)
                .to_string(),
        );
        record.push(t.state.as_str().to_string());
        record.push(t.controller.to_string());
        for v in [&t.q, &t.qd, &t.effort] {
            record.extend(v.iter().map(|x| format!("{x:.9}")));
        }
        let truth_pos = s
            .truth
            .map(|x| x.tool_pose.translation.vector)
            .unwrap_or_default();
        let truth_force = s.truth.map(|x| x.base_wrench.force).unwrap_or_default();
        for v in [
            &t.reference_position,
            &t.tool_position,
            &t.wrench.force,
            &t.wrench.torque,
            &t.commanded_wrench.force,
            &truth_pos,
            &truth_force,
        ] {
            record.extend(v.iter().map(|x| format!("{x:.9}")));
        }
        record.push(format!("{:.9}", s.truth.map_or(0.0, |x| x.kinetic_energy)));
        record.push(format!(
            "{:.9}",
            s.truth.map_or(0.0, |x| x.interaction_work)
        ));
        // The law's passivity observer; empty for a law without one.
        record.push(t.port_energy.map_or(String::new(), |e| format!("{e:.9}")));
        // The channel's two-port observer at this side's port; empty for a law without one.
        record.push(
            t.channel_energy
                .map_or(String::new(), |e| format!("{e:.9}")),
        );
        record.push(format!("{:.3}", t.wake_latency.as_secs_f64() * 1e6));
        record.push(format!("{:.3}", t.exec_time.as_secs_f64() * 1e6));
        let events: Vec<&str> = t.events.iter().map(|e| e.as_str()).collect();
        record.push(events.join(" "));
        w.write_record(&record)?;
    }
    w.flush()?;
    Ok(())
}
