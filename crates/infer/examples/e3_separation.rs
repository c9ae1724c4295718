//! How well could any estimator name `e3`'s classes? For each evaluated run (noise-free, the
//! experiment's draws), the nearest noise-free run of every other class, searched with the
//! simulator, and its distance in units of the `noisy` variant's sensor noise; from those, an
//! estimate from above of the share of runs any classifier reading those whiskers names right
//! under that noise ([`vibrissa_infer::shapes::Separation`]).
//!
//! Then the experiment's noisy runs of the same draws (sensor noise and random forces) read by
//! the least χ² under the noise level measured on them, and by the likelihood with the random
//! forces' response counted as noise at each class's fitted pose: first with each class's pose
//! searched from the truth's (its own class) or from the rival pose found above (a reading
//! that knows where to look), then searched from the nearest runs of an evenly spread pool of
//! noise-free runs, as an estimator without the truth would.
//!
//! `cargo run --release -p vibrissa-infer --example e3_separation -- WHISKERS [RUNS_PER_CLASS]
//! [STARTS_PER_CLASS] [POOL_PER_CLASS] [--csv FILE] [--set KEY=VALUE]...` with `WHISKERS` e.g.
//! `c3`, `c2+c3+c4` or `all` (defaults 50 runs, 400 starts and a pool of 3200 per class; the
//! experiment's evaluated draws of seed 1; about 15 minutes with `c3` on 2 cores). Every `--set`
//! overrides a key of every class's scenario, for the recordings and the search alike
//! (`--set hold_contacts=true`). With `E3_SEPARATION_VERBOSE` set in
//! the environment, each noisy run's χ² per sample at the truth's noise-free run and per class
//! at the searched poses go to standard error.
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};
use vibrissa_infer::experiment::{Noise, Variant};
use vibrissa_infer::shapes::{
    forced_log_likelihood, nearest_from, normal_tail, search_every_class, separations, ShapeFamily,
    ShapeSample,
};
use vibrissa_infer::Family;

fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let csv = a
        .iter()
        .position(|s| s == "--csv")
        .map(|i| a.get(i + 1).expect("--csv FILE").clone());
    let sets: Vec<String> = a
        .iter()
        .enumerate()
        .filter(|(i, _)| *i > 0 && a[i - 1] == "--set")
        .map(|(_, s)| s.clone())
        .collect();
    let pos: Vec<&String> = a
        .iter()
        .enumerate()
        .filter(|(i, s)| {
            !s.starts_with("--") && (*i == 0 || (a[i - 1] != "--csv" && a[i - 1] != "--set"))
        })
        .map(|(_, s)| s)
        .collect();
    let which = pos.first().map_or("c3", |s| s.as_str());
    let runs: usize = pos
        .get(1)
        .map_or(50, |s| s.parse().expect("RUNS_PER_CLASS"));
    let starts: usize = pos
        .get(2)
        .map_or(400, |s| s.parse().expect("STARTS_PER_CLASS"));
    let pool_per_class: usize = pos
        .get(3)
        .map_or(3200, |s| s.parse().expect("POOL_PER_CLASS"));
    let e3 = ShapeFamily::builtin_with("e3", &sets, None)
        .expect("built in")
        .expect("opens with the --set overrides");
    let family = if which == "all" {
        e3
    } else {
        let names: Vec<&str> = which.split('+').collect();
        e3.with_whiskers(&names).expect("whiskers of e3")
    };
    let noise = Family::builtin("e2")
        .unwrap()
        .noise(Variant::Noisy)
        .unwrap();
    let sigma = noise.sensor;
    let draws = family.draws(runs, false, 1 ^ 0xe3a1);
    let (clean, failed) = family
        .simulate_completed(&draws, &Noise::NONE, 2, &|| {})
        .unwrap();
    if !failed.is_empty() {
        eprintln!(
            "left out {} runs the simulator could not complete",
            failed.len()
        );
    }
    let done = AtomicUsize::new(0);
    let total = clean.len();
    let t = std::time::Instant::now();
    let tick = || {
        let n = done.fetch_add(1, Ordering::Relaxed) + 1;
        if n % 20 == 0 || n == total {
            eprintln!("[{:7.1} s] {n}/{total}", t.elapsed().as_secs_f64());
        }
    };
    let sep = separations(
        &family,
        &clean,
        sigma,
        noise.process,
        40,
        starts,
        0x5e9a,
        &tick,
    )
    .unwrap();
    let names = family.class_names();
    println!(
        "e3, whiskers {which}: {} runs, sensor noise σ = [{}] (the noisy variant's; its random \
         forces left out); {:.0} s",
        sep.len(),
        sigma
            .iter()
            .map(|s| format!("{s:.3e}"))
            .collect::<Vec<_>>()
            .join(", "),
        t.elapsed().as_secs_f64()
    );
    println!(
        "{:10} {:>5} | {:>8} {:>8} | {:>8} {:>8} {:>6} {:>6} {:>8} {:>8} | nearest rival (runs)",
        "class",
        "runs",
        "Δ median",
        "ceiling",
        "Δf q10",
        "Δf med",
        "Δf<2",
        "Δf<4",
        "ceiling",
        "lower"
    );
    let mut totals = [0.0; 3];
    for (k, name) in names.iter().enumerate() {
        let of: Vec<_> = sep.iter().filter(|s| s.class == k).collect();
        if of.is_empty() {
            continue;
        }
        let sorted = |mut d: Vec<f64>| {
            d.sort_by(|a, b| a.total_cmp(b));
            d
        };
        let white = sorted(of.iter().map(|s| s.rival().1).collect());
        let forced = sorted(
            of.iter()
                .map(|s| {
                    s.distance_with_forces
                        .iter()
                        .enumerate()
                        .filter(|(j, _)| *j != s.class)
                        .map(|(_, d)| *d)
                        .fold(f64::INFINITY, f64::min)
                })
                .collect(),
        );
        let q = |d: &[f64], f: f64| d[((f * d.len() as f64) as usize).min(d.len() - 1)];
        let share =
            |d: &[f64], x: f64| d.iter().filter(|&&v| v < x).count() as f64 / d.len() as f64;
        // From above: the nearest rival alone; from below: every rival's error added.
        let ceiling: f64 = of.iter().map(|s| 1.0 - s.least_error()).sum();
        let ceiling_f: f64 = of.iter().map(|s| 1.0 - s.least_error_with_forces()).sum();
        let lower_f: f64 = of
            .iter()
            .map(|s| {
                let e: f64 = s
                    .distance_with_forces
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| *j != s.class)
                    .map(|(_, d)| normal_tail(d / 2.0))
                    .sum();
                1.0 - e.min(1.0)
            })
            .sum();
        totals[0] += ceiling;
        totals[1] += ceiling_f;
        totals[2] += lower_f;
        let mut rivals = vec![0usize; names.len()];
        for s in &of {
            rivals[s.rival().0] += 1;
        }
        let rivals: Vec<String> = rivals
            .iter()
            .enumerate()
            .filter(|(_, n)| **n > 0)
            .map(|(j, n)| format!("{} {n}", names[j]))
            .collect();
        let n = of.len() as f64;
        println!(
            "{:10} {:>5} | {:>8.2} {:>7.1}% | {:>8.2} {:>8.2} {:>5.0}% {:>5.0}% {:>7.1}% {:>7.1}% | {}",
            name,
            of.len(),
            q(&white, 0.5),
            100.0 * ceiling / n,
            q(&forced, 0.1),
            q(&forced, 0.5),
            100.0 * share(&forced, 2.0),
            100.0 * share(&forced, 4.0),
            100.0 * ceiling_f / n,
            100.0 * lower_f / n,
            rivals.join(", ")
        );
    }
    let n = sep.len() as f64;
    println!(
        "all: sensor noise alone, ceiling {:.1}%; with the random forces, ceiling {:.1}%, lower {:.1}%",
        100.0 * totals[0] / n,
        100.0 * totals[1] / n,
        100.0 * totals[2] / n
    );
    let before: f64 = sep
        .iter()
        .map(|s| {
            s.start_distance
                .iter()
                .zip(&s.distance)
                .enumerate()
                .filter(|(k, _)| *k != s.class)
                .map(|(_, (a, b))| a / b.max(1e-12))
                .fold(0.0f64, f64::max)
        })
        .sum::<f64>()
        / sep.len() as f64;
    // The experiment's noisy runs of the same draws: each class's nearest run, searched from
    // the pose found above (the truth's own for its class), under the noise an estimator
    // measures on them.
    let (noisy, _) = family
        .simulate_completed(&draws, &noise, 1 ^ 0xe3a2, &|| {})
        .unwrap();
    let measured = ShapeSample::measured_noise(&noisy).unwrap();
    let named: Vec<(usize, bool, f64, bool)> = sep
        .par_iter()
        .zip(&clean)
        .map(|(s, c)| {
            let y = noisy
                .iter()
                .find(|n| n.class == c.class && n.params == c.params)
                .expect("the same draw");
            let fits: Vec<Option<(f64, Vec<f64>)>> = (0..names.len())
                .map(|k| nearest_from(&family, &y.whiskers, measured, k, &s.pose[k], 4))
                .collect();
            let chi2: Vec<f64> = fits
                .iter()
                .map(|f| f.as_ref().map_or(f64::INFINITY, |f| f.0))
                .collect();
            // The same poses, the recording's likelihood with the random forces' response
            // counted as noise at each pose.
            let ll: Vec<f64> = fits
                .iter()
                .enumerate()
                .map(|(k, f)| {
                    f.as_ref()
                        .and_then(|(_, p)| {
                            forced_log_likelihood(
                                &family,
                                &y.whiskers,
                                sigma,
                                k,
                                p,
                                noise.process,
                                40,
                                0xf0ce,
                            )
                        })
                        .unwrap_or(f64::NEG_INFINITY)
                })
                .collect();
            let gls_right = (0..names.len())
                .filter(|&k| k != s.class)
                .all(|k| ll[k] < ll[s.class]);
            let own = chi2[s.class];
            if std::env::var_os("E3_SEPARATION_VERBOSE").is_some() {
                let at_truth = nearest_from(&family, &y.whiskers, measured, s.class, &c.params, 0)
                    .map_or(f64::NAN, |f| f.0);
                let n: usize = y.whiskers.iter().flatten().map(Vec::len).sum();
                eprintln!(
                    "{} {:?}: χ²/n at the truth {:.2}, per class {:?}",
                    names[s.class],
                    c.params,
                    at_truth / n as f64,
                    chi2.iter()
                        .map(|v| (v / n as f64 * 100.0).round() / 100.0)
                        .collect::<Vec<_>>()
                );
            }
            let rival = chi2
                .iter()
                .enumerate()
                .filter(|(k, _)| *k != s.class)
                .map(|(_, v)| *v)
                .fold(f64::INFINITY, f64::min);
            (s.class, own < rival, rival - own, gls_right)
        })
        .collect();
    let right = named.iter().filter(|r| r.1).count();
    println!(
        "noisy runs (sensor noise and random forces), each class's nearest run searched from the \
         poses above, χ² under the measured noise [{}]: the least χ² names {right} of {} right \
         ({:.1}%)",
        measured
            .iter()
            .map(|s| format!("{s:.3e}"))
            .collect::<Vec<_>>()
            .join(", "),
        named.len(),
        100.0 * right as f64 / named.len() as f64
    );
    let gls = named.iter().filter(|r| r.3).count();
    println!(
        "  with the random forces' response at each found pose counted as noise (40 runs per \
         pose), the most likely class is right on {gls} of {} ({:.1}%)",
        named.len(),
        100.0 * gls as f64 / named.len() as f64
    );
    for (k, name) in names.iter().enumerate() {
        let of: Vec<_> = named.iter().filter(|r| r.0 == k).collect();
        let mut gap: Vec<f64> = of.iter().map(|r| r.2).collect();
        gap.sort_by(|a, b| a.total_cmp(b));
        println!(
            "  {name}: {} of {} right ({} with the forces); χ² gap to the nearest rival q10 {:.1}, median {:.1}",
            of.iter().filter(|r| r.1).count(),
            of.len(),
            of.iter().filter(|r| r.3).count(),
            gap.get(gap.len() / 10).copied().unwrap_or(f64::NAN),
            gap.get(gap.len() / 2).copied().unwrap_or(f64::NAN)
        );
    }
    // The same, searched as an estimator without the truth would: every class from the nearest
    // of an evenly spread pool of noise-free runs.
    let pool_draws = family.even_draws(pool_per_class, 0x5e9b);
    let (pool, _) = family
        .simulate_completed(&pool_draws, &Noise::NONE, 0, &|| {})
        .unwrap();
    let searched: Vec<(usize, bool, bool)> = noisy
        .par_iter()
        .map(|y| {
            let found = search_every_class(&family, &y.whiskers, measured, &pool);
            let chi2: Vec<f64> = found.iter().map(|f| f.0).collect();
            let ll: Vec<f64> = found
                .iter()
                .enumerate()
                .map(|(k, (_, p))| {
                    forced_log_likelihood(
                        &family,
                        &y.whiskers,
                        sigma,
                        k,
                        p,
                        noise.process,
                        40,
                        0xf0ce,
                    )
                    .unwrap_or(f64::NEG_INFINITY)
                })
                .collect();
            let top = |v: &[f64], larger: bool| {
                (0..v.len())
                    .max_by(|&a, &b| {
                        if larger {
                            v[a].total_cmp(&v[b])
                        } else {
                            v[b].total_cmp(&v[a])
                        }
                    })
                    .unwrap_or(0)
            };
            (
                y.class,
                top(&chi2, false) == y.class,
                top(&ll, true) == y.class,
            )
        })
        .collect();
    let n = searched.len() as f64;
    println!(
        "searched from the nearest 3 of {pool_per_class} evenly spread noise-free runs per class (no truth): \
         the least χ² names {:.1}% right, the likelihood with the forces' response {:.1}%",
        100.0 * searched.iter().filter(|r| r.1).count() as f64 / n,
        100.0 * searched.iter().filter(|r| r.2).count() as f64 / n
    );
    for (k, name) in names.iter().enumerate() {
        let of: Vec<_> = searched.iter().filter(|r| r.0 == k).collect();
        println!(
            "  {name}: {} and {} of {}",
            of.iter().filter(|r| r.1).count(),
            of.iter().filter(|r| r.2).count(),
            of.len()
        );
    }
    println!(
        "the search shrank the distance to the nearest evenly spread run by up to {before:.1} \
         times on average"
    );
    if let Some(path) = csv {
        let mut out = String::from("run,class");
        for n in &names {
            out.push_str(&format!(",delta_{n}"));
        }
        for n in &names {
            out.push_str(&format!(",delta_forces_{n}"));
        }
        out.push_str(",params\n");
        for (i, s) in sep.iter().enumerate() {
            out.push_str(&format!("{i},{}", names[s.class]));
            for d in s.distance.iter().chain(&s.distance_with_forces) {
                out.push_str(&format!(",{d:.4}"));
            }
            let p: Vec<String> = clean[i].params.iter().map(|v| format!("{v:.5}")).collect();
            out.push_str(&format!(",{}\n", p.join(" ")));
        }
        std::fs::write(&path, out).expect("write the CSV");
    }
}
