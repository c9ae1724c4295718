//! Animated GIFs of a run: the whisker and the objects at each of its [`Frames`].
//!
//! Each frame is drawn with plotters into an RGB buffer, mapped onto a small fixed palette
//! (the drawing uses a handful of colours; anti-aliased text falls on the nearest), and only the
//! rectangle that changed since the previous frame is stored, so a mostly still picture costs
//! little. The file appears only when complete ([`Pending`]).

use crate::files::{self, Pending};
use crate::frames::{outline, Frames};
use crate::plot::{self, plotting, FAMILY};
use anyhow::{bail, Context, Result};
use plotters::prelude::*;
use std::borrow::Cow;
use std::collections::HashMap;
use std::path::Path;

/// Width of the animation, px.
pub const WIDTH: u32 = 600;
/// Height of the animation, px.
pub const HEIGHT: u32 = 300;
/// Frames per second.
pub const FPS: u16 = 25;
/// Most frames of an animation (at [`FPS`], six seconds).
pub const MAX_FRAMES: usize = 150;

/// Height of the caption strip above the drawing, px.
const CAPTION: u32 = 28;

/// The palette every frame is drawn in.
const PALETTE: [RGBColor; 10] = [
    RGBColor(255, 255, 255),
    RGBColor(0, 0, 0),
    RGBColor(64, 64, 64),
    RGBColor(128, 128, 128),
    RGBColor(192, 192, 192),
    RGBColor(225, 225, 225),
    RGBColor(200, 40, 40),
    RGBColor(31, 119, 180),
    RGBColor(170, 200, 230),
    RGBColor(240, 170, 170),
];
const WHISKER: RGBColor = PALETTE[1];
const REST: RGBColor = PALETTE[4];
const OBJECT: RGBColor = PALETTE[8];
const OBJECT_EDGE: RGBColor = PALETTE[7];
const TOUCHING: RGBColor = PALETTE[6];
const TOUCHING_FILL: RGBColor = PALETTE[9];
const TEXT: RGBColor = PALETTE[2];

/// Refuses an animation path that does not end in `.gif`.
pub fn check_gif(path: &Path) -> Result<()> {
    match files::extension(path).as_deref() {
        Some("gif") => Ok(()),
        _ => bail!(
            "`{}`: unknown animation format; the extension must be .gif",
            path.display()
        ),
    }
}

/// Draws `frames` under `title` into the GIF `path`, left in a temporary file beside it to be
/// renamed into place by [`Pending::commit`].
pub fn render_gif(path: &Path, title: &str, frames: &Frames) -> Result<Pending> {
    check_gif(path)?;
    plot::register_font()?;
    let pending = Pending::beside(path)?;
    write(pending.temp(), title, frames)
        .with_context(|| format!("cannot draw the animation `{}`", path.display()))?;
    Ok(pending)
}

/// Encodes every frame into `file`.
fn write(file: &Path, title: &str, frames: &Frames) -> Result<()> {
    let (w, h) = (WIDTH as usize, HEIGHT as usize);
    let flat: Vec<u8> = PALETTE.iter().flat_map(|c| [c.0, c.1, c.2]).collect();
    let out = std::fs::File::create_new(file)?;
    let mut encoder = gif::Encoder::new(
        std::io::BufWriter::new(out),
        WIDTH as u16,
        HEIGHT as u16,
        &flat,
    )?;
    encoder.set_repeat(gif::Repeat::Infinite)?;
    let view = frames.view(WIDTH as f64 / (HEIGHT - CAPTION) as f64);
    let mut rgb = vec![0u8; w * h * 3];
    let mut previous: Option<Vec<u8>> = None;
    let mut nearest: HashMap<[u8; 3], u8> = HashMap::new();
    for f in 0..frames.samples.len() {
        draw_frame(&mut rgb, title, frames, f, view)?;
        let indices: Vec<u8> = rgb
            .chunks_exact(3)
            .map(|p| {
                let c = [p[0], p[1], p[2]];
                *nearest.entry(c).or_insert_with(|| closest(c))
            })
            .collect();
        // The rectangle that differs from the previous frame (all of the first).
        let [x0, y0, x1, y1] = match &previous {
            None => [0, 0, w, h],
            Some(prev) => changed(prev, &indices, w, h),
        };
        let mut buffer = Vec::with_capacity((x1 - x0) * (y1 - y0));
        for y in y0..y1 {
            buffer.extend_from_slice(&indices[y * w + x0..y * w + x1]);
        }
        let frame = gif::Frame {
            left: x0 as u16,
            top: y0 as u16,
            width: (x1 - x0) as u16,
            height: (y1 - y0) as u16,
            delay: (100 / FPS).max(1),
            dispose: gif::DisposalMethod::Keep,
            buffer: Cow::Owned(buffer),
            ..gif::Frame::default()
        };
        encoder.write_frame(&frame)?;
        previous = Some(indices);
    }
    let mut out = encoder.into_inner()?;
    std::io::Write::flush(&mut out)?;
    out.into_inner()
        .map_err(|e| anyhow::anyhow!("{}", e.error()))?
        .sync_all()?;
    Ok(())
}

/// The palette index nearest to the colour `c`.
fn closest(c: [u8; 3]) -> u8 {
    let d = |p: &RGBColor| {
        let e = |a: u8, b: u8| (a as i32 - b as i32).pow(2);
        e(c[0], p.0) + e(c[1], p.1) + e(c[2], p.2)
    };
    (0..PALETTE.len())
        .min_by_key(|&k| d(&PALETTE[k]))
        .unwrap_or(0) as u8
}

/// The smallest rectangle `[x0, y0, x1, y1)` holding every pixel in which `a` and `b` differ
/// (one pixel if none does: a frame cannot be empty).
fn changed(a: &[u8], b: &[u8], w: usize, h: usize) -> [usize; 4] {
    let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
    for y in 0..h {
        let (ra, rb) = (&a[y * w..(y + 1) * w], &b[y * w..(y + 1) * w]);
        if ra == rb {
            continue;
        }
        let first = ra.iter().zip(rb).position(|(p, q)| p != q).unwrap_or(0);
        let last = w - ra
            .iter()
            .zip(rb)
            .rev()
            .position(|(p, q)| p != q)
            .unwrap_or(0);
        (x0, x1, y0, y1) = (x0.min(first), x1.max(last), y0.min(y), y + 1);
    }
    if x1 <= x0 {
        [0, 0, 1, 1]
    } else {
        [x0, y0, x1, y1]
    }
}

/// Draws frame `f` of `frames` into the RGB buffer `rgb`, showing the part `view` of the world.
fn draw_frame(
    rgb: &mut [u8],
    title: &str,
    frames: &Frames,
    f: usize,
    view: [f64; 4],
) -> Result<()> {
    let root = BitMapBackend::with_buffer(rgb, (WIDTH, HEIGHT)).into_drawing_area();
    root.fill(&WHITE).map_err(plotting)?;
    let [x0, x1, y0, y1] = view;
    let top = CAPTION as f64;
    let sx = WIDTH as f64 / (x1 - x0);
    let sy = (HEIGHT as f64 - top) / (y1 - y0);
    let px = |p: [f64; 2]| -> (i32, i32) {
        (
            ((p[0] - x0) * sx).round().clamp(-1e4, 1e4) as i32,
            (top + (y1 - p[1]) * sy).round().clamp(-1e4, 1e4) as i32,
        )
    };
    let t = frames.time(f);
    let touching = frames.touching(f);
    let reach = 4.0 * (x1 - x0).max(y1 - y0);
    // Objects, their outline red while the whisker touches one.
    for o in &frames.objects {
        let points: Vec<(i32, i32)> = outline(o, t, reach).into_iter().map(px).collect();
        let Some(&first) = points.first() else {
            continue;
        };
        let (fill, edge) = if touching {
            (TOUCHING_FILL, TOUCHING)
        } else {
            (OBJECT, OBJECT_EDGE)
        };
        // An object out of the whisker's plane (above or below it) is drawn as an outline only.
        if o.in_plane(t) {
            root.draw(&Polygon::new(points.clone(), fill.filled()))
                .map_err(plotting)?;
        }
        let mut closed = points;
        closed.push(first);
        root.draw(&PathElement::new(closed, edge.stroke_width(2)))
            .map_err(plotting)?;
    }
    // The whisker at rest (the first frame), then now; its base as a dot.
    let rest: Vec<(i32, i32)> = frames.nodes[0].iter().map(|&p| px(p)).collect();
    root.draw(&PathElement::new(rest, REST.stroke_width(2)))
        .map_err(plotting)?;
    let now: Vec<(i32, i32)> = frames.nodes[f].iter().map(|&p| px(p)).collect();
    root.draw(&PathElement::new(now.clone(), WHISKER.stroke_width(3)))
        .map_err(plotting)?;
    root.draw(&Circle::new(now[0], 5, WHISKER.filled()))
        .map_err(plotting)?;
    // Caption: the run, the time, and contact.
    let (w, c) = (WIDTH as i32, CAPTION as i32);
    root.draw(&Rectangle::new([(0, 0), (w, c)], WHITE.filled()))
        .map_err(plotting)?;
    root.draw(&PathElement::new(
        vec![(0, c), (w, c)],
        PALETTE[5].stroke_width(1),
    ))
    .map_err(plotting)?;
    let font = (FAMILY, 16).into_font().color(&TEXT);
    root.draw(&Text::new(title.to_string(), (8, 6), font.clone()))
        .map_err(plotting)?;
    let mut clock = format!("t = {:6.1} ms", t * 1e3);
    if touching {
        clock.push_str("  contact");
    }
    let clock_font = (FAMILY, 16)
        .into_font()
        .color(if touching { &TOUCHING } else { &TEXT });
    root.draw(&Text::new(clock, (WIDTH as i32 - 175, 6), clock_font))
        .map_err(plotting)?;
    root.present().map_err(plotting)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_gif_paths_are_accepted() {
        assert!(check_gif(Path::new("a/run.GIF")).is_ok());
        let e = check_gif(Path::new("run.png")).unwrap_err().to_string();
        assert!(e.contains(".gif"), "{e}");
    }

    #[test]
    fn the_changed_rectangle_bounds_every_difference() {
        let (w, h) = (5, 4);
        let a = vec![0u8; w * h];
        let mut b = a.clone();
        assert_eq!(changed(&a, &b, w, h), [0, 0, 1, 1]);
        b[w + 3] = 1;
        b[2 * w + 1] = 2;
        assert_eq!(changed(&a, &b, w, h), [1, 1, 4, 3]);
    }

    #[test]
    fn colours_fall_on_the_nearest_of_the_palette() {
        assert_eq!(closest([250, 250, 250]), 0);
        assert_eq!(closest([10, 5, 0]), 1);
        assert_eq!(closest([190, 50, 45]), 6);
    }
}
