//! How smoothly a noise-free `e3` run follows its pose: one class's run (read by `c3`) at a pose
//! and at that pose with `x` moved by `STEP_UM` micrometres at a time, and each run's distance
//! from the first in units of the `noisy` variant's sensor noise (as `e3_separation` measures
//! it). A smooth simulation gives a distance that grows steadily with the move; a jagged one
//! jumps by several noise levels between neighbouring poses, which stalls a search that fits a
//! pose by differences.
//!
//! `cargo run --release -p vibrissa-infer --example e3_smoothness -- [CLASS] [STEP_UM] [STEPS]
//! [AVERAGE] [--set KEY=VALUE]...` (defaults `circle`, 2 µm, 100, 1; the peg at x 21.2 mm,
//! radius 4.44 mm, 0.98 m/s; other classes at the middle of their ranges). With `AVERAGE` n > 1
//! the runs are recorded n times as often and every sample is the mean of the n readings of its
//! period (ending at its instant): what a sensor that averages over the sample period would
//! record. Every `--set` overrides a key of every class's scenario (`--set hold_contacts=true`).
//!
//! `-- --survey [--set KEY=VALUE]...`: for every class, 8 poses drawn within the middle 60% of
//! each unknown's range (a fixed seed), each moved 60 times by 0.2 µm in `x`; the changes of the
//! distance between neighbouring poses, pooled per class: mean, median, 90th and 99th
//! percentiles and largest, in noise levels.
use vibrissa_infer::experiment::{Noise, Variant};
use vibrissa_infer::shapes::{whitened, ShapeFamily, ShapeSample};
use vibrissa_infer::Family;

/// Every whitened run's distance from the first, in noise levels.
fn distances(runs: &[ShapeSample], sigma: &[f64; 5]) -> Vec<f64> {
    let whiten = |s: &ShapeSample| whitened(&s.whiskers, sigma);
    let first = whiten(&runs[0]);
    runs.iter()
        .map(|r| {
            whiten(r)
                .iter()
                .zip(&first)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt()
        })
        .collect()
}

/// Draws of `class` at `base` and at `base` with `x` (its first value) moved by `step` once,
/// twice, … `moves` times.
fn moved_in_x(class: usize, base: &[f64], step: f64, moves: usize) -> Vec<(usize, Vec<f64>)> {
    (0..=moves)
        .map(|i| {
            let mut p = base.to_vec();
            p[0] += i as f64 * step;
            (class, p)
        })
        .collect()
}

/// The `--survey` table (see the module's documentation).
fn survey(family: &ShapeFamily, sigma: &[f64; 5]) {
    let (poses, moves, step) = (8, 60, 0.2e-6);
    // A fixed linear congruential stream: the same poses with every build and setting.
    let mut seed = 12345u64;
    let mut uniform = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for (class, name) in family.class_names().iter().enumerate() {
        let ranges = family.classes()[class].family.ranges();
        let mut jumps = Vec::new();
        for _ in 0..poses {
            let base: Vec<f64> = ranges
                .iter()
                .map(|[lo, hi]| lo + (hi - lo) * (0.2 + 0.6 * uniform()))
                .collect();
            let (runs, _) = family
                .simulate_completed(
                    &moved_in_x(class, &base, step, moves),
                    &Noise::NONE,
                    0,
                    &|| {},
                )
                .unwrap();
            let d = distances(&runs, sigma);
            jumps.extend(d.windows(2).map(|w| (w[1] - w[0]).abs()));
        }
        jumps.sort_by(f64::total_cmp);
        let q = |p: f64| jumps[((jumps.len() - 1) as f64 * p).round() as usize];
        let mean = jumps.iter().sum::<f64>() / jumps.len() as f64;
        println!(
            "{name:9} change per 0.2 µm: mean {mean:.3}, median {:.3}, 90% {:.3}, 99% {:.3}, largest {:.3}",
            q(0.5),
            q(0.9),
            q(0.99),
            q(1.0)
        );
    }
}

fn main() {
    let all: Vec<String> = std::env::args().skip(1).collect();
    let sets: Vec<String> = all
        .iter()
        .enumerate()
        .filter(|(i, _)| *i > 0 && all[i - 1] == "--set")
        .map(|(_, s)| s.clone())
        .collect();
    let a: Vec<&String> = all
        .iter()
        .enumerate()
        .filter(|(i, s)| !s.starts_with("--") && (*i == 0 || all[i - 1] != "--set"))
        .map(|(_, s)| s)
        .collect();
    let name = a.first().map_or("circle", |s| s.as_str());
    let step: f64 = a.get(1).map_or(2.0, |s| s.parse().expect("STEP_UM")) * 1e-6;
    let steps: usize = a.get(2).map_or(100, |s| s.parse().expect("STEPS"));
    let average: usize = a.get(3).map_or(1, |s| s.parse().expect("AVERAGE"));
    let family = ShapeFamily::builtin_with("e3", &sets, None)
        .expect("built in")
        .expect("opens with the --set overrides")
        .with_whiskers(&["c3"])
        .expect("c3");
    let class = family
        .class_names()
        .iter()
        .position(|n| *n == name)
        .unwrap_or_else(|| panic!("CLASS: one of {:?}", family.class_names()));
    let sigma = Family::builtin("e2")
        .unwrap()
        .noise(Variant::Noisy)
        .unwrap()
        .sensor;
    if all.iter().any(|s| s == "--survey") {
        survey(&family, &sigma);
        return;
    }
    if all.iter().any(|s| s == "--survey") {
        survey(&family, &sigma);
        return;
    }
    let ranges = family.classes()[class].family.ranges();
    let base: Vec<f64> = if name == "circle" {
        vec![0.021203, 0.0044436, 0.9813]
    } else {
        ranges.iter().map(|[lo, hi]| 0.5 * (lo + hi)).collect()
    };
    let draws = moved_in_x(class, &base, step, steps);
    let rate = family.sample_rate();
    let samples = family.samples();
    let fine = family
        .with_timing(rate * average as f64, (samples - 1) * average + 1)
        .expect("a finer timing");
    let (mut runs, _) = fine
        .simulate_completed(&draws, &Noise::NONE, 0, &|| {})
        .unwrap();
    if average > 1 {
        for r in &mut runs {
            for w in &mut r.whiskers {
                for ch in w.iter_mut() {
                    *ch = (0..samples)
                        .map(|k| {
                            let end = k * average;
                            let start = end.saturating_sub(average - 1);
                            ch[start..=end].iter().sum::<f64>() / (end - start + 1) as f64
                        })
                        .collect();
                }
            }
        }
    }
    let d = distances(&runs, &sigma);
    println!(
        "{name} at {base:?}, x moved by {:.1} µm per step",
        step * 1e6
    );
    let mut jumps = (0.0f64, 0usize);
    for (i, v) in d.iter().enumerate() {
        if i > 0 && (v - d[i - 1]).abs() > jumps.0 {
            jumps = ((v - d[i - 1]).abs(), i);
        }
        if i % 5 == 0 {
            println!("x + {:6.1} µm: Δ {v:.3}", i as f64 * step * 1e6);
        }
    }
    println!(
        "largest change of Δ between neighbouring poses: {:.3} noise levels (steps {} and {})",
        jumps.0,
        jumps.1 - 1,
        jumps.1
    );
    // Where, in the recording, the two neighbouring runs part.
    let (a, b) = (&runs[jumps.1 - 1], &runs[jumps.1]);
    let channels = vibrissa_infer::experiment::CHANNELS;
    for (c, name) in channels.iter().enumerate() {
        let diff: Vec<f64> = (0..samples)
            .map(|t| (a.whiskers[0][c][t] - b.whiskers[0][c][t]) / sigma[c])
            .collect();
        let first = diff.iter().position(|v| v.abs() > 0.1);
        let (peak, at) = diff
            .iter()
            .enumerate()
            .map(|(t, v)| (v.abs(), t))
            .fold((0.0f64, 0usize), |m, x| if x.0 > m.0 { x } else { m });
        println!(
            "  {name}: the runs part (> 0.1 σ) at {}, the largest difference {peak:.2} σ at {:.0} ms",
            first.map_or("never".to_string(), |t| format!("{:.0} ms", 1e3 * t as f64 / rate)),
            1e3 * at as f64 / rate
        );
    }
}
