//! `vibrissa bench`: how fast the segment chain steps on this machine.
//!
//! Three figures:
//! - single state on one thread, for several segment counts N and two motions (a small first-mode
//!   vibration, and a release from a large deflection whose geometry is iterated): steps per
//!   second, articulated-body solves per step and the cost of one step per segment (constant if
//!   the step is O(N));
//! - a batch of states against one model on every core, and the same batch on one thread, for
//!   the parallel speedup, and the same states stepped one at a time without lanes on one thread:
//!   once in free motion, once with every state held in contact by a peg pressed into the
//!   whisker;
//! - the ratio of the per-segment cost at the largest N to that at the smallest;
//! - whole runs: the `e2` grid's 80 box strikes with random forces (the chosen whisker and rule
//!   at N = 20), each run alone on every core against the same runs stepped together in lanes.
//!
//! Every measurement warms up, sizes its repetitions to a minimum duration, and keeps the best of
//! several repetitions (the least disturbed by other work on the machine). States restart from
//! the same initial condition before each timed call, so the motion being stepped stays of the
//! same size however long the measurement runs.

use crate::output::{grouped, sig, Align, FormatArgs, Render, Table};
use anyhow::{Context, Result};
use clap::builder::PossibleValuesParser;
use serde::Serialize;
use std::hint::black_box;
use std::io::{self, Write};
use std::time::{Duration, Instant};
use vibrissa_core::batch;
use vibrissa_core::chain::DISCRETISATIONS;
use vibrissa_core::dynamics;
use vibrissa_core::whisker::PRESETS;
use vibrissa_core::{Discretisation, Inputs, Integrator, Model, State, WhiskerParams, Workspace};

/// Arguments of `vibrissa bench`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    format: FormatArgs,
    /// Much shorter measurements (a smoke test; the figures are rough).
    #[arg(long)]
    quick: bool,
    /// Whisker preset to step.
    #[arg(long, value_name = "PRESET", default_value = "w30",
          value_parser = PossibleValuesParser::new(PRESETS))]
    whisker: String,
    /// Rule that sets the joint stiffnesses.
    #[arg(long, value_name = "RULE", default_value = Discretisation::default().name(),
          value_parser = PossibleValuesParser::new(DISCRETISATIONS))]
    discretisation: String,
    /// Measure the particle filter instead: its real-time factor on a noisy e2 run for each
    /// particle count of --particles.
    #[arg(long)]
    pf: bool,
    /// Particle counts of --pf, comma-separated.
    #[arg(
        long,
        value_name = "LIST",
        value_delimiter = ',',
        default_value = "100,1000,10000",
        value_parser = crate::limits::particles,
        requires = "pf"
    )]
    particles: Vec<usize>,
    /// With --pf: the filter for a whisker known only roughly (`estimate --method pf
    /// --randomise`): 63 alternative whiskers, the sensors' gains and offsets as unknowns.
    #[arg(long, requires = "pf")]
    randomise: bool,
    /// With --pf: islands the particles are split among, as `estimate --islands` (each keeps
    /// at least 1000 particles).
    #[arg(long, value_name = "N", default_value_t = vibrissa_infer::pf::ISLANDS,
          value_parser = crate::limits::islands, requires = "pf")]
    islands: usize,
}

/// Segment counts of the single-state measurement, ascending.
const SEGMENTS: [usize; 4] = [10, 20, 50, 100];
/// Segment count of the batched measurement.
const BATCH_SEGMENTS: usize = 20;
/// Time step, s.
const DT: f64 = 1.0e-4;
/// Largest joint amplitude of the initial first-mode vibration, rad.
const AMPLITUDE: f64 = 1.0e-3;
/// The peg of the in-contact batch: its radius, where it meets the whisker (m from the base),
/// its speed into the whisker, how far its surface starts from the whisker's axis and how long
/// it presses before the timed steps begin (m, m, m/s, m, s). It reaches the whisker (radius
/// 0.1 mm) after 0.5 ms and pushes it 0.9 mm further before the timed steps.
const PEG: (f64, f64, f64, f64, f64) = (1.0e-3, 0.015, 0.2, 2.0e-4, 5.0e-3);

/// How long and how often to measure.
#[derive(Debug, Clone, Copy)]
struct Plan {
    /// Untimed running before a measurement.
    warmup: Duration,
    /// Shortest duration of one timed repetition.
    repetition: Duration,
    /// Repetitions; the fastest one counts.
    repetitions: usize,
    /// Steps per timed call for a single state (the state restarts between calls).
    steps: usize,
    /// States in the batch.
    batch_states: usize,
    /// Steps of every state per timed call of the batch.
    batch_steps: usize,
    /// Rounds of the batch's interleaved repetitions ([`fastest_calls`]).
    batch_rounds: usize,
}

impl Plan {
    fn new(quick: bool) -> Plan {
        if quick {
            Plan {
                warmup: Duration::from_millis(5),
                repetition: Duration::from_millis(20),
                repetitions: 3,
                steps: 100,
                batch_states: 100,
                batch_steps: 10,
                batch_rounds: 3,
            }
        } else {
            Plan {
                warmup: Duration::from_millis(200),
                repetition: Duration::from_millis(500),
                repetitions: 3,
                steps: 1000,
                batch_states: 1000,
                batch_steps: 100,
                batch_rounds: 6,
            }
        }
    }
}

/// Single-state speed at one segment count and one kind of motion.
#[derive(Debug, Clone, Serialize)]
struct Single {
    /// Segment count N.
    segments: usize,
    /// `small` (1 mrad first-mode vibration) or `large` (release from a tip deflection of about
    /// 0.3 L, under W = EI/L²).
    motion: &'static str,
    /// Geometric iterations (articulated-body solves) per step, averaged.
    solves_per_step: f64,
    /// Steps per second.
    steps_per_second: f64,
    /// Seconds per step.
    seconds_per_step: f64,
    /// Seconds per step divided by N.
    seconds_per_step_per_segment: f64,
}

/// Batched throughput on all threads and on one.
#[derive(Debug, Clone, Serialize)]
struct Batched {
    /// `free` (the first-mode vibration of `small`) or `contact` (every state held against a
    /// peg of radius 1 mm pressed into the whisker 15 mm from its base at 0.2 m/s, in contact
    /// throughout the timed steps).
    motion: &'static str,
    /// Segment count N of every state.
    segments: usize,
    /// States stepped together.
    states: usize,
    /// Threads of the parallel run.
    threads: usize,
    /// State-steps per second on all threads.
    state_steps_per_second: f64,
    /// Seconds per state-step on all threads.
    seconds_per_state_step: f64,
    /// State-steps per second on one thread.
    single_thread_state_steps_per_second: f64,
    /// Seconds per state-step on one thread.
    single_thread_seconds_per_state_step: f64,
    /// Parallel throughput over one-thread throughput.
    speedup: f64,
    /// State-steps per second on one thread when the same states are stepped one at a time by
    /// the single-state step (no lanes).
    one_at_a_time_state_steps_per_second: f64,
    /// One-thread batch throughput over one-at-a-time throughput (the lanes' gain).
    over_one_at_a_time: f64,
}

/// How the cost of a step grows with N.
#[derive(Debug, Clone, Serialize)]
struct Scaling {
    /// Smallest N measured.
    from_segments: usize,
    /// Largest N measured.
    to_segments: usize,
    /// Seconds per step per segment at the largest N over that at the smallest (1 for a step
    /// that is exactly O(N)).
    ratio: f64,
}

/// Whole scenario runs: a family's runs alone (each `sim::run` on its own, in parallel) and
/// stepped together in lanes (`sim::run_many`), on every thread.
#[derive(Debug, Clone, Serialize)]
struct Runs {
    /// What was run.
    what: &'static str,
    /// Runs.
    runs: usize,
    /// Simulated seconds of each run.
    duration: f64,
    /// Threads.
    threads: usize,
    /// Seconds for all the runs, each alone.
    alone_seconds: f64,
    /// Seconds for all the runs, stepped together.
    together_seconds: f64,
    /// Alone over together.
    speedup: f64,
}

/// Everything `vibrissa bench` measured, in SI units.
#[derive(Debug, Clone, Serialize)]
struct BenchReport {
    /// Whisker preset.
    whisker: String,
    /// Stiffness rule.
    discretisation: &'static str,
    /// Time step, s.
    dt: f64,
    /// Generalized-α spectral radius at infinite frequency.
    rho_inf: f64,
    /// Whether the short plan was used.
    quick: bool,
    /// Whether this binary was built with optimisations (figures from a debug build mean little).
    optimised: bool,
    /// Threads in the machine's default pool.
    threads: usize,
    /// Single state, one thread, per N.
    single: Vec<Single>,
    /// Batch of states in free motion.
    batch: Batched,
    /// The same batch, every state in contact with a peg.
    batch_contact: Batched,
    /// Growth of the per-segment cost with N.
    scaling: Scaling,
    /// Whole runs, alone and together.
    runs: Runs,
}

/// Measures, then prints the figures.
pub fn run(args: &Args) -> Result<()> {
    if args.pf {
        return crate::bench_pf::run(
            &args.particles,
            args.quick,
            args.randomise,
            args.islands,
            &args.format,
        );
    }
    let plan = Plan::new(args.quick);
    let optimised = !cfg!(debug_assertions);
    if !optimised {
        eprintln!("warning: this is a debug build; build with --release for meaningful figures");
    }

    // The whisker, the stiffness rule and the time stepper.
    let whisker = WhiskerParams::preset(&args.whisker)?
        .check()
        .with_context(|| format!("whisker preset {}", args.whisker))?;
    let discretisation = Discretisation::from_name(&args.discretisation)?;
    let stepper = Integrator {
        dt: DT,
        ..Integrator::default()
    }
    .check()?;
    let inputs = Inputs::default();
    let threads = rayon::current_num_threads();

    // A model at `n` segments and a state in `motion`: passing through its rest shape with the
    // joint rates of a first-mode vibration of amplitude `AMPLITUDE` (free motion of the lowest
    // mode, as a flicked whisker shows), or released at rest from the static shape under a tip
    // load W = EI/L² (large rotations: the geometry is iterated).
    let setup = |n: usize, motion: &str| -> Result<(Model, State)> {
        let model = Model::new(&whisker, n, discretisation)?;
        let mut state = State::at_rest(&model, 0);
        if motion == "small" {
            let modes = model.modes()?;
            let shape = &modes.shapes[0];
            let peak = shape.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let omega = 2.0 * std::f64::consts::PI * modes.frequencies[0];
            for (v, x) in state.v_mut().iter_mut().zip(shape) {
                *v = omega * AMPLITUDE * x / peak;
            }
        } else {
            let p = whisker.params();
            let ei = p.youngs_modulus * 0.25 * std::f64::consts::PI * p.base_radius.powi(4);
            let load = vibrissa_core::PointLoad {
                segment: n - 1,
                along: model.len[n - 1],
                force: [0.0, ei / (p.length * p.length)],
            };
            let eq = vibrissa_core::statics::solve(&model, &[load])?;
            state.q_mut().copy_from_slice(&eq.q);
        }
        let mut ws = Workspace::new(&model);
        dynamics::initialize(&model, &mut state, &inputs, &mut ws)?;
        Ok((model, state))
    };

    // (a) One state on one thread, for every N and both motions.
    let mut single = Vec::with_capacity(2 * SEGMENTS.len());
    for motion in ["small", "large"] {
        for &n in &SEGMENTS {
            eprintln!("bench: single state, N = {n}, {motion} motion");
            let (model, initial) = setup(n, motion)?;
            let mut state = initial.clone();
            let mut ws = Workspace::new(&model);
            let (mut solves, mut steps) = (0usize, 0usize);
            let per_call = best_seconds_per_call(&plan, || {
                state.clone_from(&initial);
                let start = Instant::now();
                for _ in 0..plan.steps {
                    dynamics::step(&model, &stepper, &mut state, &inputs, &mut ws)?;
                    solves += ws.iterations;
                }
                steps += plan.steps;
                black_box(&mut state);
                Ok(start.elapsed())
            })
            .with_context(|| format!("single-state run at N = {n}"))?;
            let seconds_per_step = per_call / plan.steps as f64;
            single.push(Single {
                segments: n,
                motion,
                solves_per_step: solves as f64 / steps as f64,
                steps_per_second: 1.0 / seconds_per_step,
                seconds_per_step,
                seconds_per_step_per_segment: seconds_per_step / n as f64,
            });
        }
    }

    // (b) A batch of states against one model, on every thread and then on one: in free
    // motion, then held in contact by a peg.
    let (model, initial) = setup(BATCH_SEGMENTS, "small")?;
    let batch = batched(&plan, &model, &stepper, &initial, &inputs, "free")?;
    let (radius, along, speed, start_gap, press) = PEG;
    let peg = [vibrissa_core::objects::Object {
        motion: vibrissa_core::objects::Motion::Constant {
            velocity: [0.0, -speed],
            angular_velocity: 0.0,
        },
        ..vibrissa_core::scenes::peg(along, radius + start_gap, radius, 0.0)
    }];
    let pressed = Inputs {
        objects: &peg,
        ..Inputs::default()
    };
    let mut held = State::at_rest(&model, 0);
    let mut ws = Workspace::new(&model);
    dynamics::initialize(&model, &mut held, &pressed, &mut ws)?;
    while held.t < press {
        dynamics::step(&model, &stepper, &mut held, &pressed, &mut ws)?;
    }
    anyhow::ensure!(
        held.contact.is_some(),
        "the in-contact batch's peg does not touch the whisker after {press} s"
    );
    let batch_contact = batched(&plan, &model, &stepper, &held, &pressed, "contact")?;

    // (c) Growth of the per-segment cost from the smallest to the largest N (small motion).
    let (first, last) = (&single[0], &single[SEGMENTS.len() - 1]);
    let scaling = Scaling {
        from_segments: first.segments,
        to_segments: last.segments,
        ratio: last.seconds_per_step_per_segment / first.seconds_per_step_per_segment,
    };

    // (d) Whole runs: the e2 grid with random forces, alone and together.
    let runs = whole_runs(
        &plan,
        &WhiskerParams::preset(&args.whisker)?,
        discretisation,
    )?;

    let report = BenchReport {
        whisker: args.whisker.clone(),
        discretisation: discretisation.name(),
        dt: stepper.dt,
        rho_inf: stepper.rho_inf,
        quick: args.quick,
        optimised,
        threads,
        single,
        batch,
        batch_contact,
        scaling,
        runs,
    };
    args.format.format().print(&report)?;
    Ok(())
}

/// Throughput of the plan's batch of copies of `initial` stepped together with `inputs`, on
/// every thread and on one. With objects among the inputs, every state must still be touching
/// one after the timed steps.
fn batched(
    plan: &Plan,
    model: &Model,
    stepper: &vibrissa_core::Stepper,
    initial: &State,
    inputs: &Inputs,
    motion: &'static str,
) -> Result<Batched> {
    let threads = rayon::current_num_threads();
    let initial = vec![initial.clone(); plan.batch_states];
    let step_batch = |states: &mut Vec<State>| -> Result<Duration> {
        states.clone_from(&initial);
        let start = Instant::now();
        batch::step_all(model, stepper, states, inputs, plan.batch_steps)?;
        let elapsed = start.elapsed();
        black_box(&mut *states);
        anyhow::ensure!(
            inputs.objects.is_empty() || states.iter().all(|s| s.contact.is_some()),
            "a state of the in-contact batch lost contact during the timed steps"
        );
        Ok(elapsed)
    };
    let (mut states, mut states_one) = (initial.clone(), initial.clone());
    let mut batch_call = || step_batch(&mut states);
    let mut batch_call_one = || step_batch(&mut states_one);
    // The same states stepped one at a time by the single-state step, on this thread.
    let mut ws = Workspace::new(model);
    let mut single_states = initial.clone();
    let mut single_call = || -> Result<Duration> {
        single_states.clone_from(&initial);
        let start = Instant::now();
        for s in single_states.iter_mut() {
            for _ in 0..plan.batch_steps {
                dynamics::step(model, stepper, s, inputs, &mut ws)?;
            }
        }
        let elapsed = start.elapsed();
        black_box(&mut single_states);
        Ok(elapsed)
    };
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .context("could not start a one-thread pool")?;
    eprintln!(
        "bench: batch of {} states, N = {}, {motion}: {threads} threads, 1 thread and one at a time, interleaved",
        plan.batch_states, model.n
    );
    // Interleaved, so that a slow spell of the machine falls on all three alike.
    let [parallel, one_thread, one_at_a_time] = fastest_calls(
        plan,
        [
            &mut batch_call,
            &mut || one.install(&mut batch_call_one),
            &mut single_call,
        ],
    )
    .context("batched runs")?;
    let state_steps = (plan.batch_states * plan.batch_steps) as f64;
    Ok(Batched {
        motion,
        segments: model.n,
        states: plan.batch_states,
        threads,
        state_steps_per_second: state_steps / parallel,
        seconds_per_state_step: parallel / state_steps,
        single_thread_state_steps_per_second: state_steps / one_thread,
        single_thread_seconds_per_state_step: one_thread / state_steps,
        speedup: one_thread / parallel,
        one_at_a_time_state_steps_per_second: state_steps / one_at_a_time,
        over_one_at_a_time: one_at_a_time / one_thread,
    })
}

/// The `e2` grid's runs (d = 15…30 mm, v = 0.3…1.5 m/s, 150 ms each; in the quick plan every
/// fifth) with the experiments' random forces, on `whisker` at N = 20: each alone in parallel
/// against all stepped together in lanes, taking turns. Checks that both give the same rows.
fn whole_runs(plan: &Plan, whisker: &WhiskerParams, rule: Discretisation) -> Result<Runs> {
    use vibrissa_core::sim::{self, Scenario};
    let mut scenarios = Vec::new();
    for (k, d) in (0..16).map(|i| 0.015 + 0.001 * i as f64).enumerate() {
        for (j, v) in (0..5).map(|i| 0.3 + 0.3 * i as f64).enumerate() {
            scenarios.push(Scenario {
                whisker: whisker.clone(),
                segments: BATCH_SEGMENTS,
                discretisation: rule,
                objects: vec![vibrissa_core::scenes::e2_box(d, v)],
                process_noise: 2e-5,
                seed: (5 * k + j) as u64,
                ..Scenario::default()
            });
        }
    }
    if plan.batch_rounds < 6 {
        scenarios = scenarios.into_iter().step_by(5).collect();
    }
    let bits =
        |o: &sim::Output| -> Vec<u64> { o.rows.iter().flatten().map(|x| x.to_bits()).collect() };
    let alone_rows = std::cell::RefCell::new(Vec::new());
    let together_rows = std::cell::RefCell::new(Vec::new());
    let mut alone = || -> Result<Duration> {
        use rayon::prelude::*;
        let start = Instant::now();
        let out = scenarios
            .par_iter()
            .map(|s| sim::run(s, &mut |_| {}))
            .collect::<vibrissa_core::Result<Vec<_>>>()?;
        let elapsed = start.elapsed();
        *alone_rows.borrow_mut() = out.iter().map(bits).collect::<Vec<_>>();
        Ok(elapsed)
    };
    let mut together = || -> Result<Duration> {
        let start = Instant::now();
        let out = sim::run_many(&scenarios)
            .into_iter()
            .collect::<vibrissa_core::Result<Vec<_>>>()?;
        let elapsed = start.elapsed();
        *together_rows.borrow_mut() = out.iter().map(bits).collect::<Vec<_>>();
        Ok(elapsed)
    };
    eprintln!(
        "bench: {} e2 runs with random forces, N = {BATCH_SEGMENTS}: alone and together, interleaved",
        scenarios.len()
    );
    let [alone_s, together_s] = fastest_calls(plan, [&mut alone, &mut together])?;
    anyhow::ensure!(
        alone_rows.into_inner() == together_rows.into_inner(),
        "runs stepped together differ from the same runs alone"
    );
    Ok(Runs {
        what: "e2 grid with random forces",
        runs: scenarios.len(),
        duration: Scenario::default().duration,
        threads: rayon::current_num_threads(),
        alone_seconds: alone_s,
        together_seconds: together_s,
        speedup: alone_s / together_s,
    })
}

/// Warms up `call` (caches, branch predictors, the CPU clock) for the plan's warm-up time and
/// returns how many calls last at least the plan's repetition time.
fn calls_per_repetition(plan: &Plan, call: &mut dyn FnMut() -> Result<Duration>) -> Result<u32> {
    let start = Instant::now();
    let (mut calls, mut spent) = (0u32, Duration::ZERO);
    while calls == 0 || start.elapsed() < plan.warmup {
        spent += call()?;
        calls += 1;
    }
    let estimate = (spent.as_secs_f64() / f64::from(calls)).max(1e-9);
    Ok(((plan.repetition.as_secs_f64() / estimate).ceil() as u32).max(1))
}

/// Seconds of the fastest call of each of `calls`, measured in turns: each is warmed up, then
/// each of the plan's batch rounds runs a repetition of each in order. Taking turns puts a slow
/// spell of a shared machine on all of them alike, and the fastest call is what the code does
/// when nothing else runs: ratios between the calls (a speedup) are then not the scatter between
/// two spells.
fn fastest_calls<const K: usize>(
    plan: &Plan,
    mut calls: [&mut dyn FnMut() -> Result<Duration>; K],
) -> Result<[f64; K]> {
    let mut per_repetition = [1u32; K];
    for (call, per) in calls.iter_mut().zip(&mut per_repetition) {
        *per = calls_per_repetition(plan, *call)?;
    }
    let mut best = [f64::INFINITY; K];
    for _ in 0..plan.batch_rounds {
        for ((call, per), b) in calls.iter_mut().zip(&per_repetition).zip(&mut best) {
            for _ in 0..*per {
                *b = b.min(call()?.as_secs_f64());
            }
        }
    }
    Ok(best)
}

/// Best (shortest) seconds per call of `call` over the plan's repetitions. `call` does one unit
/// of work and returns the duration of its timed part (its untimed part resets the state).
fn best_seconds_per_call(plan: &Plan, mut call: impl FnMut() -> Result<Duration>) -> Result<f64> {
    let per_repetition = calls_per_repetition(plan, &mut call)?;
    // The fastest repetition.
    let mut best = f64::INFINITY;
    for _ in 0..plan.repetitions {
        let mut total = Duration::ZERO;
        for _ in 0..per_repetition {
            total += call()?;
        }
        best = best.min(total.as_secs_f64() / f64::from(per_repetition));
    }
    Ok(best)
}

impl Render for BenchReport {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        writeln!(
            out,
            "whisker {}, {} stiffness, dt = {} s, rho_inf = {}, {} threads{}{}",
            self.whisker,
            self.discretisation,
            self.dt,
            self.rho_inf,
            self.threads,
            if self.quick { ", quick" } else { "" },
            if self.optimised { "" } else { ", DEBUG BUILD" },
        )?;
        writeln!(out)?;

        // Single state.
        writeln!(out, "single state, one thread")?;
        let mut table = Table::new(&[
            ("motion", Align::Left),
            ("N", Align::Right),
            ("solves/step", Align::Right),
            ("steps/s", Align::Right),
            ("µs/step", Align::Right),
            ("ns/step/segment", Align::Right),
        ]);
        for s in &self.single {
            table.row(vec![
                s.motion.to_string(),
                s.segments.to_string(),
                format!("{:.2}", s.solves_per_step),
                grouped(s.steps_per_second),
                sig(s.seconds_per_step * 1e6, 3),
                sig(s.seconds_per_step_per_segment * 1e9, 3),
            ]);
        }
        table.write(out, "  ")?;
        writeln!(out)?;

        // Batches.
        let b = &self.batch;
        writeln!(out, "batch of {} states, N = {}", b.states, b.segments)?;
        let mut table = Table::new(&[
            ("motion", Align::Left),
            ("threads", Align::Right),
            ("state-steps/s", Align::Right),
            ("ns/state-step", Align::Right),
            ("speedup", Align::Right),
            ("vs one at a time", Align::Right),
        ]);
        for b in [&self.batch, &self.batch_contact] {
            table.row(vec![
                format!("{} (one at a time)", b.motion),
                "1".into(),
                grouped(b.one_at_a_time_state_steps_per_second),
                sig(1e9 / b.one_at_a_time_state_steps_per_second, 3),
                "".into(),
                "1.00".into(),
            ]);
            table.row(vec![
                b.motion.to_string(),
                "1".into(),
                grouped(b.single_thread_state_steps_per_second),
                sig(b.single_thread_seconds_per_state_step * 1e9, 3),
                "1.00".into(),
                format!("{:.2}", b.over_one_at_a_time),
            ]);
            table.row(vec![
                b.motion.to_string(),
                b.threads.to_string(),
                grouped(b.state_steps_per_second),
                sig(b.seconds_per_state_step * 1e9, 3),
                format!("{:.2}", b.speedup),
                "".into(),
            ]);
        }
        table.write(out, "  ")?;
        writeln!(out)?;

        // Scaling.
        let s = &self.scaling;
        writeln!(
            out,
            "cost per segment at N = {} over N = {}: {:.2} (1 for a step that is O(N))",
            s.to_segments, s.from_segments, s.ratio
        )?;
        writeln!(out)?;

        // Whole runs.
        let r = &self.runs;
        writeln!(
            out,
            "{} runs of the {} ({} s each), {} threads: each alone {} s, together in lanes {} s ({:.2}x)",
            r.runs,
            r.what,
            r.duration,
            r.threads,
            sig(r.alone_seconds, 3),
            sig(r.together_seconds, 3),
            r.speedup
        )
    }
}
