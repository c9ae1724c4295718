//! `vibrissa estimate --method pf`: the particle filter on recorded series.
//!
//! Unlike the discriminative methods, the filter reads series of any length at a constant sample
//! rate: whole missing periods are predicted across, and `NaN` values are skipped with a
//! warning. `--trace` writes the posterior at every sample and plots it. A run whose effective
//! sample size fell below 1% of the particles gets a warning: its posterior may be too narrow.

use crate::estimate::{
    check_recording, draw_check, named_noise, noise_levels, print_json_rows, read_recording,
    render_checks, Args, FileEstimate, Trained,
};
use crate::files;
use crate::plot::{render_series, Axis, Curve, Panel};
use anyhow::{bail, Context, Result};
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;
use vibrissa_infer::pf::{self, Injection, Observations, Pf, Posterior, TransitionModel};
use vibrissa_infer::Method;
use vibrissa_infer::{methods, training_for, Family, CHANNELS};

/// Channels of the contract that the filter's model cannot produce.
const UNOBSERVABLE: [&str; 4] = ["contact", "cx", "cy", "s"];

/// Share of the particles drawn from an injected method's estimate.
const INJECT_FRACTION: f64 = 0.5;

/// A least effective sample size below this share of the particles gets a warning.
const COLLAPSE_SHARE: f64 = 0.01;

/// Runs the filter on every `--obs` file and prints the contract's estimates.
/// Share of a prior's width within which a posterior mean counts as at its end.
const EDGE: f64 = 0.05;

/// Mean squared standardised residual per observation, in the units of the filter's noise model
/// before tempering, above which the recording is reported as unexplained: twice the variance
/// the model allows. Recordings of the scenario give 0.7–0.8 (own simulator and a calibrated
/// stand-in, 3% noise), another whisker described by the nominal 1.5–54.
const MISFIT_LIMIT: f64 = 2.0;

pub fn run(args: &Args, family: &Family, stated: &[Option<f64>; 5]) -> Result<()> {
    if args.particles == 0 {
        bail!("--particles must be at least 1 (got 0)");
    }
    if !(args.max_delay.is_finite() && (0.0..=1.0).contains(&args.max_delay)) {
        bail!(
            "--max-delay must be between 0 and 1 s (got {})",
            args.max_delay
        );
    }
    if let Some(trace) = &args.trace {
        if args.obs.len() != 1 {
            bail!(
                "--trace takes exactly one --obs file (got {})",
                args.obs.len()
            );
        }
        if files::extension(trace).as_deref() != Some("csv") {
            bail!("--trace must name a .csv file (got `{}`)", trace.display());
        }
        files::check_folder(trace, "--trace")?;
    }
    let channels = parse_channels(&args.channels)?;
    let priors = parse_priors(&args.prior)?;

    // Read and check every file before anything is trained.
    let obs = args
        .obs
        .iter()
        .map(|f| {
            let rec = read_recording(f, &channels, None)?;
            // The filter's clock starts at the recording's first sample.
            let t = rec.t.iter().map(|t| t - rec.t[0]).collect();
            Ok((
                Observations {
                    t,
                    values: rec.values.clone(),
                },
                rec.segments,
                rec,
            ))
        })
        .collect::<Result<Vec<_>>>()?;

    // The sensor noise of every recording (the filter is fitted to each level: no runs).
    let recordings: Vec<_> = obs.iter().map(|(_, _, rec)| rec.clone()).collect();
    let levels = noise_levels(&args.obs, &recordings, &channels, stated)?;
    let mut filter = Pf::new(args.particles);
    filter.set_model(
        TransitionModel::from_name(&args.pf_model)
            .map_err(|e| anyhow::anyhow!("--pf-model: {e}"))?,
    );
    filter.seed = args.seed;
    filter.max_delay = args.max_delay;
    if let Some(name) = &args.inject {
        if name == "pf" {
            bail!("--inject takes a discriminative method, not pf");
        }
        methods::by_name(name)?;
    }
    let mut inject = Trained::default();

    let mut rows: Vec<FileEstimate> = Vec::new();
    let mut posteriors = Vec::new();
    let mut checks = Vec::new();
    let mut figure = None;
    let mut fitted_at: Option<[f64; 5]> = None;
    for ((file, (o, segments, rec)), level) in args.obs.iter().zip(&obs).zip(&levels) {
        if fitted_at != Some(*level) {
            let training =
                training_for(family, &family.training_noise(*level), &filter, args.seed)?;
            filter.fit(&training)?;
            let sigma = filter.sigma().context("the filter was not fitted")?;
            eprintln!(
                "pf ({} particles): observation noise {}",
                args.particles,
                channels
                    .iter()
                    .map(|&c| format!("{} {:.3e}", CHANNELS[c], sigma[c]))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            fitted_at = Some(*level);
        }
        let sigma = filter.sigma().context("the filter was not fitted")?;
        let sensor = filter.sensor_noise().context("the filter was not fitted")?;
        let start = Instant::now();
        let mut config = filter.config(family, sigma)?;
        config.channels = channels.clone();
        if let Some(n) = segments {
            config.observed_segments = *n;
            if filter.model == TransitionModel::Fine {
                config.segments = *n;
            }
        }
        for &(k, p) in &priors {
            config.priors[k] = p;
        }
        config.check().context("--prior")?;
        if let Some(name) = &args.inject {
            let m = inject.get(family, rec, level, name, args.seed)?;
            let e = m.predict(&o.values).with_context(|| {
                format!(
                    "--inject {}: cannot estimate from `{}`",
                    m.name(),
                    file.display()
                )
            })?;
            let v = e
                .get(1)
                .copied()
                .unwrap_or(vibrissa_infer::Estimate::normal(config.priors[1].lo, 1.0));
            config.injection = Some(Injection {
                fraction: INJECT_FRACTION,
                mean: [e[0].mean, v.mean],
                std: [e[0].std.max(1e-5), v.std.max(1e-3)],
            });
        }
        let post = pf::run(&config, o, &mut |_| {})
            .with_context(|| format!("filtering `{}`", file.display()))?;
        let secs = start.elapsed().as_secs_f64();
        if post.skipped > 0 {
            eprintln!(
                "warning: `{}`: {} missing (NaN) values skipped",
                file.display(),
                post.skipped
            );
        }
        if let Some((t, ess)) = post.least_ess() {
            if ess < COLLAPSE_SHARE * config.particles as f64 {
                eprintln!(
                    "warning: `{}`: the effective sample size fell to {ess:.1} of {} particles at \
                     t = {t} s; the posterior after it rests on very few particles and may be too \
                     narrow: compare with more --particles or another --seed",
                    file.display(),
                    config.particles
                );
            }
        }
        // Data that no particle explains: the likelihood's mean squared standardised residual
        // per observation, in the units of the filter's noise model before tempering (about 1,
        // or less, when the model explains the recording).
        let misfit = filter.misfit(&post, config.channels.len());
        if misfit > MISFIT_LIMIT {
            eprintln!(
                "warning: `{}`: no particle explains the recording: its residuals are {:.1} times \
                 the variance the filter's noise model allows (at most {MISFIT_LIMIT} is \
                 expected); the whisker, the sensors or the prior do not describe it, and the \
                 intervals are too narrow: check the scenario (--check), calibrate it, or widen \
                 the prior",
                file.display(),
                misfit
            );
        }
        // A posterior that piles up at an end of its prior: the truth may lie beyond it.
        for (name, e) in post.unknowns.iter().zip(post.last()) {
            let Some(k) = pf::PARAMS.iter().position(|p| p == name) else {
                continue;
            };
            let prior = config.priors[k];
            let width = prior.hi - prior.lo;
            if width > 0.0 && (e.mean - prior.lo < EDGE * width || prior.hi - e.mean < EDGE * width)
            {
                eprintln!(
                    "warning: `{}`: the posterior of {name} ({}) lies at an end of its prior \
                     [{}, {}]: the recording may come from outside it; widen it (--prior \
                     {name}=LO:HI) or check the scenario (--check)",
                    file.display(),
                    e.mean,
                    prior.lo,
                    prior.hi
                );
            }
        }
        if post.diverged > 0 {
            eprintln!(
                "warning: `{}`: {} particle steps diverged (those particles were dropped)",
                file.display(),
                post.diverged
            );
        }
        let named = post
            .unknowns
            .iter()
            .map(|n| n.to_string())
            .zip(post.last().iter().copied())
            .collect();
        if args.check {
            // The scenario at the posterior mean of its own unknowns; the filter's further
            // unknowns (a start delay, the box's size or friction) are not simulated.
            let point: Option<Vec<f64>> = family
                .unknowns()
                .iter()
                .map(|k| {
                    post.unknowns
                        .iter()
                        .position(|n| n == k)
                        .map(|i| post.last()[i].mean)
                })
                .collect();
            let extra = post.unknowns.len() > family.unknowns().len();
            let c = match point {
                Some(p) if !extra => {
                    check_recording(&family.nominal(), file, rec, &p, &sensor, &channels)
                }
                _ => {
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
            estimates: named,
            seconds: secs,
            noise: named_noise(&sensor, &channels),
            filter: vec![
                ("particles", config.particles as f64),
                ("resamples", post.resamples as f64),
                ("particle_steps", post.steps as f64),
                ("diverged_steps", post.diverged as f64),
                ("refused_moves", post.refused_moves as f64),
                ("misfit", misfit),
            ],
        });
        posteriors.push(post);
    }

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
                        format!(
                            "{n} = {:.5} ± {:.5} (90%: {:.5}…{:.5})",
                            e.mean, e.std, e.ci90[0], e.ci90[1]
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
