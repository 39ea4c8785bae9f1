//! The plot of one `experiment sync` run: per frame, against the frame's capture time, the
//! video's capture-to-display latency, the skew the operator lives with unaligned, and what is
//! left after alignment, with the force's measurement-to-display latency (its median) as a line;
//! points beyond 1.3 times the video latency's p99 are off the chart (the table has the max).

use std::path::Path;

use plotters::prelude::*;

use super::SyncRecord;

/// One series: its legend, its points (s, ms), its colour.
type Series<'a> = (&'a str, &'a [(f64, f64)], RGBColor);

/// Writes the plot of `record` as SVG to `path`.
///
/// # Errors
/// Drawing or writing the file failed.
pub fn write(path: &Path, record: &SyncRecord) -> anyhow::Result<()> {
    let frames = &record.seen;
    let Some(first) = frames.iter().map(|f| f.capture_ns).min() else {
        anyhow::bail!("no frame to plot");
    };
    let t = |ns: u64| (ns.saturating_sub(first)) as f64 / 1e9;
    let ms = |ns: i128| ns as f64 / 1e6;
    let video: Vec<(f64, f64)> = frames
        .iter()
        .map(|f| {
            (
                t(f.capture_ns),
                ms(i128::from(f.display_ns) - i128::from(f.capture_ns)),
            )
        })
        .collect();
    let force_ms = record.force_latency.p50_us / 1e3;
    let unaligned: Vec<(f64, f64)> = video.iter().map(|&(x, v)| (x, v - force_ms)).collect();
    let aligned: Vec<(f64, f64)> = frames
        .iter()
        .filter_map(|f| {
            f.aligned_skew_ns
                .map(|s| (t(f.capture_ns), ms(i128::from(s)).abs()))
        })
        .collect();
    let x_max = video.iter().map(|p| p.0).fold(1.0, f64::max);
    // The scale of the bulk: a busy host's rare stalls (beyond 1.3 times the video's p99) are
    // left off the chart rather than flattening everything else.
    let y_max = (record.video_latency.p99_us / 1e3 * 1.3).max(10.0);

    let root = SVGBackend::new(path, (1000, 520)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "video and force at the operator: {} layout, camera link +{} ms, {} fps",
                record.layout, record.camera_delay_ms, record.fps
            ),
            ("sans-serif", 20),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(56)
        .build_cartesian_2d(0.0..x_max, 0.0..y_max)?;
    chart
        .configure_mesh()
        .x_desc("capture time, s")
        .y_desc("ms")
        .draw()?;
    let series: [Series<'_>; 3] = [
        ("video: capture to display", &video, RGBColor(31, 119, 180)),
        (
            "unaligned skew: video latency less force latency",
            &unaligned,
            RGBColor(214, 39, 40),
        ),
        (
            "aligned residual: |force sample - capture|",
            &aligned,
            RGBColor(44, 160, 44),
        ),
    ];
    for (label, points, colour) in series {
        chart
            .draw_series(points.iter().map(|&p| Circle::new(p, 2, colour.filled())))?
            .label(label)
            .legend(move |(x, y)| Circle::new((x + 10, y), 4, colour.filled()));
    }
    chart
        .draw_series(LineSeries::new(
            [(0.0, force_ms), (x_max, force_ms)],
            BLACK.stroke_width(2),
        ))?
        .label(format!(
            "force: measured to displayed, median {force_ms:.2} ms"
        ))
        .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    root.present()?;
    Ok(())
}
