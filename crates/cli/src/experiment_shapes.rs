//! `vibrissa experiment e3`: shape recognition scored with one, three and five whiskers.
//!
//! Simulates held-out runs of every class (each whisker of the array once) and training runs
//! drawn from the classes' priors, fits the shape estimator on each whisker set, and prints the
//! class accuracy, the calibration of the class probabilities and each class's pose errors and
//! coverage. Writes `results.json` into the output folder, and with `--export` every evaluated
//! run as a scenario file with its truth.

use crate::output::{Align, Render, Table};
use crate::plot::{render_xy, Mark, XyFigure, XyPanel, XySet};
use crate::plot_matrix::{render_matrices, Matrix};
use anyhow::{Context, Result};
use serde::Serialize;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;
use vibrissa_infer::shapes::{
    evaluate_shapes, has_filter, needs_clean_runs, ShapeEvaluation, ShapeFamily, ShapeSettings,
    BANK_PER_CLASS, DEFAULT_SHAPE_METHODS, FILTER_METHODS, SHAPE_PF_PARTICLES,
};
use vibrissa_infer::Variant;

/// Training runs per class by default.
pub const DEFAULT_TRAINING: usize = vibrissa_infer::shapes::DEFAULT_TRAINING;
/// Evaluated runs per class by default.
pub const DEFAULT_RUNS: usize = 50;

/// What the shape experiment takes from the command line.
pub struct ShapeArgs<'a> {
    pub family: ShapeFamily,
    pub variant: Variant,
    pub seed: u64,
    pub out: Option<PathBuf>,
    pub training: Option<usize>,
    pub runs: Option<usize>,
    pub bank: Option<usize>,
    pub particles: Option<usize>,
    pub whiskers: Option<&'a str>,
    pub methods: &'a [String],
    pub randomise: bool,
    pub export: Option<&'a Path>,
    pub format: crate::output::Format,
}

/// The printed result.
#[derive(Debug, Serialize)]
struct Report {
    #[serde(flatten)]
    evaluation: ShapeEvaluation,
    /// Files written.
    files: Vec<PathBuf>,
    /// Wall time of the whole command, s.
    seconds: f64,
}

/// The whisker sets of `--whiskers` (counts such as `1,3,5`, or names joined by `+` such as
/// `c2+c3`), from the array's whiskers.
fn subsets(spec: Option<&str>, all: &[String]) -> Result<Vec<Vec<String>>> {
    let default = if all.len() == 5 { "1,3,5" } else { "" };
    let spec = spec.unwrap_or(default);
    if spec.is_empty() {
        return Ok(vec![all.to_vec()]);
    }
    spec.split(',')
        .map(|part| {
            let part = part.trim();
            if let Ok(n) = part.parse::<usize>() {
                if n == 0 || n > all.len() || n % 2 == 0 && n != all.len() {
                    anyhow::bail!(
                        "--whiskers: {n} is not a set of the array's {} whiskers (an odd \
                         count, the middle ones, up to {}; or names joined by +)",
                        all.len(),
                        all.len()
                    );
                }
                // The middle n whiskers.
                let first = (all.len() - n) / 2;
                Ok(all[first..first + n].to_vec())
            } else {
                let names: Vec<String> = part.split('+').map(|s| s.trim().to_string()).collect();
                if let Some(n) = names.iter().find(|n| !all.contains(n)) {
                    anyhow::bail!(
                        "--whiskers: no whisker `{n}` (the array's whiskers: {})",
                        all.join(", ")
                    );
                }
                Ok(names)
            }
        })
        .collect()
}

/// Runs the shape experiment, writes its files and prints the table.
pub fn run(args: ShapeArgs) -> Result<()> {
    let start = Instant::now();
    let family = args.family;
    let subsets = subsets(args.whiskers, &family.whiskers())?;
    let settings = ShapeSettings {
        train_per_class: args.training.unwrap_or(DEFAULT_TRAINING),
        eval_per_class: args.runs.unwrap_or(DEFAULT_RUNS),
        bank_per_class: args.bank.unwrap_or(BANK_PER_CLASS),
        variant: args.variant,
        seed: args.seed,
        randomise: args.randomise,
        subsets,
        methods: if args.methods.is_empty() {
            DEFAULT_SHAPE_METHODS
                .iter()
                .map(|m| m.to_string())
                .collect()
        } else {
            args.methods.to_vec()
        },
        particles: args.particles.unwrap_or(SHAPE_PF_PARTICLES),
    };
    if args.particles.is_some() && !settings.methods.iter().any(|m| has_filter(m)) {
        anyhow::bail!(
            "--particles sets the particles per class of {}: add --method {}",
            FILTER_METHODS.join(" and "),
            FILTER_METHODS[0]
        );
    }
    if settings.particles < 2 {
        anyhow::bail!(
            "--particles must be at least 2 per class (got {})",
            settings.particles
        );
    }
    if args.bank.is_some() && !settings.methods.iter().any(|m| needs_clean_runs(m)) {
        anyhow::bail!(
            "--bank sets the bank of shape-bank (and of shape-mix): add --method shape-bank"
        );
    }
    if settings.train_per_class < 20 {
        anyhow::bail!(
            "--training must be at least 20 runs per class (got {})",
            settings.train_per_class
        );
    }
    if settings.eval_per_class == 0 {
        anyhow::bail!("--runs must be at least 1 run per class (got 0)");
    }
    // The export folder is checked before the experiment runs: one that cannot be made would
    // otherwise be found out only after the experiment had written its results.
    if let Some(dir) = args.export {
        check_export_folder(dir)?;
    }
    let label = Path::new(family.name())
        .file_stem()
        .map_or("shapes".into(), |s| s.to_string_lossy().to_string());
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("experiment-{label}-{}", args.variant.name())));
    std::fs::create_dir_all(&out)
        .with_context(|| format!("cannot create the output folder `{}`", out.display()))?;
    let last = Mutex::new(0usize);
    let progress = |done: usize, total: usize| {
        let mut l = last.lock().expect("progress lock");
        let tenth = done * 10 / total.max(1);
        if tenth > *l || done == total {
            *l = tenth;
            eprintln!(
                "[{:6.2} s] simulate {done}/{total}",
                start.elapsed().as_secs_f64()
            );
        }
    };
    let evaluation = evaluate_shapes(&family, &settings, &progress)?;
    eprintln!("[{:6.2} s] scored", start.elapsed().as_secs_f64());

    let mut files = Vec::new();
    let json = out.join("results.json");
    crate::files::write_atomic(&json, serde_json::to_string_pretty(&evaluation)?.as_bytes())?;
    files.push(json);
    files.extend(figures(&evaluation, &out)?);
    if let Some(dir) = args.export {
        files.push(export(&family, &settings, dir)?);
    }
    args.format.print(&Report {
        evaluation,
        files,
        seconds: start.elapsed().as_secs_f64(),
    })?;
    Ok(())
}

/// Whether `dir` can become the export folder: a folder, or a path whose nearest existing
/// ancestor is a folder (an existing file, or a file on the way, cannot).
fn check_export_folder(dir: &Path) -> Result<()> {
    let existing = dir.ancestors().find(|a| a.exists());
    match existing {
        Some(a) if a == dir && !dir.is_dir() => anyhow::bail!(
            "--export {}: is a file, not a folder; name a new or existing folder",
            dir.display()
        ),
        Some(a) if !a.is_dir() => anyhow::bail!(
            "--export {}: `{}` is a file, so no folder can be made below it",
            dir.display(),
            a.display()
        ),
        _ => Ok(()),
    }
}

/// Writes every evaluated run of the experiment as a scenario file (its class's file with the
/// run's values set) into `dir`, with `truth.csv` naming each file's class and values.
fn export(family: &ShapeFamily, settings: &ShapeSettings, dir: &Path) -> Result<PathBuf> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create the export folder `{}`", dir.display()))?;
    let draws = vibrissa_infer::shapes::evaluated_draws(family, settings);
    let mut names: Vec<String> = Vec::new();
    for c in family.classes() {
        for u in c.family.unknowns() {
            if !names.iter().any(|n| n == u) {
                names.push(u.to_string());
            }
        }
    }
    let mut truth = format!("file,class,{}\n", names.join(","));
    for (k, (class, p)) in draws.iter().enumerate() {
        let c = &family.classes()[*class];
        let file = format!("run{k:04}-{}.toml", c.name);
        let doc = c.family.document_at(p)?;
        doc.write(&dir.join(&file))?;
        let values: Vec<String> = names
            .iter()
            .map(|n| {
                c.family
                    .unknowns()
                    .iter()
                    .position(|u| u == n)
                    .map_or(String::new(), |i| format!("{}", p[i]))
            })
            .collect();
        truth.push_str(&format!("{file},{},{}\n", c.name, values.join(",")));
    }
    let path = dir.join("truth.csv");
    crate::files::write_atomic(&path, truth.as_bytes())?;
    Ok(path)
}

/// The figures: the confusion matrix of every estimator and whisker set, the accuracy and log
/// loss against the number of whiskers, the reliability diagram of the class probabilities, and
/// an online estimator's posterior over time and accuracy after every sample.
fn figures(ev: &ShapeEvaluation, dir: &Path) -> Result<Vec<PathBuf>> {
    let mut pending = Vec::new();
    // One row per estimator, one column per whisker set.
    let mut methods: Vec<&str> = Vec::new();
    for s in &ev.subsets {
        if !methods.contains(&s.method.as_str()) {
            methods.push(&s.method);
        }
    }
    let matrices: Vec<Matrix> = methods
        .iter()
        .flat_map(|m| ev.subsets.iter().filter(move |s| s.method == *m))
        .map(|s| Matrix {
            caption: format!(
                "{}, {} ({}): {:.0}% right",
                s.method,
                s.whiskers.join("+"),
                ev.variant.name(),
                100.0 * s.accuracy
            ),
            counts: s.confusion.clone(),
        })
        .collect();
    pending.extend(render_matrices(
        &dir.join("confusion.png"),
        &format!("{}: estimated against true class", ev.family),
        &ev.classes,
        &matrices,
        matrices.len() / methods.len().max(1),
    )?);
    // Accuracy and log loss against the number of whiskers read, per estimator (sets of one
    // whisker each a dot).
    let point = |m: &str, f: &dyn Fn(&vibrissa_infer::shapes::SubsetResult) -> f64| {
        ev.subsets
            .iter()
            .filter(|s| s.method == m)
            .map(|s| (s.whiskers.len() as f64, f(s)))
            .collect::<Vec<(f64, f64)>>()
    };
    let mut sets = Vec::new();
    for (k, m) in methods.iter().enumerate() {
        sets.push(XySet {
            label: format!("{m}: accuracy"),
            points: point(m, &|s| s.accuracy),
            mark: Mark::LineDots,
            colour: Some(2 * k),
        });
        sets.push(XySet {
            label: format!("{m}: log loss"),
            points: point(m, &|s| s.log_loss),
            mark: Mark::Dots,
            colour: Some(2 * k + 1),
        });
    }
    sets.push(XySet {
        label: format!("chance ({} classes)", ev.classes.len()),
        points: vec![
            (1.0, 1.0 / ev.classes.len() as f64),
            (5.0, 1.0 / ev.classes.len() as f64),
        ],
        mark: Mark::Dashed,
        colour: None,
    });
    let accuracy = XyFigure {
        title: format!(
            "{} ({}): class accuracy and log loss against the whiskers read",
            ev.family,
            ev.variant.name()
        ),
        x_desc: "whiskers read".into(),
        y_desc: "accuracy; log loss (nats)".into(),
        log_y: false,
        columns: 1,
        legend_lower_right: false,
        panels: vec![XyPanel {
            caption: String::new(),
            sets,
        }],
    };
    pending.extend(render_xy(&dir.join("accuracy.png"), &accuracy)?);
    // Reliability: the mean top probability against the share right, per bin with runs.
    let mut sets: Vec<XySet> = ev
        .subsets
        .iter()
        .enumerate()
        .map(|(k, s)| XySet {
            label: set_label(s),
            points: s
                .reliability
                .iter()
                .filter(|b| b.runs > 0)
                .map(|b| (b.confidence, b.accuracy))
                .collect(),
            mark: Mark::LineDots,
            colour: Some(k),
        })
        .collect();
    sets.push(XySet {
        label: "calibrated".into(),
        points: vec![(0.0, 0.0), (1.0, 1.0)],
        mark: Mark::Dashed,
        colour: None,
    });
    let reliability = XyFigure {
        title: format!(
            "{} ({}): reliability of the class probabilities",
            ev.family,
            ev.variant.name()
        ),
        x_desc: "probability of the most probable class".into(),
        y_desc: "share of runs it was right".into(),
        log_y: false,
        columns: 1,
        legend_lower_right: true,
        panels: vec![XyPanel {
            caption: String::new(),
            sets,
        }],
    };
    pending.extend(render_xy(&dir.join("reliability.png"), &reliability)?);
    // The online estimator's posterior over time, with the most whiskers it read: the first
    // evaluated run of each class.
    if let Some(s) = ev
        .subsets
        .iter()
        .filter(|s| !s.traces.is_empty())
        .max_by_key(|s| s.whiskers.len())
    {
        let panels = s
            .traces
            .iter()
            .map(|t| XyPanel {
                caption: format!("a {} (run {})", ev.classes[t.class], t.run),
                sets: ev
                    .classes
                    .iter()
                    .enumerate()
                    .map(|(c, name)| XySet {
                        label: name.clone(),
                        points: t
                            .probabilities
                            .iter()
                            .enumerate()
                            .map(|(k, p)| ((k + 1) as f64 / ev.sample_rate * 1e3, p[c]))
                            .collect(),
                        mark: Mark::Line,
                        colour: Some(c),
                    })
                    .collect(),
            })
            .collect();
        let posterior = XyFigure {
            title: format!(
                "{} ({}): {}'s class posterior after every sample, {} whiskers",
                ev.family,
                ev.variant.name(),
                s.method,
                s.whiskers.len()
            ),
            x_desc: "time (ms)".into(),
            y_desc: "probability".into(),
            log_y: false,
            columns: 2,
            legend_lower_right: false,
            panels,
        };
        pending.extend(render_xy(&dir.join("posterior.png"), &posterior)?);
    }
    // How soon the online estimators know: their accuracy after every sample, per whisker set.
    let mut sets: Vec<XySet> = ev
        .subsets
        .iter()
        .filter(|s| !s.accuracy_over_time.is_empty())
        .enumerate()
        .map(|(k, s)| XySet {
            label: set_label(s),
            points: s
                .accuracy_over_time
                .iter()
                .enumerate()
                .map(|(i, a)| ((i + 1) as f64 / ev.sample_rate * 1e3, *a))
                .collect(),
            mark: Mark::Line,
            colour: Some(k),
        })
        .collect();
    if !sets.is_empty() {
        let end = sets
            .iter()
            .flat_map(|s| s.points.last())
            .fold(0.0f64, |m, p| m.max(p.0));
        sets.push(XySet {
            label: format!("chance ({} classes)", ev.classes.len()),
            points: vec![
                (0.0, 1.0 / ev.classes.len() as f64),
                (end, 1.0 / ev.classes.len() as f64),
            ],
            mark: Mark::Dashed,
            colour: None,
        });
        let over_time = XyFigure {
            title: format!(
                "{} ({}): accuracy of the online class posterior after every sample",
                ev.family,
                ev.variant.name()
            ),
            x_desc: "time (ms)".into(),
            y_desc: "share of runs whose most probable class is the truth".into(),
            log_y: false,
            columns: 1,
            legend_lower_right: true,
            panels: vec![XyPanel {
                caption: String::new(),
                sets,
            }],
        };
        pending.extend(render_xy(&dir.join("accuracy_time.png"), &over_time)?);
    }
    let mut files = Vec::new();
    for (path, file) in pending {
        file.commit()?;
        files.push(path);
    }
    Ok(files)
}

/// An estimator and whisker set, for a figure's legend.
fn set_label(s: &vibrissa_infer::shapes::SubsetResult) -> String {
    format!(
        "{}, {} ({})",
        s.method,
        whisker_count(s.whiskers.len()),
        s.whiskers.join("+")
    )
}

/// "1 whisker", "3 whiskers".
fn whisker_count(n: usize) -> String {
    if n == 1 {
        "1 whisker".into()
    } else {
        format!("{n} whiskers")
    }
}

/// Percent with no decimals.
fn pct(x: f64) -> String {
    format!("{:.0}%", 100.0 * x)
}

/// An unknown's error in display units: mm for lengths, degrees for angles, m/s for speeds.
fn shown(name: &str, x: f64) -> (String, &'static str) {
    match name {
        "angle" => (format!("{:.1}", x.to_degrees()), "deg"),
        "v" => (format!("{:.3}", x), "m/s"),
        _ => (format!("{:.2}", x * 1e3), "mm"),
    }
}

impl Render for Report {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        let ev = &self.evaluation;
        writeln!(
            out,
            "shape experiment {} ({}): classes {}; {} training and {} evaluated runs per class{}",
            ev.family,
            ev.variant.name(),
            ev.classes.join(", "),
            ev.train_per_class,
            ev.eval_per_class,
            if ev.randomise {
                "; training whiskers randomised"
            } else {
                ""
            }
        )?;
        let mut t = Table::new(&[
            ("method", Align::Left),
            ("whiskers", Align::Left),
            ("accuracy", Align::Right),
            ("log loss", Align::Right),
            ("ECE", Align::Right),
            ("fit (s)", Align::Right),
            ("estimate (ms)", Align::Right),
            ("online (ms)", Align::Right),
        ]);
        for s in &ev.subsets {
            t.row(vec![
                s.method.clone(),
                format!("{} ({})", s.whiskers.len(), s.whiskers.join("+")),
                pct(s.accuracy),
                format!("{:.3}", s.log_loss),
                format!("{:.3}", s.ece),
                format!("{:.1}", s.fit_seconds),
                format!("{:.2}", s.estimate_ms),
                s.online_ms.map_or("-".into(), |m| format!("{m:.2}")),
            ]);
        }
        t.write(out, "  ")?;
        writeln!(
            out,
            "pose of the runs classified right: mean absolute error (90% coverage)"
        )?;
        let mut t = Table::new(&[
            ("method", Align::Left),
            ("whiskers", Align::Left),
            ("class", Align::Left),
            ("right", Align::Right),
            ("pose", Align::Left),
        ]);
        for s in &ev.subsets {
            for p in &s.poses {
                let pose: Vec<String> = p
                    .unknowns
                    .iter()
                    .map(|u| {
                        let (e, unit) = shown(&u.name, u.mae);
                        format!("{} {e} {unit} ({})", u.name, pct(u.coverage))
                    })
                    .collect();
                t.row(vec![
                    s.method.clone(),
                    s.whiskers.len().to_string(),
                    p.class.clone(),
                    format!("{}/{}", p.right, p.runs),
                    if p.right == 0 {
                        "(no run classified right)".into()
                    } else {
                        pose.join(", ")
                    },
                ]);
            }
        }
        t.write(out, "  ")?;
        for s in &ev.subsets {
            writeln!(
                out,
                "confusion of {} with {} (rows: truth; columns: estimate {}):",
                s.method,
                whisker_count(s.whiskers.len()),
                ev.classes.join(", ")
            )?;
            for (c, row) in s.confusion.iter().enumerate() {
                let cells: Vec<String> = row.iter().map(|n| format!("{n:4}")).collect();
                writeln!(out, "  {:>9} {}", ev.classes[c], cells.join(""))?;
            }
        }
        if !ev.failed.is_empty() {
            writeln!(
                out,
                "{} runs could not be simulated and were left out:",
                ev.failed.len()
            )?;
            for f in &ev.failed {
                writeln!(out, "  {f}")?;
            }
        }
        writeln!(
            out,
            "simulated in {:.1} s; wall time {:.1} s; files:",
            ev.simulate_seconds, self.seconds
        )?;
        for f in &self.files {
            writeln!(out, "  {}", f.display())?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whisker_sets_are_counts_of_the_middle_ones_or_names() {
        let all: Vec<String> = ["c1", "c2", "c3", "c4", "c5"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let s = subsets(None, &all).unwrap();
        assert_eq!(s.len(), 3);
        assert_eq!((s[0][0].as_str(), s[1].len()), ("c3", 3));
        assert_eq!(s[1][0], "c2");
        assert_eq!(s[2], all);
        assert_eq!(
            subsets(Some("c1+c5"), &all).unwrap(),
            vec![vec!["c1", "c5"]]
        );
        for bad in ["0", "2", "7", "c9", "c1+x"] {
            assert!(subsets(Some(bad), &all).is_err(), "{bad}");
        }
    }
}
