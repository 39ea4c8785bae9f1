//! The distributions of the probes, one chart per load (after the paper's figure 10): the share
//! of round trips per logarithmic bin, log-x, so that a 5 µs ICMP echo and a 50 µs remote call
//! are both readable.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::probes::ProbeKind;
use super::stats::Summary;

/// Bins per decade of round-trip time.
const BINS_PER_DECADE: f64 = 40.0;

/// One probe's samples under one load.
pub struct Curve<'a> {
    /// Which probe.
    pub kind: ProbeKind,
    /// Round trips, ns.
    pub samples: &'a [u64],
    /// Their summary.
    pub summary: Summary,
}

fn color(kind: ProbeKind) -> RGBColor {
    match kind {
        // The paper drew CORBA red and ICMP black.
        ProbeKind::Rpc => RGBColor(220, 30, 30),
        ProbeKind::SealedRpc => RGBColor(150, 60, 200),
        ProbeKind::Tcp => RGBColor(30, 90, 220),
        ProbeKind::TcpHandoff => RGBColor(40, 160, 60),
        ProbeKind::Icmp => RGBColor(0, 0, 0),
    }
}

fn plot_err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow::anyhow!("plot: {e}")
}

/// The share (percent) of `samples` in each log bin of `[lo_us, hi_us)`, as a step line.
fn density(samples: &[u64], lo_us: f64, hi_us: f64) -> Vec<(f64, f64)> {
    let bins = ((hi_us / lo_us).log10() * BINS_PER_DECADE).ceil().max(1.0) as usize;
    let mut counts = vec![0u64; bins];
    for &s in samples {
        let us = s as f64 / 1e3;
        if us >= lo_us && us < hi_us {
            let i = ((us / lo_us).log10() * BINS_PER_DECADE) as usize;
            counts[i.min(bins - 1)] += 1;
        }
    }
    let total = samples.len().max(1) as f64;
    let edge = |i: usize| lo_us * 10f64.powf(i as f64 / BINS_PER_DECADE);
    let mut line = Vec::with_capacity(2 * bins + 2);
    line.push((lo_us, 0.0));
    for (i, &c) in counts.iter().enumerate() {
        let y = 100.0 * c as f64 / total;
        line.push((edge(i), y));
        line.push((edge(i + 1).min(hi_us), y));
    }
    line.push((hi_us, 0.0));
    line
}

/// Draws one load's chart into `area`.
pub fn panel(
    area: &DrawingArea<SVGBackend<'_>, Shift>,
    title: &str,
    curves: &[Curve<'_>],
) -> anyhow::Result<()> {
    let lo = curves
        .iter()
        .map(|c| c.summary.min / 1e3)
        .fold(f64::MAX, f64::min)
        .max(0.1)
        * 0.8;
    let hi = curves
        .iter()
        .map(|c| c.summary.p999 / 1e3)
        .fold(0.0, f64::max)
        .max(lo * 10.0)
        * 1.5;
    let lines: Vec<Vec<(f64, f64)>> = curves.iter().map(|c| density(c.samples, lo, hi)).collect();
    let peak = lines
        .iter()
        .flatten()
        .map(|p| p.1)
        .fold(0.0, f64::max)
        .max(1.0);
    // Log y so that the tail (a few round trips in a thousand) shows beside the peak; a bin's
    // smallest non-zero share is one round trip.
    let n_max = curves
        .iter()
        .map(|c| c.samples.len())
        .max()
        .unwrap_or(1)
        .max(1);
    let floor = 50.0 / n_max as f64;
    let lines: Vec<Vec<(f64, f64)>> = lines
        .into_iter()
        .map(|l| l.into_iter().map(|(x, y)| (x, y.max(floor))).collect())
        .collect();
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d((lo..hi).log_scale(), (floor..peak * 2.0).log_scale())
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("round trip (µs, log scale; axis ends at 1.5 × the largest p99.9)")
        .y_desc("% of round trips per bin (40 bins/decade, log)")
        .draw()
        .map_err(plot_err)?;
    for (curve, line) in curves.iter().zip(lines) {
        let c = color(curve.kind);
        let s = &curve.summary;
        chart
            .draw_series(LineSeries::new(line, c.stroke_width(2)))
            .map_err(plot_err)?
            .label(format!(
                "{}: mean {:.1}, σ {:.1}, p50 {:.1}, p99 {:.1} µs",
                curve.kind.name(),
                s.mean / 1e3,
                s.std() / 1e3,
                s.p50 / 1e3,
                s.p99 / 1e3
            ))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(plot_err)?;
    Ok(())
}

/// Writes one chart per load to `path`, side by side in a grid when there are several.
pub fn write(path: &Path, charts: &[(String, Vec<Curve<'_>>)]) -> anyhow::Result<()> {
    let n = charts.len().max(1);
    let cols = if n == 1 { 1 } else { 2 };
    let rows = n.div_ceil(cols);
    let size = (1000 * cols as u32, 560 * rows as u32);
    let root = SVGBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let areas = root.split_evenly((rows, cols));
    for ((title, curves), area) in charts.iter().zip(areas.iter()) {
        panel(area, title, curves)?;
    }
    root.present().map_err(plot_err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn densities_sum_to_the_share_in_range() {
        let samples: Vec<u64> = (0..1000).map(|i| 10_000 + i * 10).collect(); // 10 to 20 µs
        let line = density(&samples, 5.0, 50.0);
        // Each bin appears as two points of the same height.
        let total: f64 = line[1..line.len() - 1].chunks(2).map(|p| p[0].1).sum();
        assert!((total - 100.0).abs() < 1e-9, "{total}");
        let out_of_range = density(&samples, 1.0, 2.0);
        assert!(out_of_range.iter().all(|p| p.1 == 0.0));
    }
}
