//! Scores the particle filter on many runs, with the options that `vibrissa experiment` does not
//! have: a recording that starts up to MAX_DELAY seconds early (t0 unknown), hypothesis injection
//! from `krr`, and a chosen tempering.
//!
//! ```sh
//! cargo run --release -p vibrissa-infer --example pf_evaluate -- SET PARTICLES TEMPER MAX_DELAY INJECT [VARIANT]
//! ```
//! - SET: `grid` (the 71 evaluated runs of `e2`), `train` (24 runs at random parameters, drawn
//!   apart from the grid) or `cal` (24 runs at d = 15.5, 18.5, …, 29.5 mm, off the grid, and
//!   v = 0.3, 0.75, 1.05, 1.5 m/s, reaching the range's edges; the tempering was chosen on it);
//! - PARTICLES, TEMPER (likelihood tempering; see `pf::temper_for`);
//! - MAX_DELAY: 0 for a known start, else each run's recording starts a random whole number of
//!   milliseconds in [0, MAX_DELAY] before the run's t = 0 and the filter's t0 is unknown on
//!   [0, 0.05 s];
//! - INJECT: share of the initial particles drawn around `krr`'s estimate (0: none);
//! - VARIANT: `noisy` (default) or `clean`: what the runs are made with; the filter's sensor
//!   noise is estimated from the set's runs, pooled, as `vibrissa experiment` does.
//!
//! Environment: `PF_SEED` (the filter's seed), `PF_MODEL` (`coarse` or `fine`), `PF_SEGMENTS`,
//! `PF_DT` (the coarse transition model), `PF_SHRINK` (Liu–West), `PF_ESS`
//! (resampling threshold) override the filter's defaults; `PF_ALL` set prints every run.
//!
//! Prints the runs whose error exceeds 0.5 mm or 0.03 m/s (with the least effective sample size
//! and the log evidence), the mean signed speed error per true
//! speed, then the mean absolute errors, the
//! coverage of the 90% intervals and the real-time factor (under whatever else the machine runs).

use std::sync::Arc;
use vibrissa_core::rng::Rng;
use vibrissa_infer::experiment::Variant;
use vibrissa_infer::pf::{Pf, TransitionModel};
use vibrissa_infer::Family;
use vibrissa_infer::{methods, Method, Training};

fn arg<T: std::str::FromStr>(args: &[String], k: usize, default: T) -> T {
    args.get(k).and_then(|s| s.parse().ok()).unwrap_or(default)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let set = args.get(1).cloned().unwrap_or_else(|| "train".into());
    let particles: usize = arg(&args, 2, 1000);
    let max_delay: f64 = arg(&args, 4, 0.0);
    let default_temper = vibrissa_infer::pf::temper_for(particles)
        * if max_delay > 0.0 {
            vibrissa_infer::pf::UNKNOWN_START_TEMPER
        } else {
            1.0
        };
    let temper: f64 = arg(&args, 3, default_temper);
    let inject: f64 = arg(&args, 5, 0.0);
    let variant = Variant::parse(args.get(6).map_or("noisy", |s| s.as_str()))?;
    let e = Family::builtin("e2")?;
    let noise = e.noise(variant)?;
    let params: Vec<[f64; 2]> = match set.as_str() {
        "train" => e
            .random_params(24, 4242)
            .into_iter()
            .map(|p| [p[0], p[1]])
            .collect(),
        "grid" => e
            .grid()
            .into_iter()
            .filter(|p| !e.is_template(p))
            .map(|p| [p[0], p[1]])
            .collect(),
        // Off the evaluated grid in d, reaching the range's edges in v.
        "cal" => [15.5, 18.5, 21.5, 24.5, 27.5, 29.5]
            .iter()
            .flat_map(|&d| [0.3, 0.75, 1.05, 1.5].map(|v| [d * 1e-3, v]))
            .collect(),
        other => return Err(format!("unknown set `{other}`: choose grid, train or cal").into()),
    };
    // The recordings, and the noise the filter measures on them.
    let mut rng = Rng::stream(77, 0);
    let recorded = params
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let delay = (rng.uniform() * max_delay * 1000.0).round() / 1000.0;
            e.simulate_delayed(p, delay, &noise, 5000 + k as u64)
                .map(|s| (delay, s))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let series: Vec<&[Vec<f64>]> = recorded.iter().map(|(_, s)| &s.series[..]).collect();
    let estimated = vibrissa_infer::evaluate::estimated_noise(&e, &series)?;
    // The injected method's training runs, as `vibrissa experiment` makes them.
    let train_p = e.random_params(400, 1 ^ 0x5eed);
    let training = Training {
        family: e.clone(),
        samples: if inject > 0.0 {
            e.simulate_all(&train_p, &estimated, 2, &|| {})?
        } else {
            Vec::new()
        },
        calibration: vec![],
        noise: estimated,
    };
    let mut pf = Pf::new(particles);
    pf.max_delay = if max_delay > 0.0 { 0.05 } else { 0.0 };
    let model = TransitionModel::from_name(&std::env::var("PF_MODEL").unwrap_or("coarse".into()))?;
    pf.set_model(model);
    // TEMPER is the tempering used, also with an unknown start (the fine model's default is
    // FINE_TEMPER whatever the start).
    pf.temper = match (model, args.get(3)) {
        (TransitionModel::Fine, None) => vibrissa_infer::pf::FINE_TEMPER,
        (TransitionModel::Fine, Some(_)) => temper,
        (TransitionModel::Coarse, _) if max_delay > 0.0 => {
            temper / vibrissa_infer::pf::UNKNOWN_START_TEMPER
        }
        (TransitionModel::Coarse, _) => temper,
    };
    if inject > 0.0 {
        let m: Arc<dyn Method> = Arc::from(methods::by_name("krr")?);
        pf.inject = Some((inject, m));
    }
    if let Ok(n) = std::env::var("PF_SEGMENTS") {
        pf.segments = Some(n.parse()?);
    }
    if let Ok(seed) = std::env::var("PF_SEED") {
        pf.seed = seed.parse()?;
    }
    if let Ok(a) = std::env::var("PF_SHRINK") {
        pf.shrink = a.parse()?;
    }
    if let Ok(f) = std::env::var("PF_ESS") {
        pf.ess_fraction = f.parse()?;
    }
    if let Ok(dt) = std::env::var("PF_DT") {
        pf.dt = dt.parse()?;
    }
    pf.fit(&training)?;

    let all = std::env::var_os("PF_ALL").is_some();
    let start = std::time::Instant::now();
    let (mut ed, mut ev, mut cd, mut cv, mut data) = (0.0, 0.0, 0, 0, 0.0);
    // Signed speed error per true speed: (speed, sum of errors, runs).
    let mut by_speed: Vec<(f64, f64, usize)> = Vec::new();
    for (p, (delay, s)) in params.iter().zip(&recorded) {
        data += (s.series[0].len() - 1) as f64 * 1e-3;
        let post = pf.posterior(&s.series)?;
        let est = post.last();
        let min_ess = post
            .trace
            .iter()
            .map(|r| r.ess)
            .fold(f64::INFINITY, f64::min);
        ed += (est[0].mean - p[0]).abs();
        ev += (est[1].mean - p[1]).abs();
        cd += usize::from(est[0].covers(p[0]));
        cv += usize::from(est[1].covers(p[1]));
        match by_speed.iter_mut().find(|b| (b.0 - p[1]).abs() < 1e-9) {
            Some(b) => {
                b.1 += est[1].mean - p[1];
                b.2 += 1;
            }
            None => by_speed.push((p[1], est[1].mean - p[1], 1)),
        }
        if all || (est[0].mean - p[0]).abs() > 5e-4 || (est[1].mean - p[1]).abs() > 0.03 {
            println!(
                "  d = {:.1} mm, v = {:.2} m/s, delay {delay} s: d = {:.2} ± {:.2} mm, v = {:.3} ± {:.3} m/s; \
                 least ESS {min_ess:.0}, log evidence {:.1}",
                p[0] * 1e3,
                p[1],
                est[0].mean * 1e3,
                est[0].std * 1e3,
                est[1].mean,
                est[1].std,
                post.log_evidence
            );
        }
    }
    by_speed.sort_by(|a, b| a.0.total_cmp(&b.0));
    let bias: Vec<String> = by_speed
        .iter()
        .map(|b| format!("{:.2}: {:+.4}", b.0, b.1 / b.2 as f64))
        .collect();
    println!(
        "mean signed speed error by true speed (m/s): {}",
        bias.join(", ")
    );
    let n = params.len() as f64;
    let wall = start.elapsed().as_secs_f64();
    let used_temper = match model {
        TransitionModel::Fine => pf.temper,
        TransitionModel::Coarse => temper,
    };
    println!(
        "{set}: {} runs, {particles} particles, {} model, tempering {}, delay <= {max_delay} s, injection {inject}: \
         MAE d {:.3} mm, v {:.4} m/s; 90% cover d {:.0}%, v {:.0}%; {wall:.1} s, real-time factor {:.2}",
        params.len(),
        model.name(),
        used_temper,
        ed / n * 1e3,
        ev / n,
        cd as f64 / n * 100.0,
        cv as f64 / n * 100.0,
        data / wall
    );
    Ok(())
}
