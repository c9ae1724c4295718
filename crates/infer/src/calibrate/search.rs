//! The Levenberg–Marquardt search, resumable: a fit is a [`Search`] advanced one iteration at a
//! time, so that several starts can each be taken a few iterations, the most promising then
//! carried on from where they stopped (the same path as one uninterrupted fit).

use super::fit::{Setup, Sims, Solution, CHANNELS};
use super::params::bounds;
use super::{GainHandling, Progress};
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use std::sync::atomic::AtomicUsize;
use vibrissa_core::sim::Response;

/// Relative decrease of the cost below which an iteration counts as stalled; two stalled
/// iterations in a row end the fit.
const FTOL: f64 = 1e-4;

/// A Levenberg–Marquardt fit in progress: the point reached, its simulations and cost, and the
/// damping state that the next iteration starts from.
///
/// Marquardt's scaling (the damping is λ times the diagonal of JᵀJ) with Nielsen's update of λ.
/// A trial point whose simulation fails counts as a rejected step. The simulated channels are
/// not smooth at the finest scale (contact events fall on time steps), so every decrease of the
/// cost is accepted and the fit ends when the cost stops falling: two iterations in a row below
/// a relative decrease of 1e-4, or no decrease for any damping.
pub(super) struct Search {
    /// Free parameters, then with joint handling the gains and offsets.
    z: Vec<f64>,
    /// Free whisker parameters among `z`.
    p: usize,
    sims: Sims,
    resp: [Response; CHANNELS],
    /// Weighted cost at `z`.
    pub cost: f64,
    lambda: Option<f64>,
    nu: f64,
    stalled: usize,
    /// Jacobians evaluated so far.
    pub iterations: usize,
    /// Residual evaluations so far.
    pub evaluations: usize,
    /// Whether the cost has stopped falling.
    pub converged: bool,
}

impl Search {
    /// A fit from `z0` (and, with joint handling, the gains and offsets of `resp0`).
    pub(super) fn start(
        setup: &Setup,
        z0: &[f64],
        resp0: &[Response; CHANNELS],
        count: &AtomicUsize,
    ) -> Result<Search> {
        let mut z = z0.to_vec();
        if setup.handling == GainHandling::Joint {
            z.extend(setup.gains().iter().map(|&c| resp0[c].gain));
            z.extend(setup.channels.iter().map(|&c| resp0[c].offset));
        }
        let p = setup.free.iter().filter(|&&f| f).count();
        let (sims, resp, cost) = evaluate(setup, &z, p, count).ok_or_else(|| {
            Error::Calibration(
                "a recording's scenario does not simulate at the starting point".into(),
            )
        })?;
        Ok(Search {
            z,
            p,
            sims,
            resp,
            cost,
            lambda: None,
            nu: 2.0,
            stalled: 0,
            iterations: 0,
            evaluations: 1,
            converged: false,
        })
    }

    /// One iteration: a Jacobian, then trial steps with more damping after each failure, until
    /// one lowers the cost. Sets `converged` when none does, or when the cost has stalled.
    pub(super) fn iterate(&mut self, setup: &Setup, count: &AtomicUsize) -> Result<()> {
        self.iterations += 1;
        let jac = jacobian(setup, &self.z, &self.sims, &self.resp, count).ok_or_else(|| {
            Error::Calibration("simulations next to the current point failed".into())
        })?;
        let e = setup.residual(&self.sims, &self.resp);
        let g = jac.transpose() * &e;
        let a = jac.transpose() * &jac;
        let diag: Vec<f64> = (0..a.nrows()).map(|k| a[(k, k)].max(1e-30)).collect();
        let lam = *self.lambda.get_or_insert(1e-3);
        let mut lam_try = lam;
        let mut accepted = None;
        let free = setup.free_indices();
        for _ in 0..12 {
            let mut m = a.clone();
            for k in 0..m.nrows() {
                m[(k, k)] += lam_try * diag[k];
            }
            let Some(step) = m.cholesky().map(|c| c.solve(&(-&g))) else {
                lam_try *= self.nu;
                self.nu *= 2.0;
                continue;
            };
            // Steps beyond a parameter's bounds stop at the bound.
            let trial: Vec<f64> = self
                .z
                .iter()
                .zip(step.iter())
                .enumerate()
                .map(|(j, (a, b))| match free.get(j) {
                    Some(&i) => {
                        let (lo, hi) = bounds(setup.params[i].kind);
                        (a + b).clamp(lo, hi)
                    }
                    None => a + b,
                })
                .collect();
            self.evaluations += 1;
            let predicted = -(step.dot(&g) * 2.0 + (&jac * &step).norm_squared());
            match evaluate(setup, &trial, self.p, count) {
                Some((s, r, c)) if c < self.cost => {
                    // Nielsen: damp less after a step that went as predicted.
                    let ratio = (self.cost - c) / predicted.max(f64::MIN_POSITIVE);
                    self.lambda =
                        Some(lam_try * (1.0 / 3.0f64).max(1.0 - (2.0 * ratio - 1.0).powi(3)));
                    self.nu = 2.0;
                    accepted = Some((trial, s, r, c));
                    break;
                }
                _ => {
                    lam_try *= self.nu;
                    self.nu *= 2.0;
                }
            }
        }
        let Some((zt, s, r, c)) = accepted else {
            // No damping lowers the cost: a minimum at the resolution of the simulations.
            self.converged = true;
            return Ok(());
        };
        let decrease = (self.cost - c) / self.cost;
        (self.z, self.sims, self.resp, self.cost) = (zt, s, r, c);
        self.stalled = if decrease < FTOL { self.stalled + 1 } else { 0 };
        if self.stalled >= 2 {
            self.converged = true;
        }
        Ok(())
    }

    /// Iterates until the fit converges; an error once `max_iterations` Jacobians (counting those
    /// already taken) have not sufficed.
    pub(super) fn finish(
        mut self,
        setup: &Setup,
        max_iterations: usize,
        count: &AtomicUsize,
        stage: &str,
        progress: &mut dyn FnMut(&Progress),
    ) -> Result<Solution> {
        while !self.converged {
            if self.iterations >= max_iterations {
                return Err(Error::Calibration(format!(
                    "the fit did not converge within {max_iterations} iterations ({stage}; the \
                     cost still fell by more than {FTOL:e} per iteration)"
                )));
            }
            self.iterate(setup, count)?;
            self.report(stage, progress);
        }
        Ok(Solution {
            z: self.z[..self.p].to_vec(),
            sims: self.sims,
            resp: self.resp,
            iterations: self.iterations,
        })
    }

    /// Tells `progress` where the fit stands.
    pub(super) fn report(&self, stage: &str, progress: &mut dyn FnMut(&Progress)) {
        progress(&Progress {
            stage: stage.to_string(),
            iteration: self.iterations,
            evaluations: self.evaluations,
            cost: self.cost,
        });
    }
}

/// Simulations, gains and offsets, and cost at `z`; `None` where a simulation fails.
fn evaluate(
    setup: &Setup,
    z: &[f64],
    p: usize,
    count: &AtomicUsize,
) -> Option<(Sims, [Response; CHANNELS], f64)> {
    let sims = setup.simulate(&setup.full_x(&z[..p]), count)?;
    let resp = responses(setup, z, &sims);
    let cost = setup.residual(&sims, &resp).norm_squared();
    cost.is_finite().then_some((sims, resp, cost))
}

/// Fits the free parameters from `z0` (and, with joint handling, the gains and offsets from
/// `resp0`) by Levenberg–Marquardt to convergence; at most `max_iterations` Jacobians.
pub(super) fn fit(
    setup: &Setup,
    z0: &[f64],
    resp0: &[Response; CHANNELS],
    max_iterations: usize,
    count: &AtomicUsize,
    stage: &str,
    progress: &mut dyn FnMut(&Progress),
) -> Result<Solution> {
    Search::start(setup, z0, resp0, count)?.finish(setup, max_iterations, count, stage, progress)
}

/// Gains and offsets at `z` (free parameters, then with joint handling the free gains and every
/// offset) for `sims`.
fn responses(setup: &Setup, z: &[f64], sims: &Sims) -> [Response; CHANNELS] {
    match setup.handling {
        GainHandling::Projected => setup.solve_linear(sims),
        GainHandling::Joint => {
            let mut resp = setup.nominal;
            let p = setup.free.iter().filter(|&&f| f).count();
            let gains = setup.gains();
            for (k, &c) in gains.iter().enumerate() {
                resp[c].gain = z[p + k];
            }
            for (k, &c) in setup.channels.iter().enumerate() {
                resp[c].offset = z[p + gains.len() + k];
            }
            resp
        }
    }
}

/// The Jacobian of the residuals at `z` (free parameters, then with joint handling the gains
/// and offsets), with `sims` the simulations there.
fn jacobian(
    setup: &Setup,
    z: &[f64],
    sims: &Sims,
    resp: &[Response; CHANNELS],
    count: &AtomicUsize,
) -> Option<DMatrix<f64>> {
    let p = setup.free.iter().filter(|&&f| f).count();
    match setup.handling {
        GainHandling::Joint => setup.jacobian_full(&z[..p], sims, resp, count),
        GainHandling::Projected => {
            // Derivatives of the residuals with the gains and offsets re-solved at each step.
            let stepped = setup.stepped(&z[..p], count)?;
            let e = setup.residual(sims, resp);
            let mut jac = DMatrix::zeros(e.len(), p);
            for (j, (a, b, h)) in stepped.iter().enumerate() {
                let ea = setup.residual(a, &setup.solve_linear(a));
                let eb = b
                    .as_ref()
                    .map_or_else(|| e.clone(), |b| setup.residual(b, &setup.solve_linear(b)));
                jac.set_column(j, &((ea - eb) / *h));
            }
            Some(jac)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{params, prepare, ranges, GainHandling};
    use super::*;
    use vibrissa_core::sim::{self as simulator, COLUMNS};
    use vibrissa_io::labelled::{read_labelled, Options};
    use vibrissa_io::scenario::Document;
    use vibrissa_io::series::{self, Series};

    /// A fresh folder `vibrissa-<name>-<pid>` in the temporary directory holding [`strikes`].
    fn strike_folder(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("vibrissa-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        strikes(&dir);
        dir
    }

    /// Three short strikes of a whisker stiffer than the nominal `e2`, with their labels.
    fn strikes(dir: &std::path::Path) {
        let doc = Document::load("e2", &[]).unwrap();
        let mut listing = String::from("file,d,v\n");
        for (k, (d, v)) in [(0.016, 0.4), (0.022, 0.9), (0.028, 1.4)]
            .iter()
            .enumerate()
        {
            let sets = [
                "duration=0.08".to_string(),
                "whisker.youngs_modulus=3.4e9".to_string(),
                format!("d={d}"),
                format!("v={v}"),
            ];
            let scenario = doc.loaded_with(&sets).unwrap().scenario;
            let out = simulator::run(&scenario, &mut |_| {}).unwrap();
            let mut series = Series::new(&COLUMNS);
            for row in &out.rows {
                series.push_row(row);
            }
            let name = format!("strike{k}.csv");
            series::write(&series, dir.join(&name)).unwrap();
            listing.push_str(&format!("{name},{d},{v}\n"));
        }
        std::fs::write(dir.join("truth.csv"), listing).unwrap();
    }

    #[test]
    fn a_search_stopped_and_carried_on_ends_where_a_whole_fit_ends() {
        let dir = strike_folder("search");
        let nominal = Document::load("e2", &["duration=0.08".to_string()]).unwrap();
        let set = read_labelled(&dir, &nominal, &Options::default()).unwrap();
        let base = nominal.loaded().unwrap().scenario;
        let reference = params::Reference::of(&base).unwrap();
        let runs = prepare(&nominal, &set).unwrap();
        let params = params::parameters(&base, &reference, &set.keys, 0.03, 2.5e-4);
        let ranges = ranges(&runs);
        let mut setup = Setup {
            runs: &runs,
            params: &params,
            reference: &reference,
            free: vec![true; params.len()],
            held: params.iter().map(|p| p.x_nominal).collect(),
            channels: (0..CHANNELS).collect(),
            sigma: std::array::from_fn(|c| 0.01 * ranges[c]),
            gain_free: [true, true, false, true, true],
            nominal: base.sensor_response.to_array(),
            handling: GainHandling::Projected,
            gain_prior: 0.01,
            smooth: 1,
            ys: Vec::new(),
            weights: Vec::new(),
            scan_substeps: None,
        };
        setup.set_smoothing(1);
        // Started with a follicle as compliant as the base joint (the clamped bound is a
        // corner of the cost that a local fit does not leave).
        let z0: Vec<f64> = params
            .iter()
            .map(|p| match p.kind {
                params::Kind::FollicleCompliance => 0.0,
                _ => p.x_start,
            })
            .collect();
        let count = AtomicUsize::new(0);
        let sims = setup.simulate(&setup.full_x(&z0), &count).unwrap();
        let resp0 = setup.solve_linear(&sims);

        let whole = fit(&setup, &z0, &resp0, 50, &count, "whole", &mut |_| {}).unwrap();
        let mut search = Search::start(&setup, &z0, &resp0, &count).unwrap();
        let start_cost = search.cost;
        for _ in 0..2 {
            search.iterate(&setup, &count).unwrap();
        }
        assert!(!search.converged && search.cost < start_cost);
        let mut reports = Vec::new();
        let resumed = search
            .finish(&setup, 50, &count, "resumed", &mut |p| {
                reports.push(p.iteration)
            })
            .unwrap();
        assert_eq!(resumed.z, whole.z);
        assert_eq!(resumed.iterations, whole.iterations);
        assert_eq!(
            reports.first(),
            Some(&3),
            "iterations count on from the stop"
        );
        // The fit moved the modulus toward the stiffer truth.
        let modulus = params
            .iter()
            .position(|p| p.key == "whisker.youngs_modulus")
            .unwrap();
        assert!(whole.z[modulus] > z0[modulus]);

        // A search that runs out of iterations says so.
        let Err(err) = Search::start(&setup, &z0, &resp0, &count).unwrap().finish(
            &setup,
            1,
            &count,
            "short",
            &mut |_| {},
        ) else {
            panic!("a fit of one iteration converged");
        };
        assert!(
            err.to_string()
                .contains("did not converge within 1 iterations"),
            "{err}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn the_starting_scan_simulates_contact_as_it_is_told() {
        let dir = strike_folder("scan");
        let short = "duration=0.08".to_string();
        let fine = Document::load("e2", &[short.clone(), "contact_substeps=5".into()]).unwrap();
        let plain = Document::load("e2", &[short]).unwrap();
        let set = read_labelled(&dir, &fine, &Options::default()).unwrap();
        let base = fine.loaded().unwrap().scenario;
        let reference = params::Reference::of(&base).unwrap();
        let params = params::parameters(&base, &reference, &set.keys, 0.03, 2.5e-4);
        let (fine_runs, plain_runs) = (
            prepare(&fine, &set).unwrap(),
            prepare(&plain, &set).unwrap(),
        );
        let setup = |runs, scan_substeps| Setup {
            runs,
            params: &params,
            reference: &reference,
            free: vec![true; params.len()],
            held: params.iter().map(|p| p.x_nominal).collect(),
            channels: (0..CHANNELS).collect(),
            sigma: [1.0; CHANNELS],
            gain_free: [true; CHANNELS],
            nominal: base.sensor_response.to_array(),
            handling: GainHandling::Projected,
            gain_prior: 0.0,
            smooth: 1,
            ys: Vec::new(),
            weights: Vec::new(),
            scan_substeps,
        };
        let x: Vec<Option<f64>> = params.iter().map(|p| p.x_nominal).collect();
        let count = AtomicUsize::new(0);
        let fit_sims = setup(&fine_runs, None).simulate(&x, &count).unwrap();
        // Not told: the scan simulates as the fit does.
        let same = setup(&fine_runs, None).simulate_scan(&x, &count).unwrap();
        assert_eq!(same, fit_sims);
        // Told one substep: the fit's runs as the plain file simulates them, and they differ.
        let scan = setup(&fine_runs, Some(1))
            .simulate_scan(&x, &count)
            .unwrap();
        let plain_sims = setup(&plain_runs, None).simulate(&x, &count).unwrap();
        assert_eq!(scan, plain_sims);
        assert_ne!(scan, fit_sims);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
