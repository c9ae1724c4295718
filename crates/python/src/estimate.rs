//! `vibrissa.estimate` and `vibrissa.estimate_shapes`: the command line's `estimate` on recordings
//! handed over as paths or arrays, pooled where the command line pools.

use crate::{family_adopting, value_error, whisker_source};
use numpy::PyReadonlyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use vibrissa_infer::contract::EstimateRow;
use vibrissa_infer::experiment::CHANNELS;
use vibrissa_infer::limits::{check_count, MAX_BANK, MAX_PARTICLES, MAX_TRAINING};
use vibrissa_infer::pf::{recording, Pf};
use vibrissa_infer::recording::batch_noise;
use vibrissa_infer::{Reader, Recording, Trained};

/// One recording handed over by the Python layer: the path of a contract CSV, or a name, the
/// sample times and one optional array per channel.
#[derive(FromPyObject)]
pub(crate) enum Input<'py> {
    /// A CSV file (its sidecar's metadata read where there is one).
    Path(String),
    /// Arrays: name, t, channels in the order of `CHANNELS` (None where not recorded).
    Arrays(
        String,
        PyReadonlyArray1<'py, f64>,
        Vec<Option<PyReadonlyArray1<'py, f64>>>,
    ),
}

/// Filters the recordings at the given indices with the given options.
pub(crate) type FilterSome<'a> =
    dyn Fn(&recording::Options, &[usize]) -> vibrissa_infer::Result<Vec<recording::Estimate>> + 'a;

/// The pooling rounds of `vibrissa estimate --pool` ([`vibrissa_infer::pf::pool::refine`]),
/// each round's favourite whisker reported in `messages`.
pub(crate) fn recording_pool(
    names: &[String],
    options: &recording::Options,
    rounds: usize,
    search: usize,
    seed: u64,
    filter: &FilterSome<'_>,
    messages: &mut Vec<String>,
) -> vibrissa_infer::Result<Vec<recording::Estimate>> {
    use vibrissa_infer::pf::pool;
    pool::refine(
        names.len(),
        options,
        rounds,
        search,
        seed,
        &mut |o, which| filter(o, which),
        &mut |m| messages.push(m),
    )
    .map(|p| {
        messages.extend(
            pool::warnings(&p, names)
                .into_iter()
                .map(|w| format!("warning: {w}")),
        );
        p.estimates
    })
}

/// Estimates the scenario's unknowns from each recording with `method`, as
/// `vibrissa estimate --json` does; returns one estimate object per recording as JSON text,
/// and the messages the command line prints on standard error (warnings, what is trained).
#[pyfunction]
#[pyo3(signature = (scenario, scenario_json, sets, inputs, method, noise, seed, randomise, particles, islands, check, whisker=None, max_delay=0.0, pool=None, pool_rounds=None, pool_search=None, whisker_from=None, pool_gains=true))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn estimate(
    py: Python<'_>,
    scenario: Option<&str>,
    scenario_json: Option<&str>,
    sets: Vec<String>,
    inputs: Vec<Input<'_>>,
    method: &str,
    noise: &str,
    seed: u64,
    randomise: Option<bool>,
    particles: Option<usize>,
    islands: Option<usize>,
    check: bool,
    whisker: Option<&str>,
    max_delay: f64,
    pool: Option<bool>,
    pool_rounds: Option<usize>,
    pool_search: Option<usize>,
    whisker_from: Option<Vec<String>>,
    pool_gains: bool,
) -> PyResult<(Vec<String>, Vec<String>)> {
    let pf = method == "pf";
    if !pool_gains && pool == Some(false) {
        return Err(PyValueError::new_err(
            "pool_gains=False: each recording learns its joint angles' gains alone when pooling, \
             with pool=True (or None)",
        ));
    }
    if pool_rounds.is_some() && pool == Some(false) {
        return Err(value_error(
            "pool_rounds: the rounds of pooling, with pool=True (or None)",
        ));
    }
    if pool_rounds == Some(0) {
        return Err(value_error(
            "pool_rounds = 0: at least 1 round of pooling (pool=False filters each recording alone)",
        ));
    }
    if pool_search.is_some() && pool == Some(false) {
        return Err(value_error(
            "pool_search: how many recordings the search rounds filter, with pool=True (or None)",
        ));
    }
    if pool_search.is_some_and(|n| n < 2) {
        return Err(value_error(
            "pool_search: the search rounds learn the whisker from several recordings: at least 2",
        ));
    }
    let rounds = pool_rounds.unwrap_or(vibrissa_infer::pf::pool::ROUNDS);
    let search = pool_search.unwrap_or(vibrissa_infer::pf::pool::SEARCH_RECORDINGS);
    if pool == Some(true) && !pf {
        return Err(value_error(
            "pool: the filter's option (method=\"pf\"): it learns one whisker from the recordings",
        ));
    }
    if pool == Some(true) && inputs.len() < 2 {
        return Err(value_error(format!(
            "pool: learns the whisker from several recordings of it: give at least 2 (got {})",
            inputs.len()
        )));
    }
    let family = family_adopting(scenario, scenario_json, &sets, whisker_from.as_deref())?
        .for_whisker(whisker, pf)
        .map_err(value_error)?;
    let probe = vibrissa_infer::methods::by_name(method).map_err(value_error)?;
    if let (true, Some(n)) = (pf, particles) {
        check_count("particles", n, 1, MAX_PARTICLES).map_err(value_error)?;
    }
    let given = vibrissa_infer::noise::parse_statement(noise)
        .map_err(|e| value_error(format!("noise: {e}")))?;
    let mut stated = family.stated_noise();
    for (c, g) in given.iter().enumerate() {
        if g.is_some() {
            stated[c] = *g;
        }
    }
    let needs = probe.channels();
    let reader = if pf {
        Reader::Filter
    } else {
        Reader::Method(probe.name())
    };
    let mut messages = Vec::new();
    let mut names = Vec::new();
    let mut recordings = Vec::new();
    for input in &inputs {
        let (name, rec) = match input {
            Input::Path(path) => {
                let (series, lines, warnings) =
                    vibrissa_io::series::read_csv_with_sidecar_lines(path).map_err(value_error)?;
                messages.extend(warnings.into_iter().map(|w| format!("warning: {w}")));
                let series = vibrissa_infer::recording::whisker_view(&series, path, whisker)
                    .map_err(value_error)?;
                // A bad row is named by the file's line, as the CSV reader names its own.
                let rec = Recording::from_series_at_lines(&series, path, &needs, reader, &lines);
                (path.clone(), rec)
            }
            Input::Arrays(name, t, columns) => {
                let t = t.as_array().to_vec();
                let columns = columns
                    .iter()
                    .map(|c| c.as_ref().map(|a| a.as_array().to_vec()))
                    .collect();
                let rec = Recording::from_columns(name, t, columns, None, &needs, reader);
                (name.clone(), rec)
            }
        };
        let rec = rec.map_err(value_error)?;
        // A recording sampled too slowly for the scenario's run (a `t` in milliseconds).
        family
            .check_sample_rate(rec.rate)
            .map_err(|e| PyValueError::new_err(format!("`{name}`: {e}")))?;
        names.push(name);
        recordings.push(rec);
    }
    // A calibrated scenario trains over what its calibration leaves uncertain unless told not to.
    let auto = randomise.is_none();
    let randomise = randomise.unwrap_or(family.is_calibrated());
    let family = family.for_method(randomise, method).map_err(value_error)?;
    if auto && family.is_calibrated() {
        let how = if pf {
            "the filter's alternative whiskers from a narrow prior around the fitted one"
        } else if family.around().is_some_and(|a| a.is_fitted()) {
            "whiskers drawn from the fit's standard errors and correlations"
        } else {
            "a narrow prior: the file records no correlations; calibrate again to record them"
        };
        messages.push(format!(
            "the scenario is calibrated: training over what its calibration leaves uncertain \
             ({how}); randomise=False trains on the fitted whisker alone"
        ));
    }
    // The filter leaves out a sensor that recorded nothing (a flat channel beside others that
    // vary), as on the command line.
    let needs = if pf {
        let (kept, warnings) =
            vibrissa_infer::recording::recorded_channels(&names, &recordings, &needs);
        messages.extend(warnings.into_iter().map(|w| format!("warning: {w}")));
        kept
    } else {
        needs
    };
    let several = names.len() > 1;
    let rows = py.detach(|| -> vibrissa_infer::Result<Vec<String>> {
        // Channels far wider than the scenario's runs: a recording in other units.
        let units = vibrissa_infer::units::unit_warnings(&family, &names, &recordings, &needs)?;
        messages.extend(units.iter().map(|w| format!("warning: {w}")));
        let noise = batch_noise(&names, &recordings, &needs, &stated, "noise={...}")?;
        messages.extend(noise.warnings.iter().map(|w| format!("warning: {w}")));
        messages.push(noise.summary.clone());
        // Recordings that show nothing beyond their noise: no strike to read.
        let quiet =
            vibrissa_infer::batch::without_strikes(&names, &recordings, &noise.levels, &needs);
        messages.extend(quiet.iter().map(|w| format!("warning: {w}")));
        // Recordings that start before the approach (stated, or evident in the batch).
        let leads = vibrissa_infer::lead_in::batch_leads(
            max_delay,
            &family,
            &names,
            &recordings,
            &noise.levels,
            &mut |w| messages.push(format!("warning: {w}")),
        )?;
        // The filter entertains whiskers drawn around a scenario that most of the recordings
        // defy (at `krr`'s estimates and near them), as on the command line.
        let family = if pf {
            vibrissa_infer::batch::filter_family(
                &family,
                &recordings,
                &noise.levels,
                &leads,
                seed,
                auto,
                &vibrissa_infer::batch::PYTHON,
                &mut |m| messages.push(m),
            )?
        } else {
            family.clone()
        };
        let options = recording::Options {
            seed,
            // The filter's start delay is unknown up to the lead-in allowed.
            max_delay: leads
                .iter()
                .zip(&recordings)
                .map(|(&l, r)| l as f64 / r.rate)
                .fold(max_delay, f64::max),
            channels: needs.clone(),
            ..recording::Options::new(
                particles.unwrap_or_else(|| vibrissa_infer::pf::default_particles(&family)),
            )
        };
        // The discriminative methods' estimates first: a scenario that is neither calibrated nor
        // randomised, which most of the recordings defy at their estimates, is not their
        // whisker, and they estimate again on whiskers drawn around it (as on the command line).
        let (family, discriminative) = if pf {
            (family, Vec::new())
        } else {
            vibrissa_infer::batch::discriminative(
                &family,
                &names,
                &recordings,
                &noise.levels,
                &leads,
                method,
                seed,
                auto,
                &vibrissa_infer::batch::PYTHON,
                &mut Trained::default(),
                &mut |m| messages.push(m),
            )?
        };
        let mut discriminative = discriminative.into_iter();
        // The filter on every recording, fitted once per noise level as on the command line.
        let filter = |options: &recording::Options,
                      which: &[usize]|
         -> vibrissa_infer::Result<Vec<recording::Estimate>> {
            let mut filtered: Option<([f64; 5], Pf)> = None;
            let mut out = Vec::new();
            for &r in which {
                let (rec, level) = (&recordings[r], &noise.levels[r]);
                if filtered.as_ref().map(|f| f.0) != Some(*level) {
                    filtered = Some((*level, recording::fitted(&family, level, options)?));
                }
                let fitted = &filtered.as_ref().expect("fitted above").1;
                out.push(recording::estimate(
                    fitted,
                    &family,
                    rec,
                    &options.for_recording(r),
                )?);
            }
            Ok(out)
        };
        let mut options = options;
        // A batch of one whisker known only roughly is pooled unless told otherwise.
        let pool = pool.unwrap_or_else(|| {
            let auto = pf && vibrissa_infer::pf::pool::by_default(recordings.len(), &family);
            if auto {
                messages.push(format!(
                    "pf: pooling the {} recordings as strikes of one whisker, which the filter \
                     learns from all of them together (pool=False filters each alone)",
                    recordings.len()
                ));
            }
            auto
        });
        options.islands = islands.unwrap_or(vibrissa_infer::pf::default_islands(pool));
        options.lost_islands = match islands {
            Some(_) => None,
            None => vibrissa_infer::pf::lost_islands(pool),
        };
        let filtered = if !pf {
            Vec::new()
        } else if pool {
            if family.randomisation().is_none() {
                return Err(vibrissa_infer::Error::Observation(
                    "pool: the filter must entertain several whiskers: randomise=True (or leave it \
                     None on a scenario the recordings defy)"
                        .into(),
                ));
            }
            // Each round's whiskers are the batch's, not the prior's: no held-out widening.
            options.interval_runs = 0;
            options.pool_gains = pool_gains;
            recording_pool(
                &names,
                &options,
                rounds,
                search,
                seed,
                &filter,
                &mut messages,
            )?
        } else {
            let all: Vec<usize> = (0..recordings.len()).collect();
            filter(&options, &all)?
        };
        let mut filtered = filtered.into_iter();
        let mut rows = Vec::new();
        for (((name, rec), level), &lead) in
            names.iter().zip(&recordings).zip(&noise.levels).zip(&leads)
        {
            let (estimates, seconds, filter, sensor) = if pf {
                let est = filtered.next().expect("one filtering per recording");
                messages.extend(
                    est.warnings(name)
                        .into_iter()
                        .map(|w| format!("warning: {w}")),
                );
                (est.named(), est.seconds, est.counts(), est.sensor)
            } else {
                let (est, seconds) = discriminative.next().expect("one estimate per recording");
                (family.named(est), seconds, Vec::new(), *level)
            };
            let check = if check {
                let point: Vec<f64> = estimates.iter().map(|(_, e)| e.mean).collect();
                let checked = family.nominal().for_recording(rec).and_then(|timed| {
                    vibrissa_infer::check::check(
                        &timed,
                        &rec.values,
                        &point,
                        &sensor,
                        &needs,
                        if pf { 0 } else { lead },
                    )
                });
                match checked {
                    Ok(c) => Some(c),
                    Err(e) => {
                        messages.push(format!(
                            "warning: `{name}`: cannot check the recording at its estimate: {e}"
                        ));
                        None
                    }
                }
            } else {
                None
            };
            let row = EstimateRow {
                file: several.then(|| name.clone()),
                class: Vec::new(),
                estimates,
                method: method.to_string(),
                seconds,
                noise: needs
                    .iter()
                    .map(|&c| (CHANNELS[c].to_string(), sensor[c]))
                    .collect(),
                filter,
                check,
                misfit: None,
            };
            rows.push(serde_json::Value::Object(row.to_json()).to_string());
        }
        Ok(rows)
    });
    let rows = rows.map_err(value_error)?;
    Ok((rows, messages))
}

/// The names of the whiskers a shape family reads (`shapes`: a built-in such as "e3" or a
/// shape-family file; `whiskers`: a subset of its array, or all).
#[pyfunction]
#[pyo3(signature = (shapes, whiskers=None))]
pub(crate) fn shape_whiskers(shapes: &str, whiskers: Option<Vec<String>>) -> PyResult<Vec<String>> {
    Ok(shape_family(shapes, whiskers, None)?.whiskers())
}

/// The shape family `shapes`, reading `whiskers` (all when `None`), its whiskers given those
/// of the scenario files `whisker_from` (`FILE` or `NAME=FILE` each) when any are named.
pub(crate) fn shape_family(
    shapes: &str,
    whiskers: Option<Vec<String>>,
    whisker_from: Option<Vec<String>>,
) -> PyResult<vibrissa_infer::shapes::ShapeFamily> {
    let source = whisker_source(whisker_from.as_deref())?;
    let family = vibrissa_infer::shapes::ShapeFamily::open_with(shapes, &[], source.as_ref())
        .map_err(value_error)?;
    match whiskers {
        Some(w) => {
            let names: Vec<&str> = w.iter().map(String::as_str).collect();
            family.with_whiskers(&names).map_err(value_error)
        }
        None => Ok(family),
    }
}

/// Estimates which object of the shape family `shapes` struck the whiskers in each recording
/// (`inputs[recording][whisker]`: a path with the whisker's name, or that whisker's arrays), as
/// `vibrissa estimate --shapes --json` does; returns one estimate object per recording as JSON
/// text, the messages the command line prints on standard error, and for an online method each
/// recording's class posterior after every sample (`[recordings][samples][classes]`) with the
/// classes' names in that order.
#[pyfunction]
#[pyo3(signature = (shapes, whiskers, inputs, noise, seed, randomise, training, method, bank, whisker_from=None, particles=None))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub(crate) fn estimate_shapes(
    py: Python<'_>,
    shapes: &str,
    whiskers: Option<Vec<String>>,
    inputs: Vec<Vec<(Input<'_>, Option<String>)>>,
    noise: &str,
    seed: u64,
    randomise: bool,
    training: usize,
    method: &str,
    bank: usize,
    whisker_from: Option<Vec<String>>,
    particles: Option<usize>,
) -> PyResult<(Vec<String>, Vec<String>, Vec<Vec<Vec<f64>>>, Vec<String>)> {
    use vibrissa_infer::shapes::{estimate_batch, has_filter, BatchOptions, FILTER_METHODS};
    check_count("training", training, 1, MAX_TRAINING).map_err(value_error)?;
    check_count("bank", bank, 1, MAX_BANK).map_err(value_error)?;
    if let Some(n) = particles {
        if !has_filter(method) {
            return Err(value_error(format!(
                "particles: sets the particles per class of {}, not of {method}",
                FILTER_METHODS.join(" and ")
            )));
        }
        check_count("particles", n, 2, MAX_PARTICLES).map_err(value_error)?;
    }
    let family = shape_family(shapes, whiskers, whisker_from)?;
    let stated = vibrissa_infer::noise::parse_statement(noise)
        .map_err(|e| value_error(format!("noise: {e}")))?;
    let all: Vec<usize> = (0..CHANNELS.len()).collect();
    let reader = Reader::Complete(method);
    let mut messages = Vec::new();
    let mut names = Vec::new();
    let mut recordings = Vec::new();
    for per in &inputs {
        let mut name = String::new();
        let mut whisker_recordings = Vec::new();
        for (input, whisker) in per {
            let rec = match input {
                Input::Path(path) => {
                    name = path.clone();
                    let (series, lines, warnings) =
                        vibrissa_io::series::read_csv_with_sidecar_lines(path)
                            .map_err(value_error)?;
                    messages.extend(warnings.into_iter().map(|w| format!("warning: {w}")));
                    let series =
                        vibrissa_infer::recording::whisker_view(&series, path, whisker.as_deref())
                            .map_err(value_error)?;
                    Recording::from_series_at_lines(&series, path, &all, reader, &lines)
                }
                Input::Arrays(n, t, columns) => {
                    name = n.clone();
                    let t = t.as_array().to_vec();
                    let columns = columns
                        .iter()
                        .map(|c| c.as_ref().map(|a| a.as_array().to_vec()))
                        .collect();
                    Recording::from_columns(n, t, columns, None, &all, reader)
                }
            };
            whisker_recordings.push(rec.map_err(value_error)?);
        }
        names.push(name);
        recordings.push(whisker_recordings);
    }
    let options = BatchOptions {
        method: method.to_string(),
        training,
        bank,
        seed,
        randomise,
        stated,
        trace: true,
        particles: particles.unwrap_or(vibrissa_infer::shapes::SHAPE_PF_PARTICLES),
    };
    messages.push(format!(
        "training {} on {} runs per class of {}",
        method,
        training,
        family.name()
    ));
    let batch = py
        .detach(|| estimate_batch(&family, &names, &recordings, &options))
        .map_err(value_error)?;
    messages.extend(batch.warnings.iter().map(|w| format!("warning: {w}")));
    let rows = batch
        .rows(&names)
        .iter()
        .map(|r| serde_json::Value::Object(r.to_json()).to_string())
        .collect();
    let classes = family.class_names().iter().map(|c| c.to_string()).collect();
    Ok((rows, messages, batch.traces, classes))
}
