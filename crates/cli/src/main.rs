//! `vibrissa`: whisker physics from the command line.
//!
//! `main` only reports: every command runs in [`run`] and returns its error, which is printed
//! with its causes. Usage errors are clap's (exit status 2); any other failure exits with 1.
#![forbid(unsafe_code)]

mod animate;
mod bench;
mod bench_pf;
mod calibrate;
mod estimate;
mod estimate_pf;
mod estimate_shapes;
mod experiment;
mod experiment_shapes;
mod files;
mod frames;
mod inverse;
mod limits;
mod output;
mod plot;
mod plot_matrix;
mod progress;
mod report;
mod simulate;
mod sweep;
mod validate;

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::io;
use std::process::ExitCode;

/// Whisker physics: a fast segment-chain whisker simulator checked against beam theory.
#[derive(Debug, Parser)]
#[command(name = "vibrissa", version, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Check the segment chain against continuum beam theory.
    ///
    /// Compares simulated static deflections (small and large), natural frequencies and base
    /// reactions with Euler–Bernoulli references, prints every error beside its target, and
    /// exits with status 1 if any check misses its target.
    Validate(validate::Args),
    /// Measure how fast the segment chain steps on this machine.
    ///
    /// Single-state steps per second for N = 10, 20, 50 and 100 segments, the throughput of a
    /// batch of states at N = 20 on all cores, on one, and on one with the states stepped one at
    /// a time (without lanes), and how the cost per segment grows with N. Run a release build on
    /// an otherwise idle machine.
    Bench(bench::Args),
    /// Run one scenario and write its time series (CSV, NPY or NPZ), optionally with a figure.
    ///
    /// SCENARIO is a built-in experiment (e1, e2) or a TOML scenario file; `--set key=value`
    /// overrides any of its keys. The series has the contract's columns (t, theta01, theta12,
    /// m0, fx, fy, contact, cx, cy, s); the run's metadata goes into a JSON sidecar beside it
    /// (`run.json` beside `run.csv`). `--plot` draws the angles, the base moment and the base
    /// forces over time with the contact period shaded; `--animate` draws the whisker and the
    /// objects as an animated GIF. No output file is left behind on error.
    Simulate(simulate::Args),
    /// Run every combination of a grid of parameter values, in parallel, one file per run.
    ///
    /// Grid keys are `--set` keys; e1 and e2 without `--grid` sweep their own grids. Each run
    /// writes its series and a JSON sidecar with its metadata. Writes `manifest.csv` beside the
    /// runs (kept up to date as runs finish); started again on the same folder, skips the runs
    /// whose series and sidecar are both there. A failed run is reported with its parameters
    /// and makes the sweep exit with status 1 after the others have run.
    Sweep(sweep::Args),
    /// Run the seed's template experiment e1 or e2 and score every estimator.
    ///
    /// Simulates the grid, fits each method on the runs its budget allows (the templates, or
    /// simulated training runs that avoid the evaluated ones), estimates every evaluated run and
    /// prints the mean absolute errors and the coverage of the 90% intervals beside the paper's
    /// figures. Writes results.json and figures (PNG) into --out, and with --report an HTML page
    /// of it all (see `report`).
    Experiment(experiment::Args),
    /// Estimate the object's distance (and speed) from recorded time series.
    ///
    /// Reads contract CSV files (t, theta01, theta12 required; any constant sample rate and
    /// length), trains the chosen method on simulations of the scenario (`--scenario`, e.g. the
    /// output of `calibrate`, or `--experiment e1|e2`) once per timing and prints one estimate
    /// per file (JSON Lines with --json and several files). `--list` names the methods.
    Estimate(estimate::Args),
    /// Fit a nominal scenario's whisker and sensors to labelled recordings.
    ///
    /// Fits Young's modulus, density, taper, follicle stiffness and damping, the whisker's
    /// damping, a time offset and each channel's gain and offset by maximum likelihood with the
    /// simulator in the loop; prints each value with its standard error (or why it was held at
    /// the nominal) and the residual RMS per channel before and after. Writes the fitted
    /// scenario, which every command accepts, only if the fit succeeds.
    Calibrate(calibrate::Args),
    /// Measure the beam-theory estimators of contact distance (M/F, Birdwell's and the chain's
    /// angle pairs, Kaneko's rotation and frequency methods) on whisks against stationary pegs.
    ///
    /// Pegs at d = 5…29 mm, read at tip deflections of 0.5…20% of the whisker's length; prints
    /// the worst relative error over the pegs for each estimator and deflection.
    Inverse(inverse::Args),
    /// Write one self-contained HTML page for an experiment's output folder.
    ///
    /// DIR is what `vibrissa experiment ... --out DIR` wrote. The page (DIR/report.html) holds
    /// the methods' errors and coverage beside the paper's figures, the experiment's figures,
    /// and animations of some of its runs (re-simulated): the whisker and the object, a time
    /// series with a cursor, and the particle filter's cloud when the experiment scored it.
    /// Everything is inline; the page needs no network.
    Report(report::Args),
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        // A closed pipe (`vibrissa ... | head`) ends the output early; that is not a failure.
        Err(err) if is_broken_pipe(&err) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err}");
            for cause in err.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            ExitCode::FAILURE
        }
    }
}

/// Parses the command line and runs the chosen command.
fn run() -> Result<()> {
    let cli = Cli::parse();
    match &cli.command {
        Command::Validate(args) => validate::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Simulate(args) => simulate::run(args),
        Command::Sweep(args) => sweep::run(args),
        Command::Experiment(args) => experiment::run(args),
        Command::Estimate(args) => estimate::run(args),
        Command::Inverse(args) => inverse::run(args),
        Command::Calibrate(args) => calibrate::run(args),
        Command::Report(args) => report::run(args),
    }
}

/// Whether the root of `err` is a write to a closed pipe.
fn is_broken_pipe(err: &anyhow::Error) -> bool {
    err.chain().any(|cause| {
        cause
            .downcast_ref::<io::Error>()
            .is_some_and(|e| e.kind() == io::ErrorKind::BrokenPipe)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn command_line_definition_is_consistent() {
        Cli::command().debug_assert();
    }
}
