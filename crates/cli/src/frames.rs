//! Frames of a run for animation: the whisker's shape and the objects' outlines at a subset of
//! its output samples, recorded while the run is simulated (the same run `vibrissa simulate`
//! makes; see [`vibrissa_core::sim::run_observed`]).

use anyhow::Result;
use vibrissa_core::objects::{Object, Shape};
use vibrissa_core::sim::{self, Output, Scenario, Snapshot};

/// Points on a circle's outline.
const CIRCLE_POINTS: usize = 32;

/// A run and its frames.
#[derive(Debug, Clone)]
pub struct Frames {
    /// The whole run, every sample.
    pub output: Output,
    /// The output samples shown, in order (every `stride`-th, starting at 0).
    pub samples: Vec<usize>,
    /// Node positions of the whisker at each shown sample, base first, m: `[frames][N+1]`.
    pub nodes: Vec<Vec<[f64; 2]>>,
    /// The scenario's objects (their shapes and motions).
    pub objects: Vec<Object>,
}

/// Every how many output samples a frame is kept so that at most `max_frames` are shown.
pub fn stride(samples: usize, max_frames: usize) -> usize {
    samples.div_ceil(max_frames.max(1)).max(1)
}

/// Frames kept of `samples` output samples at most `max_frames` of them: every
/// [`stride`]-th sample from the first.
#[cfg(test)]
fn frame_count(samples: usize, max_frames: usize) -> usize {
    samples.div_ceil(stride(samples, max_frames))
}

/// Runs `scenario`, keeping at most `max_frames` frames spread evenly over its samples;
/// `progress` gets the fraction done.
pub fn simulate(
    scenario: &Scenario,
    max_frames: usize,
    progress: &mut dyn FnMut(f64),
) -> Result<Frames> {
    let samples = (scenario.duration * scenario.sample_rate + 1e-9).floor() as usize + 1;
    let every = stride(samples, max_frames);
    let mut kept = Vec::new();
    let mut nodes = Vec::new();
    let output = sim::run_observed(
        scenario,
        progress,
        Some(&mut |s: Snapshot<'_>| {
            if s.k % every == 0 {
                kept.push(s.k);
                nodes.push(s.nodes.to_vec());
            }
        }),
    )?;
    Ok(Frames {
        output,
        samples: kept,
        nodes,
        objects: scenario.objects.clone(),
    })
}

impl Frames {
    /// The time of frame `f`, s.
    pub fn time(&self, f: usize) -> f64 {
        self.output.rows[self.samples[f]][0]
    }

    /// Whether the whisker touches an object at frame `f`.
    pub fn touching(&self, f: usize) -> bool {
        self.output.rows[self.samples[f]][6] > 0.5
    }

    /// The part of the world the animation shows, `[x0, x1, y0, y1]`, m, with width `aspect`
    /// times its height: every shape the whisker takes, with a margin of a fifth of its length
    /// (objects are drawn where they enter it).
    pub fn view(&self, aspect: f64) -> [f64; 4] {
        let mut b = [
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        for p in self.nodes.iter().flatten() {
            b = [
                b[0].min(p[0]),
                b[1].max(p[0]),
                b[2].min(p[1]),
                b[3].max(p[1]),
            ];
        }
        if !b.iter().all(|x| x.is_finite()) {
            b = [0.0, 1e-3, 0.0, 1e-3];
        }
        let size = (b[1] - b[0]).max(b[3] - b[2]).max(1e-6);
        let margin = 0.2 * size;
        let (mut x0, mut x1) = (b[0] - margin, b[1] + margin);
        let (mut y0, mut y1) = (b[2] - margin, b[3] + margin);
        let (w, h) = (x1 - x0, y1 - y0);
        if w < aspect * h {
            let grow = 0.5 * (aspect * h - w);
            (x0, x1) = (x0 - grow, x1 + grow);
        } else {
            let grow = 0.5 * (w / aspect - h);
            (y0, y1) = (y0 - grow, y1 + grow);
        }
        [x0, x1, y0, y1]
    }
}

/// The outline of `object` at time `t` as a closed polygon in the world frame, m. A wall (a
/// half-plane) is cut to a square of side `reach` below its surface.
pub fn outline(object: &Object, t: f64, reach: f64) -> Vec<[f64; 2]> {
    let pose = object.pose(t);
    let local: Vec<[f64; 2]> = match &object.shape {
        Shape::Circle { radius } => (0..CIRCLE_POINTS)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / CIRCLE_POINTS as f64;
                [radius * a.cos(), radius * a.sin()]
            })
            .collect(),
        Shape::Wall => vec![
            [-reach, 0.0],
            [reach, 0.0],
            [reach, -reach],
            [-reach, -reach],
        ],
        shape => shape.vertices().unwrap_or_default(),
    };
    local.into_iter().map(|l| pose.to_world(l)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_spread_evenly_and_never_exceed_the_limit() {
        assert_eq!((stride(151, 150), frame_count(151, 150)), (2, 76));
        assert_eq!((stride(150, 150), frame_count(150, 150)), (1, 150));
        assert_eq!((stride(10, 0), frame_count(10, 0)), (10, 1));
        for n in 1..400 {
            for max in 1..60 {
                let f = frame_count(n, max);
                assert!(f <= max && f >= 1, "{n} samples, at most {max}: {f}");
            }
        }
    }

    #[test]
    fn outlines_follow_the_object() {
        let o = vibrissa_core::scenes::e2_box(0.02, 0.5);
        let at0 = outline(&o, 0.0, 1.0);
        let at1 = outline(&o, 0.01, 1.0);
        assert_eq!(at0.len(), 4);
        for (a, b) in at0.iter().zip(&at1) {
            assert!((b[0] - a[0]).abs() < 1e-12 && (b[1] - a[1] - 0.005).abs() < 1e-12);
        }
        // The box's near edge is at x = d.
        let near = at0.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min);
        assert!((near - 0.02).abs() < 1e-12);
    }
}
