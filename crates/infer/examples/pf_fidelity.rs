//! How closely a coarse transition model reproduces the observed runs: for 15 clean `e2` runs,
//! the root-mean-square difference per channel between the data (20 segments, 0.1 ms steps) and
//! a model of SEGMENTS segments stepped at DT with ITERATIONS geometric iterations, in units of the
//! `noisy` variant's sensor noise. Joint channels of a coarser chain are mapped onto the data's
//! joints (`pf::map_joints`). Also prints how far the `noisy` variant's process noise alone moves
//! the channels, in the same units.
//!
//! ```sh
//! cargo run --release -p vibrissa-infer --example pf_fidelity -- SEGMENTS DT ITERATIONS
//! ```

use vibrissa_core::chain::{Discretisation, Model};
use vibrissa_core::dynamics::Integrator;
use vibrissa_core::scenes::e2_box;
use vibrissa_core::sim::{self, Scenario};
use vibrissa_infer::experiment::{Noise, Variant};

fn arg<T: std::str::FromStr>(args: &[String], k: usize, default: T) -> T {
    args.get(k).and_then(|s| s.parse().ok()).unwrap_or(default)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let segments: usize = arg(&args, 1, 20);
    let dt: f64 = arg(&args, 2, 2.5e-4);
    let iterations: usize = arg(&args, 3, 1);
    let sigma = Noise::of(Variant::Noisy)?.sensor;
    let base = Scenario::default();
    let w = base.whisker.check()?;
    let fine = Model::new(&w, base.segments, Discretisation::default())?;
    let coarse = Model::new(&w, segments, Discretisation::default())?;
    // The rows carry only the model's first two joints, enough to map a chain no finer than the
    // data's onto it.
    if segments > base.segments {
        return Err(format!("SEGMENTS must be at most {}", base.segments).into());
    }
    let mut sum = [0.0f64; 5];
    let mut count = 0usize;
    let mut wall = 0.0;
    for d in [15.5e-3, 19.5e-3, 23.5e-3, 27.5e-3, 29.5e-3] {
        for v in [0.35, 0.85, 1.45] {
            let mut sc = Scenario {
                objects: vec![e2_box(d, v)],
                ..Scenario::default()
            };
            let data = sim::run(&sc, &mut |_| {})?;
            sc.segments = segments;
            sc.integrator = Integrator {
                dt,
                max_iterations: iterations,
                ..Integrator::default()
            };
            let t0 = std::time::Instant::now();
            let out = sim::run(&sc, &mut |_| {})?;
            wall += t0.elapsed().as_secs_f64();
            for (a, b) in data.rows.iter().zip(&out.rows) {
                let q = [b[1], b[2]];
                let mapped = vibrissa_infer::pf::map_joints(&coarse, &fine, &q);
                let pred = [mapped[0], mapped[1], b[3], b[4], b[5]];
                for c in 0..5 {
                    let z = (a[c + 1] - pred[c]) / sigma[c];
                    sum[c] += z * z;
                }
                count += 1;
            }
        }
    }
    // The data's own process noise, against its clean runs.
    let mut pn = [0.0f64; 5];
    let mut pcount = 0usize;
    for (k, d) in [15.5e-3, 19.5e-3, 23.5e-3, 27.5e-3, 29.5e-3]
        .iter()
        .enumerate()
    {
        for v in [0.35, 0.85, 1.45] {
            let process_only = Noise {
                sensor: [0.0; 5],
                process: vibrissa_infer::experiment::PROCESS_NOISE,
            };
            let a = vibrissa_infer::experiment::simulate(
                vibrissa_infer::Experiment::E2,
                [*d, v],
                &Noise::NONE,
                k as u64,
            )?;
            let b = vibrissa_infer::experiment::simulate(
                vibrissa_infer::Experiment::E2,
                [*d, v],
                &process_only,
                k as u64,
            )?;
            for c in 0..5 {
                for (x, y) in a.series[c].iter().zip(&b.series[c]) {
                    let z = (x - y) / sigma[c];
                    pn[c] += z * z;
                }
            }
            pcount += a.series[0].len();
        }
    }
    println!(
        "process noise alone, rms / sensor sigma: {}",
        pn.iter()
            .map(|s| format!("{:.3}", (s / pcount as f64).sqrt()))
            .collect::<Vec<_>>()
            .join(" ")
    );
    // The model's process noise (same intensity), against its own clean runs.
    let mut mn = [0.0f64; 5];
    let mut mcount = 0usize;
    for (k, d) in [15.5e-3, 19.5e-3, 23.5e-3, 27.5e-3, 29.5e-3]
        .iter()
        .enumerate()
    {
        for v in [0.35, 0.85, 1.45] {
            let mut sc = Scenario {
                objects: vec![e2_box(*d, v)],
                segments,
                integrator: Integrator {
                    dt,
                    max_iterations: iterations,
                    ..Integrator::default()
                },
                seed: k as u64,
                ..Scenario::default()
            };
            let a = sim::run(&sc, &mut |_| {})?;
            sc.process_noise = vibrissa_infer::experiment::PROCESS_NOISE;
            let b = sim::run(&sc, &mut |_| {})?;
            for (x, y) in a.rows.iter().zip(&b.rows) {
                let qa = vibrissa_infer::pf::map_joints(&coarse, &fine, &[x[1], x[2]]);
                let qb = vibrissa_infer::pf::map_joints(&coarse, &fine, &[y[1], y[2]]);
                let (pa, pb) = (
                    [qa[0], qa[1], x[3], x[4], x[5]],
                    [qb[0], qb[1], y[3], y[4], y[5]],
                );
                for c in 0..5 {
                    let z = (pa[c] - pb[c]) / sigma[c];
                    mn[c] += z * z;
                }
                mcount += 1;
            }
        }
    }
    println!(
        "model's process noise alone, rms / sensor sigma: {}",
        mn.iter()
            .map(|s| format!("{:.3}", (s / mcount as f64).sqrt()))
            .collect::<Vec<_>>()
            .join(" ")
    );
    let rms: Vec<String> = sum
        .iter()
        .map(|s| format!("{:.3}", (s / count as f64).sqrt()))
        .collect();
    println!(
        "N = {segments}, dt = {dt}, iterations {iterations}: rms / sensor sigma (theta01 theta12 m0 fx fy) = {}; model wall {:.3} s for 15 runs",
        rms.join(" "),
        wall
    );
    Ok(())
}
