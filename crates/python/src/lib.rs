//! The native part of the Python package `vibrissa`: the simulator behind `vibrissa.simulate`
//! and the particle filter behind `vibrissa.Filter`. The Python layer
//! (`python/vibrissa/__init__.py`) turns keyword arguments into scenario overrides, checks types
//! and offers a pandas frame; this module loads the scenario and does the work with the
//! interpreter released.

use numpy::{IntoPyArray, PyReadonlyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use vibrissa_infer::contract::EstimateRow;
use vibrissa_infer::experiment::CHANNELS;
use vibrissa_infer::limits::{check_count, MAX_BANK, MAX_PARTICLES, MAX_TRAINING};
use vibrissa_infer::pf::{self, recording, Pf, TraceRow};
use vibrissa_infer::recording::batch_noise;
use vibrissa_infer::{Family, Reader, Recording, Trained};
use vibrissa_io::scenario::Document;
use vibrissa_io::sweep;

/// The error of a scenario or run, as Python's `ValueError` with the command line's message.
fn value_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// Simulates `scenario` (a built-in name such as "e2", or the path of a TOML scenario file)
/// with `sets` overrides ("key=value"), and returns a dict of the output columns (t, theta01,
/// theta12, m0, fx, fy, contact, cx, cy, s) as float64 arrays, SI units.
#[pyfunction]
#[pyo3(signature = (scenario, sets))]
fn simulate<'py>(
    py: Python<'py>,
    scenario: &str,
    sets: Vec<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let loaded = vibrissa_io::scenario::load_full(scenario, &sets).map_err(value_error)?;
    run_columns(py, &loaded, scenario, &sets)
}

/// The particle filter fed one sample at a time (see `vibrissa.Filter`).
#[pyclass(name = "Filter", module = "vibrissa._vibrissa")]
struct Filter {
    inner: pf::Filter,
    /// The unknowns of the posterior rows, in order.
    unknowns: Vec<&'static str>,
    /// Sample period, s.
    period: f64,
    /// The sensor noise per channel the filter assumes, SI.
    noise: [f64; 5],
    /// Per unknown, the factor its intervals are widened by (1: none; see
    /// `recording::fitted`).
    widening: Vec<f64>,
    /// Per unknown, its prior's `[lo, hi]`, within which a widened row is kept.
    support: Vec<Option<[f64; 2]>>,
    /// Number of particles.
    particles: usize,
}

/// A posterior row as a dict: `t`, `ess` and one `{mean, std, ci90}` dict per unknown.
fn row_dict<'py>(
    py: Python<'py>,
    unknowns: &[&str],
    row: &TraceRow,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("t", row.t)?;
    d.set_item("ess", row.ess)?;
    for (name, e) in unknowns.iter().zip(&row.estimates) {
        let u = PyDict::new(py);
        u.set_item("mean", e.mean)?;
        u.set_item("std", e.std)?;
        u.set_item("ci90", (e.ci90[0], e.ci90[1]))?;
        d.set_item(*name, u)?;
    }
    Ok(d)
}

/// Adds the posterior of the sensors' gains and offsets, when the filter carries them, under
/// the scenario keys `sensors.<channel>.gain` and `.offset`, and of the whisker parameters that
/// differ between the whiskers it entertains (`whisker.youngs_modulus`, …).
fn add_sensors(
    py: Python<'_>,
    d: &Bound<'_, PyDict>,
    post: &pf::Posterior,
    sensors: Option<pf::SensorPosterior>,
) -> PyResult<()> {
    let put = |key: String, e: &vibrissa_infer::Estimate| -> PyResult<()> {
        let u = PyDict::new(py);
        u.set_item("mean", e.mean)?;
        u.set_item("std", e.std)?;
        u.set_item("ci90", (e.ci90[0], e.ci90[1]))?;
        d.set_item(key, u)
    };
    if let Some(s) = &sensors {
        for (c, ch) in CHANNELS.iter().enumerate() {
            put(format!("sensors.{ch}.gain"), &s.gain[c])?;
            put(format!("sensors.{ch}.offset"), &s.offset[c])?;
        }
    }
    for (key, e) in &post.whisker {
        put(key.to_string(), e)?;
    }
    Ok(())
}

impl Filter {
    /// A posterior row as the user sees it: widened, and within the priors.
    fn shown(&self, row: &TraceRow) -> TraceRow {
        row.widened(&self.widening).within(&self.support)
    }
}

#[pymethods]
impl Filter {
    /// `noise` holds each channel's sensor noise (NaN where not given: the scenario's
    /// `[sensor_noise]` must state it then).
    #[new]
    #[pyo3(signature = (scenario, scenario_json, sets, noise, particles, seed, rate, randomise=false))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        scenario: Option<&str>,
        scenario_json: Option<&str>,
        sets: Vec<String>,
        noise: [f64; 5],
        particles: Option<usize>,
        seed: u64,
        rate: Option<f64>,
        randomise: bool,
    ) -> PyResult<Self> {
        if let Some(n) = particles {
            check_count("particles", n, 1, MAX_PARTICLES).map_err(value_error)?;
        }
        let family = family(scenario, scenario_json, &sets)?
            .randomised_if(randomise)
            .map_err(value_error)?;
        // A whisker file of the user's own, neither calibrated nor randomised: the filter takes
        // its whisker as exact, which a real whisker never is. `estimate` checks the recordings
        // against it first; a filter fed sample by sample has none to check yet.
        let builtin = scenario.is_some_and(|s| vibrissa_io::scenario::BUILTINS.contains(&s));
        if !builtin && family.randomisation().is_none() && !family.is_calibrated() {
            let message = std::ffi::CString::new(
                "vibrissa.Filter takes this scenario's whisker as exact: if the recordings \
                 come from a real whisker (or another simulator), its intervals will not hold \
                 the truth; pass randomise=True (the whisker known only roughly) or calibrate \
                 the scenario on labelled strikes first (vibrissa.calibrate)",
            )
            .expect("no NUL in the message");
            PyErr::warn(
                py,
                &py.get_type::<pyo3::exceptions::PyUserWarning>(),
                &message,
                2,
            )?;
        }
        // Online, real time comes first: the same count on every family (a whole recording in hand
        // is filtered by `estimate` with more on a randomised one).
        let particles = particles.unwrap_or(pf::ONLINE_PARTICLES);
        let stated = family.stated_noise();
        let mut sensor = [0.0; 5];
        for c in 0..5 {
            sensor[c] = match (noise[c], stated[c]) {
                (x, _) if x.is_finite() && x >= 0.0 => x,
                (x, _) if !x.is_nan() => {
                    return Err(PyValueError::new_err(format!(
                        "noise[{:?}] = {x}: a sensor noise is a finite number >= 0",
                        CHANNELS[c]
                    )))
                }
                (_, Some(s)) => s,
                (_, None) => {
                    return Err(PyValueError::new_err(format!(
                        "noise: give the sensor noise of `{}` (e.g. noise={{\"{}\": 1e-3, ...}}, \
                         SI units), or state it in the scenario's [sensor_noise]",
                        CHANNELS[c], CHANNELS[c]
                    )))
                }
            };
        }
        let rate = rate.unwrap_or(family.sample_rate());
        if !(rate.is_finite() && rate > 0.0) {
            return Err(PyValueError::new_err(format!(
                "rate = {rate}: a sample rate in Hz, > 0"
            )));
        }
        // As `vibrissa estimate --method pf` fits it, at the recording's rate: on a whisker
        // known only roughly its intervals are widened to hold 90% of the errors on held-out
        // runs of the family.
        let timed = if (rate - family.sample_rate()).abs() <= 1e-9 * rate {
            family.clone()
        } else {
            let period = (family.samples() - 1) as f64 / family.sample_rate();
            family
                .with_timing(rate, (period * rate).round() as usize + 1)
                .map_err(value_error)?
        };
        let options = recording::Options {
            seed,
            ..recording::Options::new(particles)
        };
        let filter = recording::fitted(&timed, &sensor, &options).map_err(value_error)?;
        let sigma = filter.sigma().expect("fitted");
        let config = filter.config(&family, sigma).map_err(value_error)?;
        let inner = pf::Filter::new(&config, 1.0 / rate).map_err(value_error)?;
        let unknowns = config.unknowns();
        let widening = filter.widening(&unknowns);
        let support = config.support(&unknowns);
        Ok(Filter {
            unknowns,
            inner,
            period: 1.0 / rate,
            noise: filter.sensor_noise().expect("fitted"),
            widening,
            support,
            particles,
        })
    }

    /// Takes one sample (`values` per channel theta01, theta12, m0, fx, fy; NaN where missing)
    /// at time `t` and returns the posterior row there.
    fn update<'py>(
        &mut self,
        py: Python<'py>,
        t: f64,
        values: [f64; 5],
    ) -> PyResult<Bound<'py, PyDict>> {
        let inner = &mut self.inner;
        py.detach(|| inner.update(t, &values).map(|_| ()))
            .map_err(value_error)?;
        let post = self.inner.posterior();
        let row = self.shown(post.trace.last().expect("a row"));
        let d = row_dict(py, &self.unknowns, &row)?;
        add_sensors(py, &d, post, self.inner.sensors())?;
        Ok(d)
    }

    /// The posterior after the last sample (None before the first).
    #[getter]
    fn posterior<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let post = self.inner.posterior();
        match post.trace.last() {
            Some(row) => {
                let d = row_dict(py, &self.unknowns, &self.shown(row))?;
                add_sensors(py, &d, post, self.inner.sensors())?;
                Ok(Some(d))
            }
            None => Ok(None),
        }
    }

    /// Every posterior row so far: `t`, `ess`, and per unknown `NAME_mean`, `NAME_std`,
    /// `NAME_lo`, `NAME_hi` (the 90% interval), as arrays.
    #[getter]
    fn trace<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let rows: Vec<TraceRow> = self
            .inner
            .posterior()
            .trace
            .iter()
            .map(|r| self.shown(r))
            .collect();
        let d = PyDict::new(py);
        let column = |f: &dyn Fn(&TraceRow) -> f64| rows.iter().map(f).collect::<Vec<f64>>();
        d.set_item("t", column(&|r| r.t).into_pyarray(py))?;
        d.set_item("ess", column(&|r| r.ess).into_pyarray(py))?;
        for (k, name) in self.unknowns.iter().enumerate() {
            d.set_item(
                format!("{name}_mean"),
                column(&|r| r.estimates[k].mean).into_pyarray(py),
            )?;
            d.set_item(
                format!("{name}_std"),
                column(&|r| r.estimates[k].std).into_pyarray(py),
            )?;
            d.set_item(
                format!("{name}_lo"),
                column(&|r| r.estimates[k].ci90[0]).into_pyarray(py),
            )?;
            d.set_item(
                format!("{name}_hi"),
                column(&|r| r.estimates[k].ci90[1]).into_pyarray(py),
            )?;
        }
        Ok(d)
    }

    /// The unknowns of the posterior, in order.
    #[getter]
    fn unknowns(&self) -> Vec<&'static str> {
        self.unknowns.clone()
    }

    /// Number of particles.
    #[getter]
    fn particles(&self) -> usize {
        self.particles
    }

    /// The sample period, s.
    #[getter]
    fn period(&self) -> f64 {
        self.period
    }

    /// The sensor noise per channel the filter assumes (before its model error), SI.
    #[getter]
    fn noise<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (c, x) in CHANNELS.iter().zip(self.noise) {
            d.set_item(*c, x)?;
        }
        Ok(d)
    }

    /// Particle steps that diverged (0 expected) and moves undone, so far.
    #[getter]
    fn counts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let p = self.inner.posterior();
        let d = PyDict::new(py);
        d.set_item("particle_steps", p.steps)?;
        d.set_item("diverged_steps", p.diverged)?;
        d.set_item("refused_moves", p.refused_moves)?;
        d.set_item("resamples", p.resamples)?;
        Ok(d)
    }
}

/// A scenario family from a built-in name or path (`spec`), or from the JSON text of a Python
/// dict (`json`).
fn family(spec: Option<&str>, json: Option<&str>, sets: &[String]) -> PyResult<Family> {
    family_adopting(spec, json, sets, None)
}

/// [`family`], given the whisker of the scenario file `whisker_from` when one is named.
fn family_adopting(
    spec: Option<&str>,
    json: Option<&str>,
    sets: &[String],
    whisker_from: Option<&str>,
) -> PyResult<Family> {
    let source = whisker_source(whisker_from)?;
    let text = json.map(toml_of_json).transpose()?;
    match (spec, text) {
        (Some(spec), _) => Family::open_adopting(spec, None, sets, source.as_ref()),
        (None, Some(text)) => {
            Family::open_adopting("scenario dict", Some(&text), sets, source.as_ref())
        }
        (None, None) => return Err(value_error("scenario: give a name, a path or a dict")),
    }
    .map_err(value_error)
}

/// The whisker of the scenario file `whisker_from`, read, if one is named.
fn whisker_source(
    whisker_from: Option<&str>,
) -> PyResult<Option<vibrissa_io::scenario::WhiskerSource>> {
    whisker_from
        .map(|file| {
            vibrissa_io::scenario::WhiskerSource::read(file)
                .map_err(|e| value_error(format!("whisker_from: {e}")))
        })
        .transpose()
}

/// The TOML text of a scenario given as the JSON text of a dict.
fn toml_of_json(json: &str) -> PyResult<String> {
    let value: toml::Value =
        serde_json::from_str(json).map_err(|e| value_error(format!("scenario dict: {e}")))?;
    if !value.is_table() {
        return Err(value_error(
            "scenario dict: expected a dict of scenario keys",
        ));
    }
    toml::to_string(&value).map_err(|e| value_error(format!("scenario dict: {e}")))
}

/// One recording handed over by the Python layer: the path of a contract CSV, or a name, the
/// sample times and one optional array per channel.
#[derive(FromPyObject)]
enum Input<'py> {
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
type FilterSome<'a> =
    dyn Fn(&recording::Options, &[usize]) -> vibrissa_infer::Result<Vec<recording::Estimate>> + 'a;

/// The pooling rounds of `vibrissa estimate --pool` ([`vibrissa_infer::pf::pool::refine`]),
/// each round's favourite whisker reported in `messages`.
fn recording_pool(
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
#[pyo3(signature = (scenario, scenario_json, sets, inputs, method, noise, seed, randomise, particles, check, whisker=None, max_delay=0.0, pool=None, pool_rounds=None, pool_search=None, whisker_from=None, pool_gains=true))]
#[allow(clippy::too_many_arguments)]
fn estimate(
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
    check: bool,
    whisker: Option<&str>,
    max_delay: f64,
    pool: Option<bool>,
    pool_rounds: Option<usize>,
    pool_search: Option<usize>,
    whisker_from: Option<&str>,
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
    let family = family_adopting(scenario, scenario_json, &sets, whisker_from)?
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
    let family = family.randomised_if(randomise).map_err(value_error)?;
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
fn shape_whiskers(shapes: &str, whiskers: Option<Vec<String>>) -> PyResult<Vec<String>> {
    Ok(shape_family(shapes, whiskers, None)?.whiskers())
}

/// The shape family `shapes`, reading `whiskers` (all when `None`), every whisker given the
/// whisker of the scenario file `whisker_from` when one is named.
fn shape_family(
    shapes: &str,
    whiskers: Option<Vec<String>>,
    whisker_from: Option<&str>,
) -> PyResult<vibrissa_infer::shapes::ShapeFamily> {
    let source = whisker_source(whisker_from)?;
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
#[pyo3(signature = (shapes, whiskers, inputs, noise, seed, randomise, training, method, bank, whisker_from=None))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
fn estimate_shapes(
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
    whisker_from: Option<&str>,
) -> PyResult<(Vec<String>, Vec<String>, Vec<Vec<Vec<f64>>>, Vec<String>)> {
    use vibrissa_infer::shapes::{estimate_batch, BatchOptions};
    check_count("training", training, 1, MAX_TRAINING).map_err(value_error)?;
    check_count("bank", bank, 1, MAX_BANK).map_err(value_error)?;
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

/// As [`simulate`], for a scenario given as the JSON text of a Python dict (the keys of a
/// scenario file, tables as nested dicts).
#[pyfunction]
#[pyo3(signature = (json, sets))]
fn simulate_json<'py>(
    py: Python<'py>,
    json: &str,
    sets: Vec<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let text = toml_of_json(json)?;
    let (_, loaded) =
        vibrissa_io::scenario::open_str(&text, "scenario dict", &sets).map_err(value_error)?;
    run_columns(py, &loaded, "scenario dict", &sets)
}

/// Runs `loaded` (one whisker or an array) with the interpreter released and returns its
/// columns, in the order of the command line's series.
fn run_columns<'py>(
    py: Python<'py>,
    loaded: &vibrissa_io::scenario::Loaded,
    spec: &str,
    sets: &[String],
) -> PyResult<Bound<'py, PyDict>> {
    let (series, _) = py
        .detach(|| sweep::run_series(loaded, spec, sets))
        .map_err(value_error)?;
    let columns = PyDict::new(py);
    for (name, values) in series.columns.iter().zip(series.data) {
        columns.set_item(name, values.into_pyarray(py))?;
    }
    Ok(columns)
}

/// A manifest row's figures: samples, steps, seconds, max_penetration (as written).
type RowFields = (String, String, String, String);

/// A sweep's plan: the grids' keys, and per run its file name, its `(key, value)` parameters and
/// whether it is finished in `out` already (its series and sidecar both there).
#[pyfunction]
#[pyo3(signature = (scenario, sets, grids, format, out))]
#[allow(clippy::type_complexity)]
fn sweep_plan(
    scenario: &str,
    sets: Vec<String>,
    grids: Vec<String>,
    format: &str,
    out: Option<&str>,
) -> PyResult<(Vec<String>, Vec<(String, Vec<(String, String)>, bool)>)> {
    if !vibrissa_io::series::EXTENSIONS.contains(&format) {
        return Err(value_error(format!(
            "format = {format:?}: choose one of {}",
            vibrissa_io::series::EXTENSIONS.join(", ")
        )));
    }
    let grids = sweep::grids_for(scenario, &sets, &grids).map_err(value_error)?;
    let jobs = sweep::plan(&grids, format).map_err(value_error)?;
    // An error shared by every run (a misspelt key) stops the sweep before anything runs.
    let mut first = None;
    let all_fail = jobs.iter().all(|j| {
        let all: Vec<String> = sets.iter().cloned().chain(j.sets()).collect();
        match vibrissa_io::scenario::load_full(scenario, &all) {
            Ok(_) => false,
            Err(e) => {
                first.get_or_insert(e);
                true
            }
        }
    });
    if let (true, Some(e)) = (all_fail, first) {
        return Err(value_error(e));
    }
    let keys = grids.into_iter().map(|g| g.key).collect();
    let dir = out.map(std::path::Path::new);
    let jobs = jobs
        .into_iter()
        .map(|j| {
            let done = dir.is_some_and(|d| j.done(d));
            (j.file, j.params, done)
        })
        .collect();
    Ok((keys, jobs))
}

/// Runs one job of a sweep of `scenario` (with the sweep's `sets`) and writes its series and
/// sidecar into `out`, as `vibrissa sweep` does; returns its manifest figures.
#[pyfunction]
#[pyo3(signature = (scenario, sets, file, params, out))]
fn sweep_run(
    py: Python<'_>,
    scenario: &str,
    sets: Vec<String>,
    file: String,
    params: Vec<(String, String)>,
    out: &str,
) -> PyResult<RowFields> {
    let job = sweep::Job { params, file };
    let all: Vec<String> = sets.iter().cloned().chain(job.sets()).collect();
    let loaded = vibrissa_io::scenario::load_full(scenario, &all).map_err(value_error)?;
    let dir = std::path::Path::new(out);
    let row = py
        .detach(|| sweep::run_one(&loaded, scenario, &sets, &job, dir))
        .map_err(value_error)?;
    Ok((row.samples, row.steps, row.seconds, row.max_penetration))
}

/// Runs several jobs of a sweep of `scenario` (each `(file, params)`), as [`sweep_run`] runs each,
/// those of one whisker stepped together in lanes (each to the bits it reaches alone); returns,
/// per job in order, its manifest figures or the message of its failure.
#[pyfunction]
#[pyo3(signature = (scenario, sets, jobs, out))]
fn sweep_run_batch(
    py: Python<'_>,
    scenario: &str,
    sets: Vec<String>,
    jobs: Vec<(String, Vec<(String, String)>)>,
    out: &str,
) -> Vec<(Option<RowFields>, Option<String>)> {
    let jobs: Vec<sweep::Job> = jobs
        .into_iter()
        .map(|(file, params)| sweep::Job { params, file })
        .collect();
    let dir = std::path::Path::new(out);
    py.detach(|| {
        // Each job's scenario; one that cannot be loaded fails alone.
        let loaded: Vec<vibrissa_io::Result<vibrissa_io::scenario::Loaded>> = jobs
            .iter()
            .map(|job| {
                let all: Vec<String> = sets.iter().cloned().chain(job.sets()).collect();
                vibrissa_io::scenario::load_full(scenario, &all)
            })
            .collect();
        let batch: Vec<(&vibrissa_io::scenario::Loaded, &sweep::Job)> = loaded
            .iter()
            .zip(&jobs)
            .filter_map(|(l, j)| l.as_ref().ok().map(|l| (l, j)))
            .collect();
        let mut rows = sweep::run_batch(&batch, scenario, &sets, dir).into_iter();
        loaded
            .iter()
            .map(|l| {
                let row = match l {
                    Ok(_) => rows.next().expect("one row per loaded job"),
                    Err(e) => return (None, Some(e.to_string())),
                };
                match row {
                    Ok(r) => (
                        Some((r.samples, r.steps, r.seconds, r.max_penetration)),
                        None,
                    ),
                    Err(e) => (None, Some(e.to_string())),
                }
            })
            .collect()
    })
}

/// The figures of an earlier manifest in `out`, by file name (none when there is none).
#[pyfunction]
fn sweep_previous(out: &str) -> std::collections::HashMap<String, RowFields> {
    sweep::read_manifest(&std::path::Path::new(out).join(sweep::MANIFEST))
        .into_iter()
        .map(|(f, r)| (f, (r.samples, r.steps, r.seconds, r.max_penetration)))
        .collect()
}

/// Writes `manifest.csv` in `out` (atomically): the finished runs, in the plan's order.
#[pyfunction]
#[pyo3(signature = (out, keys, jobs, rows))]
fn sweep_manifest(
    out: &str,
    keys: Vec<String>,
    jobs: Vec<(String, Vec<(String, String)>)>,
    rows: Vec<Option<RowFields>>,
) -> PyResult<String> {
    if rows.len() != jobs.len() {
        return Err(value_error("rows: one per job"));
    }
    let path = std::path::Path::new(out).join(sweep::MANIFEST);
    let jobs: Vec<sweep::Job> = jobs
        .into_iter()
        .map(|(file, params)| sweep::Job { params, file })
        .collect();
    let manifest = sweep::Manifest {
        path: path.clone(),
        keys,
        rows: rows
            .into_iter()
            .map(|r| {
                r.map(|(samples, steps, seconds, max_penetration)| sweep::Row {
                    samples,
                    steps,
                    seconds,
                    max_penetration,
                })
            })
            .collect(),
    };
    manifest.write(&jobs).map_err(value_error)?;
    Ok(path.display().to_string())
}

/// Fits the whisker and sensors of the nominal `scenario` to the labelled recordings in
/// `labelled`, as `vibrissa calibrate` does; writes the fitted scenario to `out` when given.
/// Returns the command line's JSON report (with the fitted scenario's TOML text under
/// `"scenario"`) and the stages passed.
#[pyfunction]
#[pyo3(signature = (scenario, sets, labelled, out, ignore_unlisted, gain_prior, max_iterations, finalists))]
#[allow(clippy::too_many_arguments)]
fn calibrate(
    py: Python<'_>,
    scenario: &str,
    sets: Vec<String>,
    labelled: &str,
    out: Option<&str>,
    ignore_unlisted: bool,
    gain_prior: Option<f64>,
    max_iterations: Option<usize>,
    finalists: Option<usize>,
) -> PyResult<(String, Vec<String>)> {
    use vibrissa_infer::calibrate::{calibrate, Settings};
    let gain_prior = gain_prior.unwrap_or(Settings::default().gain_prior);
    let max_iterations = max_iterations.unwrap_or(Settings::default().max_iterations);
    let finalists = finalists.unwrap_or(Settings::default().finalists);
    if let Some(out) = out {
        if !out.ends_with(".toml") {
            return Err(value_error(format!(
                "out = {out:?}: the fitted scenario is a TOML file; give a name ending in .toml"
            )));
        }
    }
    if max_iterations == 0 {
        return Err(value_error("max_iterations: at least 1"));
    }
    if finalists == 0 {
        return Err(value_error("finalists: at least 1"));
    }
    if !(gain_prior >= 0.0 && gain_prior.is_finite()) {
        return Err(value_error(format!(
            "gain_prior = {gain_prior}: the gains' relative prior standard deviation, a number \
             >= 0 (0.1 = known to 10%; 0 = no prior)"
        )));
    }
    let nominal = Document::load(scenario, &sets).map_err(value_error)?;
    nominal
        .loaded()
        .map_err(|e| value_error(format!("the nominal scenario `{scenario}`: {e}")))?;
    let options = vibrissa_io::labelled::Options { ignore_unlisted };
    let set =
        vibrissa_io::labelled::read_labelled(std::path::Path::new(labelled), &nominal, &options)
            .map_err(value_error)?;
    let settings = Settings {
        max_iterations,
        gain_prior,
        finalists,
        ..Settings::default()
    };
    let mut stages: Vec<String> = set
        .ignored
        .iter()
        .map(|n| format!("note: {n} is not named in truth.csv; skipped"))
        .collect();
    let start = std::time::Instant::now();
    let fit = py.detach(|| {
        calibrate(&nominal, &set, &settings, &mut |p| {
            if stages.last() != Some(&p.stage) {
                stages.push(p.stage.clone());
            }
        })
    });
    let fit = fit.map_err(|e| {
        value_error(format!(
            "calibration on {labelled} failed{}: {e}",
            out.map(|o| format!("; {o} was not written"))
                .unwrap_or_default()
        ))
    })?;
    let seconds = start.elapsed().as_secs_f64();
    let fitted = fit.document(&nominal, labelled).map_err(value_error)?;
    let dir = out
        .and_then(|o| std::path::Path::new(o).parent())
        .unwrap_or(std::path::Path::new(""));
    let text = fitted.to_toml(dir).map_err(value_error)?;
    if let Some(out) = out {
        fitted
            .write(std::path::Path::new(out))
            .map_err(value_error)?;
    }
    let report = serde_json::json!({
        "nominal": nominal.origin(),
        "labelled": labelled,
        "out": out,
        "recordings": set.recordings.len(),
        "ignored": set.ignored,
        "parameters": fit.parameters,
        "channels": fit.channels,
        "iterations": fit.iterations,
        "fits": fit.fits,
        "simulations": fit.simulations,
        "other_minima": fit.other_minima,
        "correlation": fit.correlation,
        "left_out": fit.left_out,
        "overrides": fit.overrides,
        "seconds": seconds,
        "scenario": text,
    });
    Ok((report.to_string(), stages))
}

/// The estimators' names.
#[pyfunction]
fn methods() -> Vec<&'static str> {
    vibrissa_infer::methods::NAMES.to_vec()
}

/// The built-in scenarios' names.
#[pyfunction]
fn builtins() -> Vec<&'static str> {
    vibrissa_io::scenario::BUILTINS.to_vec()
}

#[pymodule]
fn _vibrissa(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(simulate_json, m)?)?;
    m.add_function(wrap_pyfunction!(builtins, m)?)?;
    m.add_function(wrap_pyfunction!(estimate, m)?)?;
    m.add_function(wrap_pyfunction!(estimate_shapes, m)?)?;
    m.add_function(wrap_pyfunction!(shape_whiskers, m)?)?;
    m.add_function(wrap_pyfunction!(methods, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_plan, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_run, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_run_batch, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_previous, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_manifest, m)?)?;
    m.add_class::<Filter>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
