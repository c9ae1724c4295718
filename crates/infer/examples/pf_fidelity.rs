//! How closely a coarse transition model reproduces the observed runs: for 15 clean `e2` runs,
//! the root-mean-square difference per channel between the data (20 segments, 0.1 ms steps) and
//! a model of SEGMENTS segments stepped at DT with ITERATIONS geometric iterations, in units of the
//! `noisy` variant's sensor noise. Joint channels of a coarser chain are mapped onto the data's
//! joints (`pf::map_joints`). Also prints how far the `noisy` variant's process noise alone moves
//! the channels, in the same units, on the data's chain and on the model's, and the two parts
//! together as the filter's model error is defined (`pf::MODEL_ERROR`).
//!
//! ```sh
//! cargo run --release -p vibrissa-infer --example pf_fidelity -- SEGMENTS DT ITERATIONS [SCENARIO]
//! ```
//!
//! SCENARIO (a family's file, or `e2`, the default) gives the whisker, and the units (its
//! `noisy` level); the data's chain keeps 20 segments and the default discretisation.

use vibrissa_core::chain::{Discretisation, Model};
use vibrissa_core::dynamics::Integrator;
use vibrissa_core::scenes::e2_box;
use vibrissa_core::sim::{self, Scenario};
use vibrissa_infer::experiment::{Variant, PROCESS_NOISE};
use vibrissa_infer::pf::map_joints;
use vibrissa_infer::Family;

/// The runs compared: (d, v), off the evaluated grid.
const RUNS: [(f64, f64); 15] = {
    let d = [15.5e-3, 19.5e-3, 23.5e-3, 27.5e-3, 29.5e-3];
    let v = [0.35, 0.85, 1.45];
    let mut out = [(0.0, 0.0); 15];
    let mut k = 0;
    while k < 15 {
        out[k] = (d[k / 3], v[k % 3]);
        k += 1;
    }
    out
};

fn arg<T: std::str::FromStr>(args: &[String], k: usize, default: T) -> T {
    args.get(k).and_then(|s| s.parse().ok()).unwrap_or(default)
}

/// A chain and a time step to simulate the runs on.
struct Chain {
    model: Model,
    integrator: Integrator,
}

/// The five channels of run `k` on `chain`, its joint angles mapped onto `observed`'s.
fn channels(
    whisker: &vibrissa_core::whisker::WhiskerParams,
    chain: &Chain,
    observed: &Model,
    k: usize,
    process_noise: f64,
) -> Result<Vec<[f64; 5]>, Box<dyn std::error::Error>> {
    let (d, v) = RUNS[k];
    let sc = Scenario {
        whisker: whisker.clone(),
        objects: vec![e2_box(d, v)],
        segments: chain.model.n,
        integrator: chain.integrator,
        process_noise,
        // One noise seed per distance.
        seed: (k / 3) as u64,
        ..Scenario::default()
    };
    let out = sim::run(&sc, &mut |_| {})?;
    Ok(out
        .rows
        .iter()
        .map(|r| {
            let q = map_joints(&chain.model, observed, &[r[1], r[2]]);
            [q[0], q[1], r[3], r[4], r[5]]
        })
        .collect())
}

/// Root-mean-square difference per channel over many pairs of series, in units of `sigma`.
struct Rms {
    sigma: [f64; 5],
    sum: [f64; 5],
    count: usize,
}

impl Rms {
    fn new(sigma: [f64; 5]) -> Rms {
        Rms {
            sigma,
            sum: [0.0; 5],
            count: 0,
        }
    }

    fn add(&mut self, a: &[[f64; 5]], b: &[[f64; 5]]) {
        for (x, y) in a.iter().zip(b) {
            for c in 0..5 {
                let z = (x[c] - y[c]) / self.sigma[c];
                self.sum[c] += z * z;
            }
            self.count += 1;
        }
    }

    /// Mean square of channel `c`, in units of its sigma squared.
    fn mean_square(&self, c: usize) -> f64 {
        self.sum[c] / self.count as f64
    }

    fn text(&self) -> String {
        self.sum
            .iter()
            .map(|s| format!("{:.3}", (s / self.count as f64).sqrt()))
            .collect::<Vec<_>>()
            .join(" ")
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let segments: usize = arg(&args, 1, 20);
    let dt: f64 = arg(&args, 2, 2.5e-4);
    let iterations: usize = arg(&args, 3, 1);
    let family = match args.get(4) {
        Some(spec) => Family::open(spec, &[])?,
        None => Family::builtin("e2")?,
    };
    let sigma = family.noise(Variant::Noisy)?.sensor;
    let whisker = family.whisker().clone();
    let base = Scenario::default();
    // The rows carry only the model's first two joints, enough to map a chain no finer than the
    // data's onto it.
    if segments > base.segments {
        return Err(format!("SEGMENTS must be at most {}", base.segments).into());
    }
    let w = whisker.check()?;
    let data = Chain {
        model: Model::new(&w, base.segments, Discretisation::default())?,
        integrator: base.integrator,
    };
    let model = Chain {
        model: Model::new(&w, segments, Discretisation::default())?,
        integrator: Integrator {
            dt,
            max_iterations: iterations,
            ..Integrator::default()
        },
    };
    let (mut fit, mut data_noise, mut model_noise) =
        (Rms::new(sigma), Rms::new(sigma), Rms::new(sigma));
    let mut wall = 0.0;
    for k in 0..RUNS.len() {
        let clean = channels(&whisker, &data, &data.model, k, 0.0)?;
        let t0 = std::time::Instant::now();
        let coarse = channels(&whisker, &model, &data.model, k, 0.0)?;
        wall += t0.elapsed().as_secs_f64();
        fit.add(&clean, &coarse);
        data_noise.add(
            &clean,
            &channels(&whisker, &data, &data.model, k, PROCESS_NOISE)?,
        );
        model_noise.add(
            &coarse,
            &channels(&whisker, &model, &data.model, k, PROCESS_NOISE)?,
        );
    }
    println!(
        "process noise alone, rms / sensor sigma: {}",
        data_noise.text()
    );
    println!(
        "model's process noise alone, rms / sensor sigma: {}",
        model_noise.text()
    );
    println!(
        "N = {segments}, dt = {dt}, iterations {iterations}: rms / sensor sigma (theta01 theta12 m0 fx fy) = {}; model wall {wall:.3} s for 15 runs",
        fit.text()
    );
    // The two parts in quadrature, as the filter's model error is defined (`pf::MODEL_ERROR`):
    // the fit itself and the process noise's response that the model's chain lacks.
    let combined: Vec<String> = (0..5)
        .map(|c| {
            let lacked = (data_noise.mean_square(c) - model_noise.mean_square(c)).max(0.0);
            format!("{:.2}", (fit.mean_square(c) + lacked).sqrt())
        })
        .collect();
    println!(
        "model error, both parts in quadrature / sensor sigma: {}",
        combined.join(" ")
    );
    Ok(())
}
