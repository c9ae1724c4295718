//! The pieces of `vibrissa.sweep` and `vibrissa.ray.sweep`: the plan, one run or a batch of runs,
//! what a folder holds already, and the manifest.

use crate::value_error;
use pyo3::prelude::*;
use vibrissa_io::sweep;

/// A manifest row's figures: samples, steps, seconds, max_penetration (as written).
pub(crate) type RowFields = (String, String, String, String);

/// A sweep's plan: the grids' keys, and per run its file name, its `(key, value)` parameters and
/// whether it is finished in `out` already (its series and sidecar both there).
#[pyfunction]
#[pyo3(signature = (scenario, sets, grids, format, out))]
#[allow(clippy::type_complexity)]
pub(crate) fn sweep_plan(
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
pub(crate) fn sweep_run(
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
pub(crate) fn sweep_run_batch(
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
pub(crate) fn sweep_previous(out: &str) -> std::collections::HashMap<String, RowFields> {
    sweep::read_manifest(&std::path::Path::new(out).join(sweep::MANIFEST))
        .into_iter()
        .map(|(f, r)| (f, (r.samples, r.steps, r.seconds, r.max_penetration)))
        .collect()
}

/// Writes `manifest.csv` in `out` (atomically): the finished runs, in the plan's order.
#[pyfunction]
#[pyo3(signature = (out, keys, jobs, rows))]
pub(crate) fn sweep_manifest(
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
