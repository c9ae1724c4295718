//! The native part of the Python package `vibrissa`: the simulator behind
//! `vibrissa.simulate`. The Python layer (`python/vibrissa/__init__.py`) turns keyword arguments
//! into scenario overrides and offers a pandas frame; this module loads the scenario, runs it with
//! the interpreter released, and returns the contract's columns as numpy arrays.

use numpy::IntoPyArray;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use vibrissa_core::sim::{self, COLUMNS};

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
    let run = &loaded.scenario;
    let output = py
        .detach(|| sim::run(run, &mut |_| {}))
        .map_err(value_error)?;
    let columns = PyDict::new(py);
    for (c, name) in COLUMNS.iter().enumerate() {
        let values: Vec<f64> = output.rows.iter().map(|r| r[c]).collect();
        columns.set_item(*name, values.into_pyarray(py))?;
    }
    Ok(columns)
}

/// The built-in scenarios' names.
#[pyfunction]
fn builtins() -> Vec<&'static str> {
    vibrissa_io::scenario::BUILTINS.to_vec()
}

#[pymodule]
fn _vibrissa(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(builtins, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
