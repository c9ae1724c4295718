//! `vibrissa bench --pf`: the particle filter's real-time factor against its particle count.
//!
//! One noisy `e2` run (d = 22 mm, v = 0.9 m/s, seed 1) is filtered with each particle count on
//! every core of the machine's default pool; the real-time factor is the simulated seconds of
//! data per wall second (above 1: faster than the data arrive at 1 kHz). The filter's settings
//! are those of `vibrissa estimate --method pf` (tempering by particle count); no training runs
//! are simulated: the observation noise is the `noisy` variant's, as the filter's fit finds it.
//! With `--randomise` the filter is the one for a whisker known only roughly (`vibrissa estimate
//! --method pf --randomise`): besides the scenario's whisker it entertains the alternative
//! whiskers and carries the sensors' gains and offsets (the intervals' widening, fitted once per
//! noise level on held-out runs, is not timed).

use crate::output::{sig, Align, FormatArgs, Render, Table};
use anyhow::{bail, Result};
use serde::Serialize;
use std::io::{self, Write};
use std::time::Instant;
use vibrissa_infer::experiment::Variant;
use vibrissa_infer::pf::{self, Config, Observations, Pf, MODEL_ERROR};
use vibrissa_infer::{Family, Method, Training};

/// One particle count's figures.
#[derive(Debug, Clone, Serialize)]
struct Row {
    particles: usize,
    /// Independent filters the particles were split among.
    islands: usize,
    /// Wall seconds of the fastest repetition.
    seconds: f64,
    /// Seconds of data filtered.
    data_seconds: f64,
    /// Data seconds per wall second.
    real_time_factor: f64,
    /// Physics steps per wall second, over all particles.
    steps_per_second: f64,
    /// Share of particle-samples on the free-ringing model.
    ringing_share: f64,
    /// Particle steps that diverged (the particle was dropped): 0 expected.
    diverged_steps: usize,
    /// The estimates at the last sample, for a sanity check (m, m/s).
    d: f64,
    v: f64,
}

/// The filter's transition model: the chain it steps each particle on.
#[derive(Debug, Clone, Serialize)]
struct TransitionModel {
    /// Segments of the filter's chain.
    segments: usize,
    /// Segments of the chain that made the recording (where the angles are read).
    observed_segments: usize,
    /// Stiffness rule of the filter's chain.
    discretisation: &'static str,
    /// Time step, s.
    dt: f64,
    /// Geometric iterations per step.
    max_iterations: usize,
    /// Whiskers entertained besides the scenario's (0: the whisker is known).
    alternatives: usize,
    /// Whether the sensors' gains and offsets are unknowns of the filter.
    sensor_unknowns: bool,
}

/// The report.
#[derive(Debug, Clone, Serialize)]
struct Report {
    threads: usize,
    truth: [f64; 2],
    model: TransitionModel,
    rows: Vec<Row>,
}

impl Render for Report {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        writeln!(
            out,
            "particle filter on one noisy e2 run (d = {} mm, v = {} m/s), {} threads",
            self.truth[0] * 1e3,
            self.truth[1],
            self.threads
        )?;
        let m = &self.model;
        writeln!(
            out,
            "transition model: {} segments ({} rule; the recording's chain has {}), time step {} \
             ms, {} geometric iteration(s) per step",
            m.segments,
            m.discretisation,
            m.observed_segments,
            sig(m.dt * 1e3, 3),
            m.max_iterations
        )?;
        if m.alternatives > 0 || m.sensor_unknowns {
            writeln!(
                out,
                "a whisker known only roughly: {} alternative whiskers; the sensors' gains and \
                 offsets {}",
                m.alternatives,
                if m.sensor_unknowns {
                    "unknown"
                } else {
                    "known"
                }
            )?;
        }
        let mut t = Table::new(&[
            ("particles", Align::Right),
            ("islands", Align::Right),
            ("wall (s)", Align::Right),
            ("data (s)", Align::Right),
            ("real-time factor", Align::Right),
            ("steps/s", Align::Right),
            ("ringing", Align::Right),
            ("diverged", Align::Right),
            ("d (mm)", Align::Right),
            ("v (m/s)", Align::Right),
        ]);
        for r in &self.rows {
            t.row(vec![
                r.particles.to_string(),
                r.islands.to_string(),
                sig(r.seconds, 3),
                sig(r.data_seconds, 3),
                format!("{:.2}", r.real_time_factor),
                sig(r.steps_per_second, 3),
                format!("{:.0}%", 100.0 * r.ringing_share),
                r.diverged_steps.to_string(),
                format!("{:.2}", r.d * 1e3),
                format!("{:.3}", r.v),
            ]);
        }
        t.write(out, "  ")
    }
}

/// Measures and prints: the filter of a whisker known only roughly with `randomise`, else that
/// of the known whisker, its particles split among `islands`.
pub fn run(
    particles: &[usize],
    quick: bool,
    randomise: bool,
    islands: usize,
    format: &FormatArgs,
) -> Result<()> {
    if particles.is_empty() || particles.contains(&0) {
        bail!("--particles takes counts of at least 1 (e.g. 100,1000,10000)");
    }
    let truth = [0.022, 0.9];
    let e2 = Family::builtin("e2")?;
    let noise = e2.noise(Variant::Noisy)?;
    let run = e2.simulate(&truth, &noise, 1)?;
    let obs = Observations::at_rate(run.series, e2.sample_rate());
    let data_seconds = obs.t[obs.t.len() - 1] - obs.t[0];
    let mut rows = Vec::new();
    let mut model = None;
    for &n in particles {
        let config = if randomise {
            // As `estimate --method pf --randomise` sets the filter up.
            let family = e2.clone().randomised_if(true)?;
            let mut filter = Pf::new(n);
            filter.islands = islands;
            filter.fit(&Training {
                noise: family.training_noise(noise.sensor),
                family: family.clone(),
                samples: Vec::new(),
                calibration: Vec::new(),
            })?;
            let sigma = filter
                .sigma()
                .ok_or_else(|| anyhow::anyhow!("the filter was not fitted"))?;
            filter.config(&family, sigma)?
        } else {
            let temper = pf::temper_for(n);
            let sigma = pf::observation_sigma(
                noise.sensor,
                std::array::from_fn(|c| MODEL_ERROR[c] * noise.sensor[c]),
                temper,
            );
            Config {
                islands,
                ..Config::e2(sigma, n, 1)
            }
        };
        model.get_or_insert_with(|| TransitionModel {
            segments: config.segments,
            observed_segments: config.observed_segments,
            discretisation: config.model_discretisation().name(),
            dt: config.dt,
            max_iterations: config.max_iterations,
            alternatives: config.alternatives.len(),
            sensor_unknowns: !config.sensor_spread.is_fixed(),
        });
        // Fastest of a few repetitions (one for the largest counts).
        let reps = if quick || n >= 5000 { 1 } else { 3 };
        let mut best = f64::INFINITY;
        let mut last = None;
        for _ in 0..reps {
            let start = Instant::now();
            let post = pf::run(&config, &obs, &mut |_| {})?;
            best = best.min(start.elapsed().as_secs_f64());
            last = Some(post);
        }
        let post = last.expect("at least one repetition");
        let est = post.last();
        eprintln!("{n} particles: {best:.3} s");
        rows.push(Row {
            particles: n,
            islands: pf::islands::island_count(&config),
            seconds: best,
            data_seconds,
            real_time_factor: data_seconds / best,
            steps_per_second: post.steps as f64 / best,
            ringing_share: post.ringing_share,
            diverged_steps: post.diverged,
            d: est[0].mean,
            v: est[1].mean,
        });
    }
    format.format().print(&Report {
        threads: rayon::current_num_threads(),
        truth,
        model: model.expect("at least one particle count"),
        rows,
    })?;
    Ok(())
}
