//! Figures as PNG: stacked panels of time series over one shared x axis.
//!
//! [`plot_series`] draws any number of panels, each with one or more curves (solid or dashed,
//! with a legend), over a shared x axis, and can shade the samples where a mask is true (a
//! contact period). Quantities are given in SI units; each axis picks the SI prefix that keeps
//! its tick labels short (`0.15 s` is drawn as `150 ms`, `2e-6 N·m` as `2 µN·m`).
//!
//! Text is set in DejaVu Sans, embedded in the binary, so figures look the same on every machine
//! and need no system fonts. The file appears only when complete: it is drawn into a temporary
//! file beside the target and renamed into place ([`Pending`]).

use crate::files::{self, Pending};
use anyhow::{anyhow, bail, Context, Result};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::ops::Range;
use std::path::Path;
use std::sync::OnceLock;

/// DejaVu Sans (licence: assets/DejaVuSans-LICENSE.txt).
const FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
/// The family name under which [`FONT`] is registered.
const FAMILY: &str = "sans-serif";

/// Figure width, px.
const WIDTH: u32 = 1000;
/// Height of one panel, px.
const PANEL_HEIGHT: u32 = 250;
/// Height of the title, px.
const TITLE_HEIGHT: u32 = 50;

/// Most labelled ticks on the x axis.
const X_TICKS: usize = 10;
/// Most labelled ticks on a y axis.
const Y_TICKS: usize = 6;

/// Curve colours, in order within a panel.
const PALETTE: [RGBColor; 4] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
];
/// Colour of the shaded samples.
const SHADE: RGBColor = RGBColor(255, 190, 90);

/// The shared x axis: a quantity, its SI unit and its values.
#[derive(Debug, Clone, Copy)]
pub struct Axis<'a> {
    /// Name on the axis (`t`).
    pub quantity: &'a str,
    /// SI unit without prefix (`s`); the axis adds a prefix that suits the values.
    pub unit: &'a str,
    /// Values, one per sample: `[samples]`.
    pub values: &'a [f64],
}

/// One curve of a panel.
#[derive(Debug, Clone, Copy)]
pub struct Curve<'a> {
    /// Legend text (empty: no legend entry).
    pub name: &'a str,
    /// Values at the x axis' samples: `[samples]`, in the panel's unit; `NaN` leaves a gap.
    pub values: &'a [f64],
    /// Dashed instead of solid.
    pub dashed: bool,
}

/// One panel: curves sharing a y axis.
#[derive(Debug, Clone)]
pub struct Panel<'a> {
    /// Name on the y axis (`θ`, `m0`).
    pub quantity: &'a str,
    /// SI unit without prefix (`rad`, `N·m`); the axis adds a prefix that suits the values.
    pub unit: &'a str,
    /// Curves, drawn in order with the colours of [`PALETTE`].
    pub curves: Vec<Curve<'a>>,
}

/// Draws `panels` stacked over the shared axis `x` into the PNG file `path`, under `title`,
/// shading the samples where `shade` is true (`[samples]`). The file appears only when complete.
#[allow(dead_code)] // The one-step form, for figures that go with no other file.
pub fn plot_series(
    path: &Path,
    title: &str,
    x: &Axis<'_>,
    panels: &[Panel<'_>],
    shade: Option<&[bool]>,
) -> Result<()> {
    render_series(path, title, x, panels, shade)?.commit()
}

/// As [`plot_series`], but leaves the finished figure in a temporary file beside `path`, to be
/// renamed into place by [`Pending::commit`] once everything else a command writes has
/// succeeded (dropped uncommitted, it is removed).
pub fn render_series(
    path: &Path,
    title: &str,
    x: &Axis<'_>,
    panels: &[Panel<'_>],
    shade: Option<&[bool]>,
) -> Result<Pending> {
    check_png(path)?;
    // Every series must match the x axis sample for sample.
    let n = x.values.len();
    if panels.is_empty() {
        bail!("a figure needs at least one panel");
    }
    for panel in panels {
        for curve in &panel.curves {
            if curve.values.len() != n {
                bail!(
                    "curve `{}` of panel `{}` has {} values for {n} samples",
                    curve.name,
                    panel.quantity,
                    curve.values.len()
                );
            }
        }
    }
    if let Some(mask) = shade {
        if mask.len() != n {
            bail!("the shading mask has {} values for {n} samples", mask.len());
        }
    }

    let pending = Pending::beside(path)?;
    draw(pending.temp(), title, x, panels, shade)
        .with_context(|| format!("cannot draw the figure `{}`", path.display()))?;
    Ok(pending)
}

/// Refuses a figure path that does not end in `.png`.
pub fn check_png(path: &Path) -> Result<()> {
    match files::extension(path).as_deref() {
        Some("png") => Ok(()),
        _ => bail!(
            "`{}`: unknown figure format; the extension must be .png",
            path.display()
        ),
    }
}

/// Registers the embedded font with plotters (once per process).
fn register_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED
        .get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok {
        Ok(())
    } else {
        bail!("the embedded font could not be read")
    }
}

/// Draws the figure into `file` (PNG).
fn draw(
    file: &Path,
    title: &str,
    x: &Axis<'_>,
    panels: &[Panel<'_>],
    shade: Option<&[bool]>,
) -> Result<()> {
    register_font()?;
    let height = TITLE_HEIGHT + PANEL_HEIGHT * panels.len() as u32;
    let root = BitMapBackend::new(file, (WIDTH, height)).into_drawing_area();
    root.fill(&WHITE).map_err(plotting)?;
    let body = root
        .titled(title, (FAMILY, 24).into_font().color(&BLACK))
        .map_err(plotting)?;

    // The x axis in its prefixed unit, shared by every panel.
    let (x_factor, x_prefix) = prefix(max_abs(x.values));
    let xs: Vec<f64> = x.values.iter().map(|v| v * x_factor).collect();
    let x_range = span(&xs, 0.0);
    let x_desc = format!("{} ({x_prefix}{})", x.quantity, x.unit);
    let spans = shade
        .map(|mask| shaded_spans(&xs, mask))
        .unwrap_or_default();

    // One panel per area, the x description under the last one.
    let areas = body.split_evenly((panels.len(), 1));
    for (k, (area, panel)) in areas.iter().zip(panels).enumerate() {
        let last = k + 1 == panels.len();
        draw_panel(
            area,
            panel,
            &xs,
            x_range.clone(),
            last.then_some(x_desc.as_str()),
            &spans,
        )?;
    }
    root.present().map_err(plotting)?;
    Ok(())
}

/// Draws one panel into `area`.
fn draw_panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    panel: &Panel<'_>,
    xs: &[f64],
    x_range: Range<f64>,
    x_desc: Option<&str>,
    spans: &[Range<f64>],
) -> Result<()> {
    // The y axis in its prefixed unit.
    let all = panel.curves.iter().flat_map(|c| c.values.iter().copied());
    let (factor, unit_prefix) = prefix(all.clone().fold(0.0, |m: f64, v| m.max(v.abs())));
    let ys: Vec<Vec<f64>> = panel
        .curves
        .iter()
        .map(|c| c.values.iter().map(|v| v * factor).collect())
        .collect();
    let y_range = span(&ys.concat(), 0.06);
    let y_desc = format!("{} ({unit_prefix}{})", panel.quantity, panel.unit);

    let mut chart = ChartBuilder::on(area)
        .margin_top(6)
        .margin_bottom(4)
        .margin_left(8)
        .margin_right(24)
        .x_label_area_size(40)
        .y_label_area_size(80)
        .build_cartesian_2d(x_range.clone(), y_range.clone())
        .map_err(plotting)?;

    // The shaded spans under everything else.
    let (y0, y1) = (y_range.start, y_range.end);
    chart
        .draw_series(
            spans
                .iter()
                .map(|s| Rectangle::new([(s.start, y0), (s.end, y1)], SHADE.mix(0.35).filled())),
        )
        .map_err(plotting)?;

    // Grid, ticks and axis descriptions.
    let x_fmt = tick_formatter(&x_range, X_TICKS);
    let y_fmt = tick_formatter(&y_range, Y_TICKS);
    let mut mesh = chart.configure_mesh();
    mesh.label_style((FAMILY, 14))
        .axis_desc_style((FAMILY, 16))
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(205, 205, 205))
        .max_light_lines(2)
        .x_labels(X_TICKS)
        .y_labels(Y_TICKS)
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .y_desc(y_desc);
    if let Some(desc) = x_desc {
        mesh.x_desc(desc);
    }
    mesh.draw().map_err(plotting)?;

    // The curves, split at NaN gaps; the first piece of each carries its legend entry.
    let mut legend = false;
    for (c, (curve, values)) in panel.curves.iter().zip(&ys).enumerate() {
        let style = PALETTE[c % PALETTE.len()].stroke_width(2);
        for (piece, points) in finite_runs(xs, values).into_iter().enumerate() {
            let labelled = piece == 0 && !curve.name.is_empty();
            if curve.dashed {
                let drawn = chart
                    .draw_series(DashedLineSeries::new(points, 7, 5, style))
                    .map_err(plotting)?;
                if labelled {
                    drawn.label(curve.name).legend(move |(lx, ly)| {
                        EmptyElement::at((lx, ly))
                            + PathElement::new(vec![(0, 0), (8, 0)], style)
                            + PathElement::new(vec![(13, 0), (21, 0)], style)
                    });
                }
            } else {
                let drawn = chart
                    .draw_series(LineSeries::new(points, style))
                    .map_err(plotting)?;
                if labelled {
                    drawn.label(curve.name).legend(move |(lx, ly)| {
                        PathElement::new(vec![(lx, ly), (lx + 21, ly)], style)
                    });
                }
            }
            legend |= labelled;
        }
    }
    if legend {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font((FAMILY, 14))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(180, 180, 180))
            .draw()
            .map_err(plotting)?;
    }
    Ok(())
}

/// A plotters error as an `anyhow` error.
fn plotting<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow!("{e}")
}

/// Largest magnitude among the finite values (0 if none).
fn max_abs(values: &[f64]) -> f64 {
    values
        .iter()
        .filter(|v| v.is_finite())
        .fold(0.0, |m, v| m.max(v.abs()))
}

/// The factor and SI prefix that bring `max` into [1, 1000): none, m, µ, n or p (never a
/// prefix above one; 1 and none for zero).
fn prefix(max: f64) -> (f64, &'static str) {
    const PREFIXES: [(i32, &str); 5] = [(0, ""), (-3, "m"), (-6, "µ"), (-9, "n"), (-12, "p")];
    if !(max.is_finite() && max > 0.0) {
        return (1.0, "");
    }
    let chosen = PREFIXES
        .iter()
        .find(|(e, _)| max >= 10f64.powi(*e) * (1.0 - 1e-12))
        .unwrap_or(&PREFIXES[PREFIXES.len() - 1]);
    (10f64.powi(-chosen.0), chosen.1)
}

/// The range of the finite `values`, widened by `margin` of its length on each side; a flat or
/// empty series gets a range around its value.
fn span(values: &[f64], margin: f64) -> Range<f64> {
    let (lo, hi) = values
        .iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    if lo > hi {
        return -1.0..1.0;
    }
    if hi - lo <= 1e-12 * hi.abs().max(lo.abs()).max(1e-300) {
        let half = if lo == 0.0 { 1.0 } else { 0.5 * lo.abs() };
        return lo - half..hi + half;
    }
    let pad = margin * (hi - lo);
    lo - pad..hi + pad
}

/// Tick labels for at most `ticks` ticks over `range`, placed where plotters places them, all
/// with the decimals that the spacing of those ticks needs (`0.5, 1.0, 1.5`; `20, 40, 60`).
fn tick_formatter(range: &Range<f64>, ticks: usize) -> impl Fn(&f64) -> String {
    let points = RangedCoordf64::from(range.clone()).key_points(ticks);
    let step = points
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f64::INFINITY, f64::min);
    let decimals = if step.is_finite() && step > 0.0 {
        (-(step.log10() + 1e-9).floor()).max(0.0) as usize
    } else {
        0
    };
    move |v: &f64| {
        // No `-0` label.
        let v = if v.abs() < 0.5 * 10f64.powi(-(decimals as i32)) {
            0.0
        } else {
            *v
        };
        format!("{v:.decimals$}")
    }
}

/// The x spans of the runs of true samples in `mask`, each reaching half a sample spacing past
/// its first and last sample (clipped to the axis).
fn shaded_spans(xs: &[f64], mask: &[bool]) -> Vec<Range<f64>> {
    let n = xs.len();
    // Edge of sample i on one side: halfway to its neighbour, or the sample itself at an end.
    let left = |i: usize| {
        if i == 0 {
            xs[0]
        } else {
            0.5 * (xs[i - 1] + xs[i])
        }
    };
    let right = |i: usize| {
        if i + 1 == n {
            xs[i]
        } else {
            0.5 * (xs[i] + xs[i + 1])
        }
    };
    let mut spans = Vec::new();
    let mut start = None;
    for (i, &on) in mask.iter().enumerate() {
        match (on, start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                spans.push(left(s)..right(i - 1));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        spans.push(left(s)..right(n - 1));
    }
    spans
}

/// The runs of consecutive samples where both coordinates are finite, as point lists.
fn finite_runs(xs: &[f64], ys: &[f64]) -> Vec<Vec<(f64, f64)>> {
    let mut runs = Vec::new();
    let mut run = Vec::new();
    for (&x, &y) in xs.iter().zip(ys) {
        if x.is_finite() && y.is_finite() {
            run.push((x, y));
        } else if !run.is_empty() {
            runs.push(std::mem::take(&mut run));
        }
    }
    if !run.is_empty() {
        runs.push(run);
    }
    runs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prefixes_bring_values_into_one_to_a_thousand() {
        assert_eq!(prefix(0.15), (1e3, "m"));
        assert_eq!(prefix(2.5), (1.0, ""));
        assert_eq!(prefix(4000.0), (1.0, ""));
        assert_eq!(prefix(3.2e-6).1, "µ");
        assert_eq!(prefix(1e-3).1, "m");
        assert_eq!(prefix(0.0), (1.0, ""));
        assert_eq!(prefix(1e-15).1, "p");
    }

    #[test]
    fn shading_covers_runs_of_true_samples() {
        let xs = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
        let mask = [false, true, true, false, false, true];
        assert_eq!(shaded_spans(&xs, &mask), vec![0.5..2.5, 4.5..5.0]);
        assert!(shaded_spans(&xs, &[false; 6]).is_empty());
    }

    #[test]
    fn curves_break_at_nan() {
        let xs = [0.0, 1.0, 2.0, 3.0];
        let ys = [1.0, f64::NAN, 2.0, 3.0];
        assert_eq!(
            finite_runs(&xs, &ys),
            vec![vec![(0.0, 1.0)], vec![(2.0, 2.0), (3.0, 3.0)]]
        );
    }

    #[test]
    fn ranges_are_padded_and_never_empty() {
        assert_eq!(span(&[0.0, 10.0], 0.1), -1.0..11.0);
        assert_eq!(span(&[0.0, 0.0], 0.1), -1.0..1.0);
        assert_eq!(span(&[2.0, 2.0], 0.1), 1.0..3.0);
        assert_eq!(span(&[f64::NAN], 0.1), -1.0..1.0);
    }

    #[test]
    fn tick_labels_have_the_decimals_the_step_needs() {
        assert_eq!(tick_formatter(&(0.0..150.0), 10)(&20.0), "20");
        assert_eq!(tick_formatter(&(-2.8..1.9), 6)(&-2.0), "-2");
        assert_eq!(tick_formatter(&(-1.1..1.3), 6)(&1.0), "1.0");
        assert_eq!(tick_formatter(&(-1.1..1.3), 6)(&-1e-17), "0.0");
        assert_eq!(tick_formatter(&(0.0..0.012), 6)(&0.004), "0.004");
    }

    #[test]
    fn only_png_figures() {
        assert!(check_png(Path::new("a/b.PNG")).is_ok());
        assert!(check_png(Path::new("a/b.svg")).is_err());
        assert!(check_png(Path::new("a/b")).is_err());
    }
}
