//! SVG line and point plots with labelled axes, through plotters.
//!
//! SVG because its text is drawn by the viewer: plotters needs no font files or rasterizer for
//! it. Logarithmic axes are drawn as linear axes over the logarithms with tick labels mapped
//! back, which keeps one code path for every combination of axis scales.

use std::ops::Range;
use std::path::{Path, PathBuf};

use anyhow::anyhow;
use plotters::prelude::*;

/// Pixels of every plot.
const SIZE: (u32, u32) = (820, 520);
/// Fraction of the data range left free on each side.
const MARGIN_FRACTION: f64 = 0.06;
/// Fraction of the y range left free above the data, where the legend goes.
const LEGEND_ROOM_FRACTION: f64 = 0.3;
/// Where a point's label starts relative to the point, in pixels (right and up).
const POINT_LABEL_OFFSET: (i32, i32) = (7, -16);
/// Series colours: saturated and distinct on white.
const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];
/// Fewest and most tick labels on a logarithmic axis (one per power when there are fewer powers).
const LOG_TICKS: std::ops::RangeInclusive<usize> = 5..=12;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AxisScale {
    Linear,
    Log2,
    Log10,
}

impl AxisScale {
    fn forward(self, v: f64) -> f64 {
        match self {
            AxisScale::Linear => v,
            AxisScale::Log2 => v.log2(),
            AxisScale::Log10 => v.log10(),
        }
    }

    fn inverse(self, v: f64) -> f64 {
        match self {
            AxisScale::Linear => v,
            AxisScale::Log2 => v.exp2(),
            AxisScale::Log10 => 10f64.powf(v),
        }
    }
}

/// An axis: its label (with the unit) and scale.
#[derive(Clone, Debug, PartialEq)]
pub struct Axis {
    pub label: String,
    pub scale: AxisScale,
}

impl Axis {
    pub fn linear(label: &str) -> Axis {
        Axis {
            label: label.into(),
            scale: AxisScale::Linear,
        }
    }
    pub fn log2(label: &str) -> Axis {
        Axis {
            label: label.into(),
            scale: AxisScale::Log2,
        }
    }
    pub fn log10(label: &str) -> Axis {
        Axis {
            label: label.into(),
            scale: AxisScale::Log10,
        }
    }
}

/// One named set of points; joined by a line when `joined`; each point annotated with its
/// entry of `point_labels` when given (for parameters that are not on an axis).
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub joined: bool,
    pub point_labels: Vec<String>,
}

impl Series {
    pub fn line(label: &str, points: Vec<(f64, f64)>) -> Series {
        Series {
            label: label.into(),
            points,
            joined: true,
            point_labels: Vec::new(),
        }
    }
    pub fn points(label: &str, points: Vec<(f64, f64)>) -> Series {
        Series {
            label: label.into(),
            points,
            joined: false,
            point_labels: Vec::new(),
        }
    }

    pub fn with_point_labels(mut self, labels: Vec<String>) -> Series {
        self.point_labels = labels;
        self
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Plot {
    /// The file is `<file_stem>.svg` in the plots directory.
    pub file_stem: &'static str,
    pub title: String,
    pub x: Axis,
    pub y: Axis,
    pub series: Vec<Series>,
}

/// Draws `plot` into `dir`; returns the file written.
pub fn draw(plot: &Plot, dir: &Path) -> anyhow::Result<PathBuf> {
    let path = dir.join(format!("{}.svg", plot.file_stem));
    render(plot, &path).map_err(|e| anyhow!("drawing {}: {e}", path.display()))?;
    Ok(path)
}

fn render(plot: &Plot, path: &Path) -> Result<(), Box<dyn std::error::Error>> {
    let series: Vec<Vec<(f64, f64)>> = plot
        .series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .map(|&(x, y)| (plot.x.scale.forward(x), plot.y.scale.forward(y)))
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .collect()
        })
        .collect();
    let x_range = padded_range(series.iter().flatten().map(|p| p.0), MARGIN_FRACTION);
    let y_range = padded_range(series.iter().flatten().map(|p| p.1), LEGEND_ROOM_FRACTION);
    let root = SVGBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(&plot.title, ("sans-serif", 20))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d(x_range.clone(), y_range.clone())?;
    let (x_scale, y_scale) = (plot.x.scale, plot.y.scale);
    chart
        .configure_mesh()
        .x_labels(tick_count(&plot.x, &x_range))
        .y_labels(tick_count(&plot.y, &y_range))
        .x_desc(plot.x.label.as_str())
        .y_desc(plot.y.label.as_str())
        .x_label_formatter(&|v| tick_label(x_scale.inverse(*v)))
        .y_label_formatter(&|v| tick_label(y_scale.inverse(*v)))
        .draw()?;
    for (index, (meta, points)) in plot.series.iter().zip(&series).enumerate() {
        let color = PALETTE[index % PALETTE.len()];
        if meta.joined {
            chart.draw_series(LineSeries::new(
                points.iter().copied(),
                color.stroke_width(2),
            ))?;
        }
        chart
            .draw_series(points.iter().map(|&p| Circle::new(p, 4, color.filled())))?
            .label(meta.label.as_str())
            .legend(move |(x, y)| Circle::new((x + 8, y), 4, color.filled()));
        chart.draw_series(points.iter().zip(&meta.point_labels).map(|(&p, text)| {
            EmptyElement::at(p) + Text::new(text.clone(), POINT_LABEL_OFFSET, ("sans-serif", 13))
        }))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    root.present()?;
    Ok(())
}

/// Tick labels for an axis: on a logarithmic one, one per power (round labels) unless the
/// range spans too few powers to read values off.
fn tick_count(axis: &Axis, range: &Range<f64>) -> usize {
    match axis.scale {
        AxisScale::Linear => 10,
        AxisScale::Log2 | AxisScale::Log10 => {
            let powers = (range.end.floor() - range.start.ceil()).max(0.0) as usize + 1;
            powers.clamp(*LOG_TICKS.start(), *LOG_TICKS.end())
        }
    }
}

/// The range of `values` with a margin below and `top_fraction` of room above; a unit range
/// around a single value.
fn padded_range(values: impl Iterator<Item = f64>, top_fraction: f64) -> Range<f64> {
    let (low, high) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if !low.is_finite() {
        return 0.0..1.0;
    }
    let span = if high > low { high - low } else { 1.0 };
    (low - span * MARGIN_FRACTION)..(high + span * top_fraction)
}

/// Three significant digits without trailing zeros.
fn tick_label(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let magnitude = v.abs().log10().floor() as i32;
    let decimals = (2 - magnitude).max(0) as usize;
    let text = format!("{v:.decimals$}");
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_have_three_significant_digits() {
        // Not 1234.5: formatting rounds a tie to even, so it would print 1234.
        assert_eq!(tick_label(1234.6), "1235");
        assert_eq!(tick_label(2.0), "2");
        assert_eq!(tick_label(0.012345), "0.0123");
    }

    #[test]
    fn log_axes_invert() {
        for scale in [AxisScale::Log2, AxisScale::Log10, AxisScale::Linear] {
            assert!((scale.inverse(scale.forward(37.0)) - 37.0).abs() < 1e-9);
        }
    }
}
