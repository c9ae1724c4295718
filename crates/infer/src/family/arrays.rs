//! A family of several whiskers: which of the array's whiskers it keeps, and its runs on every
//! one of them (one scenario per whisker, stepped together).

use super::Family;
use crate::error::{Error, Result};
use crate::experiment::{Noise, Sample, CHANNELS};
use vibrissa_core::sim::{self, Output, Scenario};

impl Family {
    /// How many whiskers a run of the family records (1 for a scenario of one whisker).
    pub fn whisker_count(&self) -> usize {
        self.mounts.len().max(1)
    }

    /// The array's whiskers kept, in order (empty for a single whisker).
    pub(crate) fn mounts(&self) -> Vec<vibrissa_core::array::Mount> {
        self.mounts.iter().map(|(_, m)| m.clone()).collect()
    }

    /// The names of the array's whiskers kept, in order (empty for a single whisker).
    pub fn whisker_names(&self) -> Vec<String> {
        self.mounts.iter().map(|(_, m)| m.name.clone()).collect()
    }

    /// The same family with only the array's whiskers named in `names` (in the array's order),
    /// or an error naming the whiskers it has.
    pub fn with_whiskers(&self, names: &[&str]) -> Result<Family> {
        let have: Vec<&str> = self.mounts.iter().map(|(_, m)| m.name.as_str()).collect();
        if let Some(n) = names.iter().find(|n| !have.contains(n)) {
            return Err(Error::Setting(format!(
                "{}: no whisker named `{n}` (its whiskers: {})",
                self.name,
                if have.is_empty() {
                    "one, without a name".to_string()
                } else {
                    have.join(", ")
                }
            )));
        }
        if names.is_empty() {
            return Err(Error::Setting(format!(
                "{}: at least one whisker must be kept",
                self.name
            )));
        }
        let mut f = self.clone();
        f.mounts.retain(|(_, m)| names.contains(&m.name.as_str()));
        Ok(f)
    }

    /// The family that estimates from one whisker's recording: for a scenario with an array of
    /// whiskers, the array's whisker `whisker` (required), simulated at its place; for a scenario
    /// of one whisker, the family itself (`whisker` names the recording's columns only).
    /// `filter`: the particle filter models one whisker at the origin, so a whisker mounted
    /// elsewhere (moved, turned, or with a whisker, sensors or base motion of its own) is refused.
    pub fn for_whisker(&self, whisker: Option<&str>, filter: bool) -> Result<Family> {
        if self.mounts.is_empty() {
            return Ok(self.clone());
        }
        let names = self.whisker_names();
        let Some(name) = whisker else {
            return Err(Error::Setting(format!(
                "{} holds an array of whiskers ({}): name the one whose recording is read",
                self.name,
                names.join(", ")
            )));
        };
        let f = self.with_whiskers(&[name])?;
        if filter {
            let (_, m) = &f.mounts[0];
            if m.position != [0.0, 0.0]
                || m.angle != 0.0
                || m.whisker.is_some()
                || m.base.is_some()
                || m.sensors.is_some()
            {
                return Err(Error::Setting(format!(
                    "{}: the particle filter models one whisker at the origin pointing along +x \
                     with the scenario's whisker, sensors and base motion; `{name}` is mounted \
                     otherwise (use another method, or a scenario of that whisker alone)",
                    self.name
                )));
            }
        }
        Ok(f)
    }

    /// Simulates the run at `p` on every whisker of the array (one whisker if the scenario has
    /// no `[[whiskers]]`) with `noise`, seeded by `seed`: the observed channels of each whisker
    /// in the array's order, whisker `k`'s random forces and sensor noise drawn from streams of
    /// `seed` and `k` as `vibrissa simulate` draws them. Each whisker of a randomised family
    /// gets its own draw of whisker and sensors.
    pub fn simulate_array(&self, p: &[f64], noise: &Noise, seed: u64) -> Result<Vec<Sample>> {
        let runs = self.array_runs(p, noise, seed)?;
        let scenarios: Vec<Scenario> = runs.iter().map(|r| r.scenario.clone()).collect();
        self.array_samples(p, &runs, sim::run_together(&scenarios))
    }

    /// The runs that [`Family::simulate_array`] makes at `p`: one scenario per whisker, in the
    /// array's order (to be run, for instance with other runs' in lanes, by
    /// [`sim::run_together`], and made samples by [`Family::array_samples`]).
    pub fn array_runs(&self, p: &[f64], noise: &Noise, seed: u64) -> Result<Vec<ArrayRun>> {
        if self.mounts.is_empty() {
            let (scenario, lead) = self.delayed_scenario(p, 0.0, noise, seed)?;
            return Ok(vec![ArrayRun {
                scenario,
                lead: Some(lead),
                seed,
            }]);
        }
        let s = self.plain_recording(p, 0.0, noise, seed)?;
        // Whisker k's streams (and draws) follow its place in the file's array, whichever are
        // kept.
        Ok(self
            .mounts
            .iter()
            .map(|(k, m)| ArrayRun {
                scenario: self.mounted(&s, *k, m, seed),
                lead: None,
                seed,
            })
            .collect())
    }

    /// The samples of [`Family::simulate_array`] at `p` from the outputs `outs` of its `runs`
    /// ([`Family::array_runs`]), or the error of the first that failed.
    pub fn array_samples(
        &self,
        p: &[f64],
        runs: &[ArrayRun],
        outs: Vec<vibrissa_core::Result<Output>>,
    ) -> Result<Vec<Sample>> {
        runs.iter()
            .zip(outs)
            .map(|(run, out)| {
                let out = out.map_err(|source| self.run_error(p, source))?;
                Ok(match run.lead {
                    Some(lead) => self.delayed_sample(p, 0.0, lead, run.seed, out),
                    None => Sample {
                        series: (0..CHANNELS.len())
                            .map(|c| out.rows.iter().map(|r| r[c + 1]).collect())
                            .collect(),
                        params: p.to_vec(),
                    },
                })
            })
            .collect()
    }
}

/// One whisker's run of [`Family::simulate_array`] (see [`Family::array_runs`]).
#[derive(Debug, Clone)]
pub struct ArrayRun {
    /// Its scenario.
    pub scenario: Scenario,
    /// For a family of one whisker, how far before the run's t = 0 it starts (its series is then
    /// cut to the family's length and given its model error); `None` for a whisker of an array.
    lead: Option<f64>,
    /// The run's seed.
    seed: u64,
}
