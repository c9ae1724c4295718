//! How the time step changes the `e2` runs: every run of the grid (d = 15…30 mm in 1 mm steps,
//! v = 0.3…1.5 m/s, clean) is simulated at a fine reference step and at each step compared, and
//! for each step and each observed channel (theta01, theta12, m0, fx, fy, at the scenario's 1 kHz)
//! the root-mean-square difference to the reference, divided by the channel's range over the
//! reference run, is printed in percent: its largest value over the grid, its mean, and the grid's
//! root-mean-square (the square root of the mean of the squared values: the whole grid's series
//! against the whole grid's reference, each run in its own range). Also
//! printed: the wall time per simulated second (runs one after another, on one core) and the
//! steps taken per simulated second.
//!
//! ```sh
//! cargo run --release -p vibrissa-infer --example dt_accuracy -- [--quick] [--ref DT]
//!     [--dt DT,DT,...] [--set key=value]... [--scenario FILE.toml] [--both key=value]...
//! ```
//!
//! `--quick` runs a 4 × 3 subset of the grid (d = 15, 20, 25, 30 mm; v = 0.3, 0.9, 1.5 m/s).
//! `--ref` is the reference step (default 1e-5 s), `--dt` the steps compared (default 1e-4,
//! 2.5e-4, 5e-4, 1e-3 s). Every `--set` is applied to the compared runs (not to the reference),
//! as `vibrissa simulate --set` would, e.g. `--set contact_substeps=10`. `--scenario` replaces
//! the `e2` scenario by a file of the `e2` family (another whisker), and every `--both` is applied
//! to the reference and the compared runs alike (another chain: `--both segments=50`).

use std::time::Instant;
use vibrissa_core::sim;

const CHANNELS: [&str; 5] = ["theta01", "theta12", "m0", "fx", "fy"];

/// One run's channels, its steps and its wall time, s.
struct Run {
    rows: Vec<[f64; 5]>,
    steps: usize,
    wall: f64,
    duration: f64,
}

fn simulate(
    scenario: &str,
    d: f64,
    v: f64,
    dt: f64,
    sets: &[String],
) -> Result<Run, Box<dyn std::error::Error>> {
    let mut all = vec![format!("d={d}"), format!("v={v}"), format!("dt={dt}")];
    all.extend(sets.iter().cloned());
    let scenario = vibrissa_io::scenario::load(scenario, &all)?;
    let start = Instant::now();
    let out = sim::run(&scenario, &mut |_| {})?;
    let wall = start.elapsed().as_secs_f64();
    let rows = out
        .rows
        .iter()
        .map(|r| [r[1], r[2], r[3], r[4], r[5]])
        .collect();
    Ok(Run {
        rows,
        steps: out.steps,
        wall,
        duration: scenario.duration,
    })
}

/// Per channel: RMS of `run - reference` over the range of `reference`, %.
fn errors(run: &[[f64; 5]], reference: &[[f64; 5]]) -> [f64; 5] {
    let mut out = [0.0; 5];
    for (c, o) in out.iter_mut().enumerate() {
        let (lo, hi) = reference
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
                (lo.min(r[c]), hi.max(r[c]))
            });
        let ss: f64 = run
            .iter()
            .zip(reference)
            .map(|(a, b)| (a[c] - b[c]).powi(2))
            .sum();
        let rms = (ss / reference.len() as f64).sqrt();
        *o = 100.0 * rms / (hi - lo).max(f64::MIN_POSITIVE);
    }
    out
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut quick = false;
    let mut reference_dt = 1e-5;
    let mut dts = vec![1e-4, 2.5e-4, 5e-4, 1e-3];
    let mut sets = Vec::new();
    let mut both = Vec::new();
    let mut scenario = "e2".to_string();
    let mut k = 0;
    while k < args.len() {
        match args[k].as_str() {
            "--quick" => quick = true,
            "--ref" => {
                k += 1;
                reference_dt = args.get(k).ok_or("--ref needs a step")?.parse()?;
            }
            "--dt" => {
                k += 1;
                dts = args
                    .get(k)
                    .ok_or("--dt needs steps")?
                    .split(',')
                    .map(str::parse)
                    .collect::<Result<_, _>>()?;
            }
            "--set" => {
                k += 1;
                sets.push(args.get(k).ok_or("--set needs key=value")?.clone());
            }
            "--both" => {
                k += 1;
                both.push(args.get(k).ok_or("--both needs key=value")?.clone());
            }
            "--scenario" => {
                k += 1;
                scenario = args.get(k).ok_or("--scenario needs a file")?.clone();
            }
            other => return Err(format!("unknown argument {other}").into()),
        }
        k += 1;
    }
    let (ds, vs): (Vec<f64>, Vec<f64>) = if quick {
        (vec![0.015, 0.020, 0.025, 0.030], vec![0.3, 0.9, 1.5])
    } else {
        (
            (15..=30).map(|mm| mm as f64 * 1e-3).collect(),
            vec![0.3, 0.6, 0.9, 1.2, 1.5],
        )
    };
    let grid: Vec<(f64, f64)> = ds
        .iter()
        .flat_map(|&d| vs.iter().map(move |&v| (d, v)))
        .collect();
    eprintln!(
        "{} runs of {scenario} with {both:?}; reference dt = {reference_dt} s; compared runs with {:?}",
        grid.len(),
        sets
    );
    // The compared runs take the settings of both, then their own.
    let sets: Vec<String> = both.iter().chain(&sets).cloned().collect();

    let mut references = Vec::with_capacity(grid.len());
    let (mut ref_wall, mut ref_sim, mut ref_steps) = (0.0, 0.0, 0usize);
    for &(d, v) in &grid {
        let r = simulate(&scenario, d, v, reference_dt, &both)?;
        ref_wall += r.wall;
        ref_sim += r.duration;
        ref_steps += r.steps;
        references.push(r.rows);
    }

    println!(
        "{:>9} | {:>19} {:>19} {:>19} {:>19} {:>19} | {:>10} {:>10}",
        "dt (s)",
        "theta01 max/mean/rms",
        "theta12 max/mean/rms",
        "m0 max/mean/rms",
        "fx max/mean/rms",
        "fy max/mean/rms",
        "wall/sim",
        "steps/sim"
    );
    println!(
        "{:>9} | {:>99} | {:>10.4} {:>10.0}",
        reference_dt,
        "(reference)",
        ref_wall / ref_sim,
        ref_steps as f64 / ref_sim
    );
    for &dt in &dts {
        let (mut max, mut sum, mut squares) = ([0.0f64; 5], [0.0f64; 5], [0.0f64; 5]);
        let (mut wall, mut simulated, mut steps) = (0.0, 0.0, 0usize);
        let mut worst = [(0.0, 0.0); 5];
        for (&(d, v), reference) in grid.iter().zip(&references) {
            let r = simulate(&scenario, d, v, dt, &sets)?;
            wall += r.wall;
            simulated += r.duration;
            steps += r.steps;
            let e = errors(&r.rows, reference);
            for c in 0..5 {
                if e[c] > max[c] {
                    max[c] = e[c];
                    worst[c] = (d, v);
                }
                sum[c] += e[c];
                squares[c] += e[c] * e[c];
            }
        }
        let cells: Vec<String> = (0..5)
            .map(|c| {
                let n = grid.len() as f64;
                format!(
                    "{:>6.3}/{:.3}/{:<6.3}",
                    max[c],
                    sum[c] / n,
                    (squares[c] / n).sqrt()
                )
            })
            .collect();
        println!(
            "{:>9} | {} | {:>10.4} {:>10.0}",
            dt,
            cells.join(" "),
            wall / simulated,
            steps as f64 / simulated
        );
        let at: Vec<String> = (0..5)
            .map(|c| format!("{} at d={:.3} v={:.1}", CHANNELS[c], worst[c].0, worst[c].1))
            .collect();
        eprintln!("  worst: {}", at.join(", "));
    }
    Ok(())
}
