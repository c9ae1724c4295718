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

/// One run stepped in a lane: its scenario, state, sensor stream and what it has recorded.
struct Lane<'a> {
    scenario: &'a Scenario,
    state: State,
    sensor_rng: Rng,
    rows: Vec<[f64; 10]>,
    steps: usize,
    max_penetration: f64,
    touched: Option<ContactReport>,
    /// Still stepped in lanes (a run that failed is run again alone).
    live: bool,
}

/// The runs of `group` (scenarios that share [`lane_key`]), in order.
fn run_group(group: &[&Scenario]) -> Vec<Result<Output>> {
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
            Lane {
                scenario: s,
                state,
                sensor_rng: Rng::stream(s.seed, 1),
                rows: Vec::with_capacity(samples),
                steps: 0,
                max_penetration: 0.0,
                touched: None,
                live,
            }
        })
        .collect();

    for k in 0..samples {
        for lane in lanes.iter_mut() {
            lane.touched = None;
        }
        if k > 0 {
            for j in 1..=per_sample {
                let t = ((k - 1) * per_sample + j) as f64 * stepper.dt;
                let base = first.base.at(t);
                let mut live: Vec<&mut Lane> = lanes.iter_mut().filter(|l| l.live).collect();
                if live.is_empty() {
                    break;
                }
                let entered: Vec<bool> = live
                    .iter()
                    .map(|l| entering(&l.scenario.objects, l.state.t, t))
                    .collect();
                for (part, entered) in live.chunks_mut(LANES).zip(entered.chunks(LANES)) {
                    let objects: Vec<&[Object]> =
                        part.iter().map(|l| &l.scenario.objects[..]).collect();
                    let mut states: Vec<&mut State> =
                        part.iter_mut().map(|l| &mut l.state).collect();
                    let noise = first.process_noise;
                    let failed = step_group_each(
                        &model,
                        &stepper,
                        &mut states,
                        &objects,
                        base,
                        &|_| noise,
                        1,
                        &mut lw,
                        &mut ws,
                    );
                    for ((lane, failed), &entered) in part.iter_mut().zip(failed).zip(entered) {
                        if failed.is_some() {
                            lane.live = false;
                            continue;
                        }
                        lane.steps += 1;
                        if entered {
                            ws.evaluate(&model, &lane.state);
                            if check_clear(&model, &ws, &lane.scenario.objects, lane.state.t)
                                .is_err()
                            {
                                lane.live = false;
                                continue;
                            }
                        }
                        if lane.state.contact.is_some() {
                            let p =
                                penetration(&model, &lane.state, &mut ws, &lane.scenario.objects);
                            lane.max_penetration = lane.max_penetration.max(p);
                            lane.touched = lane.state.contact;
                        }
                    }
                }
            }
        }
        for lane in lanes.iter_mut().filter(|l| l.live) {
            let s = lane.scenario;
            lane.rows.push(sample(
                &lane.state,
                lane.state.contact.or(lane.touched),
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
