//! `vibrissa.calibrate`: the command line's `calibrate` on a folder of labelled strikes.

use crate::value_error;
use pyo3::prelude::*;
use vibrissa_io::scenario::Document;

/// Fits the whisker and sensors of the nominal `scenario` to the labelled recordings in
/// `labelled`, as `vibrissa calibrate` does; writes the fitted scenario to `out` when given.
/// Returns the command line's JSON report (with the fitted scenario's TOML text under
/// `"scenario"`) and the stages passed.
#[pyfunction]
#[pyo3(signature = (scenario, sets, labelled, out, ignore_unlisted, gain_prior, max_iterations, finalists))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn calibrate(
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
        "flat_in": fit.flat_in,
        "contact_substeps": fit.contact_substeps,
        "overrides": fit.overrides,
        "seconds": seconds,
        "scenario": text,
    });
    Ok((report.to_string(), stages))
}
