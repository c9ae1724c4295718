//! Where the fit starts: a scan of the cost over density, follicle and taper, short fits from
//! the best points of it, the lowest carried on; and the other minima those starts reach, which
//! widen the standard errors.

use super::*;

/// Density steps of the starting scan, ln ρ/ρ_nominal: −0.6 to 0.6 in steps of 0.15 (the first
/// mode's frequency from 0.74 to 1.35 times the nominal's).
pub(super) const SCAN_DENSITY: (f64, f64, usize) = (-0.6, 0.6, 9);

/// Modulus steps of the starting scan, ln E/E_nominal (the density moves with it, so that
/// these change the forces at a given frequency).
pub(super) const SCAN_MODULUS: [f64; 3] = [-0.2, 0.0, 0.2];

/// Follicle compliances of the starting scan, relative to the nominal chain's base joint
/// (0: clamped, the lower bound of the parametrisation), up to the randomisation prior's
/// largest ([`crate::randomise::Randomisation::default`]).
pub(super) const SCAN_FOLLICLE: [f64; 11] =
    [0.0, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 3.0, 5.0, 10.0];

/// Tip-to-base radius ratios of the starting scan, besides the parameter's own start; the
/// start's ratio times each of them is scanned too, so that a whisker whose tip is thinner
/// than its tapered nominal says (by the factor 0.5–0.9 that a user's guess is often off) is
/// started near. On a uniform nominal the two sets are one.
pub(super) const SCAN_TAPER: [f64; 2] = [0.7, 0.5];

/// Relative prior standard deviation of the gains while the start is searched for.
pub(super) const START_GAIN_PRIOR: f64 = 0.01;

/// Starting points besides the plain start; each is taken [`SHORT_ITERATIONS`] iterations.
pub(super) const STARTS: usize = 8;

/// Iterations every start is taken before the starts are ranked by their cost.
pub(super) const SHORT_ITERATIONS: usize = 4;

/// Starts carried on to convergence after the ranking by default
/// ([`Settings::finalists`]); the lowest minimum wins, and the others within
/// [`OTHER_MINIMA_COST`] of it widen the standard errors.
pub(super) const FINALISTS: usize = 4;

/// A local minimum of the cost that a start of the search converged to.
pub(super) struct Minimum {
    /// Its cost (sum of squared weighted residuals, with the search's noise levels).
    pub(super) cost: f64,
    /// Its free parameters, and every parameter's value.
    pub(super) z: Vec<f64>,
    pub(super) x: Vec<Option<f64>>,
    /// The gains and offsets there.
    pub(super) resp: [Response; CHANNELS],
}

/// The taper coordinates (ln tip/base) the scan visits from the start `z0`: the start, each
/// ratio of [`SCAN_TAPER`], and the start thinned by each of them; a value within 1e-9 of one
/// already listed is not repeated.
fn scan_tapers(z0: f64) -> Vec<f64> {
    let mut out = vec![z0];
    let ratios = SCAN_TAPER.iter().map(|q| q.ln());
    for z in ratios.clone().chain(ratios.map(|r| z0 + r)) {
        if out.iter().all(|&x| (x - z).abs() > 1e-9) {
            out.push(z);
        }
    }
    out
}

/// The start of the final fit: the best of several short fits.
///
/// A least-squares fit of ringing is multimodal in its frequency: from a frequency off by more
/// than about half a period over the ringing, a local fit locks onto the wrong number of
/// periods, and a taper, a compliant follicle and a time offset can trade off against each
/// other into a false minimum. So the cost (with the gains and offsets solved) is scanned over
/// a grid of density × follicle compliance × taper, the other parameters at their starts (with
/// contact stepped as [`Setup::scan_substeps`] says: the grid's points lie far apart), and a
/// Levenberg–Marquardt fit runs from the plain start and from the [`STARTS`] best grid points.
/// Each is taken [`SHORT_ITERATIONS`] iterations first; the [`FINALISTS`] lowest are then
/// carried on (from where they stopped, so on the path a whole fit would take) and the lowest
/// of their minima wins. The ranking after four iterations named the start that wins when
/// every start is fitted in full on each of stand-ins 1–6, 11–13 and another engine's set,
/// at two thirds of the time.
pub(super) fn best_start(
    setup: &Setup,
    z0: &[f64],
    settings: &Settings,
    count: &AtomicUsize,
    iterations: &mut usize,
    fits: &mut usize,
    progress: &mut dyn FnMut(&Progress),
) -> Result<(Minimum, Vec<Minimum>)> {
    use rayon::prelude::*;
    let free = setup.free_indices();
    let slot = |kind: Kind| free.iter().position(|&i| setup.params[i].kind == kind);
    let (modulus, density, follicle, taper) = (
        slot(Kind::Modulus),
        slot(Kind::Density),
        slot(Kind::FollicleCompliance),
        slot(Kind::Taper),
    );
    let moduli: Vec<Option<f64>> = match modulus {
        Some(_) => SCAN_MODULUS.iter().map(|&x| Some(x)).collect(),
        None => vec![None],
    };
    let (lo, hi, n) = SCAN_DENSITY;
    let densities: Vec<Option<f64>> = match density {
        Some(_) => (0..n)
            .map(|k| Some(lo + (hi - lo) * k as f64 / (n - 1) as f64))
            .collect(),
        None => vec![None],
    };
    let follicles: Vec<Option<f64>> = match follicle {
        Some(_) => SCAN_FOLLICLE
            .iter()
            .map(|&u| Some(if u > 0.0 { u.ln() } else { params::CLAMPED }))
            .collect(),
        None => vec![None],
    };
    let tapers: Vec<Option<f64>> = match taper {
        Some(j) => scan_tapers(z0[j]).into_iter().map(Some).collect(),
        None => vec![None],
    };
    let mut points: Vec<Vec<f64>> = Vec::new();
    for &e in &moduli {
        for &r in &densities {
            for &f in &follicles {
                for &q in &tapers {
                    let mut p = z0.to_vec();
                    for (slot, value) in [(modulus, e), (density, r), (follicle, f), (taper, q)] {
                        if let (Some(j), Some(x)) = (slot, value) {
                            // Density relative to the modulus: the scan's frequency axis.
                            p[j] = x + if slot == density {
                                e.unwrap_or(0.0)
                            } else {
                                0.0
                            };
                        }
                    }
                    points.push(p);
                }
            }
        }
    }
    let cost_at = |p: &Vec<f64>| match setup.simulate_scan(&setup.full_x(p), count) {
        Some(sims) => setup
            .residual(&sims, &setup.solve_linear(&sims))
            .norm_squared(),
        None => f64::INFINITY,
    };
    let costs: Vec<f64> = points.par_iter().map(cost_at).collect();
    let mut order: Vec<usize> = (0..points.len())
        .filter(|&k| costs[k].is_finite())
        .collect();
    order.sort_by(|&a, &b| costs[a].total_cmp(&costs[b]));
    progress(&Progress {
        stage: format!("scan of {} starting points", points.len()),
        iteration: 0,
        evaluations: points.len(),
        cost: order.first().map_or(f64::INFINITY, |&k| costs[k]),
    });
    let mut starts = vec![z0.to_vec()];
    starts.extend(order.iter().take(STARTS).map(|&k| points[k].clone()));

    // Every start is taken a few iterations; the most promising are then carried to convergence.
    let mut searches: Vec<(usize, search::Search)> = Vec::new();
    let mut last_error = None;
    let n = starts.len();
    for (k, start) in starts.iter().enumerate() {
        let Some(sims) = setup.simulate(&setup.full_x(start), count) else {
            continue;
        };
        let resp = setup.solve_linear(&sims);
        let stage = format!("start {} of {n}", k + 1);
        let mut short = || -> Result<search::Search> {
            let mut s = search::Search::start(setup, start, &resp, count)?;
            while !s.converged && s.iterations < SHORT_ITERATIONS.min(settings.max_iterations) {
                s.iterate(setup, count)?;
                s.report(&stage, progress);
            }
            Ok(s)
        };
        match short() {
            Ok(s) => searches.push((k, s)),
            Err(e) => last_error = Some(e),
        }
    }
    searches.sort_by(|a, b| a.1.cost.total_cmp(&b.1.cost));
    let mut minima: Vec<Minimum> = Vec::new();
    for (rank, (k, s)) in searches.into_iter().enumerate() {
        // The others end here; their iterations count all the same.
        if rank >= settings.finalists {
            *fits += 1;
            *iterations += s.iterations;
            continue;
        }
        let stage = format!("start {} of {n}, carried on", k + 1);
        match s.finish(setup, settings.max_iterations, count, &stage, progress) {
            Ok(sol) => {
                *fits += 1;
                *iterations += sol.iterations;
                let cost = setup.residual(&sol.sims, &sol.resp).norm_squared();
                minima.push(Minimum {
                    cost,
                    x: setup.full_x(&sol.z),
                    z: sol.z,
                    resp: sol.resp,
                });
            }
            Err(e) => last_error = Some(e),
        }
    }
    minima.sort_by(|a, b| a.cost.total_cmp(&b.cost));
    match (minima.is_empty(), last_error) {
        (false, _) => {
            let best = minima.remove(0);
            Ok((best, minima))
        }
        (true, Some(e)) => Err(e),
        (true, None) => Err(Error::Calibration(
            "no starting point of the fit simulates".into(),
        )),
    }
}

/// Other minima count towards the errors when their cost is within this factor of the best's.
/// Between points 2% apart in the parameters the residual's RMS jumps by up to 30% (the
/// simulations' roughness: docs/calibration.md), so the cost by up to 1.7 times: minima within
/// twice the best cost are not told apart by it.
pub(super) const OTHER_MINIMA_COST: f64 = 2.0;

/// Adds to `cov` the spread of the other minima the search converged to (`others`, beside the
/// `best` one that led to `sol`): the mean of `(x_k − x̂)(x_k − x̂)ᵀ` over those whose cost is
/// within [`OTHER_MINIMA_COST`] of the best's, over the free whisker parameters, the gains and
/// the offsets. Returns how many minima it counted.
///
/// The cost is rough and its minima many (docs/calibration.md, "Parameter recovery"): which one
/// the search ends in depends on where it started, and among minima of about the same cost a
/// lower one is no nearer the truth. A local error (the cost's curvature, the roughness next to
/// the solution) cannot see that choice; the minima reached from other starts measure it.
pub(super) fn add_other_minima(
    setup: &Setup,
    sol: &Solution,
    cov: &mut fit::Covariance,
    best: &Minimum,
    others: &[Minimum],
) -> usize {
    let free = setup.free_indices();
    let gains = setup.gains();
    let x = setup.full_x(&sol.z);
    let near: Vec<&Minimum> = others
        .iter()
        .filter(|m| m.cost <= OTHER_MINIMA_COST * best.cost)
        .collect();
    if near.is_empty() {
        return 0;
    }
    let p = free.len() + gains.len() + setup.channels.len();
    let deviations: Vec<nalgebra::DVector<f64>> = near
        .iter()
        .map(|m| {
            let mut d = nalgebra::DVector::<f64>::zeros(p);
            for (a, &i) in free.iter().enumerate() {
                if let (Some(xi), Some(mi)) = (x[i], m.x[i]) {
                    d[a] = mi - xi;
                }
            }
            for (k, &c) in gains.iter().enumerate() {
                d[free.len() + k] = m.resp[c].gain - sol.resp[c].gain;
            }
            for (k, &c) in setup.channels.iter().enumerate() {
                d[free.len() + gains.len() + k] = m.resp[c].offset - sol.resp[c].offset;
            }
            d
        })
        .collect();
    // The covariance's order is the same: free parameters, free gains, every offset.
    cov.cov += spread(&deviations, p);
    near.len()
}

/// The mean of `d dᵀ` over `deviations` (each of length `p`): the spread of points about a
/// centre, as a covariance.
pub(super) fn spread(deviations: &[nalgebra::DVector<f64>], p: usize) -> nalgebra::DMatrix<f64> {
    let mut out = nalgebra::DMatrix::<f64>::zeros(p, p);
    for d in deviations {
        out += d * d.transpose();
    }
    if !deviations.is_empty() {
        out /= deviations.len() as f64;
    }
    out
}
