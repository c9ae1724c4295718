//! A family of object classes: one scenario family per class, sharing the whiskers and the
//! timing, each with its own pose unknowns.

use super::e3;
use crate::error::{Error, Result};
use crate::experiment::{Noise, Sample};
use crate::family::{ArrayRun, Family};
use rayon::prelude::*;
use std::path::Path;
use vibrissa_core::dynamics::LANES;
use vibrissa_core::rng::Rng;
use vibrissa_core::sim::{self, Scenario};
use vibrissa_io::scenario::WhiskerSources;

/// One object class: its name and the scenario family of its runs (its pose unknowns).
#[derive(Debug, Clone)]
pub struct Class {
    /// Its name (`box`, `circle`, …).
    pub name: String,
    /// Runs of the class at any pose.
    pub family: Family,
}

/// Several object classes struck by the same whiskers: the family of a shape experiment.
#[derive(Debug, Clone)]
pub struct ShapeFamily {
    /// The built-in's name or the file's path.
    name: String,
    /// The classes, in the order of class posteriors.
    classes: Vec<Class>,
}

/// One run of a shape family: its class, pose and each whisker's observed channels.
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeSample {
    /// Index of its class.
    pub class: usize,
    /// The values of its class's unknowns, in order.
    pub params: Vec<f64>,
    /// Each whisker's channels, `[whiskers][CHANNELS][samples]`.
    pub whiskers: Vec<Vec<Vec<f64>>>,
}

impl ShapeSample {
    /// The sensor noise of every channel measured on `runs`, every whisker of every run pooled
    /// ([`crate::noise::estimate_pooled`]).
    pub fn measured_noise(runs: &[ShapeSample]) -> Result<[f64; 5]> {
        let series: Vec<&[Vec<f64>]> = runs
            .iter()
            .flat_map(|s| s.whiskers.iter().map(|w| &w[..]))
            .collect();
        let channels: Vec<usize> = (0..crate::experiment::CHANNELS.len()).collect();
        crate::noise::estimate_pooled(&series, &channels)
    }
}

/// Names of the built-in shape families.
pub const SHAPE_BUILTINS: [&str; 2] = ["e3", "e3-active"];

/// The built-in shape families' names.
pub const BUILTIN_SHAPES: [&str; 2] = ["e3", "e3-active"];

impl ShapeFamily {
    /// A shape family from its classes, checked: at least two, distinct names, the same whiskers
    /// and timing in every class.
    pub fn new(name: &str, classes: Vec<Class>) -> Result<ShapeFamily> {
        let bad = |m: String| Error::Setting(format!("{name}: {m}"));
        if classes.len() < 2 {
            return Err(bad(format!(
                "a shape family needs at least two classes, not {}",
                classes.len()
            )));
        }
        let first = &classes[0];
        for (k, c) in classes.iter().enumerate() {
            if classes[..k].iter().any(|o| o.name == c.name) {
                return Err(bad(format!("the class `{}` is given twice", c.name)));
            }
            if c.family.whisker_names() != first.family.whisker_names() {
                return Err(bad(format!(
                    "class `{}` has the whiskers [{}] where `{}` has [{}]: every class needs \
                     the same array",
                    c.name,
                    c.family.whisker_names().join(", "),
                    first.name,
                    first.family.whisker_names().join(", ")
                )));
            }
            if c.family.samples() != first.family.samples()
                || c.family.sample_rate() != first.family.sample_rate()
            {
                return Err(bad(format!(
                    "class `{}` records {} samples at {} Hz where `{}` records {} at {} Hz",
                    c.name,
                    c.family.samples(),
                    c.family.sample_rate(),
                    first.name,
                    first.family.samples(),
                    first.family.sample_rate()
                )));
            }
        }
        Ok(ShapeFamily {
            name: name.to_string(),
            classes,
        })
    }

    /// A built-in shape family by name (`e3`, `e3-active`), or `None`.
    pub fn builtin(name: &str) -> Option<Result<ShapeFamily>> {
        ShapeFamily::builtin_with(name, &[], None)
    }

    /// A built-in shape family with `key=value` overrides applied to every class's scenario
    /// (`whisker.youngs_modulus=3e9` changes every whisker of the array), and with `whisker`
    /// (a calibrated file's whisker, chain and sensors, say) given to every whisker first; or
    /// `None` if there is no such built-in.
    pub fn builtin_with(
        name: &str,
        sets: &[String],
        whisker: Option<&WhiskerSources>,
    ) -> Option<Result<ShapeFamily>> {
        let classes: &[(&str, &str)] = match name {
            "e3" => &e3::CLASSES,
            "e3-active" => &e3::ACTIVE_CLASSES,
            _ => return None,
        };
        let classes = classes
            .iter()
            .map(|(class, text)| {
                let origin = format!("{name}/{class}");
                Ok(Class {
                    name: class.to_string(),
                    family: Family::open_adopting(&origin, Some(text), sets, whisker)?,
                })
            })
            .collect::<Result<Vec<_>>>();
        Some(classes.and_then(|c| ShapeFamily::new(name, c)))
    }

    /// A shape family: a built-in name, or a TOML file whose `[classes]` table names each
    /// class's scenario file (`box = "box.toml"`, paths relative to the file).
    pub fn open(spec: &str) -> Result<ShapeFamily> {
        ShapeFamily::open_with(spec, &[], None)
    }

    /// [`ShapeFamily::open`] with `whisker` given to every whisker of every class and then
    /// `key=value` overrides applied to every class's scenario.
    pub fn open_with(
        spec: &str,
        sets: &[String],
        whisker: Option<&WhiskerSources>,
    ) -> Result<ShapeFamily> {
        if let Some(f) = ShapeFamily::builtin_with(spec, sets, whisker) {
            return f;
        }
        // A bare word that is no file was probably meant as a built-in name.
        if !Path::new(spec).exists() && !spec.contains(['/', '\\', '.']) {
            return Err(Error::Setting(format!(
                "no shape family `{spec}`: give a built-in one ({}) or a TOML file whose \
                 [classes] table names each class's scenario file",
                BUILTIN_SHAPES.join(", ")
            )));
        }
        let classes = vibrissa_io::scenario::read_classes(Path::new(spec))?
            .into_iter()
            .map(|(name, file)| {
                let file = file.display().to_string();
                Ok(Class {
                    name,
                    family: Family::open_adopting(&file, None, sets, whisker)?,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        ShapeFamily::new(spec, classes)
    }

    /// The built-in's name or the file's path.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The classes, in the order of class posteriors.
    pub fn classes(&self) -> &[Class] {
        &self.classes
    }

    /// The noise training runs are simulated with, given the `sensor` noise measured on (or
    /// stated for) the recordings and the random forces `process` of the family's world: those
    /// forces, and the sensor noise that the measured level leaves beyond their response
    /// ([`Family::training_sensor_noise`] of the first class; every class shares the whiskers).
    pub fn training_noise(&self, sensor: [f64; 5], process: f64) -> Result<Noise> {
        self.classes[0]
            .family
            .training_sensor_noise(&Noise { sensor, process })
    }

    /// The class names, in order.
    pub fn class_names(&self) -> Vec<&str> {
        self.classes.iter().map(|c| c.name.as_str()).collect()
    }

    /// Each class's unknowns' names, in the classes' order.
    pub fn unknown_names(&self) -> Vec<Vec<String>> {
        self.classes
            .iter()
            .map(|c| c.family.unknowns().iter().map(|s| s.to_string()).collect())
            .collect()
    }

    /// The names of the whiskers read (empty for one whisker without a name).
    pub fn whiskers(&self) -> Vec<String> {
        self.classes[0].family.whisker_names()
    }

    /// The same family with `edit` applied to every class's scenario family.
    fn map_classes(&self, edit: impl Fn(&Family) -> Result<Family>) -> Result<ShapeFamily> {
        let classes = self
            .classes
            .iter()
            .map(|c| {
                Ok(Class {
                    name: c.name.clone(),
                    family: edit(&c.family)?,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        ShapeFamily::new(&self.name, classes)
    }

    /// The same family reading only the whiskers `names`.
    pub fn with_whiskers(&self, names: &[&str]) -> Result<ShapeFamily> {
        self.map_classes(|f| f.with_whiskers(names))
    }

    /// The same family with every class's runs randomised when `randomise` is set
    /// ([`Family::randomised_if`]).
    pub fn randomised_if(&self, randomise: bool) -> Result<ShapeFamily> {
        self.map_classes(|f| f.clone().randomised_if(randomise))
    }

    /// The same family with runs of `samples` samples at `rate` Hz (a recording's timing).
    pub fn with_timing(&self, rate: f64, samples: usize) -> Result<ShapeFamily> {
        self.map_classes(|f| f.with_timing(rate, samples))
    }

    /// Output samples per second of its runs, Hz.
    pub fn sample_rate(&self) -> f64 {
        self.classes[0].family.sample_rate()
    }

    /// Samples per run.
    pub fn samples(&self) -> usize {
        self.classes[0].family.samples()
    }

    /// `per_class` draws of every class's unknowns, uniform over each range widened by its
    /// margin when `margins` is set (training runs), else over the range itself.
    pub fn draws(&self, per_class: usize, margins: bool, seed: u64) -> Vec<(usize, Vec<f64>)> {
        let mut out = Vec::with_capacity(per_class * self.classes.len());
        for (k, c) in self.classes.iter().enumerate() {
            let mut rng = Rng::stream(seed, 0x5a9e_0000 + k as u64);
            let ranges = c.family.ranges();
            let widen = c.family.margins();
            for _ in 0..per_class {
                let p = ranges
                    .iter()
                    .zip(&widen)
                    .map(|([lo, hi], [below, above])| {
                        let (lo, hi) = if margins {
                            (lo - below, hi + above)
                        } else {
                            (*lo, *hi)
                        };
                        lo + (hi - lo) * rng.uniform()
                    })
                    .collect();
                out.push((k, p));
            }
        }
        out
    }

    /// `per_class` poses of every class spread evenly over its ranges (not their margins): the
    /// Halton sequence (unknown `j` of the class in the `j`-th prime base, from the first point
    /// after the origin), shifted modulo 1 by a uniform draw of `seed` per class and unknown.
    /// Any stretch of it fills each range with fewer gaps and clumps than as many independent
    /// draws: the bank's runs then lie nearer any pose.
    pub fn even_draws(&self, per_class: usize, seed: u64) -> Vec<(usize, Vec<f64>)> {
        let mut out = Vec::with_capacity(per_class * self.classes.len());
        for (k, c) in self.classes.iter().enumerate() {
            let ranges = c.family.ranges();
            let mut rng = Rng::stream(seed, 0x5a9e_e000 + k as u64);
            let shift: Vec<f64> = ranges.iter().map(|_| rng.uniform()).collect();
            for i in 1..=per_class as u64 {
                let p = ranges
                    .iter()
                    .enumerate()
                    .map(|(j, [lo, hi])| {
                        let u = (radical_inverse(i, HALTON_BASES[j % HALTON_BASES.len()])
                            + shift[j])
                            .fract();
                        lo + (hi - lo) * u
                    })
                    .collect();
                out.push((k, p));
            }
        }
        out
    }

    /// Simulates every draw (in parallel) with `noise` (run `k` seeded by stream `k` of `seed`,
    /// `tick` called once per finished run), leaving out the runs the simulator could not
    /// complete (a divergence) and returning what each of them was; an error if more than one
    /// run in a hundred fails.
    pub fn simulate_completed(
        &self,
        draws: &[(usize, Vec<f64>)],
        noise: &Noise,
        seed: u64,
        tick: &(dyn Fn() + Sync),
    ) -> Result<(Vec<ShapeSample>, Vec<String>)> {
        // A few draws at a time, so that their whiskers' runs step together in lanes (each to
        // the bits it reaches alone).
        let threads = rayon::current_num_threads().max(1);
        let whiskers = self
            .classes
            .iter()
            .map(|c| c.family.whisker_count())
            .max()
            .unwrap_or(1);
        let per_chunk = (LANES / whiskers).max(1);
        let chunk = draws.len().div_ceil(threads).clamp(1, per_chunk);
        let results: Vec<Result<ShapeSample>> = draws
            .par_chunks(chunk)
            .enumerate()
            .flat_map_iter(|(c, part)| {
                let prepared: Vec<Result<Vec<ArrayRun>>> = part
                    .iter()
                    .enumerate()
                    .map(|(j, (class, p))| {
                        let seed = Family::run_seed(seed, c * chunk + j);
                        self.classes[*class].family.array_runs(p, noise, seed)
                    })
                    .collect();
                let scenarios: Vec<Scenario> = prepared
                    .iter()
                    .flatten()
                    .flatten()
                    .map(|r| r.scenario.clone())
                    .collect();
                let mut outs = sim::run_together(&scenarios).into_iter();
                part.iter()
                    .zip(prepared)
                    .map(|((class, p), runs)| {
                        let r = runs.and_then(|runs| {
                            let mine: Vec<_> = outs.by_ref().take(runs.len()).collect();
                            let family = &self.classes[*class].family;
                            Ok(shape_sample(
                                *class,
                                p,
                                family.array_samples(p, &runs, mine)?,
                            ))
                        });
                        tick();
                        r
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        let mut done = Vec::with_capacity(results.len());
        let mut failed = Vec::new();
        for (r, (class, _)) in results.into_iter().zip(draws) {
            match r {
                Ok(s) => done.push(s),
                Err(e @ Error::Run { .. }) => {
                    failed.push(format!("{}: {e}", self.classes[*class].name))
                }
                Err(e) => return Err(e),
            }
        }
        if failed.len() * 100 > draws.len() {
            return Err(Error::Setting(format!(
                "{}: {} of {} runs could not be simulated, the first: {}",
                self.name,
                failed.len(),
                draws.len(),
                failed[0]
            )));
        }
        Ok((done, failed))
    }

    /// One run of a draw.
    pub(super) fn simulate_one(
        &self,
        (class, p): &(usize, Vec<f64>),
        noise: &Noise,
        seed: u64,
    ) -> Result<ShapeSample> {
        let family = &self.classes[*class].family;
        Ok(shape_sample(
            *class,
            p,
            family.simulate_array(p, noise, seed)?,
        ))
    }
}

/// The run of class `class` at `p` from its whiskers' samples, in the array's order.
fn shape_sample(class: usize, p: &[f64], whiskers: Vec<Sample>) -> ShapeSample {
    ShapeSample {
        class,
        params: p.to_vec(),
        whiskers: whiskers.into_iter().map(|s| s.series).collect(),
    }
}

/// Bases of the Halton sequence's coordinates: the first primes (a class with more unknowns
/// than these reuses them, which no built-in class has).
const HALTON_BASES: [u64; 8] = [2, 3, 5, 7, 11, 13, 17, 19];

/// The radical inverse of `i` in base `b`: its digits mirrored about the point, `0.d₀d₁d₂…`
/// (the van der Corput sequence).
fn radical_inverse(mut i: u64, b: u64) -> f64 {
    let (mut x, mut f) = (0.0, 1.0 / b as f64);
    while i > 0 {
        x += f * (i % b) as f64;
        i /= b;
        f /= b as f64;
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_radical_inverse_mirrors_the_digits() {
        assert_eq!(radical_inverse(1, 2), 0.5);
        assert_eq!(radical_inverse(6, 2), 0.375); // 110 → 0.011
        assert!((radical_inverse(5, 3) - 7.0 / 9.0).abs() < 1e-15); // 12 → 0.21
        assert_eq!(radical_inverse(0, 5), 0.0);
    }

    #[test]
    fn even_draws_fill_every_share_of_each_range() {
        let family = ShapeFamily::builtin("e3").unwrap().unwrap();
        let per = 320;
        let draws = family.even_draws(per, 7);
        assert_eq!(draws.len(), per * family.classes.len());
        for (k, c) in family.classes.iter().enumerate() {
            let ranges = c.family.ranges();
            let mine: Vec<&Vec<f64>> = draws
                .iter()
                .filter(|(class, _)| *class == k)
                .map(|(_, p)| p)
                .collect();
            assert_eq!(mine.len(), per);
            for (j, [lo, hi]) in ranges.iter().enumerate() {
                // Each of 16 equal shares of the range holds 20 of the 320 poses, give or take
                // 3 (independent draws stray by 4.4 as one standard deviation, and by about 9
                // in the worst of 16 shares, typically).
                let mut bins = [0usize; 16];
                for p in &mine {
                    assert!(p[j] >= *lo && p[j] <= *hi);
                    bins[(((p[j] - lo) / (hi - lo)) * 16.0).min(15.0) as usize] += 1;
                }
                assert!(
                    bins.iter().all(|&b| (17..=23).contains(&b)),
                    "class {k}, unknown {j}: {bins:?}"
                );
            }
        }
        // Another seed shifts the sequence.
        assert_ne!(family.even_draws(4, 8), family.even_draws(4, 7));
    }
}
