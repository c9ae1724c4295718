//! A whole experiment: simulate the grid and the training runs, fit every method on the data its
//! budget allows, estimate every evaluated run, and score.

use crate::error::Result;
use crate::experiment::{Noise, Sample, Variant, CHANNELS, THETA12};
use crate::family::Family;
use crate::method::{Budget, Estimate, Method, Training};
use crate::methods::{self, Interp, Template};
use rayon::prelude::*;
use serde::Serialize;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;
use vibrissa_core::rng::Rng;

/// Random training runs of the free-budget methods: 150 for one unknown, 400 for two, and 200
/// more per further unknown; a randomised family ([`Family::randomised`]) has
/// [`crate::randomise::Randomisation::runs`] times as many, since its runs also spread over the
/// whiskers of the prior.
pub fn random_runs(family: &Family) -> usize {
    let n = match family.unknowns().len() {
        0 | 1 => 150,
        n => 400 + 200 * (n - 2),
    };
    n * family.randomisation().map_or(1, |p| p.runs)
}

/// The seed paper's mean absolute errors for its experiments, SI (empty for other families).
pub fn paper_errors(family: &Family) -> Vec<f64> {
    match family.name() {
        "e1" => vec![1.2e-3],
        "e2" => vec![2.0e-3, 0.28],
        _ => Vec::new(),
    }
}

/// `n` draws uniform in the family's ranges widened by their margins (runs just outside the
/// range keep a regression's estimates at the range's edges from being pulled inward; they are
/// clipped back to the range) but outside the ranges themselves (the band around them), so
/// never on the evaluated grid.
pub fn edge_params(family: &Family, n: usize, seed: u64) -> Vec<Vec<f64>> {
    let ranges = family.ranges();
    let wide: Vec<[f64; 2]> = ranges
        .iter()
        .zip(family.margins())
        .map(|([lo, hi], [below, above])| [lo - below, hi + above])
        .collect();
    let mut rng = Rng::stream(seed, 0x6564_6765);
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let p: Vec<f64> = wide
            .iter()
            .map(|[lo, hi]| lo + (hi - lo) * rng.uniform())
            .collect();
        let inside = p
            .iter()
            .zip(&ranges)
            .all(|(x, [lo, hi])| (*lo..=*hi).contains(x));
        if !inside {
            out.push(p);
        }
    }
    out
}

/// Edge runs of the kernel regressions: as many as give the band around the range the density
/// of the [`random_runs`] inside it.
pub fn edge_runs(family: &Family) -> usize {
    let (mut inner, mut outer) = (1.0, 1.0);
    for ([lo, hi], [below, above]) in family.ranges().iter().zip(family.margins()) {
        inner *= hi - lo;
        outer *= hi - lo + below + above;
    }
    (random_runs(family) as f64 * (outer - inner) / inner).round() as usize
}

/// One evaluated run: truth and estimate.
#[derive(Debug, Clone, Serialize)]
pub struct Prediction {
    /// True unknowns, SI.
    pub truth: Vec<f64>,
    /// Estimates per unknown.
    pub estimate: Vec<Estimate>,
}

/// One method's scores.
#[derive(Debug, Clone, Serialize)]
pub struct MethodResult {
    /// Name.
    pub name: String,
    /// Budget.
    pub budget: Budget,
    /// Mean absolute error per unknown, SI.
    pub mae: Vec<f64>,
    /// Fraction of evaluated runs whose 90% interval holds the truth, per unknown.
    pub coverage: Vec<f64>,
    /// Runs it was fitted on (not counting calibration runs).
    pub training_runs: usize,
    /// Seconds to simulate its training runs (0 for the templates, which are grid runs).
    pub simulate_seconds: f64,
    /// Seconds to fit.
    pub fit_seconds: f64,
    /// Seconds to estimate one series: the wall time of estimating every evaluated run (side by
    /// side on all cores) over their number.
    pub predict_seconds: f64,
    /// Fitted settings.
    pub settings: Vec<(String, f64)>,
    /// Per evaluated run, in grid order.
    pub predictions: Vec<Prediction>,
}

/// A whole experiment's results.
#[derive(Debug, Clone, Serialize)]
pub struct Evaluation {
    /// The family: a built-in's name or a scenario file's path.
    pub family: String,
    /// The variant.
    pub variant: Variant,
    /// Seed of all randomness.
    pub seed: u64,
    /// Noise of the variant: what the recordings (the grid's runs) were made with. No
    /// estimator is told it.
    pub noise: Noise,
    /// The noise the estimators were given: the sensor noise estimated from the grid's
    /// recordings, pooled and quantised ([`crate::noise`]; channels the scenario states as
    /// stated), and the scenario's own process noise. Simulated training runs carry it.
    pub estimated_noise: Noise,
    /// Unknowns' names.
    pub unknowns: Vec<String>,
    /// The paper's mean absolute errors, SI.
    pub paper_mae: Vec<f64>,
    /// Grid parameters `[runs][unknowns]`.
    pub grid: Vec<Vec<f64>>,
    /// Ranges of the unknowns, `[unknowns][lo, hi]`.
    pub ranges: Vec<[f64; 2]>,
    /// Which grid runs are templates.
    pub is_template: Vec<bool>,
    /// theta12 of every grid run, rad: `[runs][samples]`.
    pub theta12: Vec<Vec<f64>>,
    /// Template parameters `[templates][unknowns]`.
    pub template_params: Vec<Vec<f64>>,
    /// The template method's responsibilities for every grid run, `[runs][templates]`.
    pub responsibilities: Vec<Vec<f64>>,
    /// The template method's σ², rad².
    pub sigma2: f64,
    /// Seconds to compute the noise levels and simulate the grid.
    pub grid_seconds: f64,
    /// Wall time of the whole evaluation, s.
    pub seconds: f64,
    /// Per method.
    pub methods: Vec<MethodResult>,
}

impl Evaluation {
    /// The paper-budget and free-budget methods with the least mean absolute error (summed over
    /// unknowns in fractions of their ranges).
    pub fn best(&self, budget: Budget) -> Option<&MethodResult> {
        let ranges = &self.ranges;
        let score = |m: &MethodResult| -> f64 {
            m.mae
                .iter()
                .zip(ranges)
                .map(|(e, r)| e / (r[1] - r[0]))
                .sum()
        };
        self.methods
            .iter()
            .filter(|m| m.budget == budget)
            .min_by(|a, b| score(a).total_cmp(&score(b)))
    }
}

/// Runs the experiment of `family` in `variant`, seeded by `seed`, without the particle filter;
/// `progress(stage, done, total)` reports.
pub fn evaluate(
    family: &Family,
    variant: Variant,
    seed: u64,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<Evaluation> {
    evaluate_with(
        family,
        variant,
        seed,
        0,
        crate::pf::TransitionModel::Coarse,
        progress,
    )
}

/// [`evaluate`], with the particle filter `pf` in the table when `pf_particles > 0`, on the
/// transition model `pf_model`.
pub fn evaluate_with(
    family: &Family,
    variant: Variant,
    seed: u64,
    pf_particles: usize,
    pf_model: crate::pf::TransitionModel,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<Evaluation> {
    let start = Instant::now();
    let stage = |name: &'static str, total: usize| {
        let done = AtomicUsize::new(0);
        progress(name, 0, total);
        move || {
            let k = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress(name, k, total);
        }
    };

    // Noise levels (from the clean reference runs) and the family's grid: the recordings.
    if variant == Variant::Noisy {
        progress("noise levels", 0, 1);
    }
    let noise = family.noise(variant)?;
    let grid = family.grid();
    let grid_runs = family.simulate_all(&grid, &noise, seed, &stage("grid", grid.len()))?;
    let grid_seconds = start.elapsed().as_secs_f64();
    let recordings: Vec<&[Vec<f64>]> = grid_runs.iter().map(|s| &s.series[..]).collect();
    let estimated_noise = experiment_noise(family, &recordings, &noise)?;
    let is_template: Vec<bool> = grid.iter().map(|p| family.is_template(p)).collect();
    let mut templates: Vec<Sample> = grid_runs
        .iter()
        .zip(&is_template)
        .filter(|(_, t)| **t)
        .map(|(s, _)| s.clone())
        .collect();
    // Training runs carry the scenario's random forces and the sensor noise that the measured
    // level leaves beyond their response (see `Family::training_sensor_noise`).
    let simulated_noise = family.training_sensor_noise(&estimated_noise)?;
    // Templates that the grid does not hold are simulated on their own.
    let template_p = family.templates();
    if templates.len() != template_p.len() {
        templates =
            family.simulate_all(&template_p, &simulated_noise, seed.wrapping_add(4), &|| {})?;
    }
    let evaluated: Vec<&Sample> = grid_runs
        .iter()
        .zip(&is_template)
        .filter(|(_, t)| !**t)
        .map(|(s, _)| s)
        .collect();

    // Free-budget training runs: random draws, and the emulator's grid.
    let t0 = Instant::now();
    let random_p = family.random_params(random_runs(family), seed ^ 0x5eed);
    let random = family.simulate_all(
        &random_p,
        &simulated_noise,
        seed.wrapping_add(1),
        &stage("training runs", random_p.len()),
    )?;
    let random_seconds = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let design = Interp::design(family);
    let dense = family.simulate_all(
        &design,
        &simulated_noise,
        seed.wrapping_add(2),
        &stage("emulator grid", design.len()),
    )?;
    let dense_seconds = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let edge_p = edge_params(family, edge_runs(family), seed ^ 0xed9e);
    let edge = family.simulate_all(
        &edge_p,
        &simulated_noise,
        seed.wrapping_add(3),
        &stage("edge runs", edge_p.len()),
    )?;
    let edge_seconds = t0.elapsed().as_secs_f64();

    let paper = Training {
        family: family.clone(),
        samples: templates,
        calibration: Vec::new(),
        noise: estimated_noise,
    };
    let free_random = Training {
        family: family.clone(),
        samples: random.clone(),
        calibration: Vec::new(),
        noise: estimated_noise,
    };
    // Kernel ridge regression learns from all three sets (the grid covers the range's edges,
    // the edge runs the band just outside it).
    let free_pooled = Training {
        family: family.clone(),
        samples: random.iter().chain(&dense).chain(&edge).cloned().collect(),
        calibration: Vec::new(),
        noise: estimated_noise,
    };
    let free_dense = Training {
        family: family.clone(),
        samples: dense,
        calibration: random,
        noise: estimated_noise,
    };

    // The template method, kept concrete for its responsibilities.
    let mut template = Template::new();
    template.fit(&paper)?;
    let responsibilities = grid_runs
        .iter()
        .map(|s| template.responsibilities(&s.series))
        .collect::<Result<Vec<_>>>()?;

    let mut results = Vec::new();
    let all: Vec<Box<dyn Method>> = methods::all()
        .into_iter()
        .filter_map(|m| match m.name() {
            "pf" if pf_particles == 0 => None,
            "pf" => {
                let mut pf = crate::pf::Pf::new(pf_particles);
                pf.set_model(pf_model);
                pf.seed = seed;
                Some(Box::new(pf) as Box<dyn Method>)
            }
            _ => Some(m),
        })
        .collect();
    let total = all.len();
    for (n, mut m) in all.into_iter().enumerate() {
        progress("methods", n, total);
        let (training, sim_s) = match (m.budget(), m.name()) {
            (Budget::Paper, _) => (&paper, 0.0),
            (Budget::Free, "emulator") => (&free_dense, dense_seconds),
            (Budget::Free, "krr" | "krr-local" | "krr-invariant") => {
                (&free_pooled, random_seconds + dense_seconds + edge_seconds)
            }
            (Budget::Free, _) => (&free_random, random_seconds),
        };
        let t0 = Instant::now();
        m.fit(training)?;
        let fit_seconds = t0.elapsed().as_secs_f64();
        let t0 = Instant::now();
        // The evaluated runs side by side on every core (each estimate is deterministic and
        // independent of the others, so the scores do not depend on the order or the threads).
        let predictions = evaluated
            .par_iter()
            .map(|s| {
                Ok(Prediction {
                    truth: s.params.clone(),
                    estimate: m.predict(&s.series)?,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let predict_seconds = t0.elapsed().as_secs_f64() / evaluated.len() as f64;
        results.push(score(
            m.as_ref(),
            training,
            sim_s,
            fit_seconds,
            predict_seconds,
            predictions,
        ));
    }
    progress("methods", total, total);

    Ok(Evaluation {
        family: family.name().to_string(),
        variant,
        seed,
        noise,
        estimated_noise,
        unknowns: family.unknowns().iter().map(|s| s.to_string()).collect(),
        paper_mae: paper_errors(family),
        ranges: family.ranges(),
        theta12: grid_runs
            .iter()
            .map(|s| s.series[THETA12].clone())
            .collect(),
        grid,
        is_template,
        template_params: template.template_params().to_vec(),
        responsibilities,
        sigma2: template.sigma2(),
        grid_seconds,
        seconds: start.elapsed().as_secs_f64(),
        methods: results,
    })
}

/// Nominal levels of [`calibration`].
pub const CALIBRATION_LEVELS: [f64; 9] = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9];

/// Observed coverage of the central normal intervals `mean ± z·std` at every level of
/// [`CALIBRATION_LEVELS`], per unknown: `[unknowns][levels]`. A calibrated method lies on the
/// diagonal.
pub fn calibration(result: &MethodResult) -> Vec<Vec<f64>> {
    let unknowns = result.mae.len();
    let n = result.predictions.len().max(1) as f64;
    (0..unknowns)
        .map(|u| {
            CALIBRATION_LEVELS
                .iter()
                .map(|&p| {
                    let z = normal_quantile(0.5 + 0.5 * p);
                    result
                        .predictions
                        .iter()
                        .filter(|r| {
                            let e = r.estimate[u];
                            (r.truth[u] - e.mean).abs() <= z * e.std
                        })
                        .count() as f64
                        / n
                })
                .collect()
        })
        .collect()
}

/// Quantile of the standard normal distribution (Acklam's rational approximation, relative
/// error below 1.2e-9), for `p` in (0, 1).
pub(crate) fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < 0.02425 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.02425 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// Errors and coverage of one method's predictions.
fn score(
    m: &dyn Method,
    training: &Training,
    simulate_seconds: f64,
    fit_seconds: f64,
    predict_seconds: f64,
    predictions: Vec<Prediction>,
) -> MethodResult {
    let unknowns = training.family.unknowns().len();
    let n = predictions.len() as f64;
    let mae = (0..unknowns)
        .map(|u| {
            predictions
                .iter()
                .map(|p| (p.estimate[u].mean - p.truth[u]).abs())
                .sum::<f64>()
                / n
        })
        .collect();
    let coverage = (0..unknowns)
        .map(|u| {
            predictions
                .iter()
                .filter(|p| p.estimate[u].covers(p.truth[u]))
                .count() as f64
                / n
        })
        .collect();
    MethodResult {
        name: m.name().into(),
        budget: m.budget(),
        mae,
        coverage,
        training_runs: training.samples.len(),
        simulate_seconds,
        fit_seconds,
        predict_seconds,
        settings: m.settings(),
        predictions,
    }
}

/// The sensor noise of a batch of recordings of `family` (channel-major series), as the
/// estimators take it: every channel the scenario does not state estimated from all of them
/// pooled and quantised ([`crate::noise`]), with the scenario's process noise.
pub fn estimated_noise(family: &Family, recordings: &[&[Vec<f64>]]) -> Result<Noise> {
    let stated = family.stated_noise();
    let channels: Vec<usize> = (0..CHANNELS.len()).collect();
    let batch = crate::noise::estimate_pooled(
        recordings,
        &channels
            .iter()
            .copied()
            .filter(|&c| stated[c].is_none())
            .collect::<Vec<_>>(),
    )?;
    let sensor = std::array::from_fn(|c| stated[c].unwrap_or(crate::noise::quantise(batch[c])));
    Ok(family.training_noise(sensor))
}

/// What the estimators of an experiment know of its noise: the sensor noise they measure on its
/// recordings ([`estimated_noise`]), and the random forces of `made` (the noise the recordings
/// were made with), which are part of the experiment's world and stated as a scenario file's
/// `process_noise` would state them.
pub fn experiment_noise(
    family: &Family,
    recordings: &[&[Vec<f64>]],
    made: &Noise,
) -> Result<Noise> {
    let mut noise = estimated_noise(family, recordings)?;
    noise.process = noise.process.max(made.process);
    Ok(noise)
}

/// The training data that `method` may use in `family`, simulated afresh with `noise` (the
/// recordings' noise as estimated or stated: see [`Family::training_noise`]): the templates
/// under the paper's budget, the emulator's grid (calibrated on random runs), random runs
/// followed by the emulator's grid and the edge runs (`krr`, `krr-local`, `krr-invariant`) or random runs under
/// a free budget. The particle filter (`pf`) needs no runs: it takes the noise alone. With a
/// randomised family ([`Family::randomised`]) every run of a free budget has its own whisker and
/// sensor gains; the paper's templates are the scenario's own.
pub fn training_for(
    family: &Family,
    noise: &Noise,
    method: &dyn Method,
    seed: u64,
) -> Result<Training> {
    let noise = *noise;
    // The filter takes the measured noise as it is; training runs carry the random forces and
    // what the measured level leaves beyond their response.
    let simulated = if method.name() == "pf" {
        noise
    } else {
        family.training_sensor_noise(&noise)?
    };
    let none = || {};
    let training = |samples, calibration| Training {
        family: family.clone(),
        samples,
        calibration,
        noise,
    };
    Ok(match (method.budget(), method.name()) {
        (Budget::Paper, _) => {
            let p: Vec<Vec<f64>> = family
                .grid()
                .into_iter()
                .filter(|p| family.is_template(p))
                .collect();
            let p = if p.is_empty() { family.templates() } else { p };
            // Template methods compare with the scenario's own runs, never randomised ones.
            let nominal = family.nominal();
            training(
                nominal.simulate_all(&p, &simulated, seed, &none)?,
                Vec::new(),
            )
        }
        (Budget::Free, "pf") => training(Vec::new(), Vec::new()),
        (Budget::Free, name) => {
            let random_p = family.random_params(random_runs(family), seed ^ 0x5eed);
            let mut random =
                family.simulate_all(&random_p, &simulated, seed.wrapping_add(1), &none)?;
            if matches!(name, "krr" | "krr-local" | "krr-invariant") {
                let design = Interp::design(family);
                random.extend(family.simulate_all(
                    &design,
                    &simulated,
                    seed.wrapping_add(2),
                    &none,
                )?);
                let edge_p = edge_params(family, edge_runs(family), seed ^ 0xed9e);
                random.extend(family.simulate_all(
                    &edge_p,
                    &simulated,
                    seed.wrapping_add(3),
                    &none,
                )?);
                training(random, Vec::new())
            } else if name == "emulator" {
                let design = Interp::design(family);
                let dense =
                    family.simulate_all(&design, &simulated, seed.wrapping_add(2), &none)?;
                training(dense, random)
            } else {
                training(random, Vec::new())
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_quantiles_match_tables() {
        assert!((normal_quantile(0.95) - 1.644_853_627).abs() < 1e-8);
        assert!((normal_quantile(0.975) - 1.959_963_985).abs() < 1e-8);
        assert!(normal_quantile(0.5).abs() < 1e-12);
        assert!((normal_quantile(0.001) + 3.090_232_306).abs() < 1e-7);
    }

    #[test]
    fn edge_runs_lie_in_the_band_around_the_range() {
        for name in ["e1", "e2"] {
            let family = Family::builtin(name).unwrap();
            let n = edge_runs(&family);
            assert!(n > 0 && n < random_runs(&family));
            let ranges = family.ranges();
            for p in edge_params(&family, 300, 7) {
                let inside = p
                    .iter()
                    .zip(&ranges)
                    .all(|(x, [lo, hi])| (*lo..=*hi).contains(x));
                assert!(!inside, "{p:?} is inside the range");
                for ((x, [lo, hi]), [below, above]) in p.iter().zip(&ranges).zip(family.margins()) {
                    assert!(*x >= lo - below && *x <= hi + above, "{p:?}");
                }
            }
        }
        let e2 = Family::builtin("e2").unwrap();
        assert_eq!(edge_params(&e2, 5, 3), edge_params(&e2, 5, 3));
    }
}
