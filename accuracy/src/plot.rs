//! A sweep's plot: error against time for every setting, the Pareto front
//! drawn through the settings nothing beats on both counts, the default
//! ringed. SVG, so it diffs and reads in a browser or on GitHub.

use std::path::Path;

use plotters::coord::ranged1d::ValueFormatter;
use plotters::prelude::*;

use crate::sweep::Sweep;

/// An axis's range and whether it is logarithmic: log when every value is
/// positive and they span more than a factor of 20.
fn axis(values: impl Iterator<Item = f64>) -> (f64, f64, bool) {
    let values: Vec<f64> = values.filter(|v| v.is_finite()).collect();
    let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !lo.is_finite() || !hi.is_finite() {
        return (0.0, 1.0, false);
    }
    if lo > 0.0 && hi / lo > 20.0 {
        return (lo / 1.5, hi * 1.5, true);
    }
    let pad = ((hi - lo) * 0.1).max(hi.abs() * 0.05).max(1e-9);
    ((lo - pad).min(0.0).max(if lo >= 0.0 { 0.0 } else { f64::NEG_INFINITY }), hi + pad, false)
}

/// Writes `sweep`'s plot to `path` (SVG).
pub fn write(sweep: &Sweep, path: &Path) -> anyhow::Result<()> {
    let (x0, x1, x_log) = axis(sweep.rows.iter().map(|r| r.time));
    let (y0, y1, y_log) = axis(sweep.rows.iter().map(|r| r.error));
    let root = SVGBackend::new(path, (760, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let caption = format!("{}: error against time", sweep.knob);
    let mut builder = ChartBuilder::on(&root);
    builder.caption(caption, ("sans-serif", 20)).margin(16).x_label_area_size(44).y_label_area_size(72);
    // Four coordinate kinds, one drawing: a macro would hide less than this match.
    match (x_log, y_log) {
        (false, false) => draw(builder.build_cartesian_2d(x0..x1, y0..y1)?, sweep),
        (true, false) => draw(builder.build_cartesian_2d((x0..x1).log_scale(), y0..y1)?, sweep),
        (false, true) => draw(builder.build_cartesian_2d(x0..x1, (y0..y1).log_scale())?, sweep),
        (true, true) => draw(builder.build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?, sweep),
    }?;
    root.present()?;
    Ok(())
}

fn draw<'a, X, Y>(mut chart: ChartContext<'a, SVGBackend<'a>, Cartesian2d<X, Y>>, sweep: &Sweep) -> anyhow::Result<()>
where
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    chart.configure_mesh().x_desc(sweep.time.as_str()).y_desc(sweep.error.as_str()).draw()?;
    let front = sweep.pareto();
    let blue = RGBColor(40, 90, 170);
    let red = RGBColor(200, 50, 40);
    chart
        .draw_series(LineSeries::new(
            front.iter().map(|&i| (sweep.rows[i].time, sweep.rows[i].error)),
            red.stroke_width(2),
        ))?
        .label("Pareto front")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], red.stroke_width(2)));
    chart
        .draw_series(sweep.rows.iter().enumerate().map(|(i, r)| {
            let on_front = front.contains(&i);
            Circle::new(
                (r.time, r.error),
                if on_front { 5 } else { 4 },
                if on_front { red.filled() } else { blue.filled() },
            )
        }))?
        .label("setting")
        .legend(move |(x, y)| Circle::new((x + 9, y), 4, blue.filled()));
    chart
        .draw_series(
            sweep.rows.iter().filter(|r| r.default).map(|r| Circle::new((r.time, r.error), 10, BLACK.stroke_width(2))),
        )?
        .label("default")
        .legend(|(x, y)| Circle::new((x + 9, y), 6, BLACK.stroke_width(2)));
    chart.draw_series(
        sweep
            .rows
            .iter()
            .map(|r| Text::new(format!(" {}", r.setting), (r.time, r.error), ("sans-serif", 12).into_font())),
    )?;
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}
