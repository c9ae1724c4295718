//! The native part of the Python package `vibrissa`. The Python layer
//! (`python/vibrissa/__init__.py`) turns keyword arguments into scenario overrides, checks types
//! and offers a pandas frame; this crate loads the scenario and does the work with the
//! interpreter released: here the simulator behind `vibrissa.simulate` and the scenario
//! helpers the others share; in `filter` the particle filter fed sample by sample
//! (`vibrissa.Filter`), in `estimate` the estimators on whole recordings, in `calibrate`
//! calibration from labelled strikes, in `sweeps` the pieces of a sweep.

use numpy::IntoPyArray;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use vibrissa_infer::Family;
use vibrissa_io::sweep;

mod calibrate;
mod estimate;
mod filter;
mod sweeps;

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

/// A scenario family from a built-in name or path (`spec`), or from the JSON text of a Python
/// dict (`json`).
fn family(spec: Option<&str>, json: Option<&str>, sets: &[String]) -> PyResult<Family> {
    family_adopting(spec, json, sets, None)
}

/// [`family`], given the whiskers of the scenario files `whisker_from` (`FILE` or
/// `NAME=FILE` each, as `--whisker-from` reads them) when any are named.
fn family_adopting(
    spec: Option<&str>,
    json: Option<&str>,
    sets: &[String],
    whisker_from: Option<&[String]>,
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

/// The whiskers of the scenario files `whisker_from` (`FILE` or `NAME=FILE` each), read, if
/// any are named.
fn whisker_source(
    whisker_from: Option<&[String]>,
) -> PyResult<Option<vibrissa_io::scenario::WhiskerSources>> {
    match whisker_from {
        None | Some([]) => Ok(None),
        Some(specs) => vibrissa_io::scenario::WhiskerSources::read(specs)
            .map(Some)
            .map_err(|e| value_error(format!("whisker_from: {e}"))),
    }
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
    m.add_function(wrap_pyfunction!(estimate::estimate, m)?)?;
    m.add_function(wrap_pyfunction!(estimate::estimate_shapes, m)?)?;
    m.add_function(wrap_pyfunction!(estimate::shape_whiskers, m)?)?;
    m.add_function(wrap_pyfunction!(methods, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate::calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(sweeps::sweep_plan, m)?)?;
    m.add_function(wrap_pyfunction!(sweeps::sweep_run, m)?)?;
    m.add_function(wrap_pyfunction!(sweeps::sweep_run_batch, m)?)?;
    m.add_function(wrap_pyfunction!(sweeps::sweep_previous, m)?)?;
    m.add_function(wrap_pyfunction!(sweeps::sweep_manifest, m)?)?;
    m.add_class::<filter::Filter>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
