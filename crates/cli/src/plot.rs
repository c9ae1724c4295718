//! Figures: stacked panels of time series over one shared x axis (PNG), and grids of x-y
//! panels written both as PNG and as SVG.
//!
//! [`plot_series`] draws any number of panels, each with one or more curves (solid or dashed,
//! with a legend), over a shared x axis, and can shade the samples where a mask is true (a
//! contact period). Quantities are given in SI units; each axis picks the SI prefix that keeps
//! its tick labels short (`0.15 s` is drawn as `150 ms`, `2e-6 N·m` as `2 µN·m`).
//!
//! [`render_xy`] draws an [`XyFigure`]: panels of lines, dashed lines or dots over x-y axes
//! (optionally logarithmic in y), with a legend inside a lone panel or in a spare cell of a grid.
//! The drawing code is generic over the plotters backend, so the PNG and the SVG show the same
//! figure.
//!
//! Text in PNGs is set in DejaVu Sans, embedded in the binary, so figures look the same on every
//! machine and need no system fonts. SVGs carry their text as plain `<text>` elements in the
//! generic `sans-serif` family (the embedded font only measures it while drawing). The file appears only when complete: it is drawn into a temporary
//! file beside the target and renamed into place ([`Pending`]).

use crate::files::{self, Pending};
use anyhow::{anyhow, bail, Context, Result};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// DejaVu Sans (licence: assets/DejaVuSans-LICENSE.txt).
const FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
/// The family name under which [`FONT`] is registered.
pub const FAMILY: &str = "sans-serif";

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
pub fn register_font() -> Result<()> {
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
pub fn plotting<E: std::fmt::Display>(e: E) -> anyhow::Error {
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

/// How the points of an [`XySet`] are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mark {
    /// Joined by a solid line.
    Line,
    /// Joined by a dashed line.
    Dashed,
    /// Joined by a solid line, with a dot at every point.
    LineDots,
    /// Dots only.
    Dots,
}

/// Colours of x-y sets, in order (nine, so that nine sets stay apart).
const XY_PALETTE: [RGBColor; 9] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];
/// Colour of reference lines (truth, thresholds).
const REFERENCE: RGBColor = RGBColor(110, 110, 110);

/// One set of points of an x-y panel.
#[derive(Debug, Clone)]
pub struct XySet {
    /// Legend text (empty: no legend entry).
    pub label: String,
    /// Points `(x, y)` in the axes' units; a non-finite coordinate (or, on a logarithmic axis,
    /// a value that is not positive) leaves a gap.
    pub points: Vec<(f64, f64)>,
    /// How the points are drawn.
    pub mark: Mark,
    /// Index into the palette (wrapping), or `None` for the grey of reference lines.
    pub colour: Option<usize>,
}

/// One x-y panel.
#[derive(Debug, Clone)]
pub struct XyPanel {
    /// Caption over the panel (empty: none).
    pub caption: String,
    /// Sets, drawn in order.
    pub sets: Vec<XySet>,
}

/// A figure of x-y panels sharing their axes' ranges, laid out in a grid.
///
/// A lone panel carries its legend inside; a grid of several panels gets one legend, the first
/// panel's, in the cell after the last panel (the panels should then share their labels).
#[derive(Debug, Clone)]
pub struct XyFigure {
    /// Title over the figure.
    pub title: String,
    /// Description of the x axis, with its unit.
    pub x_desc: String,
    /// Description of the y axis, with its unit.
    pub y_desc: String,
    /// A logarithmic y axis (decades labelled, minor lines at 2…9 per decade).
    pub log_y: bool,
    /// Columns of the grid (at least 1).
    pub columns: usize,
    /// Where a lone panel's legend goes: the lower right corner instead of the upper left.
    pub legend_lower_right: bool,
    /// The panels, filled into the grid row by row.
    pub panels: Vec<XyPanel>,
}

impl XyFigure {
    /// Cells in the grid: the panels, plus the legend's cell when there are several.
    fn cells(&self) -> usize {
        self.panels.len() + usize::from(self.panels.len() > 1)
    }

    /// Columns and rows of the grid.
    fn grid(&self) -> (usize, usize) {
        let columns = self.columns.clamp(1, self.cells());
        (columns, self.cells().div_ceil(columns))
    }

    /// Size in px: 900 × 600 for a lone panel, 520 × 380 per cell of a grid.
    fn size(&self) -> (u32, u32) {
        if self.panels.len() == 1 {
            return (900, 600);
        }
        let (columns, rows) = self.grid();
        (520 * columns as u32, TITLE_HEIGHT + 380 * rows as u32)
    }
}

/// Draws `fig` as the PNG `png` and as the SVG beside it (same name, extension `.svg`), each
/// into a temporary file; returns `(target, pending)` for both, to be committed together once
/// everything else a command writes has succeeded.
pub fn render_xy(png: &Path, fig: &XyFigure) -> Result<Vec<(PathBuf, Pending)>> {
    check_png(png)?;
    if fig.panels.is_empty() {
        bail!("a figure needs at least one panel");
    }
    register_font()?;
    let size = fig.size();
    let context = || format!("cannot draw the figure `{}`", png.display());

    let png_file = Pending::beside(png)?;
    {
        let root = BitMapBackend::new(png_file.temp(), size).into_drawing_area();
        draw_xy(&root, fig).with_context(context)?;
        root.present().map_err(plotting).with_context(context)?;
    }

    let svg = png.with_extension("svg");
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
        draw_xy(&root, fig).with_context(context)?;
        root.present().map_err(plotting).with_context(context)?;
    }
    let svg_file = Pending::beside(&svg)?;
    std::fs::write(svg_file.temp(), text)
        .with_context(|| format!("cannot write `{}`", svg.display()))?;
    Ok(vec![(png.to_path_buf(), png_file), (svg, svg_file)])
}

/// A set's style: colour, and line width.
fn set_colour(set: &XySet) -> RGBColor {
    match set.colour {
        Some(c) => XY_PALETTE[c % XY_PALETTE.len()],
        None => REFERENCE,
    }
}

/// Draws `fig` onto `root` (any backend).
fn draw_xy<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, fig: &XyFigure) -> Result<()> {
    root.fill(&WHITE).map_err(plotting)?;
    let body = root
        .titled(&fig.title, (FAMILY, 22).into_font().color(&BLACK))
        .map_err(plotting)?;

    // Every panel's points on the drawn scale (log10 of y on a logarithmic axis).
    let scale = |y: f64| {
        if !fig.log_y {
            y
        } else if y > 0.0 {
            y.log10()
        } else {
            f64::NAN
        }
    };
    let panels: Vec<Vec<Vec<(f64, f64)>>> = fig
        .panels
        .iter()
        .map(|p| {
            p.sets
                .iter()
                .map(|s| s.points.iter().map(|&(x, y)| (x, scale(y))).collect())
                .collect()
        })
        .collect();

    // Shared ranges: x padded by 2%, y by 5% (whole decades on a logarithmic axis).
    let all = panels.iter().flatten().flatten();
    let xs: Vec<f64> = all.clone().map(|p| p.0).collect();
    let ys: Vec<f64> = all.map(|p| p.1).collect();
    let x_range = span(&xs, 0.02);
    let y_range = if fig.log_y {
        let r = span(&ys, 0.0);
        let (lo, hi) = (r.start.floor(), r.end.ceil());
        lo..if hi > lo { hi } else { lo + 1.0 }
    } else {
        span(&ys, 0.05)
    };

    let (columns, rows) = fig.grid();
    let cells = body.split_evenly((rows, columns));
    for (k, (cell, panel)) in cells.iter().zip(&fig.panels).enumerate() {
        draw_xy_panel(
            cell,
            fig,
            panel,
            &panels[k],
            x_range.clone(),
            y_range.clone(),
        )?;
    }
    if fig.panels.len() > 1 {
        draw_legend_cell(&cells[fig.panels.len()], &fig.panels[0].sets)?;
    }
    Ok(())
}

/// Draws one x-y panel into `area`; `points` are its sets' points on the drawn scale.
fn draw_xy_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    fig: &XyFigure,
    panel: &XyPanel,
    points: &[Vec<(f64, f64)>],
    x_range: Range<f64>,
    y_range: Range<f64>,
) -> Result<()> {
    let mut builder = ChartBuilder::on(area);
    builder
        .margin(10)
        .margin_right(20)
        .x_label_area_size(45)
        .y_label_area_size(70);
    if !panel.caption.is_empty() {
        builder.caption(&panel.caption, (FAMILY, 17));
    }
    let mut chart = builder
        .build_cartesian_2d(x_range.clone(), y_range.clone())
        .map_err(plotting)?;

    // Grid, ticks and axis descriptions; a logarithmic axis gets a tick per decade.
    let x_fmt = tick_formatter(&x_range, X_TICKS);
    let y_lin = tick_formatter(&y_range, Y_TICKS);
    let y_fmt = |v: &f64| {
        if fig.log_y {
            decade_label(*v)
        } else {
            y_lin(v)
        }
    };
    let decades = (y_range.end - y_range.start).round() as usize;
    let mut mesh = chart.configure_mesh();
    mesh.label_style((FAMILY, 14))
        .axis_desc_style((FAMILY, 15))
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(205, 205, 205))
        .max_light_lines(if fig.log_y { 0 } else { 2 })
        .x_labels(X_TICKS)
        .y_labels(if fig.log_y { decades + 1 } else { Y_TICKS })
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .x_desc(fig.x_desc.as_str())
        .y_desc(fig.y_desc.as_str());
    mesh.draw().map_err(plotting)?;
    if fig.log_y {
        // Minor lines at 2…9 times each decade.
        let minor = (y_range.start as i32..y_range.end as i32)
            .flat_map(|p| (2..10).map(move |m| p as f64 + (m as f64).log10()));
        chart
            .draw_series(minor.map(|y| {
                PathElement::new(
                    vec![(x_range.start, y), (x_range.end, y)],
                    RGBColor(238, 238, 238),
                )
            }))
            .map_err(plotting)?;
    }

    // The sets, lines split at gaps; the first piece of each carries its legend entry.
    let mut legend = false;
    for (set, pts) in panel.sets.iter().zip(points) {
        let colour = set_colour(set);
        let style = colour.stroke_width(2);
        let runs = finite_runs(
            &pts.iter().map(|p| p.0).collect::<Vec<_>>(),
            &pts.iter().map(|p| p.1).collect::<Vec<_>>(),
        );
        for (piece, run) in runs.into_iter().enumerate() {
            let labelled = piece == 0 && !set.label.is_empty() && fig.panels.len() == 1;
            let label = set.label.clone();
            match set.mark {
                Mark::Line | Mark::LineDots => {
                    let dots = set.mark == Mark::LineDots;
                    chart
                        .draw_series(LineSeries::new(run.clone(), style))
                        .map_err(plotting)?;
                    let drawn = chart
                        .draw_series(
                            run.iter()
                                .filter(|_| dots)
                                .map(|&p| Circle::new(p, 4, colour.filled())),
                        )
                        .map_err(plotting)?;
                    if labelled {
                        drawn.label(label).legend(move |(x, y)| {
                            EmptyElement::at((x, y))
                                + PathElement::new(vec![(0, 0), (22, 0)], style)
                                + Circle::new((11, 0), if dots { 4 } else { 0 }, colour.filled())
                        });
                    }
                }
                Mark::Dashed => {
                    let drawn = chart
                        .draw_series(DashedLineSeries::new(run, 7, 5, style))
                        .map_err(plotting)?;
                    if labelled {
                        drawn.label(label).legend(move |(x, y)| {
                            EmptyElement::at((x, y))
                                + PathElement::new(vec![(0, 0), (8, 0)], style)
                                + PathElement::new(vec![(13, 0), (21, 0)], style)
                        });
                    }
                }
                Mark::Dots => {
                    let drawn = chart
                        .draw_series(run.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                        .map_err(plotting)?;
                    if labelled {
                        drawn
                            .label(label)
                            .legend(move |(x, y)| Circle::new((x + 11, y), 3, colour.filled()));
                    }
                }
            }
            legend |= labelled;
        }
    }
    if legend {
        chart
            .configure_series_labels()
            .position(if fig.legend_lower_right {
                SeriesLabelPosition::LowerRight
            } else {
                SeriesLabelPosition::UpperLeft
            })
            .label_font((FAMILY, 14))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(180, 180, 180))
            .draw()
            .map_err(plotting)?;
    }
    Ok(())
}

/// Draws the legend of `sets` into a cell of its own.
fn draw_legend_cell<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    sets: &[XySet],
) -> Result<()> {
    let text = TextStyle::from((FAMILY, 15).into_font()).pos(Pos::new(HPos::Left, VPos::Center));
    let (x, mut y) = (40, 40);
    for set in sets.iter().filter(|s| !s.label.is_empty()) {
        let colour = set_colour(set);
        let style = colour.stroke_width(2);
        let line = |a: i32, b: i32| PathElement::new(vec![(x + a, y), (x + b, y)], style);
        match set.mark {
            Mark::Line => area.draw(&line(0, 30)),
            Mark::LineDots => area
                .draw(&line(0, 30))
                .and_then(|_| area.draw(&Circle::new((x + 15, y), 4, colour.filled()))),
            Mark::Dashed => area
                .draw(&line(0, 12))
                .and_then(|_| area.draw(&line(18, 30))),
            Mark::Dots => area.draw(&Circle::new((x + 15, y), 3, colour.filled())),
        }
        .map_err(plotting)?;
        area.draw(&Text::new(set.label.clone(), (x + 42, y), text.clone()))
            .map_err(plotting)?;
        y += 26;
    }
    Ok(())
}

/// The label of a decade tick at `log10(value) = v`: `0.01`, `1`, `100` (empty between decades).
fn decade_label(v: f64) -> String {
    if (v - v.round()).abs() > 1e-6 {
        return String::new();
    }
    let p = v.round() as i32;
    if p >= 0 {
        format!("{:.0}", 10f64.powi(p))
    } else {
        format!("{:.*}", (-p) as usize, 10f64.powi(p))
    }
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
    fn decades_are_labelled_plainly() {
        assert_eq!(decade_label(-2.0), "0.01");
        assert_eq!(decade_label(0.0), "1");
        assert_eq!(decade_label(2.0), "100");
        assert_eq!(decade_label(0.5), "");
    }

    #[test]
    fn xy_figures_come_as_png_and_well_formed_svg() {
        let dir = std::env::temp_dir().join(format!("vibrissa-xy-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let set = |label: &str, mark, colour| XySet {
            label: label.into(),
            points: vec![(0.5, 0.3), (2.0, 0.01), (5.0, 2.0), (20.0, 40.0)],
            mark,
            colour,
        };
        let panel = |caption: &str| XyPanel {
            caption: caption.into(),
            sets: vec![
                set("a & <b>", Mark::LineDots, Some(0)),
                set("dashed", Mark::Dashed, None),
                set("dots", Mark::Dots, Some(1)),
                set("line", Mark::Line, Some(2)),
            ],
        };
        for (k, (log_y, panels)) in [(true, 1), (false, 3)].into_iter().enumerate() {
            let fig = XyFigure {
                title: "test".into(),
                x_desc: "x (µm)".into(),
                y_desc: "y (%)".into(),
                log_y,
                columns: 2,
                legend_lower_right: log_y,
                panels: (0..panels).map(|p| panel(&format!("p{p}"))).collect(),
            };
            let png = dir.join(format!("f{k}.png"));
            let files = render_xy(&png, &fig).unwrap();
            assert_eq!(files.len(), 2);
            for (_, pending) in files {
                pending.commit().unwrap();
            }
            assert!(std::fs::metadata(&png).unwrap().len() > 1000);
            let svg = std::fs::read_to_string(png.with_extension("svg")).unwrap();
            assert!(svg.trim_start().starts_with("<svg"), "{}", &svg[..80]);
            assert!(svg.trim_end().ends_with("</svg>"));
            assert!(svg.contains("<text") && !svg.contains("a & <b>"));
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn only_png_figures() {
        assert!(check_png(Path::new("a/b.PNG")).is_ok());
        assert!(check_png(Path::new("a/b.svg")).is_err());
        assert!(check_png(Path::new("a/b")).is_err());
    }
}
