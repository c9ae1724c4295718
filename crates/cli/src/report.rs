//! `vibrissa report`: one self-contained HTML page for an experiment's output folder.
//!
//! The page holds the experiment's table (every method's errors and coverage beside the paper's
//! figures), its figures, and animations of some of its runs: the whisker and the object, a
//! time series whose cursor follows the animation, and, when the experiment scored the particle
//! filter, the filter's particle cloud over the unknowns. The runs are re-simulated from the
//! experiment's family as it recorded them (`results.json` has the seed, the noise and the
//! overrides), so the folder needs nothing else. Style, script, figures and data are all inline:
//! the page needs no network. It is written through a temporary file renamed into place.

mod page;
mod results;
mod runs;

use crate::output::{sig, FormatArgs, Render};
use anyhow::{bail, Context, Result};
use rayon::prelude::*;
use results::Results;
use serde::Serialize;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;
use vibrissa_infer::Family;

/// The file a report is written to, in the experiment's folder.
pub const REPORT: &str = "report.html";
/// Where the note names the page's size until it is known.
const PAGE_SIZE: &str = "[page size]";
/// Runs animated by default.
pub const DEFAULT_RUNS: usize = 4;

/// Arguments of `vibrissa report`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The experiment's output folder (what `vibrissa experiment ... --out DIR` wrote).
    #[arg(value_name = "DIR")]
    dir: PathBuf,
    /// Runs to animate, by their index in the experiment's grid (from 0, as the page lists
    /// them), e.g. `--runs 0,17,42`. Default: four runs spread over the grid.
    #[arg(long, value_name = "K,…", value_delimiter = ',', num_args = 1..)]
    runs: Vec<usize>,
    /// Animate every run of the grid (a page of a few megabytes for e2).
    #[arg(long, conflicts_with = "runs")]
    all_runs: bool,
    #[command(flatten)]
    format: FormatArgs,
}

/// Which runs the page animates.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Selection {
    /// [`DEFAULT_RUNS`] runs spread evenly over the grid.
    Default,
    /// These grid indices.
    Runs(Vec<usize>),
    /// Every run.
    All,
}

impl Selection {
    /// The grid indices chosen among the runs (`is_template` has one entry per run); an index
    /// beyond the grid is refused.
    fn indices(&self, is_template: &[bool]) -> Result<Vec<usize>> {
        let n = is_template.len();
        match self {
            Selection::All => Ok((0..n).collect()),
            Selection::Default => {
                // Evaluated runs (which have every method's estimates) if there are any.
                let pool: Vec<usize> = match (0..n).filter(|&k| !is_template[k]).collect::<Vec<_>>()
                {
                    evaluated if !evaluated.is_empty() => evaluated,
                    _ => (0..n).collect(),
                };
                let (p, m) = (pool.len(), DEFAULT_RUNS.min(pool.len()));
                let mut k: Vec<usize> = (0..m)
                    .map(|i| pool[if m > 1 { i * (p - 1) / (m - 1) } else { 0 }])
                    .collect();
                k.dedup();
                Ok(k)
            }
            Selection::Runs(runs) => {
                if let Some(bad) = runs.iter().find(|&&k| k >= n) {
                    bail!(
                        "--runs: there is no run {bad}; the experiment's runs are 0 to {}",
                        n - 1
                    );
                }
                let mut k = runs.clone();
                k.sort_unstable();
                k.dedup();
                Ok(k)
            }
        }
    }
}

/// What `vibrissa report` prints.
#[derive(Debug, Serialize)]
pub struct Written {
    /// The page written.
    pub path: PathBuf,
    /// Its size, bytes.
    pub bytes: usize,
    /// The grid indices of the runs animated.
    pub runs: Vec<usize>,
    /// Whether the page shows the particle filter's cloud.
    pub particle_cloud: bool,
    /// Wall time, s.
    pub seconds: f64,
}

impl Render for Written {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        writeln!(
            out,
            "wrote {} ({} kB): {} runs animated{}, in {} s",
            self.path.display(),
            sig(self.bytes as f64 / 1e3, 3),
            self.runs.len(),
            if self.particle_cloud {
                ", with the particle filter's cloud"
            } else {
                ""
            },
            sig(self.seconds, 3)
        )
    }
}

/// Writes the report of the folder `args.dir` and prints where it went.
pub fn run(args: &Args) -> Result<()> {
    let selection = if args.all_runs {
        Selection::All
    } else if args.runs.is_empty() {
        Selection::Default
    } else {
        Selection::Runs(args.runs.clone())
    };
    let written = write(&args.dir, &selection)?;
    args.format.format().print(&written)?;
    Ok(())
}

/// Writes `dir/report.html` for the experiment in `dir`, animating the `selection` of its runs.
pub fn write(dir: &Path, selection: &Selection) -> Result<Written> {
    let start = Instant::now();
    let results = Results::read(dir)?;
    let chosen = selection.indices(&results.is_template)?;
    let spec = results.family_spec();
    let family = Family::open(&spec, &results.sets).with_context(|| {
        format!(
            "cannot open the experiment's family `{spec}` to re-simulate its runs (field `family` of {})",
            dir.join(results::RESULTS).display()
        )
    })?;
    let pf = runs::fitted_filter(&results, &family)?;
    let data: Vec<runs::RunData> = chosen
        .par_iter()
        .map(|&k| runs::run_data(&results, &family, k, pf.as_ref()))
        .collect::<Result<_>>()?;
    let json = serde_json::to_string(&Page {
        unknowns: &results.unknowns,
        ranges: results.ranges.iter().map(|r| [r[0].0, r[1].0]).collect(),
        runs: data,
        all: (0..results.grid.len())
            .map(|k| (k, results.describe(k)))
            .collect(),
    })?;
    let note = format!(
        "{} of the experiment's {} runs animated (re-simulated from its family, seed and noise){}. vibrissa report DIR --runs K,… picks others; --all-runs takes every one. This page: {PAGE_SIZE}.",
        chosen.len(),
        results.grid.len(),
        if pf.is_some() {
            ", with the particle filter re-run on each"
        } else {
            ""
        }
    );
    let html = page::render(&results, dir, &json, &note)?;
    // The page states its own size (to the kilobyte, which the number itself does not change).
    let html = html.replacen(
        PAGE_SIZE,
        &format!("{} kB", sig(html.len() as f64 / 1e3, 3)),
        1,
    );
    let path = dir.join(REPORT);
    crate::files::write_atomic(&path, html.as_bytes())?;
    Ok(Written {
        path,
        bytes: html.len(),
        runs: chosen,
        particle_cloud: pf.is_some(),
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The page's data.
#[derive(Debug, Serialize)]
struct Page<'a> {
    /// Names of the unknowns.
    unknowns: &'a [String],
    /// Their ranges, SI.
    ranges: Vec<[f64; 2]>,
    /// The animated runs.
    runs: Vec<runs::RunData>,
    /// Every run of the grid: index and description.
    all: Vec<(usize, String)>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_are_chosen_within_the_grid() {
        let plain = |n: usize| vec![false; n];
        assert_eq!(
            Selection::Default.indices(&plain(80)).unwrap(),
            [0, 26, 52, 79]
        );
        assert_eq!(Selection::Default.indices(&plain(2)).unwrap(), [0, 1]);
        assert_eq!(Selection::Default.indices(&plain(1)).unwrap(), [0]);
        // Evaluated runs are preferred to templates.
        let mut some = vec![true; 10];
        (some[3], some[4], some[8]) = (false, false, false);
        assert_eq!(Selection::Default.indices(&some).unwrap(), [3, 4, 8]);
        assert_eq!(Selection::Default.indices(&[true, true]).unwrap(), [0, 1]);
        assert_eq!(Selection::All.indices(&plain(3)).unwrap(), [0, 1, 2]);
        assert_eq!(
            Selection::Runs(vec![5, 2, 5]).indices(&plain(6)).unwrap(),
            [2, 5]
        );
        let e = Selection::Runs(vec![1, 80])
            .indices(&plain(80))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("--runs") && e.contains("no run 80") && e.contains("0 to 79"),
            "{e}"
        );
    }
}
