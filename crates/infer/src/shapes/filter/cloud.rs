//! One class's particle filter over one recording. Each particle carries a pose of the class (its
//! unknowns, static) and every whisker's chain state; it is advanced by the physics against the
//! objects its pose implies, weighed by how well its whiskers' sensors match the recording, and
//! resampled and moved (Liu–West) when its weights degenerate. The product of the mean weights
//! is the recording's marginal likelihood under the class.

use super::pose::PoseObjects;
use crate::error::{Error, Result};
use crate::pf::{systematic, JointMap};
use vibrissa_core::array::Mount;
use vibrissa_core::chain::{Discretisation, Model};
use vibrissa_core::dynamics::{
    initialize, step_group_each, Inputs, LaneWorkspace, State, Stepper, Workspace, LANES,
};
use vibrissa_core::objects::{Motion, Object, Shape};
use vibrissa_core::rng::Rng;
use vibrissa_core::sensors::Sensors;
use vibrissa_core::sim::Scenario;

/// Smallest spread of the cloud a Liu–West move assumes, as a share of each unknown's range, so
/// that a cloud collapsed onto one pose still moves.
const SPREAD_FLOOR: f64 = 2e-3;
/// Liu–West shrinkage of the poses whose whiskers have left rest (`pf`'s).
const LW_SHRINK: f64 = 0.98;

/// One whisker of the array as the filter models it: a coarse chain in the whisker's own frame,
/// its joint angles read as the recording's chain's, and its sensors.
#[derive(Debug, Clone)]
pub(super) struct WhiskerModel {
    /// Where it is mounted (`None`: a scenario of one whisker, whose frame is the scene's).
    mount: Option<Mount>,
    model: Model,
    joints: JointMap,
    at_rest: State,
    /// What its sensors record while it rests.
    rest: [f64; 5],
    gain: [f64; 5],
    offset: [f64; 5],
    /// Its nodes at rest, in its frame.
    nodes: Vec<[f64; 2]>,
    /// Its thickest radius, m.
    radius: f64,
}

impl WhiskerModel {
    /// The whisker of `s` (a scenario in the whisker's own frame) as a chain of `segments`.
    pub(super) fn new(
        s: &Scenario,
        mount: Option<Mount>,
        segments: usize,
        method: &str,
    ) -> Result<WhiskerModel> {
        let fail = |e: vibrissa_core::Error| Error::Fit {
            method: method.into(),
            detail: format!("whisker model: {e}"),
        };
        let whisker = s.whisker.check().map_err(fail)?;
        let model = Model::new(&whisker, segments, Discretisation::default()).map_err(fail)?;
        let observed = Model::new(&whisker, s.segments, s.discretisation).map_err(fail)?;
        let joints = JointMap::new(&model, &observed, model.n);
        let mut at_rest = State::at_rest(&model, 0);
        let mut ws = Workspace::new(&model);
        let still = Inputs {
            base: Default::default(),
            loads: &[],
            noise: 0.0,
            objects: &[],
        };
        initialize(&model, &mut at_rest, &still, &mut ws).map_err(fail)?;
        let sensors = s.sensor_response.to_array();
        let gain = sensors.map(|r| r.gain);
        let offset = sensors.map(|r| r.offset);
        let mut nodes = vec![[0.0, 0.0]];
        let (mut x, mut y, mut angle) = (0.0f64, 0.0f64, 0.0f64);
        for i in 0..model.n {
            angle += model.rest[i];
            x += model.arc * angle.cos();
            y += model.arc * angle.sin();
            nodes.push([x, y]);
        }
        let radius = model.radius.iter().cloned().fold(0.0, f64::max);
        let mut w = WhiskerModel {
            mount,
            model,
            joints,
            at_rest,
            rest: [0.0; 5],
            gain,
            offset,
            nodes,
            radius,
        };
        w.rest = w.recorded(&w.at_rest);
        Ok(w)
    }

    /// What the sensors record of `s`: the model's channels (its joint angles read as the
    /// recording's chain's) through each sensor's gain and offset.
    fn recorded(&self, s: &State) -> [f64; 5] {
        let mut x = Sensors::read(s).to_array();
        [x[0], x[1]] = self.joints.apply(s.q());
        std::array::from_fn(|c| self.gain[c] * x[c] + self.offset[c])
    }

    /// The scene's objects as this whisker sees them.
    fn carry(&self, scene: &[Object]) -> Vec<Object> {
        match &self.mount {
            Some(m) => scene.iter().map(|o| m.carry(o)).collect(),
            None => scene.to_vec(),
        }
    }

    /// Whether every one of `objects` (in this whisker's frame) lies at time `t` farther than
    /// `margin` plus a sample `period`'s travel from the whisker at rest: it cannot have touched
    /// it yet.
    fn clear_of(&self, objects: &[Object], t: f64, margin: f64, period: f64) -> bool {
        objects.iter().all(|o| {
            let reach = match &o.shape {
                Shape::Box { width, height } => 0.5 * width.hypot(*height),
                Shape::Circle { radius } => *radius,
                Shape::Polygon { vertices } => vertices
                    .iter()
                    .map(|v| v[0].hypot(v[1]))
                    .fold(0.0, f64::max),
                Shape::Wall => return false,
            };
            let speed = match &o.motion {
                Motion::Constant {
                    velocity,
                    angular_velocity: 0.0,
                } => velocity[0].hypot(velocity[1]),
                _ => return false,
            };
            let p = o.pose(t).position;
            let gap = self
                .nodes
                .windows(2)
                .map(|ab| segment_distance(p, ab[0], ab[1]))
                .fold(f64::INFINITY, f64::min);
            gap - reach - self.radius > margin + speed * period
        })
    }
}

/// Distance from `p` to the segment `a`–`b`.
fn segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let u = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] - a[0] - u * dx).hypot(p[1] - a[1] - u * dy)
}

/// One object class as the filter models it.
#[derive(Debug, Clone)]
pub(super) struct ClassModel {
    /// Its name.
    pub(super) name: String,
    /// Its unknowns' names and ranges.
    pub(super) unknowns: Vec<String>,
    pub(super) ranges: Vec<[f64; 2]>,
    pub(super) pose: PoseObjects,
    pub(super) whiskers: Vec<WhiskerModel>,
}

/// How the filter runs: the same for every class.
#[derive(Debug, Clone)]
pub(super) struct Settings {
    pub(super) particles: usize,
    pub(super) stepper: Stepper,
    /// Steps of `stepper` per sample period.
    pub(super) substeps: usize,
    pub(super) period: f64,
    /// The likelihood's standard deviation per channel, in the recorded units.
    pub(super) sigma: [f64; 5],
    /// Resample when the effective sample size falls below this share of the particles.
    pub(super) ess_fraction: f64,
}

/// The particles of one class: poses, and per whisker their chain states, whether they have
/// left rest, and their objects.
struct Cloud<'a> {
    class: &'a ClassModel,
    set: &'a Settings,
    theta: Vec<Vec<f64>>,
    /// `[whisker][particle]`.
    states: Vec<Vec<State>>,
    touched: Vec<Vec<bool>>,
    objects: Vec<Vec<Vec<Object>>>,
    alive: Vec<bool>,
    work: Vec<(LaneWorkspace, Workspace)>,
}

impl<'a> Cloud<'a> {
    fn new(class: &'a ClassModel, set: &'a Settings, theta: Vec<Vec<f64>>) -> Cloud<'a> {
        let n = theta.len();
        let mut c = Cloud {
            class,
            set,
            states: class
                .whiskers
                .iter()
                .map(|w| vec![w.at_rest.clone(); n])
                .collect(),
            touched: vec![vec![false; n]; class.whiskers.len()],
            objects: vec![Vec::new(); class.whiskers.len()],
            alive: vec![true; n],
            work: class
                .whiskers
                .iter()
                .map(|w| (LaneWorkspace::new(&w.model), Workspace::new(&w.model)))
                .collect(),
            theta,
        };
        c.place();
        c
    }

    /// Every particle's objects from its pose.
    fn place(&mut self) {
        let scenes: Vec<Vec<Object>> = self
            .theta
            .iter()
            .map(|p| self.class.pose.objects(p))
            .collect();
        for (w, wm) in self.class.whiskers.iter().enumerate() {
            self.objects[w] = scenes.iter().map(|s| wm.carry(s)).collect();
        }
    }

    /// Advances every living particle by one sample period, to time `t`. A particle whose
    /// objects are still clear of a whisker at rest leaves it at rest; one whose step fails dies.
    fn advance(&mut self, t: f64) {
        let set = self.set;
        let margin = 1e-3;
        for (w, wm) in self.class.whiskers.iter().enumerate() {
            let (lw, ws) = &mut self.work[w];
            let objects = &self.objects[w];
            let touched = &mut self.touched[w];
            let mut moving = Vec::new();
            for (i, s) in self.states[w].iter_mut().enumerate() {
                if !self.alive[i] {
                    continue;
                }
                if !touched[i] && wm.clear_of(&objects[i], t, margin, set.period) {
                    for _ in 0..set.substeps {
                        s.t += set.stepper.dt;
                    }
                } else {
                    touched[i] = true;
                    moving.push((i, s));
                }
            }
            for group in moving.chunks_mut(LANES) {
                let index: Vec<usize> = group.iter().map(|(i, _)| *i).collect();
                let objs: Vec<&[Object]> = index.iter().map(|&i| &objects[i][..]).collect();
                let mut states: Vec<&mut State> = group.iter_mut().map(|(_, s)| &mut **s).collect();
                let out = step_group_each(
                    &wm.model,
                    &set.stepper,
                    &mut states,
                    &objs,
                    Default::default(),
                    &|_| 0.0,
                    set.substeps,
                    lw,
                    ws,
                );
                for (k, &i) in index.iter().enumerate() {
                    if out[k].is_some() {
                        self.alive[i] = false;
                    }
                }
            }
        }
    }

    /// The log-likelihood of sample `k` of `obs` (`[whiskers][channels][samples]`) for particle
    /// `i`.
    fn log_likelihood(&self, i: usize, obs: &[Vec<Vec<f64>>], k: usize) -> f64 {
        if !self.alive[i] {
            return f64::NEG_INFINITY;
        }
        let mut ll = 0.0;
        for (w, wm) in self.class.whiskers.iter().enumerate() {
            let pred = if self.touched[w][i] {
                wm.recorded(&self.states[w][i])
            } else {
                wm.rest
            };
            for (c, p) in pred.iter().enumerate() {
                let y = obs[w][c][k];
                if y.is_finite() {
                    let z = (y - p) / self.set.sigma[c];
                    ll -= 0.5 * z * z;
                }
            }
        }
        if ll.is_finite() {
            ll
        } else {
            f64::NEG_INFINITY
        }
    }

    /// Keeps the particles `parents` name (in that order).
    fn resample(&mut self, parents: &[usize]) {
        self.theta = parents.iter().map(|&p| self.theta[p].clone()).collect();
        self.alive = parents.iter().map(|&p| self.alive[p]).collect();
        for w in 0..self.class.whiskers.len() {
            self.states[w] = parents.iter().map(|&p| self.states[w][p].clone()).collect();
            self.touched[w] = parents.iter().map(|&p| self.touched[w][p]).collect();
            self.objects[w] = parents
                .iter()
                .map(|&p| self.objects[w][p].clone())
                .collect();
        }
    }

    /// The mean and spread of each unknown over the cloud (equal weights), the spread floored
    /// at [`SPREAD_FLOOR`] of its range.
    fn spread(&self) -> Vec<(f64, f64)> {
        let n = self.theta.len() as f64;
        self.class
            .ranges
            .iter()
            .enumerate()
            .map(|(j, &[lo, hi])| {
                let mean = self.theta.iter().map(|p| p[j]).sum::<f64>() / n;
                let var = self
                    .theta
                    .iter()
                    .map(|p| (p[j] - mean).powi(2))
                    .sum::<f64>()
                    / n;
                (mean, var.sqrt().max(SPREAD_FLOOR * (hi - lo)))
            })
            .collect()
    }

    /// A random-walk proposal around `p` with steps `step` per unknown, or `None` if it leaves
    /// the class's ranges (the prior is uniform over them, so such a move is refused).
    fn propose(&self, p: &[f64], step: &[f64], rng: &mut Rng) -> Option<Vec<f64>> {
        let q: Vec<f64> = p
            .iter()
            .zip(step)
            .map(|(x, s)| x + s * rng.normal())
            .collect();
        q.iter()
            .zip(&self.class.ranges)
            .all(|(x, [lo, hi])| (lo..=hi).contains(&x))
            .then_some(q)
    }

    /// The Liu–West move of the particles whose whiskers have left rest: each pose shrinks
    /// towards the cloud's mean by `LW_SHRINK` and is jittered with the cloud's spread times
    /// `√(1 − a²)`, reflected into the ranges; the whisker states stay (an approximation).
    fn jitter_touched(&mut self, rng: &mut Rng) {
        let a = LW_SHRINK;
        let stats = self.spread();
        let touched: Vec<usize> = (0..self.theta.len())
            .filter(|&i| self.touched.iter().any(|w| w[i]))
            .collect();
        for (j, (&[lo, hi], &(mean, sd))) in self.class.ranges.iter().zip(&stats).enumerate() {
            let h = (1.0 - a * a).sqrt() * sd;
            for &i in &touched {
                let x = a * self.theta[i][j] + (1.0 - a) * mean + h * rng.normal();
                let y = if x < lo {
                    2.0 * lo - x
                } else if x > hi {
                    2.0 * hi - x
                } else {
                    x
                };
                self.theta[i][j] = y.clamp(lo, hi);
            }
        }
        self.place();
    }

    /// Moves every particle none of whose whiskers has left rest by time `t` to a new pose
    /// whose objects are still clear of every whisker: its whiskers' history (at rest) and so
    /// its weight are the same under either pose, so the move keeps the posterior exactly.
    fn move_waiting(&mut self, t: f64, step: &[f64], rng: &mut Rng) {
        for i in 0..self.theta.len() {
            if !self.alive[i] || self.touched.iter().any(|w| w[i]) {
                continue;
            }
            let Some(q) = self.propose(&self.theta[i], step, rng) else {
                continue;
            };
            let scene = self.class.pose.objects(&q);
            let carried: Vec<Vec<Object>> = self
                .class
                .whiskers
                .iter()
                .map(|w| w.carry(&scene))
                .collect();
            let clear = self
                .class
                .whiskers
                .iter()
                .zip(&carried)
                .all(|(w, o)| w.clear_of(o, t, 1e-3, self.set.period));
            if clear {
                self.theta[i] = q;
                for (w, o) in carried.into_iter().enumerate() {
                    self.objects[w][i] = o;
                }
            }
        }
    }
}

/// What the filter of one class made of one recording.
#[derive(Debug, Clone)]
pub(super) struct ClassRun {
    /// The log marginal likelihood of the recording up to and including each sample.
    pub(super) log_z: Vec<f64>,
    /// The posterior mean and standard deviation of each unknown at the last sample.
    pub(super) mean: Vec<f64>,
    pub(super) std: Vec<f64>,
}

/// Runs the filter of `class` over `obs` (`[whiskers][channels][samples]`, sampled every
/// `set.period` from t = 0), its particles drawn evenly over the class's ranges and its streams
/// seeded by `seed`.
pub(super) fn filter(
    class: &ClassModel,
    set: &Settings,
    obs: &[Vec<Vec<f64>>],
    seed: u64,
) -> Result<ClassRun> {
    let samples = obs.first().and_then(|w| w.first()).map_or(0, Vec::len);
    let n = set.particles;
    let mut rng = Rng::stream(seed, 0x7066);
    let theta: Vec<Vec<f64>> = (0..n)
        .map(|_| {
            class
                .ranges
                .iter()
                .map(|[lo, hi]| lo + (hi - lo) * rng.uniform())
                .collect()
        })
        .collect();
    let mut cloud = Cloud::new(class, set, theta);
    let mut logw = vec![-(n as f64).ln(); n];
    let mut log_z = Vec::with_capacity(samples);
    let mut total = 0.0;
    let d = class.ranges.len();
    for k in 0..samples {
        if k > 0 {
            cloud.advance(k as f64 * set.period);
        }
        for (i, lw) in logw.iter_mut().enumerate() {
            *lw += cloud.log_likelihood(i, obs, k);
        }
        let norm = log_sum_exp(&logw);
        if !norm.is_finite() {
            // Every particle died or none explains the sample at all: the class cannot have
            // made the recording.
            log_z.resize(samples, f64::NEG_INFINITY);
            return Ok(ClassRun {
                log_z,
                mean: vec![f64::NAN; class.ranges.len()],
                std: vec![f64::NAN; class.ranges.len()],
            });
        }
        total += norm;
        log_z.push(total);
        for lw in &mut logw {
            *lw -= norm;
        }
        let w: Vec<f64> = logw.iter().map(|l| l.exp()).collect();
        let ess = 1.0 / w.iter().map(|x| x * x).sum::<f64>();
        if k + 1 < samples && ess < set.ess_fraction * n as f64 {
            let parents = systematic(&w, rng.uniform());
            cloud.resample(&parents);
            logw.fill(-(n as f64).ln());
            // Random-walk steps of 2.38/√d times the cloud's spread in each unknown.
            let step: Vec<f64> = cloud
                .spread()
                .iter()
                .map(|(_, s)| 2.38 / (d as f64).sqrt() * s)
                .collect();
            cloud.move_waiting(k as f64 * set.period, &step, &mut rng);
            cloud.jitter_touched(&mut rng);
        }
    }
    let w: Vec<f64> = logw.iter().map(|l| l.exp()).collect();
    let mean: Vec<f64> = (0..d)
        .map(|j| cloud.theta.iter().zip(&w).map(|(p, w)| w * p[j]).sum())
        .collect();
    let std: Vec<f64> = (0..d)
        .map(|j| {
            cloud
                .theta
                .iter()
                .zip(&w)
                .map(|(p, w)| w * (p[j] - mean[j]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .collect();
    Ok(ClassRun { log_z, mean, std })
}

/// What `class`'s model records at the pose `p` over `samples` samples, `[whiskers][samples]`
/// (no noise): the filter's transition run once, for measuring its error.
pub(super) fn replay(
    class: &ClassModel,
    set: &Settings,
    p: &[f64],
    samples: usize,
) -> Result<Vec<Vec<[f64; 5]>>> {
    let one = Settings {
        particles: 1,
        ..set.clone()
    };
    let mut cloud = Cloud::new(class, &one, vec![p.to_vec()]);
    let mut out = vec![Vec::with_capacity(samples); class.whiskers.len()];
    for k in 0..samples {
        if k > 0 {
            cloud.advance(k as f64 * set.period);
        }
        if !cloud.alive[0] {
            return Err(Error::Observation(format!(
                "the filter's model of class `{}` failed at sample {k}",
                class.name
            )));
        }
        for (w, wm) in class.whiskers.iter().enumerate() {
            out[w].push(if cloud.touched[w][0] {
                wm.recorded(&cloud.states[w][0])
            } else {
                wm.rest
            });
        }
    }
    Ok(out)
}

/// `ln Σ exp(x)`, `-inf` for none finite.
fn log_sum_exp(x: &[f64]) -> f64 {
    let m = x.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    if !m.is_finite() {
        return f64::NEG_INFINITY;
    }
    m + x.iter().map(|v| (v - m).exp()).sum::<f64>().ln()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_to_a_segment_is_to_its_nearest_point() {
        assert!((segment_distance([0.5, 1.0], [0.0, 0.0], [1.0, 0.0]) - 1.0).abs() < 1e-15);
        assert!((segment_distance([2.0, 0.0], [0.0, 0.0], [1.0, 0.0]) - 1.0).abs() < 1e-15);
    }
}
