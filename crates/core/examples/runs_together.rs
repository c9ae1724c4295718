//! Times the `e2` box runs one at a time on all cores (`sim::run` each) against the same runs
//! stepped together in lanes (`sim::run_many`), and checks that both give the same series.
//!
//! `cargo run --release -p vibrissa-core --example runs_together [-- RUNS [REPEATS]]`

use std::time::Instant;
use vibrissa_core::rng::Rng;
use vibrissa_core::scenes::e2_box;
use vibrissa_core::sim::{self, Scenario, SensorNoise};

fn main() {
    let mut args = std::env::args().skip(1);
    let runs: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(400);
    let repeats: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(3);
    // Noisy e2 runs at random distances and speeds, as a training set draws them.
    let mut rng = Rng::new(7);
    let scenarios: Vec<Scenario> = (0..runs)
        .map(|k| Scenario {
            objects: vec![e2_box(
                0.015 + 0.015 * rng.uniform(),
                0.3 + 1.2 * rng.uniform(),
            )],
            process_noise: 2e-5,
            sensor_noise: SensorNoise {
                theta01: 6e-3,
                theta12: 1.5e-2,
                m0: 2.3e-6,
                fx: 1.7e-4,
                fy: 1.2e-4,
            },
            seed: k as u64,
            ..Scenario::default()
        })
        .collect();
    for r in 0..repeats {
        let t0 = Instant::now();
        use rayon::prelude::*;
        // `TOGETHER_ONLY=1` skips the runs alone, `ALONE_ONLY=1` the runs together (to profile
        // either).
        let skip = std::env::var_os("TOGETHER_ONLY").is_some();
        let only_alone = std::env::var_os("ALONE_ONLY").is_some();
        let alone: Vec<_> = scenarios[..if skip { 0 } else { scenarios.len() }]
            .par_iter()
            .map(|s| sim::run(s, &mut |_| {}).expect("runs"))
            .collect();
        let t_alone = t0.elapsed().as_secs_f64();
        let t0 = Instant::now();
        let together: Vec<_> =
            sim::run_many(&scenarios[..if only_alone { 0 } else { scenarios.len() }])
                .into_iter()
                .map(|r| r.expect("runs"))
                .collect();
        let t_together = t0.elapsed().as_secs_f64();
        // Rows compared by their bits (a row without contact holds NaN).
        let bits = |o: &sim::Output| -> Vec<u64> {
            o.rows.iter().flatten().map(|x| x.to_bits()).collect()
        };
        assert!(
            alone
                .iter()
                .zip(&together)
                .all(|(a, b)| bits(a) == bits(b) && a.steps == b.steps),
            "the same series"
        );
        println!(
            "{runs} runs, {} threads, repeat {r}: alone {t_alone:.3} s, together {t_together:.3} s ({:.2}x)",
            rayon::current_num_threads(),
            t_alone / t_together
        );
    }
}
