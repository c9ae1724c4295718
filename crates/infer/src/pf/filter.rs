//! The filter: [`Filter`] takes one sample at a time (predict, weight, summarise; when the next
//! sample arrives, resample and move, and redraw the boxes that have not arrived), and
//! [`run_one`] feeds it a whole recording after checking it.

use super::config::{Config, PARAMS};
use super::draws::{draw_initial, redraw_waiting};
use super::likelihood::per_time_factor;
use super::posterior::{summarise_in_order, Observations, Posterior, SensorPosterior, TraceRow};
use super::sampling::{systematic, LiuWest};
use super::sensors::SensorBelief;
use super::transition::{advance, advance_together, param, ring_together, Hypothesis, ObjState};
use super::whiskers::WhiskerValues;
use crate::error::{Error, Result};
use crate::experiment::CHANNELS;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};
use vibrissa_core::batch;
use vibrissa_core::chain::Model;
use vibrissa_core::dynamics::{Integrator, State, Stepper, LANES};
use vibrissa_core::rng::Rng;
use vibrissa_core::sensors::Sensors;

/// Fewest particles of one whisker and model stepped together in lanes; fewer are stepped one at
/// a time (a lane group costs about what four single steps do, whatever its size).
const MIN_LANE_GROUP: usize = 4;

/// A particle advanced in a lane group: which model it is on (free ringing, or the contact model
/// before its box has gone) and which whisker, its index, and its parts.
struct Member<'a> {
    ringing: bool,
    whisker: u16,
    index: usize,
    state: &'a mut State,
    obj: &'a mut ObjState,
    gone: &'a mut bool,
    /// The spare slot, where a particle whose box was just moved keeps its state.
    kept: &'a mut State,
    /// The box before it was moved, if it was.
    before: Option<ObjState>,
    logw: &'a mut f64,
    belief: &'a mut SensorBelief,
}

/// Stream indices: particles' process noise, their moves, the resampling draws, the prior.
const STREAM_NOISE: u64 = 1 << 40;
pub(super) const STREAM_MOVE: u64 = 2 << 40;
const STREAM_RESAMPLE: u64 = 3 << 40;
const STREAM_PRIOR: u64 = 4 << 40;
const STREAM_REDRAW: u64 = 5 << 40;

/// Runs one filter over `obs`, one sample at a time, calling `progress` with the fraction done
/// (whatever [`Config::islands`] says: [`super::run`] splits the particles into islands).
pub(super) fn run_one(
    config: &Config,
    obs: &Observations,
    progress: &mut dyn FnMut(f64),
) -> Result<Posterior> {
    config.check()?;
    check_observations(config, obs)?;
    let period = obs.t.get(1).map_or(1e-3, |t1| t1 - obs.t[0]);
    let mut filter = Filter::new(config, period)?;
    filter.post.trace.reserve(obs.t.len());
    let samples = obs.t.len();
    for k in 0..samples {
        let y: [f64; 5] = std::array::from_fn(|c| {
            obs.values
                .get(c)
                .and_then(|v| v.get(k))
                .copied()
                .unwrap_or(f64::NAN)
        });
        filter.update(obs.t[k], &y)?;
        if k % 16 == 0 {
            progress(k as f64 / samples as f64);
        }
    }
    progress(1.0);
    Ok(filter.finish())
}

/// The particle cloud of a [`Filter`] after a sample ([`Filter::particles`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Particles {
    /// Names of the free unknowns.
    pub unknowns: Vec<&'static str>,
    /// `[unknowns][particles]`: each particle's value of each free unknown, SI.
    pub values: Vec<Vec<f64>>,
    /// Normalised weight of each particle.
    pub weights: Vec<f64>,
}

/// The particle filter as a running object, fed one sample at a time (online use: on a robot,
/// each sample as it arrives). [`super::run`] feeds it a whole recording.
pub struct Filter {
    config: Config,
    /// The whiskers entertained: `config.whisker` first, then its alternatives.
    hyps: Vec<Hypothesis>,
    stepper: Stepper,
    /// Sample period, s.
    period: f64,
    /// The free unknowns' indices into [`PARAMS`].
    free: Vec<usize>,
    /// Height above which a box counts as within reach of its whisker, m.
    reach_zone: f64,
    states: Vec<State>,
    spare: Vec<State>,
    objs: Vec<ObjState>,
    /// Each particle's whisker, an index into `hyps`.
    hyp: Vec<u16>,
    /// The whisker parameters that differ between `hyps`.
    whisker_values: WhiskerValues,
    spare_hyp: Vec<u16>,
    /// Each particle's belief over the sensors' gains and offsets (unchanging when they are
    /// known).
    sensors: Vec<SensorBelief>,
    spare_sensors: Vec<SensorBelief>,
    logw: Vec<f64>,
    /// Whether each particle's box has left for good (its whisker then rings free).
    cleared: Vec<bool>,
    spare_cleared: Vec<bool>,
    /// Whether each particle's box has come within reach of its whisker (before that, the
    /// whisker moves by process noise alone and the box's parameters are redrawn at every
    /// sample).
    arrived: Vec<bool>,
    spare_arrived: Vec<bool>,
    /// Each particle's box before the last move, until the next sample is predicted.
    unmoved: Vec<Option<ObjState>>,
    generation: u64,
    /// Per free unknown, the particles in ascending order of its value at the last sample
    /// (kept to sort the next sample's values quickly).
    order: Vec<Vec<u32>>,
    /// The last sample's time and normalised weights (resampling and the redraw of waiting
    /// boxes follow it, and are done when the next sample arrives).
    last: Option<(f64, Vec<f64>)>,
    samples: usize,
    ringing_samples: usize,
    post: Posterior,
}

impl Filter {
    /// A filter with `config`'s particles drawn from its prior, for samples `period` seconds
    /// apart (gaps of whole periods are predicted across).
    pub fn new(config: &Config, period: f64) -> Result<Filter> {
        config.check()?;
        if !(period.is_finite() && period > 0.0) {
            return Err(Error::Observation(format!(
                "the sample period must be a positive number of seconds, got {period}"
            )));
        }
        // Evidence weighed per millisecond (see `per_time_factor`).
        let widening = per_time_factor(period);
        let mut config = config.clone();
        config.sigma = config.sigma.map(|s| s * widening);
        let config = &config;
        let np = config.particles;
        let per_sample = vibrissa_core::dynamics::equal_steps(period, config.dt);
        let stepper = Integrator {
            dt: period / per_sample as f64,
            max_iterations: config.max_iterations,
            ..Integrator::default()
        }
        .check()
        .map_err(|e| Error::Observation(format!("filter integrator: {e}")))?;

        // The whiskers, each at rest; the objects drawn from the prior (or the mixture with the
        // injected proposal).
        let hyps = std::iter::once(&config.whisker)
            .chain(&config.alternatives)
            .map(|w| Hypothesis::new(config, w, period))
            .collect::<Result<Vec<_>>>()?;
        let hyp: Vec<u16> = (0..np).map(|i| (i % hyps.len()) as u16).collect();
        let states: Vec<State> = (0..np)
            .map(|i| {
                let mut s = hyps[hyp[i] as usize].at_rest.clone();
                s.rng = Rng::stream(config.seed, STREAM_NOISE + i as u64);
                s
            })
            .collect();
        let mut objs: Vec<ObjState> = Vec::with_capacity(np);
        let mut logw: Vec<f64> = Vec::with_capacity(np);
        for i in 0..np {
            let mut rng = Rng::stream(config.seed, STREAM_PRIOR + i as u64);
            let (o, lw) = draw_initial(config, &mut rng);
            objs.push(o);
            logw.push(lw);
        }
        let free: Vec<usize> = (0..PARAMS.len())
            .filter(|&k| config.priors[k].is_free())
            .collect();
        let sensors = vec![SensorBelief::prior(config); np];
        let order = vec![Vec::new(); free.len()];
        let clearance = hyps.iter().map(|h| h.ringing.clearance).fold(0.0, f64::max);
        let reach_zone = clearance + 1e-4;
        Ok(Filter {
            config: config.clone(),
            post: Posterior {
                rate_widening: widening,
                ..Posterior::empty(config.unknowns())
            },
            whisker_values: WhiskerValues::new(
                std::iter::once(&config.whisker).chain(&config.alternatives),
            ),
            hyps,
            stepper,
            spare_hyp: hyp.clone(),
            hyp,
            period,
            free,
            reach_zone,
            spare: states.clone(),
            states,
            objs,
            spare_sensors: sensors.clone(),
            sensors,
            logw,
            cleared: vec![false; np],
            spare_cleared: vec![false; np],
            arrived: vec![false; np],
            spare_arrived: vec![false; np],
            unmoved: vec![None; np],
            generation: 0,
            order,
            last: None,
            samples: 0,
            ringing_samples: 0,
        })
    }

    /// The posterior so far (its trace holds one row per sample; its `sensors` are filled in by
    /// [`Filter::finish`], and read as the filter runs by [`Filter::sensors`]).
    pub fn posterior(&self) -> &Posterior {
        &self.post
    }

    /// The sensors' gains and offsets after the last sample: the particles' beliefs mixed with
    /// their weights (formed when asked, not after every sample). `None` before the first
    /// sample, or when the filter was told them exactly.
    pub fn sensors(&self) -> Option<SensorPosterior> {
        match (self.config.sensor_spread.is_fixed(), &self.last) {
            (false, Some((_, w))) => Some(SensorBelief::mixture(&self.sensors, w)),
            _ => None,
        }
    }

    /// The particles after the last sample: their values of the free unknowns (in the order
    /// of [`Posterior`]'s estimates) and their normalised weights. Reading them changes nothing
    /// (for plots of the cloud as it evolves).
    pub fn particles(&self) -> Particles {
        let values = self
            .free
            .iter()
            .map(|&p| {
                self.objs
                    .iter()
                    .map(|o| param(o, p, self.config.gap))
                    .collect()
            })
            .collect();
        let weights = match &self.last {
            Some((_, w)) => w.clone(),
            None => {
                let max = self.logw.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
                let w: Vec<f64> = self.logw.iter().map(|l| (l - max).exp()).collect();
                let total: f64 = w.iter().sum();
                w.iter().map(|x| x / total).collect()
            }
        };
        Particles {
            unknowns: self.config.unknowns(),
            values,
            weights,
        }
    }

    /// The posterior after the last sample, with the share of particle-samples on the
    /// free-ringing model filled in.
    pub fn finish(mut self) -> Posterior {
        let np = self.config.particles;
        self.post.ringing_share = self.ringing_samples as f64 / (np * self.samples.max(1)) as f64;
        self.post.sensors = self.sensors();
        if let (false, Some((_, w))) = (self.config.sensor_spread.is_fixed(), &self.last) {
            self.post.angle_gains = Some(SensorBelief::angle_gains(&self.sensors, w));
        }
        self.post
    }

    /// Takes the sample `y` (theta01, theta12, m0, fx, fy; `NaN` where a channel is missing) at
    /// time `t`: predicts every particle to `t`, weights it, and returns the posterior row at
    /// `t`. Times must increase by whole sample periods.
    pub fn update(&mut self, t: f64, y: &[f64; 5]) -> Result<&TraceRow> {
        let config = &self.config;
        let np = config.particles;
        // The last sample's resampling and redraw, now that another sample follows it.
        let (steps, periods) = match self.last.take() {
            None => (0, 0),
            Some((t_last, w)) => {
                let periods = match whole_periods(t_last, t, self.period) {
                    Ok(periods) => periods,
                    Err(e) => {
                        // Keep the filter as it was: the sample can be given again.
                        self.last = Some((t_last, w));
                        return Err(e);
                    }
                };
                self.resample_and_redraw(t_last, &w);
                (
                    (((t - t_last) / self.stepper.dt) + 0.5).floor() as usize,
                    periods,
                )
            }
        };
        let config = &self.config;
        let k = self.samples;
        let mut seen = [false; 5];
        for &c in &config.channels {
            if y[c].is_finite() {
                seen[c] = true;
            } else {
                self.post.skipped += 1;
            }
        }
        let (hyps, stepper) = (&self.hyps, &self.stepper);
        let fixed_sensors = config.sensor_spread.is_fixed();
        // Weight mass the particles carry into this sample (for the evidence).
        let prior_mass: f64 = self.logw.iter().map(|l| l.exp()).sum();
        // The same per whisker, when there are several (for each whisker's evidence).
        let whiskers = if self.hyps.len() > 1 {
            self.hyps.len()
        } else {
            0
        };
        let whisker_mass = by_whisker(&self.hyp, self.logw.iter().map(|l| l.exp()), whiskers);
        let ringing_before = self.cleared.iter().filter(|c| **c).count();
        let undone = AtomicUsize::new(0);
        // Particles whose boxes were not just moved are advanced in lane groups of one whisker
        // and one model each (the free-ringing model once their box has gone for good, the
        // contact model before), in parallel, each to the bits it would reach alone. The others,
        // and groups too small to fill lanes, are advanced one at a time below.
        // The log-likelihood of the sample for a particle of whisker `hyp` in state `s`.
        let weigh = |hyp: &Hypothesis, s: &State, belief: &mut SensorBelief| -> f64 {
            let mut pred = Sensors::read(s).to_array();
            [pred[0], pred[1]] = hyp.joints.apply(s.q());
            if fixed_sensors {
                let mut ll = 0.0;
                for c in 0..5 {
                    if seen[c] {
                        // What the channel's sensor records of the model's value.
                        let recorded = config.sensor_gain[c] * pred[c] + config.sensor_offset[c];
                        let z = (y[c] - recorded) / config.sigma[c];
                        ll -= 0.5 * z * z;
                    }
                }
                ll
            } else {
                belief.take(&pred, y, &seen, &config.sigma)
            }
        };
        let mut grouped = vec![false; np];
        let mut diverged = 0;
        if steps > 0 && config.lane_groups {
            // Members by model (contact, then ringing) and whisker, each in particle order.
            let whiskers = hyps.len();
            let mut buckets: Vec<Vec<Member>> = (0..2 * whiskers).map(|_| Vec::new()).collect();
            for (j, (((((state, obj), gone), kept), logw), belief)) in self
                .states
                .iter_mut()
                .zip(self.objs.iter_mut())
                .zip(self.cleared.iter_mut())
                .zip(self.spare.iter_mut())
                .zip(self.logw.iter_mut())
                .zip(self.sensors.iter_mut())
                .enumerate()
            {
                if *logw == f64::NEG_INFINITY {
                    continue;
                }
                let (ringing, whisker) = (*gone, self.hyp[j]);
                buckets[usize::from(ringing) * whiskers + whisker as usize].push(Member {
                    ringing,
                    whisker,
                    index: j,
                    state,
                    obj,
                    gone,
                    kept,
                    before: self.unmoved[j],
                    logw,
                    belief,
                });
            }
            let mut groups: Vec<&mut [Member]> = Vec::new();
            for same in buckets.iter_mut() {
                for group in same.chunks_mut(LANES) {
                    if group.len() >= MIN_LANE_GROUP {
                        group.iter().for_each(|m| grouped[m.index] = true);
                        groups.push(group);
                    }
                }
            }
            diverged = groups
                .into_par_iter()
                .map_init(
                    || batch::Scratch::new(&hyps[0].model),
                    |scratch, group| {
                        let (ws, lw) = scratch.get();
                        let hyp = &hyps[group[0].whisker as usize];
                        let chain = &hyp.chain(stepper);
                        let noise = config.process_noise;
                        // A box just moved may sit where its whisker state cannot follow: keep
                        // the state to take the sample again with the unmoved box (below).
                        for m in group.iter_mut().filter(|m| m.before.is_some()) {
                            m.kept.clone_from(m.state);
                        }
                        let objs: Vec<ObjState> = group.iter().map(|m| *m.obj).collect();
                        let ringing = group[0].ringing;
                        let mut states: Vec<&mut State> =
                            group.iter_mut().map(|m| &mut *m.state).collect();
                        let ok = if ringing {
                            ring_together(chain, &mut states, periods, noise, lw, ws)
                        } else {
                            let advanced = advance_together(
                                chain,
                                &mut states,
                                &objs,
                                steps,
                                periods,
                                noise,
                                t,
                                lw,
                                ws,
                            );
                            drop(states);
                            for (m, gone) in group.iter_mut().zip(advanced) {
                                *m.gone |= gone == Some(true);
                            }
                            advanced.map(|a| a.is_some())
                        };
                        let mut failed = 0;
                        for (m, ok) in group.iter_mut().zip(ok) {
                            let mut ok =
                                ok && (m.before.is_none() || !whipped(&hyp.model, m.state));
                            if let (false, Some(b)) = (ok, m.before) {
                                undone.fetch_add(1, Ordering::Relaxed);
                                m.state.clone_from(m.kept);
                                (*m.gone, *m.obj) = (m.ringing, b);
                                ok = advance(
                                    chain, m.state, m.obj, m.gone, steps, periods, noise, t, ws,
                                )
                                .is_ok();
                            }
                            if ok {
                                *m.logw += weigh(hyp, m.state, m.belief);
                            } else {
                                *m.logw = f64::NEG_INFINITY;
                                failed += 1;
                            }
                        }
                        failed
                    },
                )
                .sum::<usize>();
        }
        // Predict every other particle, and weight every particle, in parallel.
        diverged += batch::sum_with_workspace(
            &hyps[0].model,
            self.states
                .par_iter_mut()
                .zip(self.objs.par_iter_mut())
                .zip(self.logw.par_iter_mut())
                .zip(self.cleared.par_iter_mut())
                .zip(self.unmoved.par_iter())
                .zip(self.spare.par_iter_mut())
                .zip(self.sensors.par_iter_mut())
                .zip(self.hyp.par_iter().zip(grouped.par_iter())),
            |ws, (((((((s, o), lw), gone), before), kept), belief), (h, grouped))| {
                if *lw == f64::NEG_INFINITY || *grouped {
                    return 0;
                }
                let hyp = &hyps[*h as usize];
                let chain = &hyp.chain(stepper);
                let model = &hyp.model;
                let noise = config.process_noise;
                // A box just moved may sit where its whisker state cannot follow (around
                // the tip, say): keep the state (in the spare slot, free until the next
                // resampling) to take the sample again with the unmoved box.
                let was_gone = *gone;
                if before.is_some() {
                    kept.clone_from(s);
                }
                let mut ok = advance(chain, s, o, gone, steps, periods, noise, t, ws).is_ok()
                    && (before.is_none() || !whipped(model, s));
                if let (false, Some(b)) = (ok, before) {
                    undone.fetch_add(1, Ordering::Relaxed);
                    s.clone_from(kept);
                    (*gone, *o) = (was_gone, *b);
                    ok = advance(chain, s, o, gone, steps, periods, noise, t, ws).is_ok();
                }
                if !ok {
                    *lw = f64::NEG_INFINITY;
                    return 1;
                }
                let ll = weigh(hyp, s, belief);
                *lw += ll;
                0
            },
        );
        let post = &mut self.post;
        post.diverged += diverged;
        post.refused_moves += undone.into_inner();
        self.unmoved.iter_mut().for_each(|u| *u = None);
        post.steps += ((np - ringing_before) * steps + ringing_before * periods) as u64;
        self.ringing_samples += ringing_before;
        self.samples += 1;

        // Normalise.
        let max = self.logw.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        if max == f64::NEG_INFINITY {
            return Err(Error::Observation(format!(
                "every particle diverged or has zero likelihood by t = {t} s"
            )));
        }
        let mut w: Vec<f64> = self.logw.iter().map(|l| (l - max).exp()).collect();
        let total: f64 = w.iter().sum();
        // The weights entered this sample normalised (or equal after resampling), so their new
        // sum is the sample's likelihood averaged over the particles.
        post.log_evidence += max + (total / prior_mass).ln();
        w.iter_mut().for_each(|x| *x /= total);
        let ess = 1.0 / w.iter().map(|x| x * x).sum::<f64>();

        // Posterior summary.
        let objs = &self.objs;
        let estimates = self
            .free
            .par_iter()
            .zip(self.order.par_iter_mut())
            .map(|(&p, order)| {
                let vals: Vec<f64> = objs.iter().map(|o| param(o, p, config.gap)).collect();
                summarise_in_order(&vals, &w, order)
            })
            .collect();
        post.trace.push(TraceRow { t, ess, estimates });
        if whiskers > 0 {
            // Each whisker's share of the weight: its evidence grew by the ratio of its mass
            // after the sample (share × total, relative to `max`) to its mass before.
            let share = by_whisker(&self.hyp, w.iter().copied(), whiskers);
            post.whisker_log_evidence.resize(whiskers, 0.0);
            for ((ev, p), m) in post
                .whisker_log_evidence
                .iter_mut()
                .zip(&share)
                .zip(&whisker_mass)
            {
                // A whisker whose particles are all gone has no evidence left to update.
                *ev = if *m > 0.0 {
                    *ev + max + (p * total / m).ln()
                } else {
                    f64::NEG_INFINITY
                };
            }
            if !self.whisker_values.is_empty() {
                post.whisker = self.whisker_values.posterior(&share);
            }
        }
        self.logw
            .iter_mut()
            .zip(&w)
            .for_each(|(l, x)| *l = if *x > 0.0 { x.ln() } else { f64::NEG_INFINITY });
        debug_assert_eq!(k + 1, self.samples);
        self.last = Some((t, w));
        Ok(self.post.trace.last().expect("a row was pushed"))
    }

    /// After the sample at `t` with normalised weights `w`, once another sample follows: resample
    /// and move when the effective sample size has fallen below [`Config::ess_fraction`], then
    /// redraw the boxes that have not arrived.
    fn resample_and_redraw(&mut self, t: f64, w: &[f64]) {
        let config = &self.config;
        let np = config.particles;
        let k = self.samples - 1;
        let ess = self.post.trace.last().map_or(np as f64, |r| r.ess);
        if ess < config.ess_fraction * np as f64 {
            self.generation += 1;
            let generation = self.generation;
            self.post.resamples += 1;
            let mut rng = Rng::stream(config.seed, STREAM_RESAMPLE + generation);
            let parents = systematic(w, rng.uniform());
            let kernel = LiuWest::new(config, &self.objs, w, &self.free, &self.arrived);
            for (i, &p) in parents.iter().enumerate() {
                self.spare[i].clone_from(&self.states[p]);
                self.spare_cleared[i] = self.cleared[p];
                self.spare_arrived[i] = self.arrived[p];
                self.spare_sensors[i] = self.sensors[p];
                self.spare_hyp[i] = self.hyp[p];
                self.spare[i].rng =
                    Rng::stream(config.seed, STREAM_NOISE + (generation << 20) + i as u64);
            }
            std::mem::swap(&mut self.states, &mut self.spare);
            std::mem::swap(&mut self.cleared, &mut self.spare_cleared);
            std::mem::swap(&mut self.arrived, &mut self.spare_arrived);
            std::mem::swap(&mut self.sensors, &mut self.spare_sensors);
            std::mem::swap(&mut self.hyp, &mut self.spare_hyp);
            self.objs = parents.iter().map(|&p| self.objs[p]).collect();
            self.logw.iter_mut().for_each(|l| *l = 0.0);
            if let Some(kernel) = &kernel {
                let moved = self.objs.iter_mut().zip(self.unmoved.iter_mut());
                for (i, (o, u)) in moved.enumerate() {
                    if self.arrived[i] {
                        let stream = STREAM_MOVE + (generation << 20) + i as u64;
                        let mut rng = Rng::stream(config.seed, stream);
                        *u = Some(*o);
                        *o = kernel.draw(config, o, self.cleared[i], t, &mut rng);
                    }
                }
            }
        }
        // Boxes that have not come within reach yet: the whisker has not felt them, so their
        // parameters are redrawn from the prior given "not arrived by now", with arrivals in the
        // next few milliseconds favoured (and weighted back), so that whenever contact begins
        // many particles meet it with a spread of distances and speeds.
        redraw_waiting(
            config,
            &mut self.objs,
            &mut self.logw,
            &mut self.arrived,
            t,
            self.reach_zone,
            Rng::stream(config.seed, STREAM_REDRAW + k as u64),
        );
    }
}

/// The sum of `values` (one per particle) over the particles of each of `whiskers` whiskers, by
/// each particle's whisker `hyp` (empty for none).
fn by_whisker(hyp: &[u16], values: impl Iterator<Item = f64>, whiskers: usize) -> Vec<f64> {
    let mut sums = vec![0.0; whiskers];
    if whiskers > 0 {
        for (&h, x) in hyp.iter().zip(values) {
            sums[h as usize] += x;
        }
    }
    sums
}

/// Whether a joint of `s` is bent more than [`WHIPPED`] from its rest angle.
fn whipped(model: &Model, s: &State) -> bool {
    s.q()
        .iter()
        .zip(&model.rest)
        .any(|(q, r)| (q - r).abs() > WHIPPED)
}

/// A joint angle from rest, rad, that no strike of a whisker by a moving object reaches: a
/// state bent further just after a move was launched by the move, not by the object's motion.
const WHIPPED: f64 = 0.5;

/// Refuses observations the filter cannot use.
fn check_observations(config: &Config, obs: &Observations) -> Result<()> {
    let n = obs.t.len();
    if n < 2 {
        return Err(Error::Observation(format!(
            "the filter needs at least 2 samples, got {n}"
        )));
    }
    for &c in &config.channels {
        match obs.values.get(c) {
            Some(v) if v.len() == n => {}
            _ => {
                return Err(Error::Observation(format!(
                    "channel `{}` is observed by the filter but missing or of the wrong length (expected {n} samples)",
                    CHANNELS[c]
                )))
            }
        }
    }
    if obs.t.iter().any(|t| !t.is_finite()) {
        return Err(Error::Observation("a sample time `t` is not finite".into()));
    }
    let period = obs.t[1] - obs.t[0];
    if period.is_nan() || period <= 0.0 {
        return Err(Error::Observation("sample times `t` must increase".into()));
    }
    for k in 1..n {
        whole_periods(obs.t[k - 1], obs.t[k], period)?;
    }
    Ok(())
}

/// How many sample periods lie between the samples at `t_last` and `t`: gaps of whole periods
/// are predicted across; anything else is refused.
fn whole_periods(t_last: f64, t: f64, period: f64) -> Result<usize> {
    let m = (t - t_last) / period;
    if !t.is_finite() || m.is_nan() || m < 0.5 || (m - m.round()).abs() > 1e-3 {
        return Err(Error::Observation(format!(
            "irregular sample times: t = {t} s follows {t_last} s, expected a whole number of periods of {period} s"
        )));
    }
    Ok((m + 0.5).floor() as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_state_is_whipped_when_a_joint_is_bent_far_from_rest() {
        let config = Config::e2([1.0; 5], 4, 1);
        let whisker = config.whisker.check().unwrap();
        let model = Model::new(&whisker, config.segments, config.model_discretisation()).unwrap();
        let mut s = State::at_rest(&model, 1);
        assert!(!whipped(&model, &s));
        s.q_mut()[2] = 0.9 * WHIPPED;
        assert!(!whipped(&model, &s));
        s.q_mut()[3] = -1.1 * WHIPPED;
        assert!(whipped(&model, &s));
    }
}
