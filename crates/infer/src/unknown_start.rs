//! Estimators on recordings that do not start at the approach: each evaluated run of an
//! experiment recorded from a random moment up to `max_delay` before its t = 0, so that the start
//! of the approach `t0` is a further unknown (`vibrissa experiment --max-delay`). The particle
//! filter carries `t0` as an unknown; the other methods read the recordings as `vibrissa
//! estimate --max-delay` does, aligned at the contact's onset ([`crate::methods::Aligned`]).

use crate::error::{Error, Result};
use crate::evaluate::{experiment_noise, training_for};
use crate::experiment::Noise;
use crate::experiment::Variant;
use crate::family::Family;
use crate::method::{Estimate, Method};
use crate::pf::{Pf, TransitionModel};
use crate::recording::Recording;
use crate::trained::Trained;
use serde::Serialize;
use std::time::Instant;
use vibrissa_core::rng::Rng;

/// Stream of the runs' delays (apart from every other stream of `seed`).
const STREAM_DELAY: u64 = 0xde1a_0000;

/// One delayed run and the filter's estimate.
#[derive(Debug, Clone, Serialize)]
pub struct DelayedRun {
    /// True values of the unknowns, in the order of [`StartEvaluation::unknowns`].
    pub truth: Vec<f64>,
    /// The filter's estimates, same order.
    pub estimate: Vec<Estimate>,
}

/// A method other than the filter scored on the delayed recordings, each cut to the
/// experiment's own length (so a recording that starts `delay` early ends `delay` before the
/// experiment's run does).
#[derive(Debug, Clone, Serialize)]
pub struct MethodStart {
    /// The method's name.
    pub name: String,
    /// Mean absolute error per unknown of the experiment (without `t0`), SI.
    pub mae: Vec<f64>,
    /// Share of runs whose 90% interval holds the truth, per unknown.
    pub coverage: Vec<f64>,
    /// Wall time of its training, s.
    pub train_seconds: f64,
    /// Mean wall time of one estimate, s.
    pub estimate_seconds: f64,
}

/// Estimators scored on delayed recordings of an experiment's evaluated runs.
#[derive(Debug, Clone, Serialize)]
pub struct StartEvaluation {
    /// The family: a built-in's name or a scenario file's path.
    pub family: String,
    /// The variant the recordings were made in (the filter is not told it).
    pub variant: Variant,
    /// The noise the filter was given: estimated from the recordings (see
    /// [`crate::evaluate::estimated_noise`]).
    pub estimated_noise: Noise,
    /// Seed of the runs, their delays and the filter.
    pub seed: u64,
    /// Particles of the filter.
    pub particles: usize,
    /// The filter's transition model.
    pub model: TransitionModel,
    /// Largest delay of a recording's start, s.
    pub max_delay: f64,
    /// Names of the unknowns: the experiment's, then `t0`.
    pub unknowns: Vec<String>,
    /// Mean absolute error per unknown, SI.
    pub mae: Vec<f64>,
    /// Share of runs whose 90% interval holds the truth, per unknown.
    pub coverage: Vec<f64>,
    /// Seconds of data filtered.
    pub data_seconds: f64,
    /// Wall time of the filtering, s.
    pub filter_seconds: f64,
    /// Every run.
    pub runs: Vec<DelayedRun>,
    /// The other methods scored, in the order asked for.
    pub methods: Vec<MethodStart>,
}

impl StartEvaluation {
    /// Simulated seconds of data filtered per wall second.
    pub fn real_time_factor(&self) -> f64 {
        self.data_seconds / self.filter_seconds
    }
}

/// Scores the particle filter with `particles` particles on `experiment`'s evaluated runs in
/// `variant`, each recorded from a whole number of milliseconds drawn uniformly from
/// `[0, max_delay]` before the run's t = 0; the filter's prior on `t0` is `[0, max_delay]`.
/// `model` is the filter's transition model. The methods named in `methods` are scored on the
/// same recordings, cut to the experiment's length, read with a lead-in of up to `max_delay`
/// (see [`MethodStart`]). `progress(stage, done, total)` reports.
#[allow(clippy::too_many_arguments)]
pub fn evaluate_unknown_start(
    family: &Family,
    variant: Variant,
    seed: u64,
    particles: usize,
    model: TransitionModel,
    max_delay: f64,
    methods: &[&str],
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<StartEvaluation> {
    if particles == 0 {
        return Err(Error::Setting(
            "particles: expected at least 1 particle".into(),
        ));
    }
    if !(max_delay.is_finite() && max_delay > 0.0 && max_delay <= 1.0) {
        return Err(Error::Setting(format!(
            "max_delay: expected a delay in (0, 1] s, got {max_delay}"
        )));
    }
    if variant == Variant::Noisy {
        progress("noise levels", 0, 1);
    }
    let noise = family.noise(variant)?;
    let params: Vec<Vec<f64>> = family
        .grid()
        .into_iter()
        .filter(|p| !family.is_template(p))
        .collect();
    let mut rng = Rng::stream(seed, STREAM_DELAY);
    let rate = family.sample_rate();
    let steps = (max_delay * rate).floor();
    let delays: Vec<f64> = params
        .iter()
        .map(|_| (rng.uniform() * (steps + 1.0)).floor().min(steps) / rate)
        .collect();
    // The recordings, then the filter with the noise it measures on them.
    progress("recordings", 0, params.len());
    let samples = params
        .iter()
        .zip(&delays)
        .enumerate()
        .map(|(k, (p, &delay))| {
            let run_seed = Rng::stream(seed, 7000 + k as u64).next_u64();
            family.simulate_delayed(p, delay, &noise, run_seed)
        })
        .collect::<Result<Vec<_>>>()?;
    progress("recordings", params.len(), params.len());
    let recordings: Vec<&[Vec<f64>]> = samples.iter().map(|s| &s.series[..]).collect();
    let estimated_noise = experiment_noise(family, &recordings, &noise)?;
    // The methods train on runs with the random forces, as the scenario states them.
    let stated = family.with_process_noise(estimated_noise.process);
    let mut filter = Pf::new(particles);
    filter.set_model(model);
    filter.seed = seed;
    filter.max_delay = max_delay;
    let training = training_for(family, &estimated_noise, &filter, seed)?;
    filter.fit(&training)?;

    let unknowns: Vec<String> = family
        .unknowns()
        .iter()
        .map(|u| u.to_string())
        .chain(std::iter::once("t0".to_string()))
        .collect();
    let mut runs = Vec::with_capacity(params.len());
    let (mut data_seconds, mut filter_seconds) = (0.0, 0.0);
    progress("filter", 0, params.len());
    for (k, ((p, &delay), sample)) in params.iter().zip(&delays).zip(&samples).enumerate() {
        let start = Instant::now();
        let post = filter.posterior(&sample.series)?;
        filter_seconds += start.elapsed().as_secs_f64();
        let estimate = unknowns
            .iter()
            .map(|u| {
                post.unknowns
                    .iter()
                    .position(|name| name == u)
                    .map(|i| post.last()[i])
                    .ok_or_else(|| Error::Setting(format!("the filter does not estimate {u}")))
            })
            .collect::<Result<Vec<_>>>()?;
        data_seconds += (sample.series[0].len() - 1) as f64 / rate;
        let mut truth = p.clone();
        truth.push(delay);
        runs.push(DelayedRun { truth, estimate });
        progress("filter", k + 1, params.len());
    }
    let cut: Vec<Recording> = samples
        .iter()
        .map(|s| cut_to(family, &s.series))
        .collect::<Result<_>>()?;
    let lead = (max_delay * rate - 1e-9).ceil() as usize;
    let mut scored = Vec::with_capacity(methods.len());
    for (k, name) in methods.iter().enumerate() {
        progress("methods", k, methods.len());
        scored.push(score_method(
            &stated,
            name,
            &cut,
            &params,
            &estimated_noise.sensor,
            lead,
            seed,
        )?);
    }
    progress("methods", methods.len(), methods.len());
    let n = runs.len() as f64;
    let mae = (0..unknowns.len())
        .map(|u| {
            runs.iter()
                .map(|r| (r.estimate[u].mean - r.truth[u]).abs())
                .sum::<f64>()
                / n
        })
        .collect();
    let coverage = (0..unknowns.len())
        .map(|u| {
            runs.iter()
                .filter(|r| r.estimate[u].covers(r.truth[u]))
                .count() as f64
                / n
        })
        .collect();
    Ok(StartEvaluation {
        family: family.name().to_string(),
        variant,
        estimated_noise,
        seed,
        particles,
        model,
        max_delay,
        unknowns,
        mae,
        coverage,
        data_seconds,
        filter_seconds,
        runs,
        methods: scored,
    })
}

/// The first `family.samples()` samples of the delayed series `series`, as a recording.
fn cut_to(family: &Family, series: &[Vec<f64>]) -> Result<Recording> {
    let (n, rate) = (family.samples(), family.sample_rate());
    if series.iter().any(|c| c.len() < n) {
        return Err(Error::Setting(format!(
            "a delayed run holds fewer than the experiment's {n} samples"
        )));
    }
    Ok(Recording {
        t: (0..n).map(|k| k as f64 / rate).collect(),
        values: series.iter().map(|c| c[..n].to_vec()).collect(),
        rate,
        segments: None,
    })
}

/// `name` trained on `family` for a lead-in of up to `lead` samples and scored on `recordings`
/// (true values `params`).
fn score_method(
    family: &Family,
    name: &str,
    recordings: &[Recording],
    params: &[Vec<f64>],
    noise: &[f64; 5],
    lead: usize,
    seed: u64,
) -> Result<MethodStart> {
    if name == "pf" {
        return Err(Error::Setting(
            "methods: the particle filter is scored with its particles, not as a method".into(),
        ));
    }
    let mut trained = Trained::default();
    let names: Vec<String> = (0..recordings.len()).map(|k| format!("run {k}")).collect();
    let estimates = crate::batch::estimate_each(
        family,
        &names,
        recordings,
        &vec![*noise; recordings.len()],
        &vec![lead; recordings.len()],
        name,
        seed,
        &mut trained,
        &mut |_| {},
    )?;
    let estimate_seconds: f64 = estimates.iter().map(|(_, s)| s).sum();
    let unknowns = family.unknowns().len();
    let n = recordings.len().max(1) as f64;
    let per = |f: &dyn Fn(&Estimate, f64) -> f64| -> Vec<f64> {
        (0..unknowns)
            .map(|u| {
                estimates
                    .iter()
                    .zip(params)
                    .map(|((e, _), p)| f(&e[u], p[u]))
                    .sum::<f64>()
                    / n
            })
            .collect()
    };
    Ok(MethodStart {
        name: name.to_string(),
        mae: per(&|e, truth| (e.mean - truth).abs()),
        coverage: per(&|e, truth| f64::from(u8::from(e.covers(truth)))),
        train_seconds: trained.seconds,
        estimate_seconds: estimate_seconds / n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_settings_are_refused_by_name() {
        let none = |_: &str, _: usize, _: usize| {};
        let e = evaluate_unknown_start(
            &Family::builtin("e2").unwrap(),
            Variant::Clean,
            1,
            0,
            TransitionModel::Coarse,
            0.05,
            &[],
            &none,
        );
        assert!(e.unwrap_err().to_string().contains("particles"));
        for bad in [0.0, -0.01, f64::NAN, 2.0] {
            let e = evaluate_unknown_start(
                &Family::builtin("e2").unwrap(),
                Variant::Clean,
                1,
                10,
                TransitionModel::Coarse,
                bad,
                &[],
                &none,
            );
            assert!(e.unwrap_err().to_string().contains("max_delay"), "{bad}");
        }
    }

    #[test]
    fn the_methods_are_told_the_experiment_s_random_forces() {
        let none = |_: &str, _: usize, _: usize| {};
        let e1 = Family::builtin("e1").unwrap();
        let ev = evaluate_unknown_start(
            &e1,
            Variant::Noisy,
            1,
            10,
            TransitionModel::Coarse,
            0.01,
            &["knn"],
            &none,
        )
        .unwrap();
        assert_eq!(ev.estimated_noise.process, crate::experiment::PROCESS_NOISE);
        assert_eq!(ev.methods.len(), 1);
        assert_eq!(ev.methods[0].name, "knn");
        let stated = e1.with_process_noise(ev.estimated_noise.process);
        assert_eq!(
            stated.training_noise([0.0; 5]).process,
            crate::experiment::PROCESS_NOISE
        );
    }

    #[test]
    fn the_filter_is_not_scored_as_a_method_and_short_runs_are_refused() {
        let e1 = Family::builtin("e1").unwrap();
        let rec = cut_to(&e1, &vec![vec![0.0; e1.samples()]; 5]).unwrap();
        assert_eq!(rec.t.len(), e1.samples());
        let e = score_method(&e1, "pf", &[rec], &[vec![0.02]], &[1e-3; 5], 10, 1);
        assert!(e.unwrap_err().to_string().contains("particle filter"));
        let short = cut_to(&e1, &vec![vec![0.0; e1.samples() - 1]; 5]);
        assert!(short.unwrap_err().to_string().contains("fewer"));
    }
}
