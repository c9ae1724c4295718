//! `vibrissa estimate --method pf`: the particle filter on recorded series.
//!
//! Unlike the discriminative methods, the filter reads series of any length at a constant sample
//! rate: whole missing periods are predicted across, and `NaN` values are skipped with a
//! warning. `--trace` writes the posterior at every sample and plots it. A run whose effective
//! sample size fell below 1% of the particles gets a warning: its posterior may be too narrow.

use crate::estimate::{print_json_rows, read_recording, Args, FileEstimate};
use crate::files;
use crate::plot::{render_series, Axis, Curve, Panel};
use anyhow::{bail, Context, Result};
use std::fmt::Write as _;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;
use vibrissa_infer::pf::{self, Injection, Observations, Pf, Posterior, TransitionModel};
use vibrissa_infer::{methods, training_for, Experiment, Method, Variant, CHANNELS};

/// Channels of the contract that the filter's model cannot produce.
const UNOBSERVABLE: [&str; 4] = ["contact", "cx", "cy", "s"];

/// Share of the particles drawn from an injected method's estimate.
const INJECT_FRACTION: f64 = 0.5;

/// A least effective sample size below this share of the particles gets a warning.
const COLLAPSE_SHARE: f64 = 0.01;

/// Runs the filter on every `--obs` file and prints the contract's estimates.
pub fn run(args: &Args, experiment: Experiment, variant: Variant) -> Result<()> {
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
        .map(|f| read_series(f, &channels))
        .collect::<Result<Vec<_>>>()?;

    // Fit: the sensor noise from the training runs (and the injected method, if any).
    let t0 = Instant::now();
    let mut filter = Pf::new(args.particles);
    filter.set_model(
        TransitionModel::from_name(&args.pf_model)
            .map_err(|e| anyhow::anyhow!("--pf-model: {e}"))?,
    );
    filter.seed = args.seed;
    filter.max_delay = args.max_delay;
    let mut inject: Option<Box<dyn Method>> = match &args.inject {
        Some(name) if name == "pf" => bail!("--inject takes a discriminative method, not pf"),
        Some(name) => Some(methods::by_name(name)?),
        None => None,
    };
    eprintln!("training pf ({} particles)…", args.particles);
    let training = training_for(experiment, variant, &filter, args.seed)?;
    filter.fit(&training)?;
    if let Some(m) = inject.as_mut() {
        let t = training_for(experiment, variant, m.as_ref(), args.seed)?;
        m.fit(&t)?;
    }
    let sigma = filter.sigma().context("the filter was not fitted")?;
    eprintln!(
        "trained in {:.2} s; observation noise {}",
        t0.elapsed().as_secs_f64(),
        channels
            .iter()
            .map(|&c| format!("{} {:.3e}", CHANNELS[c], sigma[c]))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let inject: Option<Arc<dyn Method>> = inject.map(Arc::from);

    let mut rows: Vec<FileEstimate> = Vec::new();
    let mut posteriors = Vec::new();
    for (file, (o, segments)) in args.obs.iter().zip(&obs) {
        let start = Instant::now();
        let mut config = filter.config(experiment, sigma);
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
        if let Some(m) = &inject {
            let e = m.predict(&o.values).with_context(|| {
                format!(
                    "--inject {}: cannot estimate from `{}` (it needs the experiment's 151 samples)",
                    m.name(),
                    file.display()
                )
            })?;
            let v = e
                .get(1)
                .copied()
                .unwrap_or(vibrissa_infer::Estimate::normal(0.6, 1.0));
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
        rows.push((file.clone(), named, secs));
        posteriors.push(post);
    }

    if let (Some(trace), Some(post)) = (&args.trace, posteriors.first()) {
        write_trace(trace, post)?;
    }

    match args.format.format() {
        crate::output::Format::Json => print_json_rows(&rows, "pf", args.obs.len() > 1)?,
        crate::output::Format::Human => {
            for ((file, est, secs), post) in rows.iter().zip(&posteriors) {
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
        }
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

/// Reads one observed series, with the segment count of the chain that recorded it when its
/// metadata says (`vibrissa simulate` writes it in the sidecar, older files have it on a `#` line;
/// the experiments' chain has 20).
fn read_series(file: &Path, channels: &[usize]) -> Result<(Observations, Option<usize>)> {
    let name = file.display();
    let series = read_recording(file)?;
    let t = series
        .require(&["t"])
        .with_context(|| format!("`{name}` lacks the column t"))?[0]
        .to_vec();
    let mut values = vec![Vec::new(); CHANNELS.len()];
    for &c in channels {
        match series.column(CHANNELS[c]) {
            Some(v) => values[c] = v.to_vec(),
            None => bail!(
                "`{name}` lacks column {}, which the filter observes (choose others with --channels)",
                CHANNELS[c]
            ),
        }
    }
    if t.len() < 2 {
        bail!(
            "`{name}` has {} samples; the filter needs at least 2",
            t.len()
        );
    }
    if let Some(k) = t.iter().position(|x| !x.is_finite()) {
        bail!("`{name}`: t is not finite in row {}", k + 1);
    }
    let segments = match series.meta_value("segments") {
        None => None,
        Some(s) => match s.trim().parse::<usize>() {
            Ok(n) if (2..=vibrissa_core::chain::MAX_SEGMENTS).contains(&n) => Some(n),
            _ => bail!(
                "`{name}`: metadata `segments` is `{s}`; expected a segment count from 2 to {}",
                vibrissa_core::chain::MAX_SEGMENTS
            ),
        },
    };
    Ok((Observations { t, values }, segments))
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
