//! What every study sweep shares (`vademecum study` and its per-effect sweeps): relative
//! errors, measurements kept as NaN in resumable JSON records, the Pareto front of error
//! against cost, and the scatter plot that shows it.

use std::path::Path;

use plotters::prelude::*;
use serde::Deserialize;

/// JSON has no NaN: serde writes it as `null`, read back here as NaN (a measurement that
/// could not be made, kept in a resumable record).
pub(super) fn nan_if_null<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// `|a − b| / |b|` (a vanishing `b` divides by the least positive number, not by zero).
pub(super) fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}

/// Marks the points no other point beats in both `cost` and error (ties kept).
pub(super) fn pareto(points: &[(f64, f64)]) -> Vec<bool> {
    points
        .iter()
        .map(|&(c, e)| !points.iter().any(|&(c2, e2)| c2 <= c && e2 <= e && (c2 < c || e2 < e)))
        .collect()
}

/// One group of points of a study's scatter plot ([`scatter`]).
pub(super) struct Group {
    pub(super) label: String,
    /// Triangles (their tags below them) instead of circles.
    pub(super) triangles: bool,
    /// `(cost, error, the tag written beside the point; none when empty)`.
    pub(super) points: Vec<(f64, f64, String)>,
}

/// A sweep's error against its cost, log–log: each group in its colour with its legend, each
/// point's tag beside it, the Pareto front `front` as a line. Points without a positive
/// finite cost and error are left out (a log scale has no place for them); nothing is
/// written when none is left.
pub(super) fn scatter(
    file: &Path,
    title: &str,
    (x_desc, y_desc): (&str, &str),
    groups: &[Group],
    front: Vec<(f64, f64)>,
) -> anyhow::Result<()> {
    let drawable = |p: &&(f64, f64, String)| p.0.is_finite() && p.0 > 0.0 && p.1.is_finite() && p.1 > 0.0;
    let all: Vec<&(f64, f64, String)> = groups.iter().flat_map(|g| &g.points).filter(drawable).collect();
    if all.is_empty() {
        return Ok(());
    }
    let range = |f: fn(&(f64, f64, String)) -> f64| all.iter().fold((f64::INFINITY, 0.0f64), |(a, b), p| (a.min(f(p)), b.max(f(p))));
    let ((x0, x1), (e0, e1)) = (range(|p| p.0), range(|p| p.1));
    let root = crate::plot::canvas(file, (900, 600))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(14)
        .x_label_area_size(44)
        .y_label_area_size(70)
        .build_cartesian_2d((x0 * 0.7..x1 * 1.4).log_scale(), (e0 * 0.3..e1 * 3.0).log_scale())?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()?;
    for (c, g) in groups.iter().enumerate() {
        let points: Vec<&(f64, f64, String)> = g.points.iter().filter(drawable).collect();
        if points.is_empty() {
            continue;
        }
        let color = super::bench_anm::PALETTE[c % super::bench_anm::PALETTE.len()];
        if g.triangles {
            chart
                .draw_series(points.iter().map(|p| TriangleMarker::new((p.0, p.1), 6, color.filled())))?
                .label(&g.label)
                .legend(move |(x, y)| TriangleMarker::new((x + 10, y), 6, color.filled()));
        } else {
            chart
                .draw_series(points.iter().map(|p| Circle::new((p.0, p.1), 5, color.filled())))?
                .label(&g.label)
                .legend(move |(x, y)| Circle::new((x + 10, y), 5, color.filled()));
        }
        let dy = if g.triangles { 0.8 } else { 1.3 };
        chart.draw_series(
            points
                .iter()
                .filter(|p| !p.2.is_empty())
                .map(|p| Text::new(p.2.clone(), (p.0 * 1.05, p.1 * dy), ("sans-serif", 12).into_font())),
        )?;
    }
    draw_front(&mut chart, front)?;
    root.present()?;
    Ok(())
}

/// Draws the Pareto front `front` (its points, in any order) as a line, and the legend.
pub(super) fn draw_front<'a>(
    chart: &mut ChartContext<'a, SVGBackend<'a>, Cartesian2d<LogCoord<f64>, LogCoord<f64>>>,
    mut front: Vec<(f64, f64)>,
) -> anyhow::Result<()> {
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    chart
        .draw_series(LineSeries::new(front, BLACK.stroke_width(2)))?
        .label("Pareto front")
        .legend(crate::plot::line_key(BLACK.stroke_width(2)));
    crate::plot::legend(chart, SeriesLabelPosition::UpperRight)?;
    Ok(())
}
