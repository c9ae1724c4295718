//! Scenario families: what every estimator is given instead of an experiment's name.
//!
//! A [`Family`] is a scenario file with `[unknowns]` (see `vibrissa_io::scenario`): it knows its
//! unknowns and their ranges, its templates and evaluation grid, how to simulate the run at a
//! parameter vector, and the sample rate and length of its runs. The seed's experiments `e1` and
//! `e2` are built-in families and nothing more. Estimators learn from runs of the family they are
//! given; a family can be re-timed to the rate and length of a recording
//! ([`Family::with_timing`]), so nothing assumes 1 kHz or 151 samples.

use crate::error::{Error, Result};
use crate::experiment::{Noise, Sample, CHANNELS};
use crate::model_error::ModelError;
use crate::randomise::{Around, FittedSpread, Randomisation};
use rayon::prelude::*;
use vibrissa_core::array::Mount;
use vibrissa_core::dynamics::LANES;
use vibrissa_core::objects::Motion;
use vibrissa_core::rng::Rng;
use vibrissa_core::sim::{self, Output, Scenario, SensorNoise};
use vibrissa_core::whisker::WhiskerParams;
use vibrissa_io::scenario::{self, Document, ExperimentRun, FamilySpec};

mod arrays;
mod noise;
pub use arrays::ArrayRun;

/// A scenario family, checked: every unknown's key makes a valid scenario.
#[derive(Debug, Clone)]
pub struct Family {
    /// The built-in's name or the file's path, as the user gave it.
    name: String,
    /// The file, from which runs at any values are made.
    doc: Document,
    /// Unknowns, templates and grid.
    spec: FamilySpec,
    /// The file's own scenario (its values of the unknowns), timing applied.
    base: Scenario,
    /// The experiment box the file names, if any.
    experiment: Option<ExperimentRun>,
    /// Samples per run.
    samples: usize,
    /// The run's duration as the file gives it, s: kept when a recording's timing is applied,
    /// to refuse a sample step that could not sample such a run ([`Family::with_timing`]).
    file_duration: f64,
    /// The sensor noise the file states per channel of [`CHANNELS`] (its `[sensor_noise]`).
    stated_noise: [Option<f64>; 5],
    /// Whether every run gets its own whisker and sensor gains ([`crate::randomise`]).
    randomised: Option<Around>,
    /// Whether the file was written by calibration (it has a `[calibration]` record).
    calibrated: bool,
    /// The calibration's joint uncertainty of whisker and gains, where the record gives it.
    spread: Option<std::sync::Arc<FittedSpread>>,
    /// What the fitted whisker misses of the labelled strikes beyond their noise, per channel of
    /// [`CHANNELS`], where the calibration record gives both ([`Family::fit_residual`]).
    fit_residual: Option<[f64; 5]>,
    /// The file's `[[whiskers]]` kept (empty: the one whisker of `base`, at the origin), each
    /// with its place in the file's array (which seeds its random streams).
    mounts: Vec<(usize, Mount)>,
    /// Longest random start of a run before its approach, s: each run is recorded from a time
    /// drawn uniformly in [0, start_jitter) before it (its length unchanged), so that the contact
    /// falls anywhere between samples, as in a recording with an unknown lead-in (0: never).
    start_jitter: f64,
    /// The folder of labelled strikes a calibrated file was fitted to, where it is found.
    labelled: Option<std::path::PathBuf>,
    /// Residuals of the fitted whisker added to every run ([`Family::with_model_error`]).
    model_error: Option<std::sync::Arc<ModelError>>,
}

/// The fewest samples a recording may hold over the scenario's run (its `duration`): at a
/// longer step the recording cannot show the strike the scenario describes, and the usual cause
/// is a time column in other units than seconds.
pub const MIN_SAMPLES_PER_RUN: usize = 10;

/// Why samples at `rate` Hz cannot read a run of `duration` s (fewer than
/// [`MIN_SAMPLES_PER_RUN`] fall in it), or `None` when they can.
pub fn too_slow(rate: f64, duration: f64) -> Option<String> {
    (MIN_SAMPLES_PER_RUN as f64 / rate > duration).then(|| {
        format!(
            "samples {} s apart ({} Hz): fewer than {MIN_SAMPLES_PER_RUN} would fall in the \
             scenario's run of {} s, too few to read it; `t` must be in seconds (a time in \
             milliseconds reads as a rate 1000 times too low)",
            crate::trained::Short(1.0 / rate),
            crate::trained::Short(rate),
            crate::trained::Short(duration)
        )
    })
}

/// Stream of a run's random start (see the field `start_jitter`), apart from its other streams.
const STREAM_JITTER: u64 = 0x5717_0000;

impl Family {
    /// Opens a family: `spec` is a built-in name (`e1`, `e2`) or the path of a scenario file,
    /// `sets` are `key=value` overrides. The file must have `[unknowns]`, or name an experiment
    /// (whose unknowns it then takes).
    pub fn open(spec: &str, sets: &[String]) -> Result<Family> {
        let (doc, loaded) = scenario::open(spec, sets)?;
        Family::from_loaded(spec, doc, loaded)
    }

    /// As [`Family::open`], for a scenario given as TOML text (`origin` names it in errors).
    pub fn open_str(text: &str, origin: &str, sets: &[String]) -> Result<Family> {
        let (doc, loaded) = scenario::open_str(text, origin, sets)?;
        Family::from_loaded(origin, doc, loaded)
    }

    /// As [`Family::open`] (or [`Family::open_str`] with `text`), every whisker of the scenario
    /// given the whisker, chain and sensors of `whisker` if there is one (a calibrated file's,
    /// say; its calibration record comes with it).
    pub fn open_adopting(
        spec: &str,
        text: Option<&str>,
        sets: &[String],
        whisker: Option<&scenario::WhiskerSources>,
    ) -> Result<Family> {
        let (doc, loaded) = scenario::open_adopting(spec, text, sets, whisker)?;
        let mut family = Family::from_loaded(spec, doc, loaded)?;
        if whisker.is_some() {
            // The record's labelled strikes are of the whisker's own scenario: what the fit
            // missed there says nothing of runs of this one.
            family.labelled = None;
        }
        Ok(family)
    }

    fn from_loaded(
        spec: &str,
        doc: scenario::Document,
        loaded: scenario::Loaded,
    ) -> Result<Family> {
        let Some(family) = loaded.family else {
            return Err(Error::Setting(format!(
                "{}: a scenario for estimation needs an [unknowns] table (e.g. d = [0.015, 0.030]) \
                 or an experiment (experiment = \"e2\")",
                loaded.origin
            )));
        };
        let base = loaded.scenario;
        let samples = samples_of(&base);
        Ok(Family {
            name: spec.to_string(),
            doc,
            spec: family,
            file_duration: base.duration,
            base,
            experiment: loaded.experiment,
            samples,
            stated_noise: loaded.stated_sensor_noise,
            randomised: None,
            calibrated: loaded.calibration.is_some(),
            spread: loaded
                .calibration
                .as_ref()
                .and_then(FittedSpread::of)
                .map(std::sync::Arc::new),
            fit_residual: loaded.calibration.as_ref().and_then(fit_residual),
            mounts: loaded.whiskers.into_iter().enumerate().collect(),
            start_jitter: 0.0,
            labelled: loaded
                .calibration
                .as_ref()
                .and_then(|c| c.labelled.as_deref())
                .and_then(|dir| find_labelled(spec, dir)),
            model_error: None,
        })
    }

    /// A built-in family by name (`e1`, `e2`).
    pub fn builtin(name: &str) -> Result<Family> {
        if scenario::builtin(name).is_none() {
            return Err(Error::Unknown {
                what: "experiment",
                name: name.to_string(),
                choices: scenario::BUILTINS.join(", "),
            });
        }
        Family::open(name, &[])
    }

    /// The built-in's name or the file's path.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The unknowns' names, in order: what estimates and labels call them (each its scenario
    /// key unless the file names it, as `name = "x"`).
    pub fn unknowns(&self) -> Vec<&str> {
        self.spec.names()
    }

    /// The unknowns' scenario keys, in order.
    pub fn keys(&self) -> Vec<&str> {
        self.spec.keys()
    }

    /// The range of each unknown, `[unknowns][lo, hi]`.
    pub fn ranges(&self) -> Vec<[f64; 2]> {
        self.spec.unknowns.iter().map(|u| u.range).collect()
    }

    /// How far training runs may reach beyond each range, `[unknowns][below, above]`.
    pub fn margins(&self) -> Vec<[f64; 2]> {
        self.spec.unknowns.iter().map(|u| u.margin).collect()
    }

    /// Template values per unknown.
    pub fn template_values(&self) -> &[Vec<f64>] {
        &self.spec.templates
    }

    /// Grid values per unknown.
    pub fn grid_values(&self) -> &[Vec<f64>] {
        &self.spec.grid
    }

    /// The template runs' parameters: every combination of the template values, the first
    /// unknown fastest.
    pub fn templates(&self) -> Vec<Vec<f64>> {
        product(&self.spec.templates)
    }

    /// The evaluation grid's parameters: every combination of the grid values, the first
    /// unknown fastest.
    pub fn grid(&self) -> Vec<Vec<f64>> {
        product(&self.spec.grid)
    }

    /// Whether `p` is a template.
    pub fn is_template(&self, p: &[f64]) -> bool {
        p.iter()
            .zip(&self.spec.templates)
            .all(|(x, set)| set.iter().any(|s| (x - s).abs() < 1e-9))
    }

    /// `n` parameter draws, uniform in the ranges and never exactly on the grid.
    pub fn random_params(&self, n: usize, seed: u64) -> Vec<Vec<f64>> {
        let grid = self.grid();
        let ranges = self.ranges();
        let mut rng = Rng::stream(seed, 0x7261_6e64);
        let mut out = Vec::with_capacity(n);
        while out.len() < n {
            let p: Vec<f64> = ranges
                .iter()
                .map(|[lo, hi]| lo + (hi - lo) * rng.uniform())
                .collect();
            let on_grid = grid
                .iter()
                .any(|g| g.iter().zip(&p).all(|(a, b)| (a - b).abs() < 1e-7));
            if !on_grid {
                out.push(p);
            }
        }
        out
    }

    /// Output samples per second of its runs, Hz.
    pub fn sample_rate(&self) -> f64 {
        self.base.sample_rate
    }

    /// Samples per run.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// The file's own scenario (the unknowns at the file's values), timing applied.
    pub fn base(&self) -> &Scenario {
        &self.base
    }

    /// The whisker (for a family that keeps one whisker of an array, that whisker's).
    pub fn whisker(&self) -> &WhiskerParams {
        match &self.mounts[..] {
            [(_, m)] => m.whisker.as_ref().unwrap_or(&self.base.whisker),
            _ => &self.base.whisker,
        }
    }

    /// The experiment box the file names (`experiment = "e1" | "e2"`), with the file's `d` and
    /// `v`, if any. Methods built on the box's geometry (the particle filter, the time-warping
    /// emulator) need one.
    pub fn experiment(&self) -> Option<ExperimentRun> {
        self.experiment
    }

    /// The object's speed `v` (m/s) of the run at `p`: the unknown `v` if the family has one,
    /// else the experiment box's fixed speed; `None` for families without an experiment box.
    pub fn speed_of(&self, p: &[f64]) -> Option<f64> {
        let i = self.unknowns().iter().position(|k| *k == "v");
        match i.and_then(|i| p.get(i)) {
            Some(v) => Some(*v),
            None => self.experiment.map(|e| e.v),
        }
    }

    /// Whether the family is the experiment box with unknowns `d` or `d, v` (in this order):
    /// what methods built on the box's geometry need.
    pub fn is_box_family(&self) -> bool {
        self.experiment.is_some() && matches!(self.unknowns()[..], ["d"] | ["d", "v"])
    }

    /// Refuses a recording's sample rate at which fewer than [`MIN_SAMPLES_PER_RUN`] samples
    /// fall in the run the file describes (its `duration`): such a recording cannot show the
    /// strike, and its time column is most likely in other units than seconds.
    pub fn check_sample_rate(&self, rate: f64) -> Result<()> {
        match too_slow(rate, self.file_duration) {
            Some(why) => Err(Error::Observation(why)),
            None => Ok(()),
        }
    }

    /// The same family with runs of `samples` samples at `rate` Hz (e.g. a recording's).
    pub fn with_timing(&self, rate: f64, samples: usize) -> Result<Family> {
        if !(rate.is_finite() && rate > 0.0) || samples < 2 {
            return Err(Error::Observation(format!(
                "a recording needs a positive sample rate and at least 2 samples, not {rate} Hz \
                 and {samples}"
            )));
        }
        self.check_sample_rate(rate)?;
        let mut f = self.clone();
        f.base.sample_rate = rate;
        f.base.duration = (samples - 1) as f64 / rate;
        f.base.check().map_err(|e| {
            Error::Observation(format!(
                "{}: {e} (timing {rate} Hz, {samples} samples)",
                self.name
            ))
        })?;
        f.samples = samples_of(&f.base);
        Ok(f)
    }

    /// The same family with its runs made by a chain of `segments` segments (the chain that made
    /// a recording, as its metadata says): joint angles are the chain's own, so a method must
    /// learn them from the same chain.
    pub fn with_segments(&self, segments: usize) -> Result<Family> {
        let mut f = self.clone();
        f.base.segments = segments;
        f.base.check().map_err(|e| {
            Error::Observation(format!("{}: {e} (a recording's `segments`)", self.name))
        })?;
        Ok(f)
    }

    /// The family as a recording was made: its timing, and its chain's segments when its
    /// metadata says.
    pub fn for_recording(&self, rec: &crate::recording::Recording) -> Result<Family> {
        let timed = self.with_timing(rec.rate, rec.t.len())?;
        match rec.segments {
            Some(n) if n != timed.segments() => timed.with_segments(n),
            _ => Ok(timed),
        }
    }

    /// `estimates`, one per unknown in order, named by the unknowns' keys.
    pub fn named(&self, estimates: Vec<crate::Estimate>) -> Vec<(String, crate::Estimate)> {
        self.unknowns()
            .iter()
            .map(|n| n.to_string())
            .zip(estimates)
            .collect()
    }

    /// The segment count of the family's chain.
    pub fn segments(&self) -> usize {
        self.base.segments
    }

    /// The same family with every run's whisker and sensor gains drawn from `prior` around the
    /// scenario's (domain randomisation, for training runs: see [`crate::randomise`]).
    pub fn randomised(&self, prior: Randomisation) -> Result<Family> {
        let mut f = self.clone();
        f.randomised = Some(Around::new(&self.base, prior)?);
        Ok(f)
    }

    /// The family with its runs randomised when `randomise` is set, else the family itself: a
    /// calibrated scenario ([`Family::is_calibrated`]) with what calibration left uncertain (the
    /// fit's own spread where its file records the correlations, [`FittedSpread`], else the
    /// narrow prior [`Randomisation::calibrated`]), any other with the default prior of a
    /// whisker known only roughly ([`Randomisation::default`]).
    pub fn randomised_if(self, randomise: bool) -> Result<Family> {
        if randomise && self.is_calibrated() {
            let mut f = self.randomised(Randomisation::calibrated())?;
            if let Some(spread) = f.spread.clone() {
                f.randomised = f.randomised.take().map(|a| a.with_fitted(spread));
            }
            Ok(f)
        } else if randomise {
            self.randomised(Randomisation::default())
        } else {
            Ok(self)
        }
    }

    /// The family whose runs train a discriminative method to read recordings made elsewhere:
    /// [`Family::randomised_if`], and where that randomises around a nominal file (not one
    /// calibration wrote) which leaves `contact_substeps` to its default, contact stepped at
    /// [`crate::resolution::CONTACT_STEP`] or finer in every run it simulates
    /// ([`crate::resolution`]): a whisker known only roughly is another's, recorded by a real
    /// sensor or another engine, whose strikes are nearer a converged integration than to the
    /// default step. A calibrated file carries the setting its fit used.
    pub fn for_recordings(self, randomise: bool) -> Result<Family> {
        let mut f = self.randomised_if(randomise)?;
        if !randomise || f.calibrated {
            return Ok(f);
        }
        if let Some(substeps) = crate::resolution::contact_resolution(&f.doc)? {
            f.doc.set(&format!("contact_substeps={substeps}"))?;
            f.base.integrator.contact_substeps = substeps;
        }
        Ok(f)
    }

    /// The family that `method` (a name of [`crate::methods::NAMES`]) trains on to read
    /// recordings: [`Family::for_recordings`] for the discriminative methods; the particle
    /// filter steps its own coarse chain whatever the file says, where the file's runs only set
    /// the scale of its noise model, so it takes [`Family::randomised_if`] (resolving those runs
    /// moved its pooled error on nine sets both ways, by less than its own seed does).
    pub fn for_method(self, randomise: bool, method: &str) -> Result<Family> {
        if method == "pf" {
            self.randomised_if(randomise)
        } else {
            self.for_recordings(randomise)
        }
    }

    /// Steps per step near contact in the family's runs (`contact_substeps`; 1: none).
    pub fn contact_substeps(&self) -> usize {
        self.base.integrator.contact_substeps
    }

    /// The same family with the scenario's own whisker in every run.
    pub fn nominal(&self) -> Family {
        Family {
            randomised: None,
            model_error: None,
            ..self.clone()
        }
    }

    /// The folder of labelled strikes that calibration fitted this file's whisker to, where it
    /// is found (as the record names it, from the file's own directory or the working one);
    /// `None` on a file calibration did not write.
    pub fn labelled_strikes(&self) -> Option<&std::path::Path> {
        self.labelled.as_deref()
    }

    /// The same family with `residuals` added to every run it simulates (one strike's, drawn
    /// per run: see [`ModelError`]), or none. [`Family::nominal`] drops them.
    pub fn with_model_error(&self, residuals: Option<std::sync::Arc<ModelError>>) -> Family {
        Family {
            model_error: residuals,
            ..self.clone()
        }
    }

    /// The scenario file as read (overrides applied).
    pub fn document(&self) -> &Document {
        &self.doc
    }

    /// The root-mean-square residual of the fitted whisker on the labelled strikes it was fitted
    /// to, less those strikes' own sensor noise (in quadrature), per channel of [`CHANNELS`] and
    /// in its unit: how far the fitted whisker is from the recordings' beyond noise. `None` on a
    /// file calibration did not write, or whose record lacks `rms_after` or `noise` for a channel
    /// it fitted; 0 for a channel the record does not name (the fit did not see it).
    pub fn fit_residual(&self) -> Option<[f64; 5]> {
        self.fit_residual
    }

    /// Whether the scenario was fitted to labelled recordings by calibration (its file has a
    /// `[calibration]` record).
    pub fn is_calibrated(&self) -> bool {
        self.calibrated
    }

    /// The prior of randomised runs, if the family's runs are randomised.
    pub fn randomisation(&self) -> Option<Randomisation> {
        self.randomised.as_ref().map(|a| a.prior)
    }

    /// How randomised runs are drawn, if the family's runs are randomised.
    pub fn around(&self) -> Option<&Around> {
        self.randomised.as_ref()
    }

    /// A digest of the family and its timing, for caches of training runs.
    pub fn digest(&self) -> u64 {
        let mut h = self.doc.digest();
        if let Some(around) = &self.randomised {
            h = (h ^ 0x7a11_d0e5 ^ around.digest()).wrapping_mul(0x0000_0100_0000_01b3);
        }
        for x in [self.base.sample_rate, self.base.duration] {
            h = (h ^ x.to_bits()).wrapping_mul(0x0000_0100_0000_01b3);
        }
        for (k, _) in &self.mounts {
            h = (h ^ (*k as u64 + 1)).wrapping_mul(0x0000_0100_0000_01b3);
        }
        if self.start_jitter > 0.0 {
            h = (h ^ 0x5717 ^ self.start_jitter.to_bits()).wrapping_mul(0x0000_0100_0000_01b3);
        }
        (h ^ self.base.segments as u64).wrapping_mul(0x0000_0100_0000_01b3)
    }

    /// The same family with the random forces of intensity `intensity` (N·s^½·m^-½) stated, as a
    /// scenario's `process_noise` states them: what [`Family::training_noise`] passes to
    /// estimators. The runs simulated with an explicit [`Noise`] are unchanged.
    pub fn with_process_noise(&self, intensity: f64) -> Family {
        let mut f = self.clone();
        f.base.process_noise = intensity.max(0.0);
        f
    }

    /// The same family with every run started a random time in [0, `seconds`) before its
    /// approach, its length unchanged (see the field `start_jitter`): training runs for series
    /// aligned at the contact, whose recordings start at any time.
    pub fn with_start_jitter(&self, seconds: f64) -> Family {
        let mut f = self.clone();
        f.start_jitter = seconds.max(0.0);
        f
    }

    /// The scenario of the run at `p` (one value per unknown), with this family's timing.
    pub fn scenario(&self, p: &[f64]) -> Result<Scenario> {
        if p.len() != self.spec.unknowns.len() {
            return Err(Error::Setting(format!(
                "{}: {} values for the unknowns {}",
                self.name,
                p.len(),
                self.unknowns().join(", ")
            )));
        }
        let values: Vec<(&str, f64)> = self.keys().into_iter().zip(p.iter().copied()).collect();
        let mut s = self.doc.with_values(&values)?.scenario;
        s.sample_rate = self.base.sample_rate;
        s.duration = self.base.duration;
        s.segments = self.base.segments;
        Ok(s)
    }

    /// The scenario file of the run at `p` (the file with its unknowns' keys set to `p`), which
    /// loads and simulates as that run: what another engine needs to reproduce it.
    pub fn document_at(&self, p: &[f64]) -> Result<vibrissa_io::scenario::Document> {
        self.scenario(p)?;
        let mut doc = self.doc.clone();
        for (key, x) in self.keys().iter().zip(p) {
            doc.set(&format!("{key}={x:?}"))?;
        }
        Ok(doc)
    }

    /// Simulates the run at `p` with `noise`, seeded by `seed`.
    pub fn simulate(&self, p: &[f64], noise: &Noise, seed: u64) -> Result<Sample> {
        self.simulate_delayed(p, 0.0, noise, seed)
    }

    /// [`Family::simulate`] recorded from `delay` seconds before the run's t = 0: every object
    /// starts where it was `delay` earlier on its path, and the series is `delay` longer.
    pub fn simulate_delayed(
        &self,
        p: &[f64],
        delay: f64,
        noise: &Noise,
        seed: u64,
    ) -> Result<Sample> {
        let (s, lead) = self.delayed_scenario(p, delay, noise, seed)?;
        let out = sim::run(&s, &mut |_| {}).map_err(|source| self.run_error(p, source))?;
        Ok(self.delayed_sample(p, delay, lead, seed, out))
    }

    /// The scenario that [`Family::simulate_delayed`] runs, and how far before the run's t = 0
    /// it starts (`delay` and the family's random start jitter).
    fn delayed_scenario(
        &self,
        p: &[f64],
        delay: f64,
        noise: &Noise,
        seed: u64,
    ) -> Result<(Scenario, f64)> {
        let jitter = if self.start_jitter > 0.0 {
            self.start_jitter * Rng::stream(seed, STREAM_JITTER).uniform()
        } else {
            0.0
        };
        let s = self.recording_scenario(p, delay + jitter, noise, seed)?;
        Ok((s, delay + jitter))
    }

    /// The sample that [`Family::simulate_delayed`] makes of the run `out` of its scenario
    /// (which started `lead` seconds early): the observed channels, as long as the run without
    /// the jitter, with the family's model error.
    fn delayed_sample(&self, p: &[f64], delay: f64, lead: f64, seed: u64, out: Output) -> Sample {
        let kept =
            ((self.base.duration + delay) * self.base.sample_rate + 1e-9).floor() as usize + 1;
        // Columns 1..=5 of the contract's rows are the observed channels.
        let mut series: Vec<Vec<f64>> = (0..CHANNELS.len())
            .map(|c| out.rows.iter().take(kept).map(|r| r[c + 1]).collect())
            .collect();
        if let Some(me) = &self.model_error {
            me.add(&mut series, self.base.sample_rate, lead, seed);
        }
        Sample {
            series,
            params: p.to_vec(),
        }
    }

    /// The error of a failed run at `p`, naming its parameters.
    pub fn run_error(&self, p: &[f64], source: vibrissa_core::Error) -> Error {
        Error::Run {
            params: self.describe(p),
            source,
        }
    }

    /// The scenario that [`Family::simulate_delayed`] runs: the run at `p` with its randomised
    /// whisker and sensors (if any), recorded from `delay` seconds early, with `noise`, seeded by
    /// `seed`; for a family that keeps one whisker of an array, that whisker's own scenario.
    pub fn recording_scenario(
        &self,
        p: &[f64],
        delay: f64,
        noise: &Noise,
        seed: u64,
    ) -> Result<Scenario> {
        let mut s = self.plain_recording(p, delay, noise, seed)?;
        // One whisker kept of an array: that whisker, at its place, against the objects.
        if let [(k, m)] = &self.mounts[..] {
            return Ok(self.mounted(&s, *k, m, seed));
        }
        if let Some(around) = &self.randomised {
            around.apply(&mut s, seed);
        }
        Ok(s)
    }

    /// Whisker `k` of the array, `mount`, in the run `s` (made by [`Family::plain_recording`]
    /// with `seed`): its own scenario, and for a randomised family its own draw of whisker and
    /// sensors (each whisker of a real array differs from the others).
    fn mounted(&self, s: &Scenario, k: usize, mount: &Mount, seed: u64) -> Scenario {
        let mut m = mount.scenario(s, k);
        if let Some(around) = &self.randomised {
            around.apply(&mut m, Rng::stream(seed, k as u64 + 1).next_u64());
        }
        m
    }

    /// [`Family::recording_scenario`] without the randomised whisker and sensors.
    fn plain_recording(&self, p: &[f64], delay: f64, noise: &Noise, seed: u64) -> Result<Scenario> {
        let mut s = self.scenario(p)?;
        if delay != 0.0 {
            for o in &mut s.objects {
                match &mut o.motion {
                    Motion::Constant {
                        velocity,
                        angular_velocity,
                    } => {
                        o.position[0] -= velocity[0] * delay;
                        o.position[1] -= velocity[1] * delay;
                        o.angle -= *angular_velocity * delay;
                    }
                    _ => {
                        return Err(Error::Setting(format!(
                            "{}: a delayed start needs objects that move at constant velocity",
                            self.name
                        )))
                    }
                }
            }
            s.duration += delay;
        }
        s.process_noise = noise.process;
        let [theta01, theta12, m0, fx, fy] = noise.sensor;
        s.sensor_noise = SensorNoise {
            theta01,
            theta12,
            m0,
            fx,
            fy,
        };
        s.seed = seed;
        Ok(s)
    }

    /// The seed of run `k` of [`Family::simulate_all`] seeded by `seed`.
    pub fn run_seed(seed: u64, k: usize) -> u64 {
        Rng::stream(seed, k as u64).next_u64()
    }

    /// Simulates every run of `params` in parallel; run `k` is seeded by stream `k` of `seed`.
    /// `tick` is called once per finished run (from any thread).
    pub fn simulate_all(
        &self,
        params: &[Vec<f64>],
        noise: &Noise,
        seed: u64,
        tick: &(dyn Fn() + Sync),
    ) -> Result<Vec<Sample>> {
        // Runs that share a whisker step together in lanes (each to the bits it reaches alone):
        // full lane groups, unless there are too few runs to give every core one.
        let threads = rayon::current_num_threads().max(1);
        let chunk = params.len().div_ceil(threads).clamp(1, LANES);
        let chunks: Vec<Vec<Sample>> = params
            .par_chunks(chunk)
            .enumerate()
            .map(|(c, ps)| {
                let prepared = ps
                    .iter()
                    .enumerate()
                    .map(|(j, p)| {
                        let run_seed = Family::run_seed(seed, c * chunk + j);
                        self.delayed_scenario(p, 0.0, noise, run_seed)
                            .map(|(s, lead)| (s, lead, run_seed))
                    })
                    .collect::<Result<Vec<_>>>()?;
                let scenarios: Vec<Scenario> = prepared.iter().map(|(s, _, _)| s.clone()).collect();
                let outs = sim::run_together(&scenarios);
                ps.iter()
                    .zip(prepared)
                    .zip(outs)
                    .map(|((p, (_, lead, run_seed)), out)| {
                        let out = out.map_err(|source| self.run_error(p, source))?;
                        tick();
                        Ok(self.delayed_sample(p, 0.0, lead, run_seed, out))
                    })
                    .collect::<Result<Vec<_>>>()
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(chunks.into_iter().flatten().collect())
    }

    /// `key = value, …` of a parameter vector, for messages.
    pub fn describe(&self, p: &[f64]) -> String {
        self.unknowns()
            .iter()
            .zip(p)
            .map(|(k, x)| format!("{k} = {x}"))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Samples of a run of `s`: t = 0, 1/rate, … up to its duration.
fn samples_of(s: &Scenario) -> usize {
    (s.duration * s.sample_rate + 1e-9).floor() as usize + 1
}

/// Every combination of `values` (one list per unknown), the first fastest.
fn product(values: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let mut out = vec![Vec::new()];
    for list in values {
        out = list
            .iter()
            .flat_map(|x| {
                out.iter().map(move |p| {
                    let mut q = p.clone();
                    q.push(*x);
                    q
                })
            })
            .collect();
    }
    out
}

/// The folder `dir` of a calibration record, for the scenario `spec`: an absolute path as it
/// is, a relative one from the scenario file's own directory (where `vibrissa calibrate` writes
/// it relative to) or else from the working directory; `None` where none is a folder.
fn find_labelled(spec: &str, dir: &str) -> Option<std::path::PathBuf> {
    let given = std::path::Path::new(dir);
    let beside = std::path::Path::new(spec)
        .parent()
        .filter(|_| given.is_relative())
        .map(|p| p.join(given));
    beside
        .into_iter()
        .chain(std::iter::once(given.to_path_buf()))
        .find(|p| p.is_dir())
}

/// [`Family::fit_residual`] from a calibration record: per channel √(rms_after² − noise²),
/// floored at 0; 0 where the record names neither, `None` where it names one without the other,
/// a value that is not finite and non-negative, or no channel at all.
fn fit_residual(record: &vibrissa_io::scenario::Calibration) -> Option<[f64; 5]> {
    let after = record.rms_after.to_array();
    let noise = record.noise.to_array();
    let mut out = [0.0; 5];
    let mut named = false;
    for c in 0..5 {
        match (after[c], noise[c]) {
            (None, None) => {}
            (Some(r), Some(n)) if r.is_finite() && n.is_finite() && r >= 0.0 && n >= 0.0 => {
                out[c] = (r * r - n * n).max(0.0).sqrt();
                named = true;
            }
            _ => return None,
        }
    }
    named.then_some(out)
}

#[cfg(test)]
mod tests {
    #[test]
    fn each_whisker_of_a_randomised_array_gets_its_own_draw() {
        let text = "duration = 0.01\n[[whiskers]]\nname = \"a\"\n[[whiskers]]\nname = \"b\"\nposition = [0.0, 0.002]\n[[objects]]\nshape = \"circle\"\nradius = 0.002\nposition = [0.02, -0.01]\n[unknowns]\n\"objects.0.position.0\" = [0.015, 0.025]\n";
        let family = Family::open_str(text, "pair", &[])
            .unwrap()
            .randomised_if(true)
            .unwrap();
        let s = family
            .plain_recording(&[0.02], 0.0, &Noise::NONE, 7)
            .unwrap();
        let (a, b) = (&family.mounts[0], &family.mounts[1]);
        let (wa, wb) = (
            family.mounted(&s, a.0, &a.1, 7).whisker,
            family.mounted(&s, b.0, &b.1, 7).whisker,
        );
        assert_ne!(wa.youngs_modulus, wb.youngs_modulus);
        assert_ne!(wa.youngs_modulus, s.whisker.youngs_modulus);
        // The same seed gives the same draw.
        assert_eq!(
            family.mounted(&s, a.0, &a.1, 7).whisker.youngs_modulus,
            wa.youngs_modulus
        );
    }

    #[test]
    fn training_noise_leaves_out_what_the_random_forces_show() {
        let e2 = Family::builtin("e2").unwrap();
        let measured = Noise {
            sensor: [6e-3, 1.5e-2, 2.5e-6, 3.5e-4, 2e-4],
            process: 2e-5,
        };
        let t = e2.training_sensor_noise(&measured).unwrap();
        // The forces' response is a large part of the base forces' level, a small part of the
        // angles'.
        assert!(t.sensor[3] < 0.9 * measured.sensor[3], "{:?}", t.sensor);
        assert!(t.sensor[0] > 0.9 * measured.sensor[0], "{:?}", t.sensor);
        assert!(t.sensor.iter().all(|x| x.is_finite() && *x >= 0.0));
        assert_eq!(t.process, measured.process);
        // Without random forces the measured level is the sensor noise.
        let quiet = Noise {
            process: 0.0,
            ..measured
        };
        assert_eq!(e2.training_sensor_noise(&quiet).unwrap(), quiet);
    }
    use super::*;

    #[test]
    fn grids_and_templates_match_the_restated_experiments() {
        let e1 = Family::builtin("e1").unwrap();
        assert_eq!(e1.grid().len(), 16);
        assert_eq!(e1.grid().iter().filter(|p| e1.is_template(p)).count(), 3);
        let e2 = Family::builtin("e2").unwrap();
        let grid = e2.grid();
        assert_eq!(grid.len(), 80);
        assert_eq!(grid.iter().filter(|p| e2.is_template(p)).count(), 9);
        // Distance fastest, as the seed's tables run.
        assert_eq!(grid[0], [0.015, 0.3]);
        assert_eq!(grid[1], [0.016, 0.3]);
        assert_eq!(grid[16], [0.015, 0.6]);
        assert_eq!(e2.templates().len(), 9);
        assert_eq!((e2.samples(), e2.sample_rate()), (151, 1000.0));
        assert!(Family::builtin("e3").is_err());
    }

    #[test]
    fn random_draws_stay_in_range_and_off_the_grid() {
        let e2 = Family::builtin("e2").unwrap();
        for p in e2.random_params(200, 3) {
            assert!((0.015..=0.030).contains(&p[0]));
            assert!((0.3..=1.5).contains(&p[1]));
        }
        assert_eq!(e2.random_params(5, 3), e2.random_params(5, 3));
    }

    #[test]
    fn a_retimed_family_samples_its_runs_at_the_new_rate() {
        let e2 = Family::builtin("e2").unwrap();
        let fast = e2.with_timing(2000.0, 301).unwrap();
        assert_eq!(fast.samples(), 301);
        assert_ne!(fast.digest(), e2.digest());
        let run = fast.simulate(&[0.02, 0.6], &Noise::NONE, 1).unwrap();
        assert_eq!(run.series[1].len(), 301);
        // Every second sample of the 2 kHz run is the 1 kHz run's (same physics, same dt).
        let slow = e2.simulate(&[0.02, 0.6], &Noise::NONE, 1).unwrap();
        for k in 0..151 {
            assert!((run.series[1][2 * k] - slow.series[1][k]).abs() < 1e-12);
        }
        assert!(e2.with_timing(0.0, 10).is_err());
        assert!(e2.with_timing(1000.0, 1).is_err());
    }

    #[test]
    fn a_rate_too_low_for_the_scenario_s_run_is_refused_whatever_the_retiming() {
        // e2's run lasts 0.15 s: 100 Hz puts 15 samples in it, 60 Hz 9, and a time column in
        // milliseconds (1 Hz) one.
        let e2 = Family::builtin("e2").unwrap();
        assert!(e2.with_timing(100.0, 16).is_ok());
        for rate in [60.0, 1.0] {
            let e = e2.with_timing(rate, 151).unwrap_err().to_string();
            assert!(e.contains("`t` must be in seconds"), "{e}");
            assert!(e.contains("0.150 s"), "{e}");
        }
        // A family already retimed to a long recording still judges by the file's run.
        let long = e2.with_timing(1000.0, 2001).unwrap();
        assert!(long.with_timing(50.0, 101).is_err());
        assert!(long.check_sample_rate(1000.0).is_ok());
    }

    #[test]
    fn recordings_made_elsewhere_are_read_with_contact_resolved() {
        let e2 = Family::builtin("e2").unwrap();
        assert_eq!(e2.contact_substeps(), 1);
        // Told the whisker exactly: the file's step.
        let exact = e2.clone().for_recordings(false).unwrap();
        assert_eq!(exact.contact_substeps(), 1);
        assert_eq!(exact.digest(), e2.digest());
        // Known only roughly: contact at 20 µs (5 substeps of the 0.1 ms step), in the runs too.
        let rough = e2.clone().for_recordings(true).unwrap();
        assert_eq!(rough.contact_substeps(), 5);
        assert_eq!(
            rough
                .scenario(&[0.02, 0.6])
                .unwrap()
                .integrator
                .contact_substeps,
            5
        );
        assert_ne!(
            rough.digest(),
            e2.clone().randomised_if(true).unwrap().digest()
        );
        // The same strike simulated both ways differs (the default step is not converged).
        let fine = rough
            .nominal()
            .simulate(&[0.02, 0.9], &Noise::NONE, 1)
            .unwrap();
        let coarse = e2.simulate(&[0.02, 0.9], &Noise::NONE, 1).unwrap();
        let gap = fine.series[0]
            .iter()
            .zip(&coarse.series[0])
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(gap > 1e-6, "{gap}");
        // The filter keeps the file's step; the other methods take the resolved family.
        let for_pf = e2.clone().for_method(true, "pf").unwrap();
        assert_eq!(for_pf.contact_substeps(), 1);
        assert!(for_pf.randomisation().is_some());
        let for_krr = e2.clone().for_method(true, "krr-invariant").unwrap();
        assert_eq!(for_krr.digest(), rough.digest());
        // A file that names the setting, or a step already fine, is read as it says.
        for set in ["contact_substeps=1", "dt=1e-5"] {
            let named = Family::open("e2", &[set.to_string()]).unwrap();
            let kept = named.clone().for_recordings(true).unwrap();
            assert_eq!(kept.contact_substeps(), 1, "{set}");
        }
    }
}
