//! Cramér–Rao bound on the `e2` unknowns with the `noisy` variant's process noise counted, for
//! chosen runs. `info_bound` counts the sensor noise alone; here the observations are modelled as
//! the clean series plus a Gaussian perturbation whose covariance is estimated from M runs with
//! process noise (different seeds, no sensor noise), plus the sensor noise. The Fisher information
//! about (d, v) and (d, v, t0) is Jᵀ Σ⁻¹ J with J the central differences of the clean series and
//! Σ that covariance over all 151 samples of the five channels. The Gaussian model of the process
//! noise's effect is an approximation (a slip-off that comes a sample early or late is not
//! Gaussian), so the figures say how much the data can tell at best, not what a filter reaches.
//!
//! ```sh
//! cargo run --release -p vibrissa-infer --example info_bound_process -- [M] [D:V ...]
//! ```
//! M: runs for the covariance (3000; at least twice the 755 observed values). D:V: runs in mm and
//! m/s (default: the 71 evaluated runs, about 8 minutes on 2 cores). Prints, per run, the bound's
//! standard deviations without and with the process noise, then the mean absolute error an
//! unbiased, efficient estimator would reach (√(2/π)·σ), averaged over the runs.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use vibrissa_core::scenes::e2_box;
use vibrissa_core::sim::{self, Scenario};
use vibrissa_infer::experiment::Variant;
use vibrissa_infer::Family;

/// Start of the approach before the recording's t = 0 (the bound needs a t0 inside its prior).
const T0: f64 = 0.01;

/// The five channels of a run with the box at (d, v) started `t0` earlier, with process noise
/// `process` seeded by `seed`, flattened sample by sample and scaled by the sensor noise.
fn run(d: f64, v: f64, t0: f64, process: f64, seed: u64, sigma: &[f64; 5]) -> Vec<f64> {
    let mut object = e2_box(d, v);
    object.position[1] -= v * t0;
    let sc = Scenario {
        objects: vec![object],
        process_noise: process,
        seed,
        ..Scenario::default()
    };
    let out = sim::run(&sc, &mut |_| {}).expect("the e2 run simulates");
    out.rows
        .iter()
        .flat_map(|r| (0..5).map(move |c| r[c + 1] / sigma[c]))
        .collect()
}

/// Standard deviations of the bound from a Fisher information matrix over (d, v, t0): with a
/// known start (the first two unknowns) and an unknown one.
fn bounds(fisher: &DMatrix<f64>) -> ([f64; 2], [f64; 3]) {
    let known = fisher
        .view((0, 0), (2, 2))
        .into_owned()
        .try_inverse()
        .expect("information about d and v");
    let unknown = fisher
        .clone()
        .try_inverse()
        .expect("information about d, v and t0");
    (
        [known[(0, 0)].sqrt(), known[(1, 1)].sqrt()],
        [
            unknown[(0, 0)].sqrt(),
            unknown[(1, 1)].sqrt(),
            unknown[(2, 2)].sqrt(),
        ],
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let m: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(3000);
    let mut runs: Vec<[f64; 2]> = args
        .iter()
        .skip(2)
        .filter_map(|s| {
            let (d, v) = s.split_once(':')?;
            Some([d.parse::<f64>().ok()? * 1e-3, v.parse().ok()?])
        })
        .collect();
    if runs.is_empty() {
        let e = Family::builtin("e2")?;
        runs = e
            .grid()
            .into_iter()
            .filter(|p| !e.is_template(p))
            .map(|p| [p[0], p[1]])
            .collect();
    }
    // Per run: σv with a known and an unknown start, sensor noise only and with process noise,
    // then σd with process noise and an unknown start.
    let mut table: Vec<[f64; 5]> = Vec::with_capacity(runs.len());
    let noise = Family::builtin("e2")?.noise(Variant::Noisy)?;
    let sigma = noise.sensor;
    let h = [2e-5, 2e-3, 2e-5];
    for [d, v] in runs {
        let p = [d, v, T0];
        // Central differences of the clean series, in sensor sigmas per unit of each unknown.
        let jac: Vec<Vec<f64>> = (0..3)
            .map(|k| {
                let (mut plus, mut minus) = (p, p);
                plus[k] += h[k];
                minus[k] -= h[k];
                let a = run(plus[0], plus[1], plus[2], 0.0, 0, &sigma);
                let b = run(minus[0], minus[1], minus[2], 0.0, 0, &sigma);
                a.iter()
                    .zip(&b)
                    .map(|(x, y)| (x - y) / (2.0 * h[k]))
                    .collect()
            })
            .collect();
        let n = jac[0].len();
        let j = DMatrix::from_fn(n, 3, |i, k| jac[k][i]);
        // Covariance of the process noise's effect, from m seeded runs.
        let samples: Vec<Vec<f64>> = (0..m)
            .into_par_iter()
            .map(|s| run(d, v, T0, noise.process, 1 + s as u64, &sigma))
            .collect();
        let mut mean = DVector::<f64>::zeros(n);
        for s in &samples {
            mean += DVector::from_column_slice(s);
        }
        mean /= m as f64;
        let mut centred = DMatrix::<f64>::zeros(n, m);
        for (k, s) in samples.iter().enumerate() {
            centred.set_column(k, &(DVector::from_column_slice(s) - &mean));
        }
        let process = &centred * centred.transpose() / (m as f64 - 1.0);
        let sensor_only = j.transpose() * &j;
        let total = process + DMatrix::<f64>::identity(n, n);
        let chol = total
            .cholesky()
            .ok_or("the covariance is not positive definite")?;
        // The inverse of a sample covariance overstates the information by m / (m − n − 2)
        // (Wishart); the sensor part is known exactly, so this correction is conservative.
        let shrink = ((m as f64 - n as f64 - 2.0) / m as f64).max(0.0);
        let with_process = j.transpose() * chol.solve(&j) * shrink;
        let (ks, us) = bounds(&sensor_only);
        let (kp, up) = bounds(&with_process);
        table.push([ks[1], us[1], kp[1], up[1], up[0]]);
        println!(
            "d = {:.1} mm, v = {:.2} m/s: sensor noise only: σv {:.4} (known start), {:.4} (unknown); \
             with process noise: σv {:.4} (known), {:.4} (unknown), σd {:.3} mm, σt0 {:.3} ms",
            d * 1e3,
            v,
            ks[1],
            us[1],
            kp[1],
            up[1],
            up[0] * 1e3,
            up[2] * 1e3
        );
    }
    let mae = (2.0 / std::f64::consts::PI).sqrt() / table.len() as f64;
    let avg = |k: usize| mae * table.iter().map(|r| r[k]).sum::<f64>();
    println!(
        "bound on the mean absolute error over {} runs: speed, sensor noise only {:.4} m/s (known \
         start), {:.4} (unknown); with process noise {:.4} (known), {:.4} (unknown); distance with \
         process noise, unknown start {:.3} mm",
        table.len(),
        avg(0),
        avg(1),
        avg(2),
        avg(3),
        avg(4) * 1e3
    );
    Ok(())
}
