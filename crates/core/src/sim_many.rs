//! Many scenario runs at once: the runs of a family (a training set, a sweep, a data set) differ
//! mostly in their objects and seeds, so those that share a whisker, chain, time step, base
//! motion, sample rate, duration and random-force intensity are stepped together in lanes
//! ([`step_group_each`]), each against its own objects, with its own random streams and its own
//! sensors. Every run's output is the one [`run`] gives it alone, bit for bit; a run that fails
//! (a refused scenario, a divergence, an object entering the plane on the whisker) is run again
//! alone, so its error, with its explanation, is the one [`run`] gives too.

use crate::chain::Model;
use crate::contact::ContactReport;
use crate::dynamics::{
    initialize, lanes_apply, step_group_each, Inputs, LaneWorkspace, State, Workspace, LANES,
};
use crate::error::Result;
use crate::objects::Object;
use crate::rng::Rng;
use crate::sim::{
    check_clear, entering, penetration, run, sample, timing, Output, Scenario, SensorNoise,
    SensorResponse,
};
use rayon::prelude::*;

/// Runs every scenario of `scenarios` as [`run`] does (without progress), on all cores, those
/// that can share lanes together: the outputs, in order, are [`run`]'s to the bit.
pub fn run_many(scenarios: &[Scenario]) -> Vec<Result<Output>> {
    // A lane group costs about the same however many of its lanes hold runs: full groups,
    // unless there are too few runs to give every core one.
    let threads = rayon::current_num_threads().max(1);
    let chunk = scenarios.len().div_ceil(threads).clamp(1, LANES);
    let chunks: Vec<&[Scenario]> = scenarios.chunks(chunk).collect();
    chunks.into_par_iter().flat_map_iter(run_together).collect()
}

/// Runs every scenario of `scenarios` as [`run`] does, on this thread, up to [`LANES`] at a
/// time in lanes where they share all but their objects, seeds and sensors: the outputs, in
/// order, are [`run`]'s to the bit.
pub fn run_together(scenarios: &[Scenario]) -> Vec<Result<Output>> {
    let mut out: Vec<Option<Result<Output>>> = (0..scenarios.len()).map(|_| None).collect();
    let mut left: Vec<usize> = (0..scenarios.len()).collect();
    while let Some(&first) = left.first() {
        let key = lane_key(&scenarios[first]);
        let (same, rest): (Vec<usize>, Vec<usize>) = left
            .iter()
            .partition(|&&k| k == first || lane_key(&scenarios[k]) == key);
        left = rest;
        for part in same.chunks(LANES) {
            let group: Vec<&Scenario> = part.iter().map(|&k| &scenarios[k]).collect();
            for (&k, r) in part.iter().zip(run_group(&group)) {
                out[k] = Some(r);
            }
        }
    }
    out.into_iter()
        .map(|r| r.expect("every run is run"))
        .collect()
}

/// What runs stepped together must share: the scenario without its objects, seed and sensors.
fn lane_key(s: &Scenario) -> Scenario {
    Scenario {
        objects: Vec::new(),
        seed: 0,
        sensor_noise: SensorNoise::default(),
        sensor_response: SensorResponse::default(),
        ..s.clone()
    }
}

/// One run stepped in a lane: its scenario, sensor stream and what it has recorded (its state
/// is kept beside the others', so that all can be stepped as one slice).
struct Lane<'a> {
    scenario: &'a Scenario,
    sensor_rng: Rng,
    rows: Vec<[f64; 10]>,
    steps: usize,
    max_penetration: f64,
    touched: Option<ContactReport>,
    /// Still stepped in lanes (a run that failed is run again alone).
    live: bool,
}

/// The runs of `group` (at most [`LANES`] scenarios that share [`lane_key`]), in order.
fn run_group(group: &[&Scenario]) -> Vec<Result<Output>> {
    assert!(
        group.len() <= LANES,
        "a lane group holds at most {LANES} runs"
    );
    let alone = |s: &Scenario| run(s, &mut |_| {});
    let Some(first) = group.first() else {
        return Vec::new();
    };
    if group.len() < 2 {
        return group.iter().map(|s| alone(s)).collect();
    }
    // What the group shares; a scenario that fails here fails alone in the same way.
    let shared = first.check().and_then(|_| {
        let whisker = first.whisker.check()?;
        let model = Model::new(&whisker, first.segments, first.discretisation)?;
        let (stepper, per_sample, samples) = timing(first)?;
        Ok((model, stepper, per_sample, samples))
    });
    let Ok((model, stepper, per_sample, samples)) = shared else {
        return group.iter().map(|s| alone(s)).collect();
    };
    if !lanes_apply::<State>(&model, &stepper, &[State::at_rest(&model, 0)], false) {
        return group.iter().map(|s| alone(s)).collect();
    }
    let period = 1.0 / first.sample_rate;
    let mut ws = Workspace::new(&model);
    let mut lw = LaneWorkspace::new(&model);

    // Each run starts as `run` starts it: at rest, clear of every object.
    let objects: Vec<&[Object]> = group.iter().map(|s| &s.objects[..]).collect();
    let mut states = Vec::with_capacity(group.len());
    let mut lanes: Vec<Lane> = group
        .iter()
        .map(|&s| {
            let mut state = State::at_rest(&model, s.seed);
            let base0 = s.base.at(0.0);
            state.base = base0;
            let inputs = Inputs {
                base: base0,
                loads: &[],
                noise: s.process_noise,
                objects: &s.objects,
            };
            let live = s.check().is_ok()
                && initialize(&model, &mut state, &inputs, &mut ws).is_ok()
                && check_clear(&model, &ws, &s.objects, 0.0).is_ok();
            states.push(state);
            Lane {
                scenario: s,
                sensor_rng: Rng::stream(s.seed, 1),
                rows: Vec::with_capacity(samples),
                steps: 0,
                max_penetration: 0.0,
                touched: None,
                live,
            }
        })
        .collect();

    let noise = first.process_noise;
    for k in 0..samples {
        for lane in lanes.iter_mut() {
            lane.touched = None;
        }
        // The steps since the previous sample (none before the first).
        let steps = if k > 0 { per_sample } else { 0 };
        for j in 1..=steps {
            if !lanes.iter().any(|l| l.live) {
                break;
            }
            let t = ((k - 1) * per_sample + j) as f64 * stepper.dt;
            let base = first.base.at(t);
            let entered: [bool; LANES] = std::array::from_fn(|l| {
                l < lanes.len() && lanes[l].live && entering(objects[l], states[l].t, t)
            });
            let failed: [Option<crate::Error>; LANES] = if lanes.iter().all(|l| l.live) {
                step_group_each(
                    &model,
                    &stepper,
                    &mut states,
                    &objects,
                    base,
                    &|_| noise,
                    1,
                    &mut lw,
                    &mut ws,
                )
            } else {
                // Some runs failed and are left out (they are run again alone at the end).
                let live: Vec<usize> = (0..lanes.len()).filter(|&l| lanes[l].live).collect();
                let live_objects: Vec<&[Object]> = live.iter().map(|&l| objects[l]).collect();
                let mut live_states: Vec<&mut State> = states
                    .iter_mut()
                    .zip(&lanes)
                    .filter(|(_, lane)| lane.live)
                    .map(|(s, _)| s)
                    .collect();
                let mut out = step_group_each(
                    &model,
                    &stepper,
                    &mut live_states,
                    &live_objects,
                    base,
                    &|_| noise,
                    1,
                    &mut lw,
                    &mut ws,
                );
                let mut failed: [Option<crate::Error>; LANES] = Default::default();
                for (i, &l) in live.iter().enumerate() {
                    failed[l] = out[i].take();
                }
                failed
            };
            for (l, (lane, state)) in lanes.iter_mut().zip(&states).enumerate() {
                if !lane.live {
                    continue;
                }
                if failed[l].is_some() {
                    lane.live = false;
                    continue;
                }
                lane.steps += 1;
                if entered[l] {
                    ws.evaluate(&model, state);
                    if check_clear(&model, &ws, objects[l], state.t).is_err() {
                        lane.live = false;
                        continue;
                    }
                }
                if state.contact.is_some() {
                    let p = penetration(&model, state, &mut ws, objects[l]);
                    lane.max_penetration = lane.max_penetration.max(p);
                    lane.touched = state.contact;
                }
            }
        }
        for (lane, state) in lanes.iter_mut().zip(&states).filter(|(l, _)| l.live) {
            let s = lane.scenario;
            lane.rows.push(sample(
                state,
                state.contact.or(lane.touched),
                k as f64 * period,
                &s.sensor_noise,
                &s.sensor_response,
                &mut lane.sensor_rng,
            ));
        }
    }
    lanes
        .into_iter()
        .map(|lane| {
            if lane.live {
                Ok(Output {
                    rows: lane.rows,
                    segments: model.n,
                    dt: stepper.dt,
                    steps: lane.steps,
                    max_penetration: lane.max_penetration,
                })
            } else {
                alone(lane.scenario)
            }
        })
        .collect()
}
