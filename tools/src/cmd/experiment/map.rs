//! The stability map: one row per law, one column per round-trip delay, each cell green
//! (stable) or red (not), with its energy growth and free-motion tracking written in it.

use std::path::Path;

use penelope_supervisor::runs::delay::{
    DelayPlan, DelayRun, MAX_CONTACT_RIPPLE, MAX_GROWTH_RATIO, MAX_REST_MOTION_MM, MAX_TRACKING_MM,
};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

const CELL: (i32, i32) = (150, 80);
const LEFT: i32 = 170;
const TOP: i32 = 70;

/// Writes the map of `runs` (in `plan` order) as SVG to `path`.
///
/// # Errors
/// Drawing or writing the file failed.
pub fn write(path: &Path, plan: &DelayPlan, runs: &[DelayRun]) -> anyhow::Result<()> {
    let columns = plan.round_trip_ms.len().max(1) as i32;
    let rows = plan.laws.len().max(1) as i32;
    let size = (
        (LEFT + columns * CELL.0 + 20) as u32,
        (TOP + rows * CELL.1 + 60) as u32,
    );
    let root = SVGBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE)?;
    let centred = Pos::new(HPos::Center, VPos::Center);
    let text = |size: i32| ("sans-serif", size).into_font().color(&BLACK);
    root.draw(&Text::new(
        format!(
            "Stability map: tapping on the wall{}, jitter {} ms each way, seed {}",
            plan.wall_stiffness
                .map_or(String::new(), |k| format!(" ({k} N/m)")),
            plan.jitter_ms,
            plan.seed
        ),
        (10, 10),
        text(18),
    ))?;
    root.draw(&Text::new(
        "round-trip delay (ms), half each way",
        (LEFT, TOP - 40),
        text(14),
    ))?;
    for (c, d) in plan.round_trip_ms.iter().enumerate() {
        let x = LEFT + c as i32 * CELL.0 + CELL.0 / 2;
        root.draw(&Text::new(
            format!("{d}"),
            (x, TOP - 12),
            text(15).pos(centred),
        ))?;
    }
    for (row, law) in plan.laws.iter().enumerate() {
        let y = TOP + row as i32 * CELL.1;
        root.draw(&Text::new(
            law.as_str(),
            (10, y + CELL.1 / 2),
            text(15).pos(Pos::new(HPos::Left, VPos::Center)),
        ))?;
        for (c, d) in plan.round_trip_ms.iter().enumerate() {
            let x = LEFT + c as i32 * CELL.0;
            let run = runs
                .iter()
                .find(|r| r.law == law.as_str() && r.delay_ms == *d);
            let (fill, lines) = match run {
                Some(r) if r.stable => (
                    RGBColor(150, 215, 150),
                    [
                        "stable".to_string(),
                        format!("growth {:.2}", r.energy_growth),
                        format!("track {:.2} mm", r.tracking_rms_mm),
                    ],
                ),
                Some(r) => (
                    RGBColor(235, 130, 120),
                    [
                        "UNSTABLE".to_string(),
                        format!("growth {:.2}", r.energy_growth),
                        format!("ripple {:.2}", r.contact_ripple),
                    ],
                ),
                None => (
                    RGBColor(220, 220, 220),
                    ["not run".to_string(), String::new(), String::new()],
                ),
            };
            root.draw(&Rectangle::new(
                [(x + 2, y + 2), (x + CELL.0 - 2, y + CELL.1 - 2)],
                fill.filled(),
            ))?;
            for (k, line) in lines.iter().enumerate() {
                root.draw(&Text::new(
                    line.clone(),
                    (x + CELL.0 / 2, y + 18 + k as i32 * 22),
                    text(13).pos(centred),
                ))?;
            }
        }
    }
    root.draw(&Text::new(
        format!(
            "stable: no fault, tap energy growth <= {MAX_GROWTH_RATIO}, contact-force ripple <= \
             {MAX_CONTACT_RIPPLE}, rest motion <= {MAX_REST_MOTION_MM} mm, tracking within \
             {MAX_TRACKING_MM} mm (penelope_supervisor::runs::delay)"
        ),
        (10, TOP + rows * CELL.1 + 20),
        text(12),
    ))?;
    root.present()?;
    Ok(())
}
