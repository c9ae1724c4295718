//! The sensor noise estimated from recordings of our own simulator and of a perturbed stand-in
//! whisker, at 3%, 5% and 10% of each channel's range and without noise.

use std::path::{Path, PathBuf};
use vibrissa_core::chain::Discretisation;
use vibrissa_infer::noise::{estimate, estimate_pooled};
use vibrissa_infer::standin::{make, Options};
use vibrissa_infer::CHANNELS;
use vibrissa_io::scenario::Document;

fn temp(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("noise-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The recordings of `dir/eval` (channel-major) and the true noise of `noise.json` (0 if none).
fn read_eval(dir: &Path) -> (Vec<Vec<Vec<f64>>>, [f64; 5]) {
    let eval = dir.join("eval");
    let truth = std::fs::read_to_string(eval.join("truth.csv")).unwrap();
    let runs = truth
        .lines()
        .skip(1)
        .map(|line| {
            let file = line.split(',').next().unwrap();
            let s = vibrissa_io::series::read_csv(eval.join(file)).unwrap();
            CHANNELS
                .iter()
                .map(|c| s.column(c).unwrap().to_vec())
                .collect()
        })
        .collect();
    let sigma = match std::fs::read_to_string(eval.join("noise.json")) {
        Ok(text) => {
            let v: serde_json::Value = serde_json::from_str(&text).unwrap();
            std::array::from_fn(|c| v[CHANNELS[c]].as_f64().unwrap())
        }
        Err(_) => [0.0; 5],
    };
    (runs, sigma)
}

fn check(name: &str, perturb: bool, segments: usize, discretisation: Discretisation) {
    let nominal = Document::load("e2", &[]).unwrap();
    let all: Vec<usize> = (0..CHANNELS.len()).collect();
    let mut three_percent = [0.0; 5];
    for level in [0.03, 0.05, 0.10, 0.0] {
        let options = Options {
            segments,
            discretisation,
            off_grid: 12,
            eval_noise: level,
            calib_noise: 0.0,
            perturb,
            max_lead: 0.0,
            compliance: None,
            dt: None,
        };
        let dir = temp(&format!("{name}-{level}"));
        make(&nominal, 11, &options)
            .unwrap()
            .write(&dir, &options)
            .unwrap();
        let (runs, sigma) = read_eval(&dir);
        let refs: Vec<&[Vec<f64>]> = runs.iter().map(|r| &r[..]).collect();
        let pooled = estimate_pooled(&refs, &all).unwrap();
        let own: Vec<[f64; 5]> = refs.iter().map(|r| estimate(r, &all).unwrap()).collect();
        if level == 0.03 {
            three_percent = sigma;
        }
        for c in 0..CHANNELS.len() {
            if level > 0.0 {
                let ratio = pooled[c] / sigma[c];
                eprintln!("{name} {level}: {} pooled {ratio:.3}", CHANNELS[c]);
                assert!(
                    (ratio - 1.0).abs() < 0.2,
                    "{name} {level} {}: {ratio}",
                    CHANNELS[c]
                );
                for (k, o) in own.iter().enumerate() {
                    let ratio = o[c] / sigma[c];
                    assert!(
                        (ratio - 1.0).abs() < 0.35,
                        "{name} {level} {} run {k}: {ratio}",
                        CHANNELS[c]
                    );
                }
            } else {
                // Clean recordings: a small fraction of the 3% level, never NaN.
                let ratio = pooled[c] / three_percent[c];
                eprintln!(
                    "{name} clean: {} pooled {ratio:.4} of the 3% level",
                    CHANNELS[c]
                );
                assert!(
                    ratio.is_finite() && ratio < 0.1,
                    "{name} clean {}: {ratio}",
                    CHANNELS[c]
                );
            }
        }
    }
}

#[test]
fn noise_of_our_own_simulator_is_measured() {
    check("own", false, 20, Discretisation::Gregory);
}

#[test]
fn noise_of_a_stand_in_whisker_is_measured() {
    check("standin", true, 50, Discretisation::Seed);
}
