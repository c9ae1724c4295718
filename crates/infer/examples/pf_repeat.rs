//! Filters one noisy `e2` run REPEATS times with PARTICLES particles, one filter seed each, and
//! prints each posterior (for profiling the filter alone and for studying single runs).
//!
//! ```sh
//! cargo run --release -p vibrissa-infer --example pf_repeat -- PARTICLES REPEATS [SEED D V DELAY]
//! ```
//! The run: d = D m (22 mm), v = V m/s (0.9), its recording started DELAY s early (0; a delay
//! makes the start unknown to the filter, on 0…50 ms), noise seeded by SEED (1). Environment:
//! `PF_SEGMENTS`, `PF_DT`, `PF_TEMPER` override the filter's model and tempering; `PF_CLEAN=1`
//! filters the clean run instead (the filter's noise is then the model error alone); `PF_TRACE=1`
//! prints the posterior every 5 samples; `PF_PRINT=A:B` prints samples A..B of the run.

use vibrissa_infer::experiment::{Noise, Variant};
use vibrissa_infer::pf::{self, Config, Observations, Prior};
use vibrissa_infer::Family;

fn arg<T: std::str::FromStr>(args: &[String], k: usize, default: T) -> T {
    args.get(k).and_then(|s| s.parse().ok()).unwrap_or(default)
}

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|s| s.parse().ok())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let particles: usize = arg(&args, 1, 1000);
    let repeats: usize = arg(&args, 2, 20);
    let run_seed: u64 = arg(&args, 3, 1);
    let (d, v, delay): (f64, f64, f64) =
        (arg(&args, 4, 0.022), arg(&args, 5, 0.9), arg(&args, 6, 0.0));
    let e2 = Family::builtin("e2")?;
    let noise = e2.noise(Variant::Noisy)?;
    let clean_run = env::<u32>("PF_CLEAN") == Some(1);
    let run = if clean_run {
        e2.simulate_delayed(&[d, v], delay, &Noise::NONE, run_seed)?
    } else {
        e2.simulate_delayed(&[d, v], delay, &noise, run_seed)?
    };
    let model: [f64; 5] = std::array::from_fn(|c| noise.sensor[c] * pf::MODEL_ERROR[c]);
    let unknown = if delay > 0.0 {
        pf::UNKNOWN_START_TEMPER
    } else {
        1.0
    };
    let temper = env("PF_TEMPER").unwrap_or(pf::temper_for(particles) * unknown);
    let sensor = if clean_run { [0.0; 5] } else { noise.sensor };
    let sigma = pf::observation_sigma(sensor, model, temper);
    let obs = Observations::at_rate(run.series.clone(), 1000.0);
    if let Some((a, b)) = env::<String>("PF_PRINT").and_then(|s| {
        let (a, b) = s.split_once(':')?;
        Some((a.parse::<usize>().ok()?, b.parse::<usize>().ok()?))
    }) {
        let clean = e2.simulate_delayed(&[d, v], delay, &Noise::NONE, run_seed)?;
        for k in a..b.min(obs.t.len()) {
            let row: Vec<String> = (0..5)
                .map(|c| {
                    format!(
                        "{:+.2}/{:+.2}",
                        run.series[c][k] / noise.sensor[c],
                        clean.series[c][k] / noise.sensor[c]
                    )
                })
                .collect();
            println!(
                "  sample {k}: noisy/clean in sensor sigmas {}",
                row.join("  ")
            );
        }
    }
    let start = std::time::Instant::now();
    for r in 0..repeats {
        let mut config = Config::e2(sigma, particles, r as u64);
        if delay > 0.0 {
            config.priors[2] = Prior::uniform(0.0, 0.05);
        }
        if let Some(n) = env("PF_SEGMENTS") {
            config.segments = n;
        }
        if let Some(dt) = env("PF_DT") {
            config.dt = dt;
        }
        let post = pf::run(&config, &obs, &mut |_| {})?;
        if env::<u32>("PF_TRACE") == Some(1) {
            for row in post.trace.iter().step_by(5) {
                let e = &row.estimates;
                println!(
                    "  t = {:5.1} ms  ess {:6.0}  d {:6.2} ± {:5.2} mm  v {:.3} ± {:.3} m/s{}",
                    row.t * 1e3,
                    row.ess,
                    e[0].mean * 1e3,
                    e[0].std * 1e3,
                    e[1].mean,
                    e[1].std,
                    e.get(2)
                        .map(|t| format!("  t0 {:5.2} ± {:4.2} ms", t.mean * 1e3, t.std * 1e3))
                        .unwrap_or_default()
                );
            }
        }
        let e = post.last();
        println!(
            "filter seed {r}: d = {:.2} ± {:.2} mm, v = {:.3} ± {:.3} m/s, log evidence {:.1}",
            e[0].mean * 1e3,
            e[0].std * 1e3,
            e[1].mean,
            e[1].std,
            post.log_evidence
        );
    }
    let wall = start.elapsed().as_secs_f64() / repeats as f64;
    let data = (obs.t.len() - 1) as f64 * 1e-3;
    println!(
        "{particles} particles, tempering {temper:.2}: {wall:.4} s per run, real-time factor {:.2}",
        data / wall
    );
    Ok(())
}
