//! `vibrissa.Filter`: the particle filter fed one sample at a time, its posterior rows as dicts.

use crate::{family, value_error};
use numpy::IntoPyArray;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use vibrissa_infer::experiment::CHANNELS;
use vibrissa_infer::limits::{check_count, MAX_PARTICLES};
use vibrissa_infer::pf::{self, recording, TraceRow};

/// The particle filter fed one sample at a time (see `vibrissa.Filter`).
#[pyclass(name = "Filter", module = "vibrissa._vibrissa")]
pub(crate) struct Filter {
    inner: pf::islands::Islands,
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
pub(crate) fn row_dict<'py>(
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
pub(crate) fn add_sensors(
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
    #[pyo3(signature = (scenario, scenario_json, sets, noise, particles, seed, rate, randomise=None, islands=None))]
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
        randomise: Option<bool>,
        islands: Option<usize>,
    ) -> PyResult<Self> {
        if let Some(n) = particles {
            check_count("particles", n, 1, MAX_PARTICLES).map_err(value_error)?;
        }
        if let Some(n) = islands {
            check_count("islands", n, 1, 64).map_err(value_error)?;
        }
        let family = family(scenario, scenario_json, &sets)?;
        // As `estimate`: a calibrated file draws what its calibration left uncertain unless told
        // otherwise.
        let randomise = randomise.unwrap_or(family.is_calibrated());
        let family = family.randomised_if(randomise).map_err(value_error)?;
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
        // Online, real time comes first, but for a calibrated family, whose intervals need the
        // particles (`pf::online_particles`).
        let particles = particles.unwrap_or_else(|| pf::online_particles(&family));
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
        // Its held-out runs are filtered on the islands it runs, so that their widening is the
        // one it needs.
        let options = recording::Options {
            seed,
            islands: islands.unwrap_or(pf::ISLANDS),
            ..recording::Options::new(particles)
        };
        let filter = recording::fitted(&timed, &sensor, &options).map_err(value_error)?;
        let sigma = filter.sigma().expect("fitted");
        let config = filter.config(&family, sigma).map_err(value_error)?;
        let inner = pf::islands::Islands::new(&config, 1.0 / rate).map_err(value_error)?;
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
        d.set_item("islands", self.inner.count())?;
        Ok(d)
    }
}
