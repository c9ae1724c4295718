//! Cramér–Rao bound on the `e2` unknowns from the `noisy` variant's sensor noise: for every
//! evaluated run (d, v), the Fisher information of the 151 samples of all five channels about
//! (d, v), and about (d, v, t0) when the start of the approach is unknown, from central
//! differences of clean simulations. Prints the bound's standard deviations and the mean absolute
//! error an unbiased, efficient estimator would reach (√(2/π)·σ), averaged over the 71 runs.
//! Process noise is left out, so the bound is optimistic.
//!
//! ```sh
//! cargo run --release -p vibrissa-infer --example info_bound
//! ```

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use vibrissa_core::scenes::e2_box;
use vibrissa_core::sim::{self, Scenario};
use vibrissa_infer::experiment::Variant;
use vibrissa_infer::Family;

/// A run's (d, v), its bound's σ with a known start (d, v) and with an unknown one (d, v, t0).
type Row = ([f64; 2], [f64; 2], [f64; 3]);

/// The five channels of a clean run with the box at (d, v), started `t0` earlier.
fn run(d: f64, v: f64, t0: f64) -> Vec<[f64; 5]> {
    let mut object = e2_box(d, v);
    object.position[1] -= v * t0;
    let sc = Scenario {
        objects: vec![object],
        ..Scenario::default()
    };
    let out = sim::run(&sc, &mut |_| {}).expect("the e2 run simulates");
    out.rows
        .iter()
        .map(|r| [r[1], r[2], r[3], r[4], r[5]])
        .collect()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let e = Family::builtin("e2")?;
    let sigma = e.noise(Variant::Noisy)?.sensor;
    let grid: Vec<[f64; 2]> = e
        .grid()
        .into_iter()
        .filter(|p| !e.is_template(p))
        .map(|p| [p[0], p[1]])
        .collect();
    // Steps of the central differences: d, v, t0.
    let h = [2e-5, 2e-3, 2e-5];
    let rows: Vec<Row> = grid
        .par_iter()
        .map(|&[d, v]| {
            let t0 = 0.01;
            let diff = |k: usize| -> Vec<[f64; 5]> {
                let mut plus = [d, v, t0];
                let mut minus = plus;
                plus[k] += h[k];
                minus[k] -= h[k];
                let (a, b) = (
                    run(plus[0], plus[1], plus[2]),
                    run(minus[0], minus[1], minus[2]),
                );
                a.iter()
                    .zip(&b)
                    .map(|(x, y)| std::array::from_fn(|c| (x[c] - y[c]) / (2.0 * h[k])))
                    .collect()
            };
            let g: Vec<Vec<[f64; 5]>> = (0..3).map(diff).collect();
            let mut fisher = DMatrix::<f64>::zeros(3, 3);
            for (t, _) in g[0].iter().enumerate() {
                for c in 0..5 {
                    let j = DVector::from_iterator(3, g.iter().map(|gk| gk[t][c] / sigma[c]));
                    fisher += &j * j.transpose();
                }
            }
            let known = fisher.view((0, 0), (2, 2)).into_owned();
            let ck = known.try_inverse().expect("information about d and v");
            let cu = fisher.try_inverse().expect("information about d, v and t0");
            (
                [d, v],
                [ck[(0, 0)].sqrt(), ck[(1, 1)].sqrt()],
                [cu[(0, 0)].sqrt(), cu[(1, 1)].sqrt(), cu[(2, 2)].sqrt()],
            )
        })
        .collect();
    let mae = (2.0 / std::f64::consts::PI).sqrt();
    let n = rows.len() as f64;
    for (p, k, u) in &rows {
        println!(
            "d = {:.0} mm, v = {:.1} m/s: known start σd {:.3} mm, σv {:.4} m/s; unknown start σd {:.3} mm, σv {:.4} m/s, σt0 {:.3} ms",
            p[0] * 1e3, p[1], k[0] * 1e3, k[1], u[0] * 1e3, u[1], u[2] * 1e3
        );
    }
    let avg = |f: &dyn Fn(&Row) -> f64| rows.iter().map(f).sum::<f64>() / n;
    println!(
        "bound on the mean absolute error over {} runs: known start d {:.3} mm, v {:.4} m/s; unknown start d {:.3} mm, v {:.4} m/s",
        rows.len(),
        mae * avg(&|r| r.1[0]) * 1e3,
        mae * avg(&|r| r.1[1]),
        mae * avg(&|r| r.2[0]) * 1e3,
        mae * avg(&|r| r.2[1]),
    );
    for v in [0.3, 0.6, 0.9, 1.2, 1.5] {
        let sel: Vec<_> = rows.iter().filter(|r| (r.0[1] - v).abs() < 1e-9).collect();
        let m = sel.iter().map(|r| r.2[1]).sum::<f64>() / sel.len() as f64;
        println!(
            "  v = {v}: unknown start, bound on MAE v {:.4} m/s ({} runs)",
            mae * m,
            sel.len()
        );
    }
    Ok(())
}
