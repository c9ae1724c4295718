//! `vibrissa simulate`: one run of a scenario, written as a time series (and a figure).
//!
//! The scenario is loaded and checked, run, and written in the contract's columns, with its
//! metadata in a JSON sidecar beside it (`run.json` beside `run.csv`); `--plot` also draws the
//! observed channels over time like the seed paper's Fig. 3, with the contact period shaded.
//! Every output file appears whole or not at all: the figure is drawn first into a temporary
//! file, the series and its sidecar are written (atomically), and only then is the figure
//! renamed into place. On any error no output file is left behind.

use crate::animate;
use crate::files;
use crate::frames;
use crate::output::{sig, FormatArgs, Render};
use crate::plot::{self, Axis, Curve, Panel};
use crate::progress::Progress;
use anyhow::{bail, Result};
use serde::Serialize;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use vibrissa_core::sim::{self, Output, COLUMNS};
use vibrissa_io::scenario::{self, Loaded};
use vibrissa_io::series::{self, Series, EXTENSIONS};
use vibrissa_io::sweep::series_of;

/// Arguments of `vibrissa simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scenario: a built-in experiment (e1, e2) or the path of a TOML scenario file.
    #[arg(value_name = "SCENARIO")]
    scenario: String,
    /// Overrides a scenario key, e.g. `d=0.023`, `whisker.length=0.04`,
    /// `objects.0.friction=0.3` (repeatable; applied in order).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Time-series file to write; its extension picks the format: .csv, .npy or .npz. The run's
    /// metadata goes beside it, into the same name with the extension .json.
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Also draw the observed channels over time into this PNG file.
    #[arg(long, value_name = "FILE.png")]
    plot: Option<PathBuf>,
    /// Also animate the whisker and the objects into this GIF file (600 × 300 px, 25 frames
    /// per second, at most 150 frames spread evenly over the run).
    #[arg(long, value_name = "FILE.gif")]
    animate: Option<PathBuf>,
    #[command(flatten)]
    format: FormatArgs,
}

/// Runs shorter than this show no progress.
const PROGRESS_DELAY: Duration = Duration::from_secs(1);

/// Loads, runs and writes one scenario, then prints its summary.
pub fn run(args: &Args) -> Result<()> {
    // Refuse unusable output paths before computing anything.
    check_series_path(&args.out)?;
    files::check_folder(&args.out, "--out")?;
    if let Some(plot) = &args.plot {
        plot::check_png(plot)?;
        files::check_folder(plot, "--plot")?;
        if plot == &args.out {
            bail!("--out and --plot name the same file `{}`", plot.display());
        }
    }
    if let Some(gif) = &args.animate {
        animate::check_gif(gif)?;
        files::check_folder(gif, "--animate")?;
        if gif == &args.out {
            bail!("--out and --animate name the same file `{}`", gif.display());
        }
    }

    // Load and run, with progress on standard error for long runs.
    let loaded = scenario::load_full(&args.scenario, &args.sets)?;
    let objects = !loaded.scenario.objects.is_empty();
    if let Some(w) = loaded.scenario.integrator.coarse_contact_warning(objects) {
        eprintln!("warning: {w}");
    }
    if !loaded.whiskers.is_empty() {
        return run_array(args, &loaded);
    }
    let start = Instant::now();
    let mut progress = Progress::fraction(PROGRESS_DELAY);
    let (output, frames) = match &args.animate {
        Some(_) => {
            let frames = frames::simulate(&loaded.scenario, animate::MAX_FRAMES, &mut |f| {
                progress.set(f)
            })?;
            (frames.output.clone(), Some(frames))
        }
        None => (sim::run(&loaded.scenario, &mut |f| progress.set(f))?, None),
    };
    progress.finish();
    let seconds = start.elapsed().as_secs_f64();

    // Draw the figure (kept aside), write the series, then put the figure in place.
    let series = series_of(&loaded, &output, &args.scenario, &args.sets);
    let figure = match &args.plot {
        Some(path) => Some(plot::render_series(
            path,
            &title(&loaded, &args.scenario, &args.sets),
            &Axis {
                quantity: "t",
                unit: "s",
                values: column(&series, "t"),
            },
            &panels(&series),
            Some(&contact_mask(&series)),
        )?),
        None => None,
    };
    let animation = match (&args.animate, &frames) {
        (Some(path), Some(frames)) => Some(animate::render_gif(
            path,
            &title(&loaded, &args.scenario, &args.sets),
            frames,
        )?),
        _ => None,
    };
    series::write(&series, &args.out)?;
    // The figure and the animation, renamed into place; on a failure, whatever this run put in
    // place is removed again.
    let mut placed = vec![args.out.clone(), series::sidecar_path(&args.out)];
    let extras = [(&args.plot, figure), (&args.animate, animation)];
    for (path, pending) in extras {
        let (Some(path), Some(pending)) = (path, pending) else {
            continue;
        };
        if let Err(e) = pending.commit() {
            for p in &placed {
                let _ = std::fs::remove_file(p);
            }
            return Err(e);
        }
        placed.push(path.clone());
    }

    let summary = Summary::new(&loaded, &output, seconds, args);
    args.format.format().print(&summary)?;
    Ok(())
}

/// Refuses a time-series path whose extension names no supported format.
pub fn check_series_path(path: &Path) -> Result<()> {
    match files::extension(path) {
        Some(ext) if EXTENSIONS.contains(&ext.as_str()) => Ok(()),
        _ => bail!(
            "`{}`: unknown output format; the extension must be one of {}",
            path.display(),
            EXTENSIONS
                .iter()
                .map(|e| format!(".{e}"))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// A column of a series built by [`series_of`] (every contract column is there).
fn column<'a>(series: &'a Series, name: &str) -> &'a [f64] {
    series.column(name).unwrap_or(&[])
}

/// Position of a contract column in a row of [`Output::rows`].
fn index(name: &str) -> usize {
    COLUMNS
        .iter()
        .position(|c| *c == name)
        .unwrap_or_else(|| panic!("`{name}` is a contract column"))
}

/// Most contact intervals printed one by one; more are summarised (the JSON has them all).
const LISTED_INTERVALS: usize = 6;

/// Contact intervals as text: every one when there are few, else the first three and the last
/// two with how many lie between.
fn intervals_text(intervals: &[[f64; 2]]) -> String {
    let one = |&[a, b]: &[f64; 2]| {
        if a == b {
            format!("{} ms", short(a * 1e3))
        } else {
            format!("{}–{} ms", short(a * 1e3), short(b * 1e3))
        }
    };
    let n = intervals.len();
    if n <= LISTED_INTERVALS {
        return intervals.iter().map(one).collect::<Vec<_>>().join(", ");
    }
    let head: Vec<String> = intervals[..3].iter().map(one).collect();
    let tail: Vec<String> = intervals[n - 2..].iter().map(one).collect();
    format!(
        "{}, … {} more …, {}",
        head.join(", "),
        n - 5,
        tail.join(", ")
    )
}

/// Where the whisker touches an object (`contact` = 1).
fn contact_mask(series: &Series) -> Vec<bool> {
    column(series, "contact").iter().map(|&c| c > 0.5).collect()
}

/// The figure's title: the experiment with d and v, or the scenario as named; other
/// overrides follow in parentheses.
fn title(loaded: &Loaded, spec: &str, sets: &[String]) -> String {
    let mut title = match &loaded.experiment {
        Some(e) => format!(
            "{}: d = {} mm, v = {} m/s",
            e.experiment.name(),
            short(e.d * 1e3),
            short(e.v)
        ),
        None => spec.to_string(),
    };
    let others: Vec<&str> = sets
        .iter()
        .map(String::as_str)
        .filter(|s| {
            let key = s.split('=').next().unwrap_or("").trim();
            loaded.experiment.is_none() || !matches!(key, "d" | "v")
        })
        .collect();
    if !others.is_empty() {
        title.push_str(&format!(" ({})", others.join(", ")));
    }
    title
}

/// The panels of the seed paper's Fig. 3 and the base reactions: the two angles (θ01 solid,
/// θ12 dashed), the base moment, and the base forces.
fn panels(series: &Series) -> Vec<Panel<'_>> {
    vec![
        Panel {
            quantity: "angle",
            unit: "rad",
            curves: vec![
                Curve {
                    name: "θ01 (base angle)",
                    values: column(series, "theta01"),
                    dashed: false,
                },
                Curve {
                    name: "θ12 (curvature)",
                    values: column(series, "theta12"),
                    dashed: true,
                },
            ],
        },
        Panel {
            quantity: "m0",
            unit: "N·m",
            curves: vec![Curve {
                name: "",
                values: column(series, "m0"),
                dashed: false,
            }],
        },
        Panel {
            quantity: "force",
            unit: "N",
            curves: vec![
                Curve {
                    name: "fx",
                    values: column(series, "fx"),
                    dashed: false,
                },
                Curve {
                    name: "fy",
                    values: column(series, "fy"),
                    dashed: false,
                },
            ],
        },
    ]
}

/// `x` in its shortest form after rounding to 10 significant digits (`23`, not
/// `23.000000000000004`).
pub fn short(x: f64) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    let rounded: f64 = format!("{x:.9e}").parse().unwrap_or(x);
    format!("{rounded}")
}

/// The experiment of a run, for the summary.
#[derive(Debug, Serialize)]
struct ExperimentSummary {
    /// `e1` or `e2`.
    name: &'static str,
    /// Near-edge distance of the box, m.
    d: f64,
    /// Box speed, m/s.
    v: f64,
}

/// When the whisker touched an object.
#[derive(Debug, Serialize)]
struct ContactSummary {
    /// First sample time in contact, s.
    start: f64,
    /// Last sample time in contact, s.
    end: f64,
    /// Samples in contact.
    samples: usize,
    /// Every interval of consecutive samples in contact, as the times of its first and last
    /// sample, s (a whisker that leaves an object and strikes it again has several).
    intervals: Vec<[f64; 2]>,
}

impl ContactSummary {
    /// The contact of a run from its rows (`None` if nothing was touched).
    fn of(rows: &[[f64; 10]]) -> Option<ContactSummary> {
        let (t, flag) = (index("t"), index("contact"));
        let mut intervals: Vec<[f64; 2]> = Vec::new();
        let mut samples = 0;
        let mut touching = false;
        for row in rows {
            if row[flag] > 0.5 {
                match intervals.last_mut() {
                    Some(last) if touching => last[1] = row[t],
                    _ => intervals.push([row[t], row[t]]),
                }
                samples += 1;
                touching = true;
            } else {
                touching = false;
            }
        }
        Some(ContactSummary {
            start: intervals.first()?[0],
            end: intervals.last()?[1],
            samples,
            intervals,
        })
    }
}

/// Runs and writes a scenario with an array of whiskers, then prints each whisker's contacts.
fn run_array(args: &Args, loaded: &Loaded) -> Result<()> {
    if args.plot.is_some() || args.animate.is_some() {
        bail!(
            "{}: --plot and --animate draw one whisker; this scenario has an array of {} \
             (simulate each alone by giving it as the only entry of [[whiskers]])",
            loaded.origin,
            loaded.whiskers.len()
        );
    }
    let start = Instant::now();
    let (series, outputs) = vibrissa_io::sweep::run_series(loaded, &args.scenario, &args.sets)?;
    let seconds = start.elapsed().as_secs_f64();
    series::write(&series, &args.out)?;
    let summary = ArraySummary {
        scenario: args.scenario.clone(),
        out: args.out.display().to_string(),
        sidecar: series::sidecar_path(&args.out).display().to_string(),
        samples: series.rows(),
        whiskers: loaded
            .whiskers
            .iter()
            .zip(&outputs)
            .map(|(m, o)| WhiskerSummary {
                name: m.name.clone(),
                steps: o.steps,
                contact: ContactSummary::of(&o.rows),
                max_penetration: o.max_penetration,
            })
            .collect(),
        seconds,
    };
    args.format.format().print(&summary)?;
    Ok(())
}

/// What `vibrissa simulate` prints for an array of whiskers.
#[derive(Debug, Serialize)]
struct ArraySummary {
    scenario: String,
    out: String,
    sidecar: String,
    samples: usize,
    whiskers: Vec<WhiskerSummary>,
    seconds: f64,
}

/// One whisker of an array's run.
#[derive(Debug, Serialize)]
struct WhiskerSummary {
    name: String,
    steps: usize,
    contact: Option<ContactSummary>,
    max_penetration: f64,
}

impl Render for ArraySummary {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        writeln!(
            out,
            "simulated {} ({} whiskers, {} samples each) in {:.3} s",
            self.scenario,
            self.whiskers.len(),
            self.samples,
            self.seconds
        )?;
        for w in &self.whiskers {
            let contact = match &w.contact {
                Some(c) => intervals_text(&c.intervals),
                None => "no contact".to_string(),
            };
            writeln!(out, "  {:10} {contact}", w.name)?;
        }
        writeln!(out, "  wrote      {}, {}", self.out, self.sidecar)
    }
}

/// What `vibrissa simulate` prints.
#[derive(Debug, Serialize)]
struct Summary {
    /// The scenario as named (a built-in's name or the file's path).
    scenario: String,
    /// Overrides, in order.
    set: Vec<String>,
    /// The experiment family and parameters, if any.
    experiment: Option<ExperimentSummary>,
    /// The time-series file written.
    out: String,
    /// Its sidecar, with the run's metadata.
    sidecar: String,
    /// The figure written, if any.
    plot: Option<String>,
    /// The animation written, if any.
    animation: Option<String>,
    /// Samples (rows).
    samples: usize,
    /// Time of the last sample, s.
    duration: f64,
    /// Integrator steps.
    steps: usize,
    /// Time step used, s.
    dt: f64,
    /// Segment count.
    segments: usize,
    /// Contact periods, if the whisker touched anything.
    contact: Option<ContactSummary>,
    /// Largest penetration into an object, m.
    max_penetration: f64,
    /// Wall time of the simulation, s.
    seconds: f64,
}

impl Summary {
    fn new(loaded: &Loaded, output: &Output, seconds: f64, args: &Args) -> Summary {
        let t = index("t");
        let contact = ContactSummary::of(&output.rows);
        Summary {
            scenario: args.scenario.clone(),
            set: args.sets.clone(),
            experiment: loaded.experiment.map(|e| ExperimentSummary {
                name: e.experiment.name(),
                d: e.d,
                v: e.v,
            }),
            out: args.out.display().to_string(),
            sidecar: series::sidecar_path(&args.out).display().to_string(),
            plot: args.plot.as_ref().map(|p| p.display().to_string()),
            animation: args.animate.as_ref().map(|p| p.display().to_string()),
            samples: output.rows.len(),
            duration: output.rows.last().map_or(0.0, |r| r[t]),
            steps: output.steps,
            dt: output.dt,
            segments: output.segments,
            contact,
            max_penetration: output.max_penetration,
            seconds,
        }
    }
}

impl Render for Summary {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        let mut heading = format!("simulated {}", self.scenario);
        if let Some(e) = &self.experiment {
            heading.push_str(&format!(
                " ({}, d = {} mm, v = {} m/s)",
                e.name,
                short(e.d * 1e3),
                short(e.v)
            ));
        }
        writeln!(out, "{heading}")?;
        if !self.set.is_empty() {
            writeln!(out, "  {:<16} {}", "overrides", self.set.join(" "))?;
        }
        let line =
            |out: &mut dyn Write, key: &str, value: String| writeln!(out, "  {key:<16} {value}");
        line(
            out,
            "samples",
            format!(
                "{} (t = 0 … {} ms)",
                self.samples,
                short(self.duration * 1e3)
            ),
        )?;
        line(
            out,
            "steps",
            format!(
                "{} of dt = {} µs, {} segments",
                self.steps,
                short(self.dt * 1e6),
                self.segments
            ),
        )?;
        let contact = match &self.contact {
            Some(c) if c.intervals.len() > LISTED_INTERVALS => format!(
                "{} ({} intervals, {} samples)",
                intervals_text(&c.intervals),
                c.intervals.len(),
                c.samples
            ),
            Some(c) => format!("{} ({} samples)", intervals_text(&c.intervals), c.samples),
            None => "none".to_string(),
        };
        line(out, "contact", contact)?;
        line(
            out,
            "max penetration",
            format!("{} m", sig(self.max_penetration, 3)),
        )?;
        line(out, "wall time", format!("{} s", sig(self.seconds, 3)))?;
        let mut wrote = format!("{}, {}", self.out, self.sidecar);
        for p in self.plot.iter().chain(&self.animation) {
            wrote.push_str(", ");
            wrote.push_str(p);
        }
        line(out, "wrote", wrote)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_numbers_lose_rounding_noise() {
        assert_eq!(short(0.023 * 1e3), "23");
        assert_eq!(short(0.6), "0.6");
        assert_eq!(short(0.15 * 1e3), "150");
        assert_eq!(short(1e-4 * 1e6), "100");
    }

    #[test]
    fn many_contact_intervals_are_summarised() {
        let few = [[0.001, 0.002], [0.003, 0.003]];
        assert_eq!(intervals_text(&few), "1–2 ms, 3 ms");
        let many: Vec<[f64; 2]> = (0..40)
            .map(|k| [k as f64 * 1e-3, k as f64 * 1e-3])
            .collect();
        let text = intervals_text(&many);
        assert_eq!(text, "0 ms, 1 ms, 2 ms, … 35 more …, 38 ms, 39 ms");
    }

    #[test]
    fn contact_lists_every_interval() {
        let row = |k: usize, touching: bool| {
            let mut r = [0.0; 10];
            r[index("t")] = k as f64 / 8.0;
            r[index("contact")] = if touching { 1.0 } else { 0.0 };
            r
        };
        let flags = [0, 1, 1, 0, 1, 0, 0, 1, 1, 1];
        let rows: Vec<[f64; 10]> = flags
            .iter()
            .enumerate()
            .map(|(k, &f)| row(k, f == 1))
            .collect();
        let c = ContactSummary::of(&rows).unwrap();
        assert_eq!(c.intervals, [[0.125, 0.25], [0.5, 0.5], [0.875, 1.125]]);
        assert_eq!((c.start, c.end, c.samples), (0.125, 1.125, 6));
        let none: Vec<[f64; 10]> = (0..5).map(|k| row(k, false)).collect();
        assert!(ContactSummary::of(&none).is_none());
        assert!(ContactSummary::of(&[]).is_none());
    }

    #[test]
    fn series_paths_need_a_known_extension() {
        assert!(check_series_path(Path::new("run.CSV")).is_ok());
        assert!(check_series_path(Path::new("run.npz")).is_ok());
        let err = check_series_path(Path::new("run.txt")).unwrap_err();
        assert!(err.to_string().contains(".csv, .npy, .npz"), "{err}");
        assert!(check_series_path(Path::new("run")).is_err());
    }
}
