//! Filters one noisy `e2` run (d = 22 mm, v = 0.9 m/s) REPEATS times with PARTICLES particles (the run's noise seeded by SEED),
//! for profiling the filter alone.
//!
//! ```sh
//! cargo run --release -p vibrissa-infer --example pf_repeat -- PARTICLES REPEATS [SEED]
//! ```

use vibrissa_infer::experiment::{simulate, Experiment, Noise, Variant};
use vibrissa_infer::pf::{self, Config, Observations};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let particles: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(1000);
    let repeats: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(20);
    let noise = Noise::of(Variant::Noisy)?;
    let run_seed: u64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(1);
    let run = simulate(Experiment::E2, [0.022, 0.9], &noise, run_seed)?;
    let model = noise.sensor.map(|s| s * pf::MODEL_ERROR);
    let sigma = pf::observation_sigma(noise.sensor, model, pf::temper_for(particles));
    let obs = Observations::at_rate(run.series.clone(), 1000.0);
    let start = std::time::Instant::now();
    for r in 0..repeats {
        let mut config = Config::e2(sigma, particles, r as u64);
        if let Ok(n) = std::env::var("PF_SEGMENTS") {
            config.segments = n.parse()?;
        }
        if let Ok(dt) = std::env::var("PF_DT") {
            config.dt = dt.parse()?;
        }
        let post = pf::run(&config, &obs, &mut |_| {})?;
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
    println!(
        "{particles} particles: {wall:.4} s per run, real-time factor {:.2}",
        0.15 / wall
    );
    Ok(())
}
