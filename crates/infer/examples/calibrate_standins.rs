//! Calibrates stand-in "foreign" whiskers and checks what the fit recovers.
//!
//! ```sh
//! cargo run --release -p vibrissa-infer --example calibrate_standins -- \
//!     [--seeds 1..20] [--segments 20] [--discretisation gregory] [--nominal e2] [--out DIR] \
//!     [--calib-noise 0] [--step 0.03] [--gain-prior 0.1] [--noise-rounds 3] [--finalists 2]
//!     [--truth-start]
//! ```
//!
//! For every seed: draw a stand-in whisker from the nominal scenario (`vibrissa_infer::standin`),
//! write its 9 clean template strikes, calibrate the nominal on them, and compare each
//! determined parameter with its true value in units of its standard error. With the stand-in
//! made at the nominal's own segments and discretisation, the fitted model can match the truth,
//! so |z| ≤ 2 should hold for about 95% of parameters; with another discretisation the
//! parameters are effective ones and z measures the model difference as well.

use std::path::PathBuf;
use std::time::Instant;
use vibrissa_core::chain::Discretisation;
use vibrissa_infer::calibrate::{calibrate, Settings};
use vibrissa_infer::standin::{make, Options};
use vibrissa_io::labelled::{read_labelled, Options as LabelledOptions};
use vibrissa_io::scenario::Document;

fn main() {
    if let Err(e) = run() {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let (mut seeds, mut nominal, mut out) = ((1u64, 20u64), "e2".to_string(), None);
    let mut settings = Settings::default();
    let mut truth_start = false;
    let mut options = Options {
        segments: 20,
        discretisation: Discretisation::Gregory,
        off_grid: 0,
        ..Options::default()
    };
    while let Some(flag) = args.next() {
        let mut value = || args.next().ok_or(format!("{flag} needs a value"));
        match flag.as_str() {
            "--seeds" => {
                let v = value()?;
                let (a, b) = v.split_once("..").ok_or("--seeds A..B")?;
                seeds = (a.parse()?, b.parse()?);
            }
            "--segments" => options.segments = value()?.parse()?,
            "--discretisation" => options.discretisation = Discretisation::from_name(&value()?)?,
            "--nominal" => nominal = value()?,
            "--out" => out = Some(PathBuf::from(value()?)),
            "--calib-noise" => options.calib_noise = value()?.parse()?,
            "--step" => settings.step = value()?.parse()?,
            "--gain-prior" => settings.gain_prior = value()?.parse()?,
            "--noise-rounds" => settings.noise_rounds = value()?.parse()?,
            "--finalists" => settings.finalists = value()?.parse()?,
            "--truth-start" => truth_start = true,
            _ => return Err(format!("unknown option {flag}").into()),
        }
    }
    let root = out.unwrap_or_else(|| std::env::temp_dir().join("vibrissa-standins"));
    let doc = Document::load(&nominal, &[])?;
    let (mut inside, mut total, mut failed) = (0usize, 0usize, 0usize);
    let mut undetermined: std::collections::BTreeMap<String, usize> = Default::default();
    let mut seconds = Vec::new();
    for seed in seeds.0..=seeds.1 {
        let dir = root.join(format!("seed{seed}"));
        let standin = make(&doc, seed, &options)?;
        standin.write(&dir, &options)?;
        let mut truth = standin.true_values()?;
        // Diagnostic: start from the true whisker and sensors; the residual "before" is then the
        // truth's own (zero up to rounding for a stand-in made at the nominal's segments and
        // discretisation), and a fit that leaves the truth would show a cost without a minimum
        // there.
        let mut doc_used = doc.clone();
        if truth_start {
            doc_used = Document::load(&dir.join("standin.toml").to_string_lossy(), &[])?;
            for t in &truth {
                if t.key.starts_with("sensors.") {
                    doc_used.set(&format!("{}={}", t.key, t.value))?;
                }
            }
        }
        // The recordings cannot separate a common gain of the force channels from the whisker's
        // stiffness and mass: the fit holds the reference channel's gain (m0) at its nominal 1
        // and reports the modulus, the density and the follicle scaled by that gain, the other
        // force gains divided by it. The truth is compared in the same terms.
        let g = truth
            .iter()
            .find(|t| t.key == "sensors.m0.gain")
            .map_or(1.0, |t| t.value);
        for t in &mut truth {
            match t.key.as_str() {
                "whisker.youngs_modulus"
                | "whisker.density"
                | "whisker.follicle.stiffness"
                | "whisker.follicle.damping" => t.value *= g,
                "sensors.fx.gain" | "sensors.fy.gain" | "sensors.m0.gain" => t.value /= g,
                _ => {}
            }
        }
        let set = read_labelled(&dir.join("calib"), &doc_used, &LabelledOptions::default())?;
        let start = Instant::now();
        let fit = match calibrate(&doc_used, &set, &settings, &mut |_| {}) {
            Ok(f) => f,
            Err(e) => {
                println!("seed {seed}: {e}");
                failed += 1;
                continue;
            }
        };
        seconds.push(start.elapsed().as_secs_f64());
        println!(
            "seed {seed}: {:.1} s, {} simulations, {} iterations",
            seconds.last().unwrap_or(&0.0),
            fit.simulations,
            fit.iterations
        );
        for c in &fit.channels {
            println!(
                "  {:8} residual RMS {:.3e} -> {:.3e} {}",
                c.name, c.rms_before, c.rms_after, c.unit
            );
        }
        for p in &fit.parameters {
            let Some(t) = truth.iter().find(|t| t.key == p.key) else {
                continue;
            };
            match p.std_error {
                Some(se) if p.determined && t.value.is_finite() => {
                    let z = (p.value - t.value) / se;
                    total += 1;
                    inside += usize::from(z.abs() <= 2.0);
                    println!(
                        "  {:28} true {:>11.4e} fit {:>11.4e} ± {:>9.2e}  z {:+6.2}",
                        p.key, t.value, p.value, se, z
                    );
                }
                _ => {
                    *undetermined.entry(p.key.clone()).or_default() += 1;
                    println!(
                        "  {:28} true {:>11.4e} held {:>11.4e}  ({})",
                        p.key,
                        t.value,
                        p.value,
                        p.note.clone().unwrap_or_default()
                    );
                }
            }
        }
    }
    println!(
        "\n{inside} of {total} determined parameters within 2 standard errors ({:.0}%); {failed} fits failed",
        100.0 * inside as f64 / total.max(1) as f64
    );
    seconds.sort_by(f64::total_cmp);
    if let (Some(lo), Some(hi)) = (seconds.first(), seconds.last()) {
        println!(
            "calibration time {lo:.1}–{hi:.1} s (median {:.1} s)",
            seconds[seconds.len() / 2]
        );
    }
    for (k, n) in &undetermined {
        println!("not determined or not comparable: {k} in {n} stand-ins");
    }
    Ok(())
}
