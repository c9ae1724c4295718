//! Recordings in other units than the contract's: a channel that spans far more than any run of
//! the scenario does.
//!
//! The joint angles are bounded by the geometry of the strike (the object pushes the whisker
//! aside by so much), and the base's moment and forces by the whisker's stiffness; another chain
//! (joint angles scale with the joint spacing), another whisker or other sensors' gains move
//! them by a factor of a few. A column in degrees spans 57 times what it would in radians, one in
//! millinewtons 1000 times: a channel that spans more than [`UNIT_FACTOR`] times the widest span
//! of the scenario's own clean runs is most likely in other units, and the estimates would read
//! it as a whisker bent or loaded far beyond the scenario's, with intervals that do not hold.

use crate::calibrate::UNITS;
use crate::experiment::CHANNELS;
use crate::recording::Recording;
use crate::trained::Short;
use crate::{Family, Result};

/// How many times the widest span of the scenario's clean runs a recorded channel may span
/// before it is taken for a channel in other units.
pub const UNIT_FACTOR: f64 = 20.0;

/// Recordings named in a warning before the rest are counted.
const NAMED: usize = 3;

/// One warning per channel of `needs` that spans more than [`UNIT_FACTOR`] times the widest span
/// of `family`'s clean runs ([`Family::clean_ranges`]) in any of `recordings` (named by
/// `names`): which recordings, by how much, and the units it may be in.
pub fn unit_warnings(
    family: &Family,
    names: &[String],
    recordings: &[Recording],
    needs: &[usize],
) -> Result<Vec<String>> {
    if recordings.is_empty() {
        return Ok(Vec::new());
    }
    let spans: Vec<[f64; 5]> = recordings.iter().map(spans_of).collect();
    let widest = |c: usize| spans.iter().map(|s| s[c]).fold(0.0, f64::max);
    let ranges = family.clean_ranges()?;
    let mut out = Vec::new();
    for &c in needs {
        // A channel the scenario's runs leave flat has no scale to compare with.
        if ranges[c] <= 0.0 || !ranges[c].is_finite() {
            continue;
        }
        let limit = UNIT_FACTOR * ranges[c];
        let over: Vec<usize> = (0..recordings.len())
            .filter(|&r| spans[r][c] > limit)
            .collect();
        if over.is_empty() {
            continue;
        }
        let factor = widest(c) / ranges[c];
        let mut files: Vec<String> = over
            .iter()
            .take(NAMED)
            .map(|&r| format!("`{}`", names[r]))
            .collect();
        if over.len() > NAMED {
            files.push(format!("{} more", over.len() - NAMED));
        }
        out.push(format!(
            "{}: channel {} spans up to {} ({} times the widest span of the scenario's runs, {} {}): \
             is it in {}? ({})",
            files.join(", "),
            CHANNELS[c],
            Short(widest(c)),
            Short(factor),
            Short(ranges[c]),
            UNITS[c],
            UNITS[c],
            hint(c)
        ));
    }
    Ok(out)
}

/// Peak-to-peak span of each channel of a recording (0 for a channel it lacks).
fn spans_of(rec: &Recording) -> [f64; 5] {
    std::array::from_fn(|c| {
        let (lo, hi) = rec.values[c]
            .iter()
            .filter(|v| v.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            });
        if hi >= lo {
            hi - lo
        } else {
            0.0
        }
    })
}

/// The usual other units of channel `c`, and how much larger they read.
fn hint(c: usize) -> &'static str {
    match c {
        0 | 1 => "degrees read 57.3 times larger than radians",
        2 => "N·mm read 1000 times larger than N·m, µN·m a million times",
        _ => "mN read 1000 times larger than N, µN a million times",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::Noise;

    fn recording_of(family: &Family, scale: [f64; 5]) -> Recording {
        let run = family.simulate(&[0.022, 0.8], &Noise::NONE, 1).unwrap();
        let t: Vec<f64> = (0..run.series[0].len())
            .map(|k| k as f64 / family.sample_rate())
            .collect();
        let columns = (0..5)
            .map(|c| Some(run.series[c].iter().map(|v| v * scale[c]).collect()))
            .collect();
        Recording::from_columns(
            "r",
            t,
            columns,
            None,
            &[0, 1, 2, 3, 4],
            crate::recording::Reader::Filter,
        )
        .unwrap()
    }

    #[test]
    fn angles_in_degrees_and_forces_in_millinewtons_are_named_and_si_units_are_not() {
        let e2 = Family::builtin("e2").unwrap();
        let names = vec!["si.csv".to_string(), "deg.csv".to_string()];
        let all = [0, 1, 2, 3, 4];
        let si = recording_of(&e2, [1.0; 5]);
        let deg = recording_of(&e2, [57.3, 57.3, 1.0, 1000.0, 1.0]);
        let w = unit_warnings(&e2, &names, &[si.clone(), deg], &all).unwrap();
        assert_eq!(w.len(), 3, "{w:?}");
        assert!(w[0].starts_with("`deg.csv`: channel theta01") && w[0].contains("degrees"));
        assert!(w[1].contains("channel theta12"), "{w:?}");
        assert!(w[2].contains("channel fx") && w[2].contains("mN"), "{w:?}");
        // The same whisker's recording in SI units, even with gains off by a factor of two.
        let twice = recording_of(&e2, [2.0; 5]);
        assert!(unit_warnings(&e2, &names, &[si, twice], &all)
            .unwrap()
            .is_empty());
    }
}
