//! An experiment folder's `results.json`, read back: the parts of the evaluation the report
//! shows, and what re-simulating its runs needs.

use anyhow::{bail, Context, Result};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// A number that `results.json` may hold as `null` (JSON has no NaN; serde_json writes NaN and
/// infinities as `null`), read back as NaN.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(from = "Option<f64>")]
pub struct Num(pub f64);

impl From<Option<f64>> for Num {
    fn from(x: Option<f64>) -> Num {
        Num(x.unwrap_or(f64::NAN))
    }
}

/// Noise of the recordings or of the estimators' training.
#[derive(Debug, Clone, Copy, Deserialize)]
pub struct Noise {
    /// Sensor noise per channel (theta01, theta12, m0, fx, fy), SI.
    pub sensor: [Num; 5],
    /// Process-noise intensity, N·s^½·m^-½.
    pub process: Num,
}

impl Noise {
    /// As the estimators' library takes it.
    pub fn to_infer(self) -> vibrissa_infer::experiment::Noise {
        vibrissa_infer::experiment::Noise {
            sensor: self.sensor.map(|s| s.0),
            process: self.process.0,
        }
    }
}

/// One estimate of an unknown.
#[derive(Debug, Clone, Deserialize)]
pub struct Estimate {
    /// Point estimate, SI.
    pub mean: Num,
}

/// One evaluated run's truth and estimates.
#[derive(Debug, Clone, Deserialize)]
pub struct Prediction {
    /// Estimates per unknown.
    pub estimate: Vec<Estimate>,
}

/// One method's scores.
#[derive(Debug, Clone, Deserialize)]
pub struct Method {
    /// Name.
    pub name: String,
    /// Budget (`paper`, `free`).
    pub budget: String,
    /// Mean absolute error per unknown, SI.
    pub mae: Vec<Num>,
    /// Share of evaluated runs whose 90% interval holds the truth, per unknown.
    pub coverage: Vec<Num>,
    /// Runs it was fitted on.
    pub training_runs: usize,
    /// Seconds to simulate its training runs.
    pub simulate_seconds: Num,
    /// Seconds to fit.
    pub fit_seconds: Num,
    /// Seconds to estimate one series.
    pub predict_seconds: Num,
    /// Fitted settings.
    pub settings: Vec<(String, Num)>,
    /// Per evaluated run, in grid order.
    pub predictions: Vec<Prediction>,
}

impl Method {
    /// A fitted setting's value.
    pub fn setting(&self, key: &str) -> Option<f64> {
        self.settings
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, x)| x.0)
    }
}

/// The experiment's results, as far as the report uses them.
#[derive(Debug, Clone, Deserialize)]
pub struct Results {
    /// The family: a built-in's name or a scenario file's path.
    pub family: String,
    /// `clean` or `noisy`.
    pub variant: String,
    /// Seed of all randomness.
    pub seed: u64,
    /// Noise the recordings were made with.
    pub noise: Noise,
    /// Noise the estimators were given.
    pub estimated_noise: Noise,
    /// Names of the unknowns.
    pub unknowns: Vec<String>,
    /// The paper's mean absolute errors, SI.
    pub paper_mae: Vec<Num>,
    /// Grid parameters `[runs][unknowns]`.
    pub grid: Vec<Vec<f64>>,
    /// Ranges of the unknowns.
    pub ranges: Vec<[Num; 2]>,
    /// Which grid runs are templates.
    pub is_template: Vec<bool>,
    /// The template method's σ², rad².
    pub sigma2: Num,
    /// Wall time of the evaluation, s.
    pub seconds: Num,
    /// Per method.
    pub methods: Vec<Method>,
    /// The scenario file's absolute path (a family given by `--scenario`).
    #[serde(default)]
    pub scenario_file: Option<PathBuf>,
    /// Overrides of the scenario's keys.
    #[serde(default)]
    pub sets: Vec<String>,
    /// The particle filter's transition model (older folders: the default, coarse).
    #[serde(default)]
    pub pf_model: Option<String>,
}

/// Where an experiment keeps its results in its output folder.
pub const RESULTS: &str = "results.json";

impl Results {
    /// Reads `dir/results.json`, refusing a folder that is not an experiment's output.
    pub fn read(dir: &Path) -> Result<Results> {
        if dir.is_file() {
            bail!(
                "DIR `{}` is a file: give the output folder of `vibrissa experiment ... --out DIR`",
                dir.display()
            );
        }
        if !dir.is_dir() {
            bail!(
                "DIR `{}`: no such folder (give the output folder of `vibrissa experiment ... --out DIR`)",
                dir.display()
            );
        }
        let path = dir.join(RESULTS);
        if !path.is_file() {
            bail!(
                "DIR `{}` is not an experiment's output folder: it has no {RESULTS} (`vibrissa experiment e2 --out DIR` writes one)",
                dir.display()
            );
        }
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("cannot read `{}`", path.display()))?;
        let value: serde_json::Value = serde_json::from_str(&text)
            .with_context(|| format!("`{}` is not valid JSON", path.display()))?;
        if value.get("max_delay").is_some() {
            bail!(
                "`{}` holds an unknown-start evaluation (`experiment --max-delay`); the report covers experiments run without --max-delay",
                path.display()
            );
        }
        let results: Results = serde_json::from_value(value).with_context(|| {
            format!(
                "`{}` is not the results of `vibrissa experiment`",
                path.display()
            )
        })?;
        results.check(&path)?;
        Ok(results)
    }

    /// Refuses results whose parts do not fit together.
    fn check(&self, path: &Path) -> Result<()> {
        let n = self.grid.len();
        let k = self.unknowns.len();
        if n == 0 {
            bail!("`{}`: field `grid` holds no runs", path.display());
        }
        if k == 0 {
            bail!("`{}`: field `unknowns` names no unknown", path.display());
        }
        if self.is_template.len() != n {
            bail!(
                "`{}`: field `is_template` has {} entries for {n} runs of `grid`",
                path.display(),
                self.is_template.len()
            );
        }
        if let Some(p) = self.grid.iter().position(|p| p.len() != k) {
            bail!(
                "`{}`: grid run {p} has {} values for the {k} unknowns",
                path.display(),
                self.grid[p].len()
            );
        }
        if self.ranges.len() != k {
            bail!(
                "`{}`: field `ranges` has {} entries for {k} unknowns",
                path.display(),
                self.ranges.len()
            );
        }
        let evaluated = self.is_template.iter().filter(|t| !**t).count();
        for m in &self.methods {
            if m.predictions.len() != evaluated || m.mae.len() != k || m.coverage.len() != k {
                bail!(
                    "`{}`: method `{}` has {} predictions, {} errors and {} coverages (expected {evaluated}, {k} and {k})",
                    path.display(),
                    m.name,
                    m.predictions.len(),
                    m.mae.len(),
                    m.coverage.len()
                );
            }
        }
        Ok(())
    }

    /// The position of grid run `k` among the evaluated runs (the predictions' order), if it is
    /// one.
    pub fn evaluated_index(&self, k: usize) -> Option<usize> {
        if self.is_template.get(k).copied().unwrap_or(true) {
            return None;
        }
        Some(self.is_template[..k].iter().filter(|t| !**t).count())
    }

    /// The family's name as a scenario spec to open: the scenario file's absolute path when it
    /// was recorded, else the name as given.
    pub fn family_spec(&self) -> String {
        match &self.scenario_file {
            Some(p) => p.display().to_string(),
            None => self.family.clone(),
        }
    }

    /// `d = 20 mm, v = 0.6 m/s` for grid run `k`.
    pub fn describe(&self, k: usize) -> String {
        self.unknowns
            .iter()
            .zip(&self.grid[k])
            .map(|(u, x)| match u.as_str() {
                "d" => format!("d = {} mm", crate::simulate::short(x * 1e3)),
                "v" => format!("v = {} m/s", crate::simulate::short(*x)),
                _ => format!("{u} = {}", crate::simulate::short(*x)),
            })
            .collect::<Vec<_>>()
            .join(", ")
    }
}
