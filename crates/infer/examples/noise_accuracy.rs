//! Measures the sensor noise estimate on folders written by the `standin` example.
//!
//! ```sh
//! cargo run --release -p vibrissa-infer --example noise_accuracy -- DIR... [--reference DIR]
//! ```
//!
//! For each DIR (its `eval/` recordings and `eval/noise.json`, the true σ per channel), prints per
//! channel the true σ, the estimate from all recordings pooled, and the estimate from each
//! recording alone (median, least and greatest), as ratios to the true σ. A folder without
//! `noise.json` (clean recordings) is compared with the σ of `--reference` instead.

use std::path::Path;
use vibrissa_infer::noise::{estimate, estimate_pooled};
use vibrissa_infer::CHANNELS;

type Res<T> = Result<T, Box<dyn std::error::Error>>;

/// Recordings (channel-major each) and their true noise per channel, if stated.
type Set = (Vec<Vec<Vec<f64>>>, Option<[f64; 5]>);

fn main() {
    if let Err(e) = run() {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

/// The recordings of `dir/eval` (channel-major) and their true noise, if stated.
fn read(dir: &Path) -> Res<Set> {
    let eval = dir.join("eval");
    let truth = std::fs::read_to_string(eval.join("truth.csv"))?;
    let mut runs = Vec::new();
    for line in truth.lines().skip(1) {
        let file = line.split(',').next().ok_or("empty line in truth.csv")?;
        let s = vibrissa_io::series::read_csv(eval.join(file))?;
        let mut run = Vec::new();
        for c in CHANNELS {
            run.push(s.column(c).ok_or(format!("{file} lacks {c}"))?.to_vec());
        }
        runs.push(run);
    }
    let sigma = match std::fs::read_to_string(eval.join("noise.json")) {
        Ok(text) => {
            let v: serde_json::Value = serde_json::from_str(&text)?;
            let mut s = [0.0; 5];
            for (c, name) in CHANNELS.iter().enumerate() {
                s[c] = v[name].as_f64().ok_or(format!("noise.json lacks {name}"))?;
            }
            Some(s)
        }
        Err(_) => None,
    };
    Ok((runs, sigma))
}

fn run() -> Res<()> {
    let mut dirs = Vec::new();
    let mut reference = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--reference" => reference = Some(args.next().ok_or("--reference needs a folder")?),
            _ => dirs.push(a),
        }
    }
    let reference = match reference {
        Some(r) => read(Path::new(&r))?.1,
        None => None,
    };
    let all: Vec<usize> = (0..CHANNELS.len()).collect();
    println!("| recordings | channel | true σ | pooled / true | one recording / true: median [least, greatest] |");
    println!("|---|---|---|---|---|");
    for dir in &dirs {
        let (runs, sigma) = read(Path::new(dir))?;
        let scale = match (sigma, reference) {
            (Some(s), _) => s,
            (None, Some(r)) => r,
            (None, None) => return Err(format!("{dir}: no noise.json; give --reference").into()),
        };
        let refs: Vec<&[Vec<f64>]> = runs.iter().map(|r| &r[..]).collect();
        let pooled = estimate_pooled(&refs, &all)?;
        let own = refs
            .iter()
            .map(|r| estimate(r, &all))
            .collect::<Result<Vec<_>, _>>()?;
        for c in all.iter().copied() {
            let mut r: Vec<f64> = own.iter().map(|o| o[c] / scale[c]).collect();
            r.sort_by(f64::total_cmp);
            println!(
                "| {dir} ({} runs) | {} | {:.3e}{} | {:.3} | {:.3} [{:.3}, {:.3}] |",
                runs.len(),
                CHANNELS[c],
                if sigma.is_some() { scale[c] } else { 0.0 },
                if sigma.is_some() {
                    ""
                } else {
                    " (vs the reference's)"
                },
                pooled[c] / scale[c],
                r[r.len() / 2],
                r[0],
                r[r.len() - 1]
            );
        }
    }
    Ok(())
}
