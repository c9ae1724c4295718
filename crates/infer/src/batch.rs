//! What `vibrissa estimate` and the Python `vibrissa.estimate` do with a batch of recordings,
//! written once for both: every recording estimated by a discriminative method (trained once per
//! timing, noise level and lead-in), and the choice, when the user left it open, to entertain
//! whiskers drawn around a scenario that most of the recordings defy.
//!
//! The front ends read the recordings, measure their noise ([`crate::recording::batch_noise`])
//! and lead-ins ([`crate::lead_in::batch_leads`]), then call [`discriminative`] (which fills in
//! the values missing for the method, [`fill_missing`]) or [`filter_family`]; what they print is
//! passed to `log`.

use crate::check::{defies, unexplained};
use crate::error::{Error, Result};
use crate::method::{Budget, Estimate};
use crate::methods;
use crate::recording::Recording;
use crate::trained::{defied_by, null_unexplained, Trained};
use crate::Family;
use std::time::Instant;

/// Each recording's estimates (one per unknown) and the seconds they took.
pub type Estimates = Vec<(Vec<Estimate>, f64)>;

/// How a front end names the switches its messages point to.
#[derive(Debug, Clone, Copy)]
pub struct Switches {
    /// What makes the model check say where (e.g. `--check`).
    pub check: &'static str,
    /// What asks for whiskers drawn around the scenario (e.g. `--randomise`).
    pub randomise: &'static str,
    /// What keeps the scenario's whisker (e.g. `--no-randomise`).
    pub keep: &'static str,
}

/// The command line's switches.
pub const COMMAND_LINE: Switches = Switches {
    check: "vibrissa estimate --check",
    randomise: "--randomise",
    keep: "--no-randomise",
};

/// The Python module's arguments.
pub const PYTHON: Switches = Switches {
    check: "check=True",
    randomise: "randomise=True",
    keep: "randomise=False",
};

/// Every recording's estimate by the method `name` and the seconds it took, trained on `family`
/// (by `trained`, once per timing, noise level and lead-in) with each recording's noise
/// `levels` and lead-in `leads` (samples). `names` name the recordings in errors.
#[allow(clippy::too_many_arguments)]
pub fn estimate_each(
    family: &Family,
    names: &[String],
    recordings: &[Recording],
    levels: &[[f64; 5]],
    leads: &[usize],
    name: &str,
    seed: u64,
    trained: &mut Trained,
    log: &mut dyn FnMut(String),
) -> Result<Estimates> {
    let mut out = Vec::with_capacity(recordings.len());
    for (((file, rec), level), &lead) in names.iter().zip(recordings).zip(levels).zip(leads) {
        let method = trained.get(family, rec, level, name, seed, lead, log)?;
        let start = Instant::now();
        let est = method.predict(&rec.values).map_err(|e| {
            // Said once: "unusable observation: estimating from `f`: <why>".
            let why = match e {
                Error::Observation(why) => why,
                e => e.to_string(),
            };
            Error::Observation(format!("estimating from `{file}`: {why}"))
        })?;
        out.push((est, start.elapsed().as_secs_f64()));
    }
    Ok(out)
}

/// The discriminative method `name`'s estimates of a batch ([`estimate_each`]), and the family
/// they were trained on. With `auto` (the user chose neither to randomise nor to keep the
/// scenario's whisker), a scenario that is neither calibrated nor randomised and that the
/// recordings defy at their estimates and near them ([`unexplained`], [`defies`]) is not their
/// whisker: the batch is estimated again on whiskers drawn around it, with a warning. Missing
/// values are filled in first ([`fill_missing`], with a warning). Estimates
/// held at an end of their range are warned of ([`at_range_ends`]), and so are channels that
/// look recorded with the opposite sign ([`crate::signs::sign_warnings`]). `trained` ends with
/// the methods that made the estimates, and counts the training of both passes.
#[allow(clippy::too_many_arguments)]
pub fn discriminative(
    family: &Family,
    names: &[String],
    recordings: &[Recording],
    levels: &[[f64; 5]],
    leads: &[usize],
    name: &str,
    seed: u64,
    auto: bool,
    switches: &Switches,
    trained: &mut Trained,
    log: &mut dyn FnMut(String),
) -> Result<(Family, Estimates)> {
    // Whole series: values a tracker missed are filled in (the noise was measured without them).
    let needs = methods::by_name(name)?.channels();
    let (filled, gaps) = fill_missing(names, recordings, &needs);
    for w in gaps {
        log(format!("warning: {w}"));
    }
    let recordings = &filled[..];
    let (family, estimates) = trusted_or_drawn(
        family, names, recordings, levels, leads, name, seed, auto, switches, trained, log,
    )?;
    for w in at_range_ends(&family, names, &estimates, switches) {
        log(format!("warning: {w}"));
    }
    let flipped = crate::signs::sign_warnings(
        &family, names, recordings, levels, leads, &estimates, name, seed, trained, log,
    )?;
    for w in flipped {
        log(format!("warning: {w}"));
    }
    Ok((family, estimates))
}

/// [`discriminative`] without its warnings of estimates at the ends of their ranges.
#[allow(clippy::too_many_arguments)]
fn trusted_or_drawn(
    family: &Family,
    names: &[String],
    recordings: &[Recording],
    levels: &[[f64; 5]],
    leads: &[usize],
    name: &str,
    seed: u64,
    auto: bool,
    switches: &Switches,
    trained: &mut Trained,
    log: &mut dyn FnMut(String),
) -> Result<(Family, Estimates)> {
    let estimates = estimate_each(
        family, names, recordings, levels, leads, name, seed, trained, log,
    )?;
    let method = methods::by_name(name)?;
    if !(auto && family.randomisation().is_none() && method.budget() == Budget::Free) {
        return Ok((family.clone(), estimates));
    }
    let points: Vec<Vec<Estimate>> = estimates.iter().map(|(e, _)| e.clone()).collect();
    let recs: Vec<&Recording> = recordings.iter().collect();
    let needs = method.channels();
    let defied = unexplained(&family.nominal(), &recs, &points, levels, &needs, leads);
    let verdict = defies(defied, recordings.len(), || {
        null_unexplained(
            trained,
            family,
            &recordings[0],
            &levels[0],
            leads[0],
            name,
            seed,
            log,
        )
    });
    if !verdict.defiant {
        return Ok((family.clone(), estimates));
    }
    log(format!(
        "warning: the scenario {} ({} says where): their whisker is not the scenario's, and \
         estimates that trust it would be wrong with narrow intervals; estimating again on \
         whiskers drawn around it, as {} does (calibrate on labelled strikes for better \
         estimates; {} keeps the scenario's whisker)",
        verdict.describe(" at their estimates"),
        switches.check,
        switches.randomise,
        switches.keep
    ));
    let randomised = family.clone().for_recordings(true)?;
    let mut again = Trained::default();
    let estimates = estimate_each(
        &randomised,
        names,
        recordings,
        levels,
        leads,
        name,
        seed,
        &mut again,
        log,
    )?;
    // What trained the estimates returned, with the time and runs of both passes.
    again.seconds += trained.seconds;
    again.runs += trained.runs;
    *trained = again;
    Ok((randomised, estimates))
}

/// Share of an unknown's range within which an estimate counts as held at its end.
const RANGE_END: f64 = 1e-9;

/// A warning for every estimate that a discriminative method held at an end of its unknown's
/// range. These methods read nothing beyond the range they were trained over (their outputs are
/// clipped to it), so an object beyond it (a box farther than the range's far end, one that never
/// touched the whisker) is read as the end itself, with an interval about it that need not hold
/// the truth.
pub fn at_range_ends(
    family: &Family,
    names: &[String],
    estimates: &Estimates,
    switches: &Switches,
) -> Vec<String> {
    let unknowns = family.unknowns();
    let ranges = family.ranges();
    let mut out = Vec::new();
    for (name, (est, _)) in names.iter().zip(estimates) {
        for ((unknown, [lo, hi]), e) in unknowns.iter().zip(&ranges).zip(est) {
            let tol = RANGE_END * (hi - lo);
            let end = if e.mean <= lo + tol {
                "lower"
            } else if e.mean >= hi - tol {
                "upper"
            } else {
                continue;
            };
            out.push(format!(
                "`{name}`: the estimate of {unknown} ({}) is the {end} end of its range [{lo}, \
                 {hi}], beyond which the method reads nothing: the object may lie outside the \
                 range (or have missed the whisker), and the interval need not hold it; widen \
                 the range (the scenario's [unknowns]) or check the scenario ({})",
                e.mean, switches.check
            ));
        }
    }
    out
}

/// A warning for every recording that shows nothing beyond its sensor noise
/// ([`crate::noise::shows_signal`]): no strike to read, so that any estimate of it is the
/// method's reading of noise, and its interval need not hold the object.
pub fn without_strikes(
    names: &[String],
    recordings: &[Recording],
    levels: &[[f64; 5]],
    needs: &[usize],
) -> Vec<String> {
    names
        .iter()
        .zip(recordings)
        .zip(levels)
        .filter(|((_, rec), level)| crate::noise::shows_signal(rec, level, needs) == Some(false))
        .map(|((name, _), _)| {
            let read: Vec<&str> = needs.iter().map(|&c| crate::CHANNELS[c]).collect();
            format!(
                "`{name}`: nothing the method reads ({}) moves beyond its sensor noise: the \
                 object missed the whisker, stayed beyond its reach or barely touched its tip, \
                 and the estimate reads noise, with an interval that need not hold the object",
                read.join(", ")
            )
        })
        .collect()
}

/// The recordings with the missing (`NaN`) values of the channels `needs` filled in for a
/// discriminative method ([`Recording::filled`]), and a warning for each recording that missed
/// any. Called once the noise has been estimated from the values recorded (an interpolated
/// stretch has no noise to measure).
fn fill_missing(
    names: &[String],
    recordings: &[Recording],
    needs: &[usize],
) -> (Vec<Recording>, Vec<String>) {
    let mut warnings = Vec::new();
    let filled = names
        .iter()
        .zip(recordings)
        .map(|(name, rec)| {
            let (filled, gaps) = rec.filled(needs);
            if !gaps.is_empty() {
                let each: Vec<String> = gaps
                    .iter()
                    .map(|g| {
                        format!(
                            "{} {} (the longest gap {} sample{}, {} ms)",
                            crate::CHANNELS[g.channel],
                            g.missing,
                            g.longest,
                            if g.longest == 1 { "" } else { "s" },
                            (1e6 * g.longest as f64 / rec.rate).round() / 1e3
                        )
                    })
                    .collect();
                warnings.push(format!(
                    "`{name}`: missing values filled in by linear interpolation for the \
                     discriminative method: {}; its interval does not count what the \
                     interpolation misses (the filter, --method pf, skips them instead)",
                    each.join(", ")
                ));
            }
            filled
        })
        .collect();
    (filled, warnings)
}

/// The family the particle filter runs on for a batch. With `auto` (the user chose neither to
/// randomise nor to keep the scenario's whisker), a scenario that is neither calibrated nor
/// randomised and that the recordings defy at `krr`'s estimates and near them ([`defied_by`]) is
/// not their whisker: the filter then entertains whiskers drawn around it, with a warning.
#[allow(clippy::too_many_arguments)]
pub fn filter_family(
    family: &Family,
    recordings: &[Recording],
    levels: &[[f64; 5]],
    leads: &[usize],
    seed: u64,
    auto: bool,
    switches: &Switches,
    log: &mut dyn FnMut(String),
) -> Result<Family> {
    if !(auto && family.randomisation().is_none()) {
        return Ok(family.clone());
    }
    log("checking that the scenario explains the recordings, at krr's estimates…".into());
    let verdict = defied_by(family, recordings, levels, leads, seed, log)?;
    if verdict.looked == 0 && !recordings.is_empty() {
        // Nothing could be checked: the scenario's whisker is not trusted unchecked.
        log(format!(
            "warning: the scenario could not be checked against the recordings (the check reads \
             krr's estimates, which need every channel, and each recording lacks one or holds \
             one flat): the filter entertains whiskers drawn around it, as {} does ({} keeps \
             the scenario's whisker)",
            switches.randomise, switches.keep
        ));
        return family.clone().randomised_if(true);
    }
    if !verdict.defiant {
        return Ok(family.clone());
    }
    log(format!(
        "warning: the scenario {} ({} says where): their whisker is not the scenario's, and a \
         filter that trusts it would be wrong with narrow intervals; it entertains whiskers \
         drawn around it instead, as {} does (calibrate on labelled strikes for better \
         estimates; {} keeps the scenario's whisker)",
        verdict.describe(""),
        switches.check,
        switches.randomise,
        switches.keep
    ));
    family.clone().randomised_if(true)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::Noise;

    /// Sensor noise of the test's recordings, per channel.
    const LEVEL: [f64; 5] = [1e-3, 1e-3, 1e-8, 1e-6, 1e-6];

    /// `e2` runs of `family` at `points` with sensor noise [`LEVEL`], as recordings.
    fn recordings(family: &Family, points: &[[f64; 2]]) -> Vec<Recording> {
        let noise = Noise {
            sensor: LEVEL,
            process: 0.0,
        };
        points
            .iter()
            .enumerate()
            .map(|(k, p)| {
                let s = family.simulate(p, &noise, k as u64).unwrap();
                Recording::at_rate(s.series, family.sample_rate())
            })
            .collect()
    }

    #[test]
    fn recordings_with_missing_values_still_defy_a_scenario_that_is_not_their_whisker() {
        // The filter skips missing values, but its check reads `krr`'s estimates, which need
        // whole series: with three samples missing in every channel, a stiffer whisker's batch
        // must still send the filter to whiskers drawn around the scenario.
        let e2 = Family::builtin("e2").unwrap();
        let points = [[0.018, 0.5], [0.024, 1.1], [0.027, 0.8]];
        let sets = [
            "whisker.youngs_modulus=4.5e9",
            "sensors.theta01.gain=0.8",
            "sensors.theta12.gain=0.8",
        ]
        .map(String::from);
        let mut foreign = recordings(&Family::open("e2", &sets).unwrap(), &points);
        for rec in &mut foreign {
            for channel in &mut rec.values {
                channel[60..63].fill(f64::NAN);
            }
        }
        let (levels, leads) = (vec![LEVEL; points.len()], vec![0; points.len()]);
        let mut log = Vec::new();
        let family = filter_family(
            &e2,
            &foreign,
            &levels,
            &leads,
            1,
            true,
            &COMMAND_LINE,
            &mut |m| log.push(m),
        )
        .unwrap();
        assert!(family.randomisation().is_some(), "{log:?}");
    }

    #[test]
    fn a_scenario_the_check_cannot_read_against_is_not_trusted_unchecked() {
        // The scenario's own runs, whose force sensors recorded nothing (one flat m0) or were
        // not recorded at all: `krr`, which the check reads, needs every channel, so nothing is
        // checked, and the filter entertains whiskers drawn around the scenario.
        let e2 = Family::builtin("e2").unwrap();
        let points = [[0.018, 0.5], [0.024, 1.1]];
        let mut own = recordings(&e2, &points);
        own[0].values[2].fill(1e30);
        own[1].values[2].clear();
        let (levels, leads) = (vec![LEVEL; points.len()], vec![0; points.len()]);
        let mut log = Vec::new();
        let family = filter_family(
            &e2,
            &own,
            &levels,
            &leads,
            1,
            true,
            &COMMAND_LINE,
            &mut |m| log.push(m),
        )
        .unwrap();
        assert!(family.randomisation().is_some(), "{log:?}");
        assert!(
            log.iter().any(|m| m.contains("could not be checked")),
            "{log:?}"
        );
    }

    #[test]
    fn the_scenario_s_own_recordings_keep_it_and_a_stiffer_whisker_s_defy_it() {
        let e2 = Family::builtin("e2").unwrap();
        let points = [[0.018, 0.5], [0.024, 1.1], [0.027, 0.8]];
        let names: Vec<String> = (0..points.len()).map(|k| format!("r{k}")).collect();
        let levels = vec![LEVEL; points.len()];
        let leads = vec![0; points.len()];
        let mut trained = Trained::default();
        // The batch `recs` estimated by `knn` on `e2`: the family used, the estimates and the
        // messages.
        let mut run = |recs: &[Recording], auto: bool, switches: &Switches| {
            let mut log = Vec::new();
            let (family, est) = discriminative(
                &e2,
                &names,
                recs,
                &levels,
                &leads,
                "knn",
                1,
                auto,
                switches,
                &mut trained,
                &mut |m| log.push(m),
            )
            .unwrap();
            assert_eq!(est.len(), recs.len());
            (family, log)
        };
        let (family, log) = run(&recordings(&e2, &points), true, &COMMAND_LINE);
        assert!(family.randomisation().is_none(), "{log:?}");
        assert!(!log.iter().any(|m| m.starts_with("warning")), "{log:?}");

        // A whisker half again as stiff, with the angle sensors' gain off by a fifth.
        let sets = [
            "whisker.youngs_modulus=4.5e9",
            "sensors.theta01.gain=0.8",
            "sensors.theta12.gain=0.8",
        ]
        .map(String::from);
        let foreign = recordings(&Family::open("e2", &sets).unwrap(), &points);
        let (family, log) = run(&foreign, true, &PYTHON);
        assert!(family.randomisation().is_some(), "{log:?}");
        let warning = log.iter().find(|m| m.starts_with("warning")).unwrap();
        assert!(warning.contains("randomise=True"), "{warning}");

        // Asked to keep the scenario's whisker: no second pass.
        let (family, _) = run(&foreign, false, &COMMAND_LINE);
        assert!(family.randomisation().is_none());
    }

    #[test]
    fn an_estimate_held_at_an_end_of_its_range_is_warned_of() {
        let e2 = Family::builtin("e2").unwrap();
        let [[d_lo, d_hi], [v_lo, _]] = [e2.ranges()[0], e2.ranges()[1]];
        let names = ["inside", "far", "slow"].map(String::from);
        let est = |d: f64, v: f64| {
            (
                vec![Estimate::normal(d, 1e-3), Estimate::normal(v, 0.05)],
                0.0,
            )
        };
        let estimates = vec![
            est(0.5 * (d_lo + d_hi), 0.9),
            est(d_hi, 0.9),
            est(0.02, v_lo),
        ];
        let warnings = at_range_ends(&e2, &names, &estimates, &COMMAND_LINE);
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(
            warnings[0].starts_with("`far`: the estimate of d"),
            "{}",
            warnings[0]
        );
        assert!(warnings[0].contains("upper end"), "{}", warnings[0]);
        assert!(
            warnings[1].starts_with("`slow`: the estimate of v"),
            "{}",
            warnings[1]
        );
        assert!(warnings[1].contains("lower end"), "{}", warnings[1]);
        assert!(
            warnings[1].contains("vibrissa estimate --check"),
            "{}",
            warnings[1]
        );
        // Just inside the range: no warning.
        let near = vec![est(d_hi - 1e-6, 0.9)];
        assert!(at_range_ends(&e2, &names[..1], &near, &PYTHON).is_empty());
    }

    #[test]
    fn a_box_beyond_the_range_is_read_as_the_range_s_end_with_a_warning() {
        // The box 6 mm beyond the whisker's tip: it never touches, and `krr` reads the range's
        // far end.
        let e2 = Family::builtin("e2").unwrap();
        let recs = recordings(&e2, &[[0.036, 0.9]]);
        let names = vec!["miss".to_string()];
        let mut log = Vec::new();
        let (_, est) = discriminative(
            &e2,
            &names,
            &recs,
            &[LEVEL],
            &[0],
            "krr",
            1,
            false,
            &COMMAND_LINE,
            &mut Trained::default(),
            &mut |m| log.push(m),
        )
        .unwrap();
        assert_eq!(est[0].0[0].mean, e2.ranges()[0][1], "{log:?}");
        assert!(
            log.iter()
                .any(|m| m.starts_with("warning: `miss`: the estimate of d")),
            "{log:?}"
        );
    }
}
