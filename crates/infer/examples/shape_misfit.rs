//! How far fresh recordings of the simulator's own whisker lie from a `shape-bank` fitted on
//! `e3` read by `c3`, against the bank's held-out yardstick: the misfit ratio's 10%, 50% and
//! 90% quantiles for 160 runs with the experiment's noise and 160 with the training runs' noise.
//! Both should sit at a median of 1, as the held-out runs do by construction.
//!
//! `cargo run --release -p vibrissa-infer --example shape_misfit -- [TRAIN_PER_CLASS] [BANK_PER_CLASS]`
//! (defaults 400 and 1600; a few minutes on 2 cores).
use vibrissa_infer::experiment::Variant;
use vibrissa_infer::shapes::{CleanRuns, ShapeBank, ShapeFamily, ShapeSample};
use vibrissa_infer::Family;

/// The 10%, 50% and 90% quantiles of `v`.
fn quantiles(mut v: Vec<f64>) -> [f64; 3] {
    v.sort_by(|a, b| a.total_cmp(b));
    [0.1, 0.5, 0.9].map(|f| v[((f * v.len() as f64) as usize).min(v.len() - 1)])
}

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let train: usize = a
        .get(1)
        .map_or(400, |s| s.parse().expect("TRAIN_PER_CLASS"));
    let bank_runs: usize = a
        .get(2)
        .map_or(1600, |s| s.parse().expect("BANK_PER_CLASS"));
    let family = ShapeFamily::builtin("e3")
        .expect("e3 is built in")
        .expect("e3 opens")
        .with_whiskers(&["c3"])
        .expect("e3 has c3");
    let noise = Family::builtin("e2")
        .unwrap()
        .noise(Variant::Noisy)
        .unwrap();
    // Evaluated runs with the experiment's noise; the noise measured on them sets the
    // training runs' sensor noise, as `vibrissa experiment e3` does.
    let draws = family.draws(40, false, 1 ^ 0xe3a1);
    let (evaluated, _) = family
        .simulate_completed(&draws, &noise, 7, &|| {})
        .unwrap();
    let measured = ShapeSample::measured_noise(&evaluated).unwrap();
    let trained = family.training_noise(measured, noise.process).unwrap();
    let train_draws = family.draws(train, true, 1 ^ 0xe3b1);
    let (training, _) = family
        .simulate_completed(&train_draws, &trained, 1 ^ 0xe3b2, &|| {})
        .unwrap();
    let (clean, _) = CleanRuns::simulate(
        &family,
        &train_draws,
        bank_runs,
        1 ^ 0xe3b1,
        1 ^ 0xe3b2,
        &|| {},
    )
    .unwrap();
    let bank = ShapeBank::fit(&family, &training, &clean).unwrap();
    for (k, v) in bank.settings() {
        println!("{k} = {v}");
    }
    let misfits = |runs: &[ShapeSample]| -> Vec<f64> {
        runs.iter()
            .map(|s| {
                bank.predict(&s.whiskers)
                    .unwrap()
                    .misfit
                    .unwrap_or(f64::NAN)
            })
            .collect()
    };
    println!(
        "misfit ratio q10/q50/q90, the experiment's noise: {:.2?}",
        quantiles(misfits(&evaluated))
    );
    let (fresh, _) = family
        .simulate_completed(&draws, &trained, 99, &|| {})
        .unwrap();
    println!(
        "misfit ratio q10/q50/q90, the training runs' noise: {:.2?}",
        quantiles(misfits(&fresh))
    );
}
