//! Plots a person can read: tracking, forces, and (real-time runs) loop timing, as SVG.

use std::path::{Path, PathBuf};

use penelope_hal::Kinematics;
use penelope_rt_core::telemetry::ReferenceKind;
use penelope_runtime::objects::clock::ClockMode;
use penelope_runtime::objects::teleop::sensor_to_base;
use penelope_runtime::objects::tick::TickRecord;
use penelope_supervisor::runs::RunOutput;
use penelope_supervisor::runs::report::motor_force;
use plotters::prelude::*;

const SIZE: (u32, u32) = (1100, 700);

type Series = Vec<(f64, f64)>;

fn time_of(out: &RunOutput, s: &TickRecord) -> f64 {
    (s.sample.time - out.info.start).as_secs_f64()
}

fn bounds(series: &[&Series]) -> (f64, f64, f64, f64) {
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for s in series {
        for &(x, y) in s.iter() {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
    }
    if x0 > x1 {
        return (0.0, 1.0, 0.0, 1.0);
    }
    let pad = ((y1 - y0) * 0.08).max(1e-6);
    (x0, x1.max(x0 + 1e-6), y0 - pad, y1 + pad)
}

/// Draws one panel of time series with a legend.
fn panel(
    area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    title: &str,
    y_label: &str,
    lines: &[(&str, &Series, RGBColor)],
) -> anyhow::Result<()> {
    let all: Vec<&Series> = lines.iter().map(|l| l.1).collect();
    let (x0, x1, y0, y1) = bounds(&all);
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc(y_label)
        .draw()?;
    for (name, series, color) in lines {
        let color = *color;
        // At most about 4000 points a line: enough for the eye, small enough for a browser.
        let stride = (series.len() / 4000).max(1);
        chart
            .draw_series(LineSeries::new(
                series.iter().step_by(stride).copied(),
                color.stroke_width(2),
            ))?
            .label(*name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

/// Writes `tracking.svg`, `forces.svg` and, for real-time runs, `timing.svg`.
pub fn write_all(dir: &Path, out: &RunOutput) -> anyhow::Result<Vec<PathBuf>> {
    let mut written = vec![write_tracking(dir, out)?, write_forces(dir, out)?];
    // Timing: wake-up latency per tick of the control threads (real-time runs only).
    if out.info.clock == ClockMode::RealTime {
        written.push(write_timing(dir, out)?);
    }
    Ok(written)
}

/// `tracking.svg`: the slave's reference and tool position along each axis, and the error.
fn write_tracking(dir: &Path, out: &RunOutput) -> anyhow::Result<PathBuf> {
    // Tracking: the slave's reference and tool position along each axis, and the error, from the
    // first reference on.
    let tracked = || {
        out.slave
            .iter()
            .filter(|s| s.sample.reference_kind != ReferenceKind::None)
    };
    let axis = |i: usize, reference: bool| -> Series {
        tracked()
            .map(|s| {
                let v = if reference {
                    s.sample.reference_position
                } else {
                    s.sample.tool_position
                };
                (time_of(out, s), v[i] * 1e3)
            })
            .collect()
    };
    let error: Series = tracked()
        .map(|s| {
            (
                time_of(out, s),
                (s.sample.reference_position - s.sample.tool_position).norm() * 1e3,
            )
        })
        .collect();
    let path = dir.join("tracking.svg");
    {
        let root = SVGBackend::new(&path, SIZE).into_drawing_area();
        root.fill(&WHITE)?;
        let (top, bottom) = root.split_vertically(SIZE.1 * 3 / 5);
        let (rx, tx, ry, ty, rz, tz) = (
            axis(0, true),
            axis(0, false),
            axis(1, true),
            axis(1, false),
            axis(2, true),
            axis(2, false),
        );
        panel(
            &top,
            "Slave tool position against its reference (the mapped master pose)",
            "position (mm)",
            &[
                ("x reference", &rx, BLUE),
                ("x slave", &tx, CYAN),
                ("y reference", &ry, GREEN),
                ("y slave", &ty, BLACK),
                ("z reference", &rz, RED),
                ("z slave", &tz, MAGENTA),
            ],
        )?;
        panel(
            &bottom,
            "Tracking error",
            "error (mm)",
            &[("|reference - slave|", &error, BLACK)],
        )?;
        root.present()?;
    }
    Ok(path)
}

/// `forces.svg`: what the slave senses, what the master displays, what the hand feels.
fn write_forces(dir: &Path, out: &RunOutput) -> anyhow::Result<PathBuf> {
    // Forces: what the slave senses (base frame), what the master displays, what the hand feels.
    let slave_model = &out.info.slave_model;
    let sensed: Series = out
        .slave
        .iter()
        .map(|s| {
            let pose = slave_model.forward(&s.sample.q);
            (
                time_of(out, s),
                sensor_to_base(&s.sample.wrench, &out.info.sensor_mount, &pose)
                    .force
                    .norm(),
            )
        })
        .collect();
    let scaled: Series = sensed
        .iter()
        .map(|&(t, f)| (t, f * out.info.mapping.force_gain))
        .collect();
    let displayed: Series = out
        .master
        .iter()
        .filter_map(|s| Some((time_of(out, s), motor_force(&out.info, s)?.norm())))
        .collect();
    let hand: Series = out
        .master
        .iter()
        .filter_map(|s| {
            s.truth
                .map(|t| (time_of(out, s), t.base_wrench.force.norm()))
        })
        .collect();
    let path = dir.join("forces.svg");
    {
        let root = SVGBackend::new(&path, SIZE).into_drawing_area();
        root.fill(&WHITE)?;
        panel(
            &root,
            "Contact force at the slave and force reflected to the operator",
            "force magnitude (N)",
            &[
                ("slave wrist sensor", &sensed, RED),
                ("force gain x sensor", &scaled, MAGENTA),
                ("master motors display", &displayed, BLUE),
                ("operator's hand", &hand, GREEN),
            ],
        )?;
        root.present()?;
    }
    Ok(path)
}

/// `timing.svg`: the control threads' wake-up latency per tick.
fn write_timing(dir: &Path, out: &RunOutput) -> anyhow::Result<PathBuf> {
    let latency = |rows: &[TickRecord]| -> Series {
        rows.iter()
            .map(|s| (time_of(out, s), s.sample.wake_latency.as_secs_f64() * 1e6))
            .collect()
    };
    let (m, s) = (latency(&out.master), latency(&out.slave));
    let path = dir.join("timing.svg");
    {
        let root = SVGBackend::new(&path, SIZE).into_drawing_area();
        root.fill(&WHITE)?;
        panel(
            &root,
            "Control threads: wake-up latency per tick",
            "latency (µs)",
            &[("master control", &m, BLUE), ("slave control", &s, RED)],
        )?;
        root.present()?;
    }
    Ok(path)
}
