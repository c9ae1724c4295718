//! `vibrissa estimate --shapes FAMILY`: the class posterior and pose of the object in recordings
//! of one or several whiskers.
//!
//! Reads every file's whiskers (`c1.theta01`, … for an array; the plain columns for one
//! whisker), measures the sensor noise on the recordings, trains `shape-krr` once on runs of the
//! shape family simulated at the files' timing with that noise, and prints one estimate per
//! file: `"class"` (each class's probability) and the most probable class's pose unknowns.

use crate::estimate::{read_recording, Args};
use crate::output::Render;
use anyhow::{bail, Result};
use serde::Serialize;
use serde_json::{json, Map, Value};
use std::io::{self, Write};
use std::time::Instant;
use vibrissa_infer::experiment::Noise;
use vibrissa_infer::shapes::{ShapeFamily, ShapeKrr};
use vibrissa_infer::{Reader, CHANNELS};

/// Training runs per class by default.
const DEFAULT_TRAINING: usize = crate::experiment_shapes::DEFAULT_TRAINING;

/// The printed estimates, one per file.
#[derive(Debug, Serialize)]
#[serde(transparent)]
struct Estimates(Vec<Map<String, Value>>);

impl Render for Estimates {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        for e in &self.0 {
            if let Some(f) = e.get("file").and_then(|f| f.as_str()) {
                writeln!(out, "{f}:")?;
            }
            let mut classes: Vec<(&String, f64)> = e["class"]
                .as_object()
                .map(|m| {
                    m.iter()
                        .map(|(k, v)| (k, v.as_f64().unwrap_or(0.0)))
                        .collect()
                })
                .unwrap_or_default();
            classes.sort_by(|a, b| b.1.total_cmp(&a.1));
            let shown: Vec<String> = classes
                .iter()
                .map(|(k, p)| format!("{k} {:.2}", p))
                .collect();
            writeln!(out, "  class: {}", shown.join(", "))?;
            for (k, v) in e {
                if let Some(mean) = v.get("mean").and_then(|m| m.as_f64()) {
                    let ci = &v["ci90"];
                    writeln!(
                        out,
                        "  {k} = {} (90%: {} … {})",
                        crate::output::sig(mean, 4),
                        crate::output::sig(ci[0].as_f64().unwrap_or(f64::NAN), 4),
                        crate::output::sig(ci[1].as_f64().unwrap_or(f64::NAN), 4)
                    )?;
                }
            }
        }
        Ok(())
    }
}

/// Runs the shape estimate.
pub(crate) fn run(args: &Args, spec: &str) -> Result<()> {
    let started = Instant::now();
    if let Some(m) = args.method.as_deref() {
        if m != ShapeKrr::NAME {
            bail!(
                "--method {m}: shape families are estimated by {} (leave --method out)",
                ShapeKrr::NAME
            );
        }
    }
    if args.particles.is_some() || args.trace.is_some() || args.check || !args.prior.is_empty() {
        bail!("--particles, --trace, --check and --prior do not apply to shape families");
    }
    if !args.sets.is_empty() {
        bail!("--set does not apply to shape families: edit the class files");
    }
    let family = ShapeFamily::open(spec)?;
    let family = match &args.whiskers {
        Some(list) => {
            let names: Vec<&str> = list.split('+').map(str::trim).collect();
            family.with_whiskers(&names)?
        }
        None => family,
    };
    let whiskers = family.whiskers();
    let all: Vec<usize> = (0..CHANNELS.len()).collect();
    // Each file's whiskers, `[files][whiskers]`.
    let mut recordings = Vec::with_capacity(args.obs.len());
    for file in &args.obs {
        let per: Vec<_> = if whiskers.is_empty() {
            vec![read_recording(
                file,
                &all,
                Reader::Method(ShapeKrr::NAME),
                None,
            )?]
        } else {
            whiskers
                .iter()
                .map(|w| read_recording(file, &all, Reader::Method(ShapeKrr::NAME), Some(w)))
                .collect::<Result<_>>()?
        };
        recordings.push(per);
    }
    let first = &recordings[0][0];
    let (rate, samples) = (first.rate, first.t.len());
    for (file, per) in args.obs.iter().zip(&recordings) {
        let r = &per[0];
        if (r.rate - rate).abs() > 1e-6 * rate || r.t.len() != samples {
            bail!(
                "`{}` has {} samples at {} Hz where `{}` has {samples} at {rate} Hz: estimate \
                 recordings of one timing together",
                file.display(),
                r.t.len(),
                r.rate,
                args.obs[0].display()
            );
        }
        if let Some((c, _)) = r.constant_channels(&all).first() {
            eprintln!(
                "warning: `{}`: channel {} is constant",
                file.display(),
                CHANNELS[*c]
            );
        }
    }
    let timed = family.with_timing(rate, samples)?;
    // The sensor noise: stated, none, or measured on every whisker of every file.
    let series: Vec<&[Vec<f64>]> = recordings.iter().flatten().map(|r| &r.values[..]).collect();
    let measured = vibrissa_infer::noise::estimate_pooled(&series, &all)?;
    let stated = crate::estimate::stated_noise(&timed.classes()[0].family, &args.noise)?;
    let sensor: [f64; 5] = std::array::from_fn(|c| stated[c].unwrap_or(measured[c]));
    let training = args.training.unwrap_or(DEFAULT_TRAINING);
    if training < 20 {
        bail!("--training must be at least 20 runs per class (got {training})");
    }
    eprintln!(
        "training {} on {} runs per class of {} ({} whiskers)...",
        ShapeKrr::NAME,
        training,
        family.name(),
        whiskers.len().max(1)
    );
    let train = timed.randomised_if(args.randomise)?;
    let draws = timed.draws(training, true, args.seed);
    // Training runs carry the scenario's random forces (its `process_noise`, 0 unless stated)
    // and the sensor noise that the measured level leaves beyond their response.
    let class = &timed.classes()[0].family;
    let noise = class.training_sensor_noise(&Noise {
        sensor,
        process: class.base().process_noise,
    })?;
    let (runs, failed) = train.simulate_completed(&draws, &noise, args.seed ^ 0x5ea9, &|| {})?;
    for f in &failed {
        eprintln!("warning: a training run could not be simulated and is left out: {f}");
    }
    let model = ShapeKrr::fit(&timed, &runs)?;
    eprintln!("trained in {:.1} s", started.elapsed().as_secs_f64());
    let mut out = Vec::with_capacity(recordings.len());
    for (file, per) in args.obs.iter().zip(&recordings) {
        let t0 = Instant::now();
        let values: Vec<Vec<Vec<f64>>> = per.iter().map(|r| r.values.clone()).collect();
        let e = model.predict(&values)?;
        let mut m = Map::new();
        if args.obs.len() > 1 {
            m.insert("file".into(), json!(file.display().to_string()));
        }
        let class: Map<String, Value> =
            e.class.iter().map(|(k, p)| (k.clone(), json!(p))).collect();
        m.insert("class".into(), Value::Object(class));
        for (name, est) in &e.pose {
            m.insert(
                name.clone(),
                json!({"mean": est.mean, "std": est.std, "ci90": est.ci90}),
            );
        }
        m.insert("method".into(), json!(ShapeKrr::NAME));
        m.insert("seconds".into(), json!(t0.elapsed().as_secs_f64()));
        let noise: Map<String, Value> = CHANNELS
            .iter()
            .zip(sensor)
            .map(|(c, s)| (c.to_string(), json!(s)))
            .collect();
        m.insert("noise".into(), Value::Object(noise));
        out.push(m);
    }
    match args.format.format() {
        crate::output::Format::Json if out.len() == 1 => {
            println!("{}", serde_json::to_string_pretty(&out[0])?)
        }
        // JSON Lines, one object per file, as for the other estimators.
        crate::output::Format::Json => {
            for m in &out {
                println!("{}", serde_json::to_string(m)?);
            }
        }
        human => human.print(&Estimates(out))?,
    }
    Ok(())
}
