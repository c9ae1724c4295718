//! `vibrissa estimate --shapes FAMILY`: the class posterior and pose of the object in recordings
//! of one or several whiskers.
//!
//! Reads every file's whiskers (`c1.theta01`, … for an array; the plain columns for one
//! whisker), measures the sensor noise on the recordings, trains the shape estimator
//! (`shape-krr`, the online `shape-esn`, or `shape-bank`) once on runs of the shape family
//! simulated at the files' timing with that noise, and prints one estimate per file: `"class"`
//! (each class's probability) and the most probable class's pose unknowns. With `shape-esn` or
//! `shape-bank`, `--trace` writes the class posterior after every sample and its plot.

use crate::estimate::{read_recording, Args};
use crate::files;
use crate::output::Render;
use crate::plot::{render_xy, Mark, XyFigure, XyPanel, XySet};
use anyhow::{bail, Result};
use serde::Serialize;
use serde_json::{Map, Value};
use std::io::{self, Write};
use std::path::Path;
use vibrissa_infer::shapes::{
    check_recordings, check_shape_method, estimate_batch, has_filter, needs_clean_runs,
    BatchOptions, ShapeBank, ShapeEsn, ShapeFamily, ShapeKrr, ShapeMix, ShapePf, DEFAULT_TRAINING,
    FILTER_METHODS, SHAPE_METHODS, SHAPE_PF_PARTICLES, SHAPE_PF_TRAINING,
};
use vibrissa_infer::{Reader, CHANNELS};

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
    let method = args.method.as_deref().unwrap_or(ShapeKrr::NAME);
    if check_shape_method(method).is_err() {
        bail!(
            "--method {method}: shape families are estimated by {}",
            SHAPE_METHODS.join(" or ")
        );
    }
    if args.check || !args.prior.is_empty() {
        bail!("--check and --prior do not apply to shape families");
    }
    if args.particles.is_some() && !has_filter(method) {
        bail!(
            "--particles sets the particles per class of {}, not of {method}",
            FILTER_METHODS.join(" and ")
        );
    }
    if args.particles.is_some_and(|n| n < 2) {
        bail!("--particles must be at least 2 per class (got 1)");
    }
    let online = [
        ShapeEsn::NAME,
        ShapeBank::NAME,
        ShapePf::NAME,
        ShapeMix::NAME,
    ];
    if args.trace.is_some() && !online.contains(&method) {
        bail!(
            "--trace with a shape family needs --method {} (the online estimators)",
            online.join(", ")
        );
    }
    crate::estimate::check_trace_file(args)?;
    let whisker = crate::estimate::whisker_source(args)?;
    let family = ShapeFamily::open_with(spec, &args.sets, whisker.as_ref())?;
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
            vec![read_recording(file, &all, Reader::Complete(method), None)?]
        } else {
            whiskers
                .iter()
                .map(|w| read_recording(file, &all, Reader::Complete(method), Some(w)))
                .collect::<Result<_>>()?
        };
        recordings.push(per);
    }
    if args.bank.is_some() && !needs_clean_runs(method) {
        anyhow::bail!(
            "--bank sets the bank of shape-bank (and of shape-mix): add --method shape-bank"
        );
    }
    let stated = crate::estimate::stated_noise(&family.classes()[0].family, &args.noise)?;
    let options = BatchOptions {
        method: method.to_string(),
        // The filter reads a few dozen training runs per class; the others learn from all.
        training: args.training.unwrap_or(if method == ShapePf::NAME {
            SHAPE_PF_TRAINING
        } else {
            DEFAULT_TRAINING
        }),
        bank: args.bank.unwrap_or(vibrissa_infer::shapes::BANK_PER_CLASS),
        seed: args.seed,
        randomise: args.randomise,
        stated,
        trace: args.trace.is_some(),
        particles: args.particles.unwrap_or(SHAPE_PF_PARTICLES),
    };
    let names: Vec<String> = args.obs.iter().map(|f| f.display().to_string()).collect();
    // Refused before training, not after it (its warnings come with the batch's).
    check_recordings(&family, &names, &recordings)?;
    let on = match &whisker {
        Some(w) if w.own.is_empty() => format!(", each the whisker of {}", w.describe()),
        Some(w) => format!(", their whiskers from {}", w.describe()),
        None => String::new(),
    };
    eprintln!(
        "training {} on {} runs per class of {} ({} whiskers{on})...",
        method,
        options.training,
        family.name(),
        whiskers.len().max(1)
    );
    let batch = estimate_batch(&family, &names, &recordings, &options)?;
    for w in &batch.warnings {
        eprintln!("warning: {w}");
    }
    eprintln!("trained in {:.1} s", batch.training_seconds);
    if !batch.settings.is_empty() {
        let fitted: Vec<String> = batch
            .settings
            .iter()
            .map(|(k, v)| {
                if *v != 0.0 && (v.abs() < 1e-3 || v.abs() >= 1e4) {
                    format!("{k} {v:.3e}")
                } else {
                    format!("{k} {v:.4}")
                }
            })
            .collect();
        eprintln!("fitted: {}", fitted.join(", "));
    }
    if let (Some(path), Some(trace), Some(first)) =
        (&args.trace, batch.traces.first(), recordings.first())
    {
        let t = &first[0].t;
        let classes: Vec<String> = family.class_names().iter().map(|c| c.to_string()).collect();
        write_trace(path, t, &classes, trace)?;
        eprintln!("wrote {} and its plot", path.display());
    }
    let out: Vec<Map<String, Value>> = batch.rows(&names).iter().map(|r| r.to_json()).collect();
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

/// Writes the class posterior after every sample as CSV (`t` and one column per class), and its
/// plot beside it (same name, .png).
fn write_trace(path: &Path, t: &[f64], classes: &[String], trace: &[Vec<f64>]) -> Result<()> {
    let mut csv = format!("t,{}\n", classes.join(","));
    for (tk, p) in t.iter().zip(trace) {
        let cells: Vec<String> = p.iter().map(|x| x.to_string()).collect();
        csv.push_str(&format!("{tk},{}\n", cells.join(",")));
    }
    let figure = XyFigure {
        title: format!(
            "class posterior after every sample ({})",
            path.file_name()
                .map_or(String::new(), |n| n.to_string_lossy().to_string())
        ),
        x_desc: "t (s)".into(),
        y_desc: "probability".into(),
        log_y: false,
        columns: 1,
        legend_lower_right: false,
        panels: vec![XyPanel {
            caption: String::new(),
            sets: classes
                .iter()
                .enumerate()
                .map(|(c, name)| XySet {
                    label: name.clone(),
                    points: t.iter().zip(trace).map(|(tk, p)| (*tk, p[c])).collect(),
                    mark: Mark::Line,
                    colour: Some(c),
                })
                .collect(),
        }],
    };
    let pending = render_xy(&path.with_extension("png"), &figure)?;
    files::write_atomic(path, csv.as_bytes())?;
    for (_, file) in pending {
        file.commit()?;
    }
    Ok(())
}
