//! The animated runs of a report: each run of the experiment's grid re-simulated as the
//! experiment recorded it (same scenario, noise and seed), its frames, its channels, and, when
//! the experiment scored the particle filter, the filter's particle cloud over the unknowns at
//! every frame. Everything is rounded to what a screen shows and kept as integers where it can
//! be, so the page stays small.

use super::results::Results;
use crate::frames::{self, Frames};
use anyhow::{anyhow, Context, Result};
use serde::Serialize;
use vibrissa_core::objects::Shape;
use vibrissa_infer::pf::{Filter, Observations, Pf, TransitionModel};
use vibrissa_infer::{Family, Method, Training};

/// Most frames of a run's animation.
pub const MAX_FRAMES: usize = 150;
/// Most particles drawn of the filter's cloud at each frame (equally weighted draws).
pub const CLOUD_POINTS: usize = 120;
/// Positions are stored in micrometres.
const MICRONS: f64 = 1e6;

/// An object's shape, in its own frame, µm.
#[derive(Debug, Serialize)]
#[serde(tag = "shape", rename_all = "snake_case")]
enum ShapeData {
    /// A convex polygon (boxes too): its vertices.
    Polygon { vertices: Vec<[i64; 2]> },
    /// A disc.
    Circle { radius: i64 },
    /// The half-plane below the local x axis.
    Wall,
}

/// The particle filter's cloud over the run.
#[derive(Debug, Serialize)]
struct Cloud {
    /// Names of the unknowns plotted (the first two of the filter's).
    unknowns: Vec<String>,
    /// Scale of the stored values: value = stored / scale, SI.
    scale: Vec<f64>,
    /// Per frame: equally weighted draws of the cloud, `[u0, u1, u0, u1, …]` scaled.
    points: Vec<Vec<i64>>,
    /// Per frame: the posterior mean of each unknown, SI.
    mean: Vec<Vec<f64>>,
    /// The filter's estimate after the last sample, SI (the experiment's, re-computed).
    last: Vec<f64>,
    /// Particles of the filter.
    particles: usize,
}

/// One animated run.
#[derive(Debug, Serialize)]
pub struct RunData {
    /// Index in the experiment's grid.
    index: usize,
    /// `d = 20 mm, v = 0.6 m/s`.
    label: String,
    /// Whether it is a template.
    template: bool,
    /// True values of the unknowns, SI.
    truth: Vec<f64>,
    /// Each method's estimate of the unknowns, SI (evaluated runs).
    estimates: Vec<(String, Vec<f64>)>,
    /// Sample times of the whole recording, ms.
    t: Vec<f64>,
    /// The recorded channels at every sample (as the estimators saw them).
    theta12: Vec<f64>,
    /// Base moment at every sample, N·m.
    m0: Vec<f64>,
    /// Whether the whisker touches the object at each sample (0 or 1).
    contact: Vec<u8>,
    /// The sample shown at each frame.
    frames: Vec<usize>,
    /// Whisker nodes at each frame, `[x0, y0, x1, y1, …]`, µm.
    nodes: Vec<Vec<i64>>,
    /// The objects' shapes.
    objects: Vec<ShapeData>,
    /// Each object's pose at each frame: `[x µm, y µm, angle µrad]`, `[frames][objects]`.
    poses: Vec<Vec<[i64; 3]>>,
    /// The particle filter's cloud, if the experiment scored the filter.
    pf: Option<Cloud>,
}

/// Re-simulates grid run `k` of `results` (its recording, noise included) and, when `pf` is
/// given, runs the filter on it.
pub fn run_data(results: &Results, family: &Family, k: usize, pf: Option<&Pf>) -> Result<RunData> {
    let p = &results.grid[k];
    let scenario = family
        .recording_scenario(
            p,
            0.0,
            &results.noise.to_infer(),
            Family::run_seed(results.seed, k),
        )
        .with_context(|| format!("run {k} ({})", results.describe(k)))?;
    let frames = frames::simulate(&scenario, MAX_FRAMES, &mut |_| {})
        .with_context(|| format!("cannot re-simulate run {k} ({})", results.describe(k)))?;
    let rows = &frames.output.rows;
    let estimates = match results.evaluated_index(k) {
        Some(j) => results
            .methods
            .iter()
            .map(|m| {
                let e = m.predictions[j].estimate.iter().map(|e| e.mean.0).collect();
                (m.name.clone(), e)
            })
            .collect(),
        None => Vec::new(),
    };
    let pf = match pf {
        Some(pf) => Some(
            cloud(pf, family, &frames)
                .with_context(|| format!("particle filter on run {k} ({})", results.describe(k)))?,
        ),
        None => None,
    };
    Ok(RunData {
        index: k,
        label: results.describe(k),
        template: results.is_template[k],
        truth: p.clone(),
        estimates,
        t: rows.iter().map(|r| round(r[0] * 1e3, 6)).collect(),
        theta12: rows.iter().map(|r| round(r[2], 5)).collect(),
        m0: rows.iter().map(|r| round(r[3], 5)).collect(),
        contact: rows.iter().map(|r| u8::from(r[6] > 0.5)).collect(),
        frames: frames.samples.clone(),
        nodes: frames
            .nodes
            .iter()
            .map(|n| {
                n.iter()
                    .flat_map(|q| [microns(q[0]), microns(q[1])])
                    .collect()
            })
            .collect(),
        objects: frames.objects.iter().map(|o| shape(&o.shape)).collect(),
        poses: frames
            .samples
            .iter()
            .map(|&s| {
                frames
                    .objects
                    .iter()
                    .map(|o| {
                        let pose = o.pose(rows[s][0]);
                        [
                            microns(pose.position[0]),
                            microns(pose.position[1]),
                            microns(pose.angle),
                        ]
                    })
                    .collect()
            })
            .collect(),
        pf,
    })
}

/// The filter that the experiment scored, fitted as it was: its particles, transition model
/// and seed, with the noise the estimators were given. `None` if the experiment did not score
/// it.
pub fn fitted_filter(results: &Results, family: &Family) -> Result<Option<Pf>> {
    let Some(m) = results.methods.iter().find(|m| m.name == "pf") else {
        return Ok(None);
    };
    let particles = m
        .setting("particles")
        .filter(|n| n.is_finite() && *n >= 1.0)
        .ok_or_else(|| anyhow!("method `pf` in results.json has no setting `particles` >= 1"))?;
    let model = TransitionModel::from_name(results.pf_model.as_deref().unwrap_or("coarse"))
        .map_err(|e| anyhow!("field `pf_model` of results.json: {e}"))?;
    let mut pf = Pf::new(particles as usize);
    pf.set_model(model);
    pf.seed = results.seed;
    pf.fit(&Training {
        family: family.clone(),
        samples: Vec::new(),
        calibration: Vec::new(),
        noise: results.estimated_noise.to_infer(),
    })?;
    Ok(Some(pf))
}

/// Runs `pf` over the recording of `frames`, one sample at a time, keeping the cloud at each
/// frame.
fn cloud(pf: &Pf, family: &Family, frames: &Frames) -> Result<Cloud> {
    let sigma = pf
        .sigma()
        .ok_or_else(|| anyhow!("the particle filter is not fitted"))?;
    let config = pf.config(family, sigma)?;
    let rows = &frames.output.rows;
    let series: Vec<Vec<f64>> = (0..5)
        .map(|c| rows.iter().map(|r| r[c + 1]).collect())
        .collect();
    let obs = Observations::at_rate(series, family.sample_rate());
    let period = obs
        .t
        .get(1)
        .map_or(1.0 / family.sample_rate(), |t1| t1 - obs.t[0]);
    let mut filter = Filter::new(&config, period)?;
    let shown = config.unknowns().len().min(2);
    let unknowns: Vec<String> = config.unknowns()[..shown]
        .iter()
        .map(|u| u.to_string())
        .collect();
    // d in units of 10 µm, v in mm/s, anything else in hundred-thousandths: finer than a
    // plot's pixel.
    let scale: Vec<f64> = unknowns
        .iter()
        .map(|u| if u == "v" { 1e3 } else { 1e5 })
        .collect();
    let mut next = frames.samples.iter().peekable();
    let (mut points, mut mean) = (Vec::new(), Vec::new());
    let mut last = Vec::new();
    for (k, &t) in obs.t.iter().enumerate() {
        let y: [f64; 5] = std::array::from_fn(|c| obs.values[c][k]);
        let row = filter.update(t, &y)?;
        last = row.estimates.iter().map(|e| e.mean).collect();
        if next.peek() == Some(&&k) {
            next.next();
            let cloud = filter.particles();
            let mut drawn = Vec::with_capacity(CLOUD_POINTS * shown);
            for i in systematic(&cloud.weights, CLOUD_POINTS.min(cloud.weights.len())) {
                for (values, s) in cloud.values.iter().zip(&scale) {
                    drawn.push((values[i] * s).round() as i64);
                }
            }
            points.push(drawn);
            mean.push(last[..shown].to_vec());
        }
    }
    Ok(Cloud {
        unknowns,
        scale,
        points,
        mean,
        last,
        particles: config.particles,
    })
}

/// `n` equally weighted draws of the indices of `weights` (systematic, evenly offset: the same
/// cloud every time).
fn systematic(weights: &[f64], n: usize) -> Vec<usize> {
    let total: f64 = weights.iter().sum();
    let mut out = Vec::with_capacity(n);
    if total.is_nan() || total <= 0.0 || weights.is_empty() {
        return out;
    }
    let mut cum = 0.0;
    let mut i = 0;
    for j in 0..n {
        let u = (j as f64 + 0.5) / n as f64 * total;
        while i + 1 < weights.len() && cum + weights[i] < u {
            cum += weights[i];
            i += 1;
        }
        out.push(i);
    }
    out
}

/// A shape for the page, µm.
fn shape(s: &Shape) -> ShapeData {
    match s {
        Shape::Circle { radius } => ShapeData::Circle {
            radius: microns(*radius),
        },
        Shape::Wall => ShapeData::Wall,
        other => ShapeData::Polygon {
            vertices: other
                .vertices()
                .unwrap_or_default()
                .iter()
                .map(|v| [microns(v[0]), microns(v[1])])
                .collect(),
        },
    }
}

/// Metres (or radians) in millionths, rounded.
fn microns(x: f64) -> i64 {
    (x * MICRONS).round() as i64
}

/// `x` rounded to `digits` significant digits (NaN stays NaN, written as `null`).
fn round(x: f64, digits: usize) -> f64 {
    if !x.is_finite() || x == 0.0 {
        return x;
    }
    format!("{x:.*e}", digits - 1).parse().unwrap_or(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn systematic_draws_follow_the_weights() {
        assert_eq!(systematic(&[0.0, 1.0, 0.0], 3), [1, 1, 1]);
        assert_eq!(systematic(&[0.5, 0.5], 4), [0, 0, 1, 1]);
        assert_eq!(systematic(&[0.25, 0.0, 0.75], 4), [0, 2, 2, 2]);
        assert!(systematic(&[], 4).is_empty());
        assert!(systematic(&[f64::NAN], 4).is_empty());
    }

    #[test]
    fn numbers_are_rounded_to_significant_digits() {
        assert_eq!(round(0.0123456, 3), 0.0123);
        assert_eq!(round(-1234.5, 2), -1200.0);
        assert!(round(f64::NAN, 3).is_nan());
        assert_eq!(microns(0.0215), 21500);
    }
}
