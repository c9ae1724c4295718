//! `vibrissa estimate --method pf`: the particle filter on recorded series.
//!
//! Unlike the discriminative methods, the filter reads series of any length at a constant sample
//! rate: whole missing periods are predicted across, and `NaN` values are skipped with a
//! warning. `--trace` writes the posterior at every sample and plots it. A run whose effective
//! sample size fell below 1% of the particles gets a warning: its posterior may be too narrow.

use crate::estimate::{
    check_recording, check_sample_rates, draw_check, lead_ins, named_noise, noise_levels,
    print_json_rows, read_recording, render_checks, trained_for, warn_of_units, Args, FileEstimate,
};
use crate::files;
use crate::plot::{render_series, Axis, Curve, Panel};
use anyhow::{bail, Context, Result};
use std::fmt::Write as _;
use std::path::Path;
use vibrissa_infer::pf::{self, Posterior, TransitionModel};
use vibrissa_infer::{methods, Family, Reader, Trained, CHANNELS};

/// Channels of the contract that the filter's model cannot produce.
const UNOBSERVABLE: [&str; 4] = ["contact", "cx", "cy", "s"];

/// Runs the filter on every `--obs` file and prints the contract's estimates.
pub fn run(args: &Args, family: &Family, stated: &[Option<f64>; 5]) -> Result<()> {
    if args.particles == Some(0) {
        bail!("--particles must be at least 1 (got 0)");
    }
    if !(args.max_delay.is_finite() && (0.0..=1.0).contains(&args.max_delay)) {
        bail!(
            "--max-delay must be between 0 and 1 s (got {})",
            args.max_delay
        );
    }
    crate::estimate::check_trace_file(args)?;
    let channels = parse_channels(&args.channels)?;
    let priors = parse_priors(&args.prior)?;

    // Read and check every file before anything is trained.
    let recordings = args
        .obs
        .iter()
        .map(|f| read_recording(f, &channels, Reader::Filter, args.whisker.as_deref()))
        .collect::<Result<Vec<_>>>()?;
    check_sample_rates(family, &args.obs, &recordings)?;
    // A sensor that recorded nothing (a flat channel beside others that vary) is left out,
    // unless the channels were named.
    let names: Vec<String> = args.obs.iter().map(|f| f.display().to_string()).collect();
    let channels = if args.channels.is_empty() {
        let (kept, warnings) =
            vibrissa_infer::recording::recorded_channels(&names, &recordings, &channels);
        for w in warnings {
            eprintln!("warning: {w}");
        }
        kept
    } else {
        channels
    };
    warn_of_units(family, &args.obs, &recordings, &channels)?;

    // The sensor noise of every recording (the filter is fitted to each level: no runs).
    let levels = noise_levels(&args.obs, &recordings, &channels, stated)?;
    for w in vibrissa_infer::batch::without_strikes(&names, &recordings, &levels, &channels) {
        eprintln!("warning: {w}");
    }
    let leads = lead_ins(args.max_delay, family, &args.obs, &recordings, &levels)?;
    // A scenario that is neither calibrated nor randomised, which most of the recordings defy
    // (at `krr`'s estimates and near them), is not their whisker: the filter then entertains
    // whiskers drawn around it, as --randomise asks.
    let family = vibrissa_infer::batch::filter_family(
        family,
        &recordings,
        &levels,
        &leads,
        args.seed,
        !args.randomise && !args.no_randomise,
        &vibrissa_infer::batch::COMMAND_LINE,
        &mut |m| eprintln!("{m}"),
    )?;
    let family = &family;
    // A box whose near edge lies beyond the tip never touches the whisker: the filter could not
    // tell such distances apart.
    let length = family.base().whisker.length;
    for (k, p) in &priors {
        if pf::PARAMS[*k] == "d" && p.hi > length {
            bail!(
                "--prior d={}:{}: the distance's upper end must be within the whisker's length \
                 ({length} m): a box whose near edge lies beyond the tip never touches it",
                p.lo,
                p.hi
            );
        }
    }
    let particles = args
        .particles
        .unwrap_or_else(|| pf::default_particles(family));
    if family.randomisation().is_some() && particles <= args.alternatives {
        bail!(
            "--particles {particles} is too few for the {} whiskers the filter entertains on a \
             whisker known only roughly (the scenario's and --alternatives {}): give more \
             particles than alternatives (the default here is {}) or fewer --alternatives",
            args.alternatives + 1,
            args.alternatives,
            pf::default_particles(family)
        );
    }
    let mut options = pf::recording::Options::new(particles);
    options.seed = args.seed;
    // A lead-in that the recordings show, unless one is stated: the start delay is then unknown.
    options.max_delay = leads
        .iter()
        .zip(&recordings)
        .map(|(&l, r)| l as f64 / r.rate)
        .fold(args.max_delay, f64::max);
    options.model = TransitionModel::from_name(&args.pf_model)
        .map_err(|e| anyhow::anyhow!("--pf-model: {e}"))?;
    options.channels = channels.clone();
    options.priors = priors;
    options.alternatives = args.alternatives;
    if let Some(name) = &args.inject {
        if name == "pf" {
            bail!("--inject takes a discriminative method, not pf");
        }
        methods::by_name(name)?;
    }
    // A batch of one whisker known only roughly is pooled unless told otherwise.
    let pool = args.pool
        || (!args.no_pool && args.inject.is_none() && pf::pool::by_default(args.obs.len(), family));
    if pool && !args.pool {
        eprintln!(
            "pf: pooling the {} recordings as strikes of one whisker, which the filter learns \
             from all of them together (--no-pool filters each alone)",
            args.obs.len()
        );
    }
    options.islands = args.islands.unwrap_or(pf::default_islands(pool));
    options.lost_islands = match args.islands {
        Some(_) => None,
        None => pf::lost_islands(pool),
    };
    if args.no_pool_gains && !pool {
        bail!(
            "--no-pool-gains applies to a pooled batch (--pool, or 5 recordings or more of a \
             whisker known only roughly); this one is filtered recording by recording"
        );
    }
    if pool {
        if args.obs.len() < 2 {
            bail!(
                "--pool learns the whisker from several recordings of it: give at least 2 (got 1)"
            );
        }
        if args.inject.is_some() {
            bail!("--pool and --inject do not go together");
        }
        if args.pool_rounds == 0 {
            bail!("--pool-rounds must be at least 1 (got 0)");
        }
        if args.pool_search < 2 {
            bail!(
                "--pool-search: the search rounds learn the whisker from several recordings: at \
                 least 2 (got {})",
                args.pool_search
            );
        }
        if family.randomisation().is_none() {
            bail!(
                "--pool needs a filter that entertains several whiskers: add --randomise (the \
                 scenario's whisker is taken as known)"
            );
        }
        if family.is_calibrated() {
            eprintln!(
                "warning: --pool on a calibrated scenario: the fitted whisker is usually the \
                 better one (on three foreign sets pooling moved the distance error from \
                 0.17-0.21 mm to 0.27-0.47 mm); leave out --pool to keep it"
            );
        }
        // Each round's whiskers are the batch's, not the prior's: no held-out widening.
        options.interval_runs = 0;
        options.pool_gains = !args.no_pool_gains;
    }
    let mut inject = Trained::default();
    let mut filter = |o: &pf::recording::Options, which: &[usize], verbose: bool| {
        filter_all(
            args,
            family,
            &recordings,
            &levels,
            &leads,
            o,
            &mut inject,
            which,
            verbose,
        )
    };
    let ests = if pool {
        // The noise and the widening are reported on the first filtering only.
        let mut first = true;
        let pooled = pf::pool::refine(
            recordings.len(),
            &options,
            args.pool_rounds,
            args.pool_search,
            args.seed,
            &mut |o, which| {
                let verbose = std::mem::replace(&mut first, false);
                filter(o, which, verbose)
                    .map_err(|e| vibrissa_infer::Error::Observation(format!("{e:#}")))
            },
            &mut |m| eprintln!("{m}"),
        )?;
        for w in pf::pool::warnings(&pooled, &names) {
            eprintln!("warning: {w}");
        }
        pooled.estimates
    } else {
        let all: Vec<usize> = (0..recordings.len()).collect();
        filter(&options, &all, true)?
    };

    let mut rows: Vec<FileEstimate> = Vec::new();
    let mut posteriors = Vec::new();
    let mut checks = Vec::new();
    let mut figure = None;
    for ((file, rec), est) in args.obs.iter().zip(&recordings).zip(ests) {
        for w in est.warnings(&file.display().to_string()) {
            eprintln!("warning: {w}");
        }
        let post = &est.posterior;
        if args.check {
            // The scenario at the posterior mean of its own unknowns; the filter's further
            // unknowns (a start delay, the box's size or friction) are not simulated.
            let c = match est.scenario_point(family) {
                Some(p) => {
                    check_recording(&family.nominal(), file, rec, &p, &est.sensor, &channels, 0)
                }
                None => {
                    eprintln!(
                        "warning: `{}`: cannot check a posterior over unknowns the scenario does not \
                         simulate ({})",
                        file.display(),
                        post.unknowns.join(", ")
                    );
                    None
                }
            };
            if let (Some(c), Some(png)) = (&c, &args.check_plot) {
                figure = Some(draw_check(png, file, rec, c)?);
            }
            checks.push(c);
        }
        rows.push(FileEstimate {
            file: file.clone(),
            estimates: est.named(),
            seconds: est.seconds,
            noise: named_noise(&est.sensor, &channels),
            filter: est.counts(),
        });
        posteriors.push(est.posterior);
    }

    crate::estimate::ensure_finite(&rows, "pf")?;
    if let (Some(trace), Some(post)) = (&args.trace, posteriors.first()) {
        write_trace(trace, post)?;
    }

    match args.format.format() {
        crate::output::Format::Json => print_json_rows(&rows, &checks, "pf", args.obs.len() > 1)?,
        crate::output::Format::Human => {
            for (row, post) in rows.iter().zip(&posteriors) {
                let (file, est, secs) = (&row.file, &row.estimates, row.seconds);
                let parts: Vec<String> = est
                    .iter()
                    .map(|(n, e)| {
                        use crate::output::sig;
                        format!(
                            "{n} = {} ± {} (90%: {}…{})",
                            sig(e.mean, 4),
                            sig(e.std, 2),
                            sig(e.ci90[0], 4),
                            sig(e.ci90[1], 4)
                        )
                    })
                    .collect();
                let data = post.trace.last().map_or(0.0, |r| r.t) - post.trace[0].t;
                println!(
                    "{}: {} [{:.3} s for {:.3} s of data: real-time factor {:.2}; {} resamplings]",
                    file.display(),
                    parts.join(", "),
                    secs,
                    data,
                    data / secs,
                    post.resamples
                );
            }
            let stdout = std::io::stdout();
            render_checks(&mut stdout.lock(), &rows, &checks)?;
        }
    }
    if let (Some(f), Some(png)) = (figure, &args.check_plot) {
        f.commit()?;
        eprintln!("wrote {}", png.display());
    }
    Ok(())
}

/// `NAME=LO:HI` priors as (index into `pf::PARAMS`, prior).
fn parse_priors(specs: &[String]) -> Result<Vec<(usize, pf::Prior)>> {
    specs
        .iter()
        .map(|spec| {
            let bad = || {
                anyhow::anyhow!(
                    "--prior `{spec}`: expected NAME=LO:HI with NAME one of {} and numbers LO <= HI (SI units)",
                    pf::PARAMS.join(", ")
                )
            };
            let (name, range) = spec.split_once('=').ok_or_else(bad)?;
            let k = pf::PARAMS
                .iter()
                .position(|p| *p == name.trim())
                .ok_or_else(bad)?;
            let (lo, hi) = range.split_once(':').ok_or_else(bad)?;
            let (lo, hi): (f64, f64) = (
                lo.trim().parse().map_err(|_| bad())?,
                hi.trim().parse().map_err(|_| bad())?,
            );
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(bad());
            }
            let (least, most) = pf::PRIOR_BOUNDS[k];
            if lo < least || hi > most {
                let upper = if most.is_finite() {
                    format!("{most}]")
                } else {
                    "∞)".to_string()
                };
                bail!(
                    "--prior `{spec}`: {} must lie within [{least}, {upper} (SI units)",
                    name.trim()
                );
            }
            if lo == hi {
                eprintln!(
                    "note: --prior `{spec}` fixes {} at {lo}: the filter does not estimate it, \
                     and the estimate leaves it out",
                    name.trim()
                );
            }
            Ok((k, pf::Prior::uniform(lo, hi)))
        })
        .collect()
}

/// Channel indices from names (all five when none are given).
fn parse_channels(names: &[String]) -> Result<Vec<usize>> {
    if names.is_empty() {
        return Ok((0..CHANNELS.len()).collect());
    }
    let mut out = Vec::new();
    for n in names {
        match CHANNELS.iter().position(|c| c == n) {
            Some(c) if !out.contains(&c) => out.push(c),
            Some(_) => {}
            None if UNOBSERVABLE.contains(&n.as_str()) => bail!(
                "--channels: the filter's model cannot produce `{n}`; choose from {}",
                CHANNELS.join(", ")
            ),
            None => bail!(
                "--channels: unknown channel `{n}`; choose from {}",
                CHANNELS.join(", ")
            ),
        }
    }
    Ok(out)
}

/// Writes the posterior at every sample as CSV, and its plot beside it (.png).
fn write_trace(path: &Path, post: &Posterior) -> Result<()> {
    let mut csv = String::from("t,ess");
    for u in &post.unknowns {
        write!(csv, ",{u}_mean,{u}_std,{u}_lo90,{u}_hi90")?;
    }
    csv.push('\n');
    for r in &post.trace {
        write!(csv, "{},{}", r.t, r.ess)?;
        for e in &r.estimates {
            write!(csv, ",{},{},{},{}", e.mean, e.std, e.ci90[0], e.ci90[1])?;
        }
        csv.push('\n');
    }
    let t: Vec<f64> = post.trace.iter().map(|r| r.t).collect();
    let column = |k: usize, f: &dyn Fn(&vibrissa_infer::Estimate) -> f64| -> Vec<f64> {
        post.trace.iter().map(|r| f(&r.estimates[k])).collect()
    };
    let per_unknown: Vec<[Vec<f64>; 3]> = (0..post.unknowns.len())
        .map(|k| {
            [
                column(k, &|e| e.mean),
                column(k, &|e| e.ci90[0]),
                column(k, &|e| e.ci90[1]),
            ]
        })
        .collect();
    let ess: Vec<f64> = post.trace.iter().map(|r| r.ess).collect();
    let units = |u: &str| match u {
        "d" | "size" => "m",
        "v" => "m/s",
        "t0" => "s",
        _ => "",
    };
    let mut panels: Vec<Panel> = post
        .unknowns
        .iter()
        .zip(&per_unknown)
        .map(|(u, [mean, lo, hi])| Panel {
            quantity: u,
            unit: units(u),
            curves: vec![
                Curve {
                    name: "posterior mean",
                    values: mean,
                    dashed: false,
                },
                Curve {
                    name: "5% quantile",
                    values: lo,
                    dashed: true,
                },
                Curve {
                    name: "95% quantile",
                    values: hi,
                    dashed: true,
                },
            ],
        })
        .collect();
    panels.push(Panel {
        quantity: "ESS",
        unit: "particles",
        curves: vec![Curve {
            name: "effective sample size",
            values: &ess,
            dashed: false,
        }],
    });
    let png = path.with_extension("png");
    let pending = render_series(
        &png,
        "Particle filter: posterior at every sample",
        &Axis {
            quantity: "t",
            unit: "s",
            values: &t,
        },
        &panels,
        None,
    )?;
    files::write_atomic(path, csv.as_bytes())?;
    pending.commit()?;
    eprintln!("wrote {} and {}", path.display(), png.display());
    Ok(())
}

/// Filters every recording with `options` (fitting the filter once per noise level); `verbose`
/// prints the filter's noise and widening.
#[allow(clippy::too_many_arguments)]
fn filter_all(
    args: &Args,
    family: &Family,
    recordings: &[vibrissa_infer::Recording],
    levels: &[[f64; 5]],
    leads: &[usize],
    options: &pf::recording::Options,
    inject: &mut Trained,
    which: &[usize],
    verbose: bool,
) -> Result<Vec<pf::recording::Estimate>> {
    let mut options = options.clone();
    let mut fitted: Option<([f64; 5], pf::Pf)> = None;
    let mut out = Vec::with_capacity(which.len());
    for &r in which {
        let (file, rec, level, lead) = (&args.obs[r], &recordings[r], &levels[r], leads[r]);
        if fitted.as_ref().map(|f| f.0) != Some(*level) {
            let filter = pf::recording::fitted(family, level, &options)?;
            let sigma = filter.sigma().context("the filter was not fitted")?;
            if verbose {
                let config = filter.config(family, sigma)?;
                let (chain, rule) = (config.segments, config.model_discretisation().name());
                let islands = match pf::islands::island_count(&config) {
                    1 => String::new(),
                    n => format!(" in {n} islands"),
                };
                eprintln!(
                    "pf ({} particles{islands}, a {chain}-segment transition chain, {rule} rule): observation noise {}",
                    options.particles,
                    per_channel(&options.channels, &sigma)
                );
            }
            if let (true, Some(r)) = (verbose, filter.fit_residual()) {
                eprintln!(
                    "pf: the calibration's residual beyond noise is part of that noise ({})",
                    per_channel(&options.channels, &r)
                );
            }
            if verbose && !filter.interval_scale.is_empty() {
                eprintln!(
                    "pf: intervals widened ({}) to hold {:.0}% of the errors on {} held-out runs \
                     of whiskers drawn around the scenario",
                    filter
                        .interval_scale
                        .iter()
                        .map(|(k, f)| format!("{k} ×{f:.2}"))
                        .collect::<Vec<_>>()
                        .join(", "),
                    pf::recording::INTERVAL_QUANTILE * 100.0,
                    options.interval_runs
                );
            }
            fitted = Some((*level, filter));
        }
        let filter = &fitted.as_ref().expect("fitted above").1;
        options.inject = match &args.inject {
            Some(name) => {
                let m = trained_for(inject, family, rec, level, name, args.seed, lead)?;
                // It reads whole series: missing values filled in, as for its own estimates.
                let filled = rec.filled(&m.channels()).0;
                Some(m.predict(&filled.values).with_context(|| {
                    format!(
                        "--inject {}: cannot estimate from `{}`",
                        m.name(),
                        file.display()
                    )
                })?)
            }
            None => None,
        };
        let est = pf::recording::estimate(filter, family, rec, &options.for_recording(r))
            .with_context(|| format!("filtering `{}`", file.display()))?;
        out.push(est);
    }
    Ok(out)
}

/// `theta01 1.234e-3, …`: `values` of `channels`, for messages.
fn per_channel(channels: &[usize], values: &[f64; 5]) -> String {
    channels
        .iter()
        .map(|&c| format!("{} {:.3e}", CHANNELS[c], values[c]))
        .collect::<Vec<_>>()
        .join(", ")
}
