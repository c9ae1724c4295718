//! Confusion matrices as figures: one panel per matrix, each cell shaded by its share of its
//! row (the true class) and labelled with its count.

use crate::files::Pending;
use crate::plot::{check_png, plotting, register_font, FAMILY};
use anyhow::{bail, Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::{Path, PathBuf};

/// One confusion matrix: `counts[truth][estimate]`.
pub struct Matrix {
    /// Caption over its panel.
    pub caption: String,
    /// Runs per true class (rows) and estimated class (columns).
    pub counts: Vec<Vec<usize>>,
}

/// Side of one panel, px.
const PANEL: u32 = 420;
/// Height of the title, px.
const TITLE: u32 = 50;

/// Draws `matrices` in a grid of `columns` columns filled row by row, with the class `labels`,
/// as the PNG `png` and the SVG beside it; returns `(target, pending)` for both, to be committed
/// with the command's other files.
pub fn render_matrices(
    png: &Path,
    title: &str,
    labels: &[String],
    matrices: &[Matrix],
    columns: usize,
) -> Result<Vec<(PathBuf, Pending)>> {
    check_png(png)?;
    if matrices.is_empty() || labels.is_empty() {
        bail!("a confusion figure needs at least one matrix and one class");
    }
    if let Some(m) = matrices.iter().find(|m| {
        m.counts.len() != labels.len() || m.counts.iter().any(|r| r.len() != labels.len())
    }) {
        bail!(
            "the confusion matrix `{}` is not {} × {}",
            m.caption,
            labels.len(),
            labels.len()
        );
    }
    register_font()?;
    let columns = columns.clamp(1, matrices.len());
    let rows = matrices.len().div_ceil(columns);
    let size = (PANEL * columns as u32, TITLE + PANEL * rows as u32);
    let context = || format!("cannot draw the figure `{}`", png.display());
    let png_file = Pending::beside(png)?;
    {
        let root = BitMapBackend::new(png_file.temp(), size).into_drawing_area();
        draw(&root, title, labels, matrices, (rows, columns)).with_context(context)?;
        root.present().map_err(plotting).with_context(context)?;
    }
    let svg = png.with_extension("svg");
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
        draw(&root, title, labels, matrices, (rows, columns)).with_context(context)?;
        root.present().map_err(plotting).with_context(context)?;
    }
    let svg_file = Pending::beside(&svg)?;
    std::fs::write(svg_file.temp(), text)
        .with_context(|| format!("cannot write `{}`", svg.display()))?;
    Ok(vec![(png.to_path_buf(), png_file), (svg, svg_file)])
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    labels: &[String],
    matrices: &[Matrix],
    grid: (usize, usize),
) -> Result<()> {
    root.fill(&WHITE).map_err(plotting)?;
    let body = root
        .titled(title, (FAMILY, 22).into_font().color(&BLACK))
        .map_err(plotting)?;
    let k = labels.len();
    for (area, m) in body.split_evenly(grid).iter().zip(matrices) {
        let mut chart = ChartBuilder::on(area)
            .caption(&m.caption, (FAMILY, 17))
            .margin(10)
            .x_label_area_size(55)
            .y_label_area_size(75)
            .build_cartesian_2d(0.0..k as f64, 0.0..k as f64)
            .map_err(plotting)?;
        let label_at = |x: &f64| {
            let i = x.floor() as usize;
            if (x - i as f64 - 0.5).abs() < 1e-6 && i < k {
                labels[i].clone()
            } else {
                String::new()
            }
        };
        let centres: Vec<f64> = (0..k).map(|i| i as f64 + 0.5).collect();
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(2 * k + 1)
            .y_labels(2 * k + 1)
            .x_label_formatter(&label_at)
            .y_label_formatter(&|y: &f64| label_at(&(k as f64 - y)))
            .x_desc("estimated class")
            .y_desc("true class")
            .label_style((FAMILY, 14))
            .axis_desc_style((FAMILY, 15))
            .draw()
            .map_err(plotting)?;
        for (t, row) in m.counts.iter().enumerate() {
            let total = row.iter().sum::<usize>().max(1) as f64;
            // Row t is drawn from the top.
            let y0 = (k - 1 - t) as f64;
            for (e, &n) in row.iter().enumerate() {
                let share = n as f64 / total;
                let shade = (255.0 * (1.0 - 0.8 * share)) as u8;
                let fill = RGBColor(shade, shade, 255);
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(e as f64, y0), (e as f64 + 1.0, y0 + 1.0)],
                        fill.filled(),
                    )))
                    .map_err(plotting)?;
                let colour = if share > 0.55 { WHITE } else { BLACK };
                let style = (FAMILY, 18)
                    .into_font()
                    .color(&colour)
                    .pos(Pos::new(HPos::Center, VPos::Center));
                chart
                    .draw_series(std::iter::once(Text::new(
                        n.to_string(),
                        (centres[e], y0 + 0.5),
                        style,
                    )))
                    .map_err(plotting)?;
            }
        }
    }
    Ok(())
}
