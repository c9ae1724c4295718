//! `vibrissa calibrate`: fits the whisker and sensor parameters of a nominal scenario to
//! labelled recordings and writes the fitted scenario.
//!
//! The fit itself is [`vibrissa_infer::calibrate`]; this command reads the folder, shows the
//! fit's progress, prints what was fitted (value, standard error, or why a parameter was held)
//! and the residual RMS per channel before and after, draws the fitted runs over the recordings
//! (`--plot`), and writes `--out` only when everything succeeded.

use crate::files::Pending;
use crate::output::{sig, Align, FormatArgs, Render, Table};
use crate::plot::{self, Axis, Curve, Panel};
use crate::progress::Progress;
use anyhow::{bail, Context, Result};
use serde::Serialize;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use vibrissa_infer::calibrate::{calibrate, ChannelFit, Fit, ParameterFit, Settings, UNITS};
use vibrissa_io::labelled::{read_labelled, Options};
use vibrissa_io::scenario::Document;

/// Arguments of `vibrissa calibrate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The nominal scenario: what is believed about the whisker, its sensors and the
    /// experiment (a TOML file, or the built-in e1 or e2).
    #[arg(long, value_name = "FILE.toml")]
    pub scenario: String,
    /// Override a key of the nominal scenario (repeatable), e.g. `--set whisker.length=0.04`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub sets: Vec<String>,
    /// Folder of labelled recordings: CSV files and `truth.csv` (a `file` column, then one
    /// column per label named by its scenario key, e.g. `file,d,v`; every unknown of the
    /// scenario needs a column).
    #[arg(long, value_name = "DIR")]
    pub labelled: PathBuf,
    /// Where the fitted scenario goes (TOML): the nominal with the fitted values and a
    /// `[calibration]` table of standard errors; written only if the fit succeeds.
    #[arg(long, value_name = "FILE.toml")]
    pub out: PathBuf,
    /// Skip CSV files in the folder that `truth.csv` does not name (by default an error).
    #[arg(long)]
    pub ignore_unlisted: bool,
    /// Draw the recordings with the nominal and fitted simulations into this PNG file.
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
    /// How well the sensors' gains are known beforehand: the prior standard deviation of each
    /// fitted gain about the nominal scenario's, relative (0.1 = ±10%; 0: no prior, maximum
    /// likelihood alone, which lets the angle gains trade against the follicle and the taper).
    #[arg(long, default_value_t = Settings::default().gain_prior, value_name = "FRACTION")]
    pub gain_prior: f64,
    /// Most Levenberg–Marquardt iterations of one fit.
    #[arg(long, default_value_t = Settings::default().max_iterations)]
    pub max_iterations: usize,
    /// Starting points carried on to convergence after the short fits: the lowest minimum is
    /// the fit, and the others within twice its cost widen the standard errors (the cost has
    /// many minima; more finalists search wider, at about a tenth more time each).
    #[arg(long, default_value_t = Settings::default().finalists, value_name = "N")]
    pub finalists: usize,
    #[command(flatten)]
    pub format: FormatArgs,
}

/// Size of a correlation between two parameters' errors that the report names.
const STRONG_CORRELATION: f64 = 0.9;

/// How many such pairs the report names (the rest are counted).
const SHOWN_CORRELATIONS: usize = 4;

/// What `calibrate` prints.
#[derive(Debug, Serialize)]
struct Report {
    /// The nominal scenario.
    nominal: String,
    /// The folder fitted.
    labelled: String,
    /// The fitted scenario written.
    out: String,
    /// Recordings fitted.
    recordings: usize,
    /// Recordings skipped (not named in truth.csv).
    ignored: Vec<String>,
    /// Every parameter considered.
    parameters: Vec<ParameterFit>,
    /// Residuals per channel.
    channels: Vec<ChannelFit>,
    /// Levenberg–Marquardt iterations, fits and simulations.
    iterations: usize,
    fits: usize,
    simulations: usize,
    /// Other minima of the cost whose spread is in the standard errors.
    other_minima: usize,
    /// Correlations of the determined parameters' errors.
    correlation: vibrissa_io::scenario::Correlation,
    /// Channels left out of the fit: one value in every strike (channel, value).
    left_out: Vec<(&'static str, f64)>,
    /// Channels left out of single strikes: one value there while they vary in others
    /// (strike, channel, value).
    flat_in: Vec<(String, &'static str, f64)>,
    /// Substeps near contact that the fit simulated with and wrote into the fitted file, where
    /// the nominal left them to their default (`None`: as the nominal says).
    contact_substeps: Option<usize>,
    /// Whether the fit held contacts and wrote `hold_contacts = true` into the fitted file,
    /// where the nominal left it to its default.
    hold_contacts: bool,
    /// Wall-clock time of the fit, s.
    seconds: f64,
}

/// Runs `vibrissa calibrate`.
pub fn run(args: &Args) -> Result<()> {
    if !matches!(args.out.extension().and_then(|e| e.to_str()), Some("toml")) {
        bail!(
            "--out `{}`: the fitted scenario is a TOML file; give a name ending in .toml",
            args.out.display()
        );
    }
    crate::files::check_folder(&args.out, "--out")?;
    if let Some(png) = &args.plot {
        plot::check_png(png)?;
        crate::files::check_folder(png, "--plot")?;
    }
    if args.max_iterations == 0 {
        bail!("--max-iterations must be at least 1");
    }
    if args.finalists == 0 {
        bail!("--finalists must be at least 1 (the start whose minimum is the fit)");
    }
    if !(args.gain_prior >= 0.0 && args.gain_prior.is_finite()) {
        bail!(
            "--gain-prior {}: give the gains' relative prior standard deviation, a number ≥ 0 \
             (0.1 = known to ±10%; 0 = no prior)",
            args.gain_prior
        );
    }
    let nominal = Document::load(&args.scenario, &args.sets)?;
    nominal
        .loaded()
        .with_context(|| format!("the nominal scenario `{}`", args.scenario))?;
    let options = Options {
        ignore_unlisted: args.ignore_unlisted,
    };
    let set = read_labelled(&args.labelled, &nominal, &options)?;
    for name in &set.ignored {
        eprintln!("note: {name} is not named in truth.csv; skipped");
    }

    let settings = Settings {
        max_iterations: args.max_iterations,
        gain_prior: args.gain_prior,
        finalists: args.finalists,
        ..Settings::default()
    };
    let start = Instant::now();
    let mut progress = Progress::fraction(Duration::ZERO);
    let mut stage = String::new();
    let fit = calibrate(&nominal, &set, &settings, &mut |p| {
        if p.stage != stage {
            stage.clone_from(&p.stage);
            progress.message(&p.stage);
        }
    });
    progress.finish();
    let fit = fit.with_context(|| {
        format!(
            "calibration on {} failed; {} was not written",
            args.labelled.display(),
            args.out.display()
        )
    })?;
    let seconds = start.elapsed().as_secs_f64();
    for (name, value) in &fit.left_out {
        eprintln!(
            "warning: channel `{name}` holds {} in every strike: a sensor that recorded nothing? \
             It is left out of the fit (leave the column out of the recordings to say so)",
            sig(*value, 3)
        );
    }
    for (file, name, value) in &fit.flat_in {
        eprintln!(
            "warning: `{file}`: channel `{name}` holds {} from the first sample to the last while \
             it varies in other strikes: a sensor that recorded nothing in this strike? It is \
             left out of this strike's fit",
            sig(*value, 3)
        );
    }

    let labelled = recorded_folder(&args.labelled, &args.out);
    let fitted = fit.document(&nominal, &labelled)?;
    let figure = match &args.plot {
        Some(png) => Some(draw(png, &fit, &args.scenario)?),
        None => None,
    };
    fitted
        .write(&args.out)
        .with_context(|| format!("cannot write the fitted scenario {}", args.out.display()))?;
    if let Some(figure) = figure {
        figure.commit()?;
    }

    let report = Report {
        nominal: nominal.origin().to_string(),
        labelled,
        out: args.out.display().to_string(),
        recordings: set.recordings.len(),
        ignored: set.ignored.clone(),
        parameters: fit.parameters.clone(),
        channels: fit.channels.clone(),
        iterations: fit.iterations,
        fits: fit.fits,
        simulations: fit.simulations,
        other_minima: fit.other_minima,
        correlation: fit.correlation.clone(),
        left_out: fit.left_out.clone(),
        flat_in: fit.flat_in.clone(),
        contact_substeps: fit.contact_substeps,
        hold_contacts: fit.hold_contacts,
        seconds,
    };
    args.format.format().print(&report)?;
    Ok(())
}

impl Render for Report {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        writeln!(
            out,
            "calibrated {} on {} recordings in {} ({:.1} s, {} simulations)",
            self.nominal, self.recordings, self.labelled, self.seconds, self.simulations
        )?;
        if let Some(m) = self.contact_substeps {
            writeln!(
                out,
                "contact simulated in {m} substeps of each step near the object \
                 (contact_substeps = {m}, written to the fitted file, so that what is trained on \
                 it simulates as the fit did)"
            )?;
        }
        if self.hold_contacts {
            writeln!(
                out,
                "contacts held while the whisker still closes on the object (hold_contacts = \
                 true, written to the fitted file; docs/contact.md, \"Held contacts\")"
            )?;
        }
        writeln!(out, "\nparameters:")?;
        let mut table = Table::new(&[
            ("key", Align::Left),
            ("nominal", Align::Right),
            ("fitted", Align::Right),
            ("std. error", Align::Right),
            ("unit", Align::Left),
        ]);
        let mut notes = Vec::new();
        for p in &self.parameters {
            let nominal = p.nominal.map_or("clamped".to_string(), |v| sig(v, 4));
            let (value, error) = if p.determined {
                (
                    sig(p.value, 5),
                    p.std_error.map_or("-".to_string(), |e| sig(e, 2)),
                )
            } else {
                ("held".to_string(), "-".to_string())
            };
            table.row(vec![
                p.key.clone(),
                nominal,
                value,
                error,
                p.unit.to_string(),
            ]);
            if let Some(note) = &p.note {
                notes.push(format!("{}: {note}", p.key));
            }
        }
        table.write(out, "  ")?;
        for note in notes {
            writeln!(out, "  - {note}")?;
        }
        writeln!(
            out,
            "  the standard errors include the spread of {} other minim{} of the cost within \
             twice the best one's{}",
            self.other_minima,
            if self.other_minima == 1 { "um" } else { "a" },
            if self.other_minima == 0 {
                " (none found: the errors are the local ones only)"
            } else {
                ""
            }
        )?;
        // The pairs whose errors move together most, among the whisker's parameters and the
        // gains (the offsets' correlations are in the file and the JSON).
        let strong = self.correlation.strongest(STRONG_CORRELATION, |k| {
            k.starts_with("whisker.") || k.ends_with(".gain")
        });
        if !strong.is_empty() {
            let shown: Vec<String> = strong
                .iter()
                .take(SHOWN_CORRELATIONS)
                .map(|(a, b, r)| format!("{a} and {b} {r:+.2}"))
                .collect();
            writeln!(
                out,
                "  errors correlated by {STRONG_CORRELATION} or more: {}{}",
                shown.join(", "),
                match strong.len().saturating_sub(SHOWN_CORRELATIONS) {
                    0 => String::new(),
                    1 => " and 1 more pair".to_string(),
                    more => format!(" and {more} more pairs"),
                }
            )?;
        }
        writeln!(out, "\nresidual RMS per channel:")?;
        let mut table = Table::new(&[
            ("channel", Align::Left),
            ("nominal", Align::Right),
            ("fitted", Align::Right),
            ("noise", Align::Right),
            ("unit", Align::Left),
        ]);
        for c in &self.channels {
            table.row(vec![
                c.name.to_string(),
                sig(c.rms_before, 3),
                sig(c.rms_after, 3),
                sig(c.noise, 3),
                c.unit.to_string(),
            ]);
        }
        table.write(out, "  ")?;
        writeln!(out, "\nwrote {}", self.out)
    }
}

/// The labelled folder as the fitted file records it, so that estimating finds it again from
/// anywhere (each training run then carries the fit's residual on one of its strikes): relative
/// to the fitted file's directory when the folder lies under it (the two move together),
/// absolute otherwise, as given when it cannot be resolved.
fn recorded_folder(labelled: &Path, out: &Path) -> String {
    let Ok(folder) = std::fs::canonicalize(labelled) else {
        return labelled.display().to_string();
    };
    let dir = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let beside = std::fs::canonicalize(dir).ok();
    match beside.and_then(|b| folder.strip_prefix(b).ok().map(Path::to_path_buf)) {
        Some(rel) if !rel.as_os_str().is_empty() => rel.display().to_string(),
        _ => folder.display().to_string(),
    }
}

/// The recordings one after another (a gap between them), with the nominal and the fitted
/// simulations, one panel per channel.
fn draw(png: &Path, fit: &Fit, nominal: &str) -> Result<Pending> {
    let mut t = Vec::new();
    let mut recorded: Vec<Vec<f64>> = vec![Vec::new(); UNITS.len()];
    let mut before = recorded.clone();
    let mut after = recorded.clone();
    let mut offset = 0.0;
    for run in &fit.runs {
        let (Some(&t0), Some(&t1)) = (run.t.first(), run.t.last()) else {
            continue;
        };
        let gap = 0.1 * (t1 - t0);
        for &tk in &run.t {
            t.push(offset + tk - t0);
        }
        t.push(offset + (t1 - t0) + 0.5 * gap);
        for c in 0..UNITS.len() {
            let n = run.t.len();
            match &run.recorded[c] {
                Some(y) => recorded[c].extend_from_slice(y),
                None => recorded[c].extend(std::iter::repeat_n(f64::NAN, n)),
            }
            before[c].extend_from_slice(&run.nominal[c]);
            after[c].extend_from_slice(&run.fitted[c]);
            for v in [&mut recorded[c], &mut before[c], &mut after[c]] {
                v.push(f64::NAN);
            }
        }
        offset += (t1 - t0) + gap;
    }
    let names = ["θ01", "θ12", "m0", "fx", "fy"];
    let panels: Vec<Panel> = (0..UNITS.len())
        .filter(|&c| recorded[c].iter().any(|v| v.is_finite()))
        .map(|c| Panel {
            quantity: names[c],
            unit: UNITS[c],
            curves: vec![
                Curve {
                    name: "recorded",
                    values: &recorded[c],
                    dashed: false,
                },
                Curve {
                    name: "nominal",
                    values: &before[c],
                    dashed: true,
                },
                Curve {
                    name: "fitted",
                    values: &after[c],
                    dashed: false,
                },
            ],
        })
        .collect();
    plot::render_series(
        png,
        &format!(
            "calibration of {nominal}: {} recordings, one after another",
            fit.runs.len()
        ),
        &Axis {
            quantity: "t",
            unit: "s",
            values: &t,
        },
        &panels,
        None,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use vibrissa_io::scenario::Correlation;

    #[test]
    fn the_labelled_folder_is_recorded_so_that_it_is_found_again() {
        let root = std::env::temp_dir().join(format!("vibrissa-recorded-{}", std::process::id()));
        let (calib, elsewhere) = (root.join("rig").join("calib"), root.join("other"));
        std::fs::create_dir_all(&calib).unwrap();
        std::fs::create_dir_all(&elsewhere).unwrap();
        let out = root.join("rig").join("fitted.toml");
        // Under the fitted file's directory: relative to it, so that the two move together.
        assert_eq!(recorded_folder(&calib, &out), "calib");
        // Elsewhere: absolute.
        let abs = recorded_folder(&calib, &elsewhere.join("fitted.toml"));
        assert!(
            Path::new(&abs).is_absolute() && abs.ends_with("calib"),
            "{abs}"
        );
        // Not found: as given.
        assert_eq!(recorded_folder(Path::new("no/such"), &out), "no/such");
        let _ = std::fs::remove_dir_all(&root);
    }

    fn report(matrix: Vec<Vec<f64>>) -> Report {
        Report {
            nominal: "nominal.toml".into(),
            labelled: "calib".into(),
            out: "fitted.toml".into(),
            recordings: 9,
            ignored: Vec::new(),
            parameters: Vec::new(),
            channels: Vec::new(),
            iterations: 10,
            fits: 2,
            simulations: 100,
            other_minima: 1,
            left_out: Vec::new(),
            flat_in: Vec::new(),
            correlation: Correlation {
                keys: vec![
                    "whisker.youngs_modulus".into(),
                    "whisker.density".into(),
                    "sensors.m0.offset".into(),
                ],
                matrix,
            },
            contact_substeps: Some(5),
            hold_contacts: true,
            seconds: 1.0,
        }
    }

    fn text(r: &Report) -> String {
        let mut out = Vec::new();
        r.render(&mut out).unwrap();
        String::from_utf8(out).unwrap()
    }

    #[test]
    fn the_report_names_the_strongly_correlated_whisker_parameters_and_gains() {
        let strong = report(vec![
            vec![1.0, 0.95, 0.99],
            vec![0.95, 1.0, 0.0],
            vec![0.99, 0.0, 1.0],
        ]);
        let t = text(&strong);
        assert!(
            t.contains("errors correlated by 0.9 or more: whisker.youngs_modulus and whisker.density +0.95"),
            "{t}"
        );
        // Offsets are left to the file and the JSON.
        assert!(!t.contains("sensors.m0.offset and"), "{t}");
        let weak = report(vec![
            vec![1.0, 0.5, 0.99],
            vec![0.5, 1.0, 0.0],
            vec![0.99, 0.0, 1.0],
        ]);
        assert!(!text(&weak).contains("errors correlated"));
        // The contact stepping the fit used is said, and nothing when the nominal set it.
        assert!(text(&weak).contains("contact_substeps = 5"));
        assert!(text(&weak).contains("hold_contacts = true"));
        let named = Report {
            contact_substeps: None,
            hold_contacts: false,
            ..weak
        };
        assert!(!text(&named).contains("contact_substeps"));
        assert!(!text(&named).contains("hold_contacts"));
    }
}
