//! A recording to estimate from: its sample times, the channels of [`CHANNELS`] and its rate,
//! checked once for every estimator (the command line reads it from a contract CSV, the Python
//! package from arrays).
//!
//! The times may start anywhere and may have any constant step: a step that differs from the
//! first by more than 1% (a gap, an irregular clock) or that does not advance is refused with
//! its row. The channels an estimator reads must be present. Missing (`NaN`) values are skipped
//! by the filter; a discriminative method, which reads whole series, has them filled in by linear
//! interpolation ([`Recording::filled`], up to [`MAX_MISSING`] of a channel) once the noise has
//! been estimated from the samples recorded; the shape estimators need complete series.

use crate::experiment::CHANNELS;
use crate::noise::{self, Source};
use crate::trained::describe_noise;
use crate::{Error, Result};
use std::borrow::Cow;
use vibrissa_core::chain::MAX_SEGMENTS;
use vibrissa_io::series::Series;

/// A recording: sample times, channel-major values and sample rate.
#[derive(Debug, Clone)]
pub struct Recording {
    /// Sample times, s, strictly increasing at a constant step.
    pub t: Vec<f64>,
    /// `[CHANNELS][samples]`; a channel not recorded is empty.
    pub values: Vec<Vec<f64>>,
    /// Samples per second, Hz.
    pub rate: f64,
    /// The segment count of the chain that recorded it, when its metadata says.
    pub segments: Option<usize>,
}

/// Who reads a recording, for what it must hold.
#[derive(Debug, Clone, Copy)]
pub enum Reader<'a> {
    /// A discriminative method, by name: the channels it reads may miss (`NaN`) up to
    /// [`MAX_MISSING`] of their values, which [`Recording::filled`] fills in; infinities are
    /// refused.
    Method(&'a str),
    /// A method that reads complete series, by name (the shape estimators): the channels it
    /// reads must be finite.
    Complete(&'a str),
    /// The particle filter: missing (`NaN`) values are skipped.
    Filter,
}

/// The largest share of a channel's samples that may be missing (`NaN`) for a discriminative
/// method, which fills them in by linear interpolation: a tracker that lost the whisker for a
/// few frames. The intervals do not count what interpolation misses: on the other engine's 20
/// strikes with 5% of their samples missing in runs of 1–4, `krr-invariant`'s distance error
/// went from 0.83 to 0.93 mm (90% → 85% of its intervals holding the truth), with 15% missing
/// to 1.44 mm (65%).
pub const MAX_MISSING: f64 = 0.1;

fn bad(text: String) -> Error {
    Error::Recording(text)
}

/// The words this module's messages name a row with: "data row K", K counted from 1 after the
/// header.
const DATA_ROW: &str = "data row ";

/// A recording's error `e` with its data row named by the file's line instead (`lines[k]`: the
/// line of data row `k + 1`), where it names one.
fn at_lines(e: Error, lines: &[usize]) -> Error {
    let Error::Recording(text) = e else {
        return e;
    };
    let Some(at) = text.find(DATA_ROW) else {
        return Error::Recording(text);
    };
    let digits = &text[at + DATA_ROW.len()..];
    let len = digits.bytes().take_while(u8::is_ascii_digit).count();
    match digits[..len]
        .parse::<usize>()
        .ok()
        .and_then(|k| lines.get(k.checked_sub(1)?))
    {
        Some(line) => Error::Recording(format!("{}line {line}{}", &text[..at], &digits[len..])),
        None => Error::Recording(text),
    }
}

/// `x` to four significant digits, for messages.
fn short(x: f64) -> String {
    format!("{}", format!("{x:.3e}").parse::<f64>().unwrap_or(x))
}

/// The names of the whiskers whose columns `series` holds (`c1` for `c1.theta01`), in order.
pub fn whiskers_in(series: &Series) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for c in &series.columns {
        if let Some((name, "theta01")) = c.rsplit_once('.') {
            if !names.iter().any(|n| n == name) {
                names.push(name.to_string());
            }
        }
    }
    names
}

/// One whisker's view of a recording: `t` and that whisker's columns without their prefix (for a
/// recording of an array of whiskers, whose columns are `c1.theta01`, ...). `whisker` names it;
/// `None` takes the recording's own unprefixed columns, and is refused, naming the whiskers, for
/// a recording that has only prefixed ones.
pub fn whisker_view<'a>(
    series: &'a Series,
    name: &str,
    whisker: Option<&str>,
) -> Result<Cow<'a, Series>> {
    let names = whiskers_in(series);
    match whisker {
        None => {
            if series.column("theta01").is_none() && !names.is_empty() {
                return Err(bad(format!(
                    "`{name}` holds the columns of several whiskers ({}): choose one (--whisker \
                     NAME on the command line, whisker= in Python)",
                    names.join(", ")
                )));
            }
            Ok(Cow::Borrowed(series))
        }
        Some(w) => {
            if !names.iter().any(|n| n == w) {
                return Err(bad(format!(
                    "`{name}` has no whisker `{w}`; {}",
                    if names.is_empty() {
                        "it holds one whisker's unprefixed columns".to_string()
                    } else {
                        format!("its whiskers are {}", names.join(", "))
                    }
                )));
            }
            let prefix = format!("{w}.");
            let mut view = Series {
                columns: Vec::new(),
                data: Vec::new(),
                meta: series.meta.clone(),
            };
            for (c, data) in series.columns.iter().zip(&series.data) {
                let own = if c == "t" {
                    Some(c.as_str())
                } else {
                    c.strip_prefix(&prefix)
                };
                if let Some(own) = own {
                    view.columns.push(own.to_string());
                    view.data.push(data.clone());
                }
            }
            Ok(Cow::Owned(view))
        }
    }
}

impl Recording {
    /// The recording `name` (a file name, for messages) from a contract series: `t`, `theta01`
    /// and `theta12` always, the channels `needs` as `reader` requires, and the metadata
    /// `segments` when present.
    pub fn from_series(
        series: &Series,
        name: &str,
        needs: &[usize],
        reader: Reader,
    ) -> Result<Recording> {
        let t = series.require(&["t", "theta01", "theta12"]).map_err(|e| {
            bad(format!(
                "`{name}` lacks a required column (every recording has t, theta01, theta12): \
                     {e}"
            ))
        })?[0]
            .to_vec();
        let columns: Vec<Option<Vec<f64>>> = CHANNELS
            .iter()
            .map(|ch| series.column(ch).map(<[f64]>::to_vec))
            .collect();
        let segments = match series.meta_value("segments") {
            None => None,
            Some(s) => match s.trim().parse::<usize>() {
                Ok(n) if (2..=MAX_SEGMENTS).contains(&n) => Some(n),
                _ => {
                    return Err(bad(format!(
                        "`{name}`: metadata `segments` is `{s}`; expected a segment count from 2 \
                         to {MAX_SEGMENTS}"
                    )))
                }
            },
        };
        Recording::from_columns(name, t, columns, segments, needs, reader)
    }

    /// [`Recording::from_series`] of a file whose data rows are on `lines` (the file's line of
    /// each, from 1): its messages name the line rather than the data row.
    pub fn from_series_at_lines(
        series: &Series,
        name: &str,
        needs: &[usize],
        reader: Reader,
        lines: &[usize],
    ) -> Result<Recording> {
        Recording::from_series(series, name, needs, reader).map_err(|e| at_lines(e, lines))
    }

    /// The recording `name` from its times and one optional column per channel of
    /// [`CHANNELS`] (each as long as `t`).
    pub fn from_columns(
        name: &str,
        t: Vec<f64>,
        columns: Vec<Option<Vec<f64>>>,
        segments: Option<usize>,
        needs: &[usize],
        reader: Reader,
    ) -> Result<Recording> {
        if columns.len() != CHANNELS.len() {
            return Err(bad(format!(
                "`{name}`: {} channels given; expected {} ({})",
                columns.len(),
                CHANNELS.len(),
                CHANNELS.join(", ")
            )));
        }
        if t.len() < 2 {
            return Err(bad(format!(
                "`{name}` has {} sample{}; at least 2 are needed",
                t.len(),
                if t.len() == 1 { "" } else { "s" }
            )));
        }
        if let Some(k) = t.iter().position(|x| !x.is_finite()) {
            return Err(bad(format!(
                "`{name}`: t is not a finite number in {DATA_ROW}{}",
                k + 1
            )));
        }
        // Every step against the first (1% allowed), then the mean step sets the rate.
        let first = t[1] - t[0];
        for k in 1..t.len() {
            let dt = t[k] - t[k - 1];
            if dt <= 0.0 {
                return Err(bad(format!(
                    "`{name}`: t does not increase at {DATA_ROW}{} ({} after {})",
                    k + 1,
                    t[k],
                    t[k - 1]
                )));
            }
            if (dt - first).abs() > 0.01 * first {
                return Err(bad(format!(
                    "`{name}`: the sample step before {DATA_ROW}{} is {} s, not the first step's \
                     {} s (a gap or an irregular clock; resample it to a constant rate first)",
                    k + 1,
                    short(dt),
                    short(first)
                )));
            }
        }
        let rate = vibrissa_io::labelled::sample_rate(&t);
        let mut values = Vec::with_capacity(CHANNELS.len());
        for (c, (ch, column)) in CHANNELS.iter().zip(columns).enumerate() {
            match column {
                Some(v) => {
                    if v.len() != t.len() {
                        return Err(bad(format!(
                            "`{name}`: column {ch} has {} values for {} sample times",
                            v.len(),
                            t.len()
                        )));
                    }
                    if needs.contains(&c) {
                        check_values(name, ch, &v, reader)?;
                    }
                    values.push(v);
                }
                None if needs.contains(&c) => {
                    return Err(bad(match reader {
                        Reader::Method(m) | Reader::Complete(m) => format!(
                            "method {m} needs column {ch}, which `{name}` lacks (the template \
                             method uses theta12 alone)"
                        ),
                        Reader::Filter => format!(
                            "`{name}` lacks column {ch}, which the filter observes (choose others \
                             with --channels)"
                        ),
                    }))
                }
                None => values.push(Vec::new()),
            }
        }
        Ok(Recording {
            t,
            values,
            rate,
            segments,
        })
    }

    /// A simulated run's channels (`[CHANNELS][samples]`) as a recording sampled at `rate` from
    /// t = 0, without chain metadata.
    pub fn at_rate(values: Vec<Vec<f64>>, rate: f64) -> Recording {
        let n = values.first().map_or(0, Vec::len);
        Recording {
            t: (0..n).map(|k| k as f64 / rate).collect(),
            values,
            rate,
            segments: None,
        }
    }

    /// The recording with the missing (`NaN`) values of the channels `needs` filled in, for a
    /// discriminative method: each by linear interpolation between the nearest recorded values
    /// before and after it (the nearest one where it has a recorded value on one side only).
    /// Also per channel that had any: the channel, how many were missing and the longest run of
    /// them, in samples.
    pub fn filled(&self, needs: &[usize]) -> (Recording, Vec<Gaps>) {
        let mut rec = self.clone();
        let mut gaps = Vec::new();
        for &c in needs {
            let v = &mut rec.values[c];
            let missing = v.iter().filter(|x| x.is_nan()).count();
            if missing == 0 || missing == v.len() {
                continue;
            }
            let mut longest = 0;
            let mut k = 0;
            while k < v.len() {
                if !v[k].is_nan() {
                    k += 1;
                    continue;
                }
                let end = (k..v.len()).find(|&j| !v[j].is_nan()).unwrap_or(v.len());
                longest = longest.max(end - k);
                let before = k.checked_sub(1).map(|j| v[j]);
                let after = v.get(end).copied();
                for (i, x) in v[k..end].iter_mut().enumerate() {
                    *x = match (before, after) {
                        (Some(a), Some(b)) => {
                            let f = (i + 1) as f64 / (end + 1 - k) as f64;
                            a + f * (b - a)
                        }
                        (Some(a), None) => a,
                        (None, Some(b)) => b,
                        (None, None) => unreachable!("a channel with a recorded value"),
                    };
                }
                k = end;
            }
            gaps.push(Gaps {
                channel: c,
                missing,
                longest,
            });
        }
        (rec, gaps)
    }

    /// The channels of `needs` that never change (a sensor that recorded nothing), with their
    /// one value.
    pub fn constant_channels(&self, needs: &[usize]) -> Vec<(usize, f64)> {
        needs
            .iter()
            .filter_map(|&c| {
                let finite = self.values[c].iter().filter(|v| v.is_finite());
                let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                    (lo.min(v), hi.max(v))
                });
                (lo == hi).then_some((c, lo))
            })
            .collect()
    }

    /// The channels of `needs` that hold one value while another of `needs` varies (a sensor
    /// that recorded nothing), with their value; none when every one of them is flat (a whisker
    /// that never moved).
    pub fn dead_channels(&self, needs: &[usize]) -> Vec<(usize, f64)> {
        let constant = self.constant_channels(needs);
        if constant.len() < needs.len() {
            constant
        } else {
            Vec::new()
        }
    }
}

/// The channels of `needs` that the batch's sensors recorded: a channel that holds one value
/// from the first sample to the last in a recording whose other channels of `needs` vary (a
/// sensor that recorded nothing) is left out, with a warning naming the recording. `needs` as
/// it is when that would leave no channel. For an estimator that can read any subset of the
/// channels (the filter); [`batch_noise`] refuses such a channel.
pub fn recorded_channels(
    names: &[String],
    recordings: &[Recording],
    needs: &[usize],
) -> (Vec<usize>, Vec<String>) {
    let mut dead: Vec<usize> = Vec::new();
    let mut warnings = Vec::new();
    for (name, rec) in names.iter().zip(recordings) {
        for (c, value) in rec.dead_channels(needs) {
            warnings.push(format!(
                "`{name}`: channel `{}` holds {value} from the first sample to the last while \
                 the others vary: a sensor that recorded nothing? It is left out of every \
                 recording's estimate (name the channels to read to keep it)",
                CHANNELS[c]
            ));
            if !dead.contains(&c) {
                dead.push(c);
            }
        }
    }
    let kept: Vec<usize> = needs
        .iter()
        .copied()
        .filter(|c| !dead.contains(c))
        .collect();
    if kept.is_empty() {
        (needs.to_vec(), warnings)
    } else {
        (kept, warnings)
    }
}

/// Missing values of one channel that [`Recording::filled`] filled in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Gaps {
    /// The channel, an index into [`CHANNELS`].
    pub channel: usize,
    /// How many of its values were missing.
    pub missing: usize,
    /// The longest run of missing values, samples.
    pub longest: usize,
}

/// Checks the values `v` of channel `ch` that `reader` reads (see [`Reader`]).
fn check_values(name: &str, ch: &str, v: &[f64], reader: Reader) -> Result<()> {
    let row = |k: usize| format!("{DATA_ROW}{}", k + 1);
    match reader {
        Reader::Filter => Ok(()),
        Reader::Complete(m) => match v.iter().position(|x| !x.is_finite()) {
            Some(k) => Err(bad(format!(
                "`{name}`: column {ch} has a non-finite value in {}; method {m} needs every \
                 value of the channels it reads",
                row(k)
            ))),
            None => Ok(()),
        },
        Reader::Method(m) => {
            if let Some(k) = v.iter().position(|x| x.is_infinite()) {
                return Err(bad(format!(
                    "`{name}`: column {ch} has an infinite value in {} (a missing value is \
                     written NaN)",
                    row(k)
                )));
            }
            let missing = v.iter().filter(|x| x.is_nan()).count();
            if missing as f64 > MAX_MISSING * v.len() as f64 {
                return Err(bad(format!(
                    "`{name}`: column {ch} misses {missing} of its {} values (NaN), more than \
                     the {}% that method {m} fills in by interpolation; the filter (--method pf) \
                     skips missing values instead",
                    v.len(),
                    100.0 * MAX_MISSING
                )));
            }
            Ok(())
        }
    }
}

/// The sensor noise of a batch of recordings (see [`noise::batch_levels`]), with what a user
/// should hear about it.
#[derive(Debug, Clone)]
pub struct NoiseReport {
    /// Per recording: the sensor noise per channel of [`CHANNELS`], SI.
    pub levels: Vec<[f64; 5]>,
    /// Warnings: constant channels, recordings whose noise differs from the batch's.
    pub warnings: Vec<String>,
    /// One line: where the levels came from and what they are.
    pub summary: String,
}

/// The sensor noise of every recording on the channels `needs` (`stated`: channels whose noise
/// is given, not estimated). Recordings that agree share their pooled estimate; one that does
/// not gets its own, with a warning. `how_to_state` tells the user how to state a noise that
/// cannot be estimated (e.g. `--noise CHANNEL=SIGMA,...`).
pub fn batch_noise(
    names: &[String],
    recordings: &[Recording],
    needs: &[usize],
    stated: &[Option<f64>; 5],
    how_to_state: &str,
) -> Result<NoiseReport> {
    let estimated: Vec<usize> = needs
        .iter()
        .copied()
        .filter(|&c| stated[c].is_none())
        .collect();
    let mut warnings = Vec::new();
    // A channel that never changes is a sensor that recorded nothing: its noise measures as 0 and
    // an estimator would compare a flat line with simulated signals (and a filter with free
    // sensor gains would read any value it holds as a gain). Beside channels that vary it is
    // refused; a recording in which nothing varies is only warned of (a whisker never touched).
    for (name, rec) in names.iter().zip(recordings) {
        if let Some(&(c, value)) = rec.dead_channels(needs).first() {
            return Err(bad(format!(
                "`{name}`: channel `{}` holds {value} from the first sample to the last while \
                 the others vary: a sensor that recorded nothing? Leave the column out of the \
                 file and use a method that does without it: the filter (method pf) leaves such \
                 a channel out by itself unless its channels are named; the other methods read \
                 every channel they list",
                CHANNELS[c]
            )));
        }
        // Here every channel read is flat, or none is: one warning for the recording.
        let flat = rec.constant_channels(needs);
        if !flat.is_empty() {
            let values: Vec<String> = flat
                .iter()
                .map(|(c, value)| format!("{} {value}", CHANNELS[*c]))
                .collect();
            warnings.push(format!(
                "`{name}`: every channel read is constant ({}): a whisker that never moved, or \
                 sensors that recorded nothing? The estimate compares flat lines with simulated \
                 signals",
                values.join(", ")
            ));
        }
    }
    // Each recording alone first, so that a channel too short to measure is named with its file.
    for (name, rec) in names.iter().zip(recordings) {
        noise::estimate(&rec.values, &estimated).map_err(|e| {
            bad(format!(
                "`{name}`: cannot estimate its sensor noise ({e}); state it with {how_to_state} \
                 or in the scenario's [sensor_noise]"
            ))
        })?;
    }
    let series: Vec<&[Vec<f64>]> = recordings.iter().map(|r| &r.values[..]).collect();
    let batch = noise::batch_levels(&series, needs, stated)?;
    let several = names.len() > 1;
    for (((name, source), own), f) in names
        .iter()
        .zip(&batch.sources)
        .zip(&batch.own)
        .zip(&batch.agreement)
    {
        if *source == Source::Own && several {
            warnings.push(format!(
                "`{name}`: its sensor noise ({}) differs from the rest of the batch's (more \
                 than {f:.2} times as noisy on some channel, {f:.2} times as quiet on every \
                 one, or {:.2} times as quiet on one; a recording shorter than {} samples is \
                 allowed more); it is estimated from this recording alone",
                describe_noise(own, &estimated),
                f * f,
                noise::AGREEMENT_SAMPLES
            ));
        }
    }
    let shared = batch
        .sources
        .iter()
        .filter(|s| **s == Source::Batch)
        .count();
    let what = if estimated.is_empty() {
        "as stated".to_string()
    } else if !several {
        "estimated from the recording".to_string()
    } else {
        format!("estimated from {shared} of the recordings, pooled")
    };
    // Channels whose noise was given are said to be so, beside those estimated.
    let given: Vec<&str> = needs
        .iter()
        .filter(|&&c| stated[c].is_some())
        .map(|&c| CHANNELS[c])
        .collect();
    let what = if given.is_empty() || estimated.is_empty() {
        what
    } else {
        format!("{what} ({} as stated)", given.join(", "))
    };
    let summary = match batch.sources.iter().position(|s| *s == Source::Batch) {
        Some(k) => format!(
            "sensor noise {what}: {}",
            describe_noise(&batch.levels[k], needs)
        ),
        None if !several || estimated.is_empty() => format!(
            "sensor noise {what}: {}",
            describe_noise(&batch.levels[0], needs)
        ),
        None => "sensor noise estimated from each recording alone".to_string(),
    };
    Ok(NoiseReport {
        levels: batch.levels,
        warnings,
        summary,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn columns(n: usize) -> Vec<Option<Vec<f64>>> {
        let mut c = vec![None; 5];
        c[0] = Some(vec![0.0; n]);
        c[1] = Some((0..n).map(|k| k as f64 * 1e-3).collect());
        c
    }

    #[test]
    fn one_whisker_of_an_array() {
        let mut s = Series::new(&["t", "c1.theta01", "c1.theta12", "c2.theta01", "c2.theta12"]);
        s.push_row(&[0.0, 1.0, 2.0, 3.0, 4.0]);
        s.push_row(&[0.001, 1.5, 2.5, 3.5, 4.5]);
        assert_eq!(whiskers_in(&s), ["c1", "c2"]);
        let v = whisker_view(&s, "a.csv", Some("c2")).unwrap();
        assert_eq!(v.columns, ["t", "theta01", "theta12"]);
        assert_eq!(v.data[1], [3.0, 3.5]);
        let r = Recording::from_series(&v, "a.csv", &[0, 1], Reader::Filter).unwrap();
        assert_eq!(r.values[1], [4.0, 4.5]);
        let e = whisker_view(&s, "a.csv", None).unwrap_err().to_string();
        assert!(e.contains("several whiskers (c1, c2)"), "{e}");
        let e = whisker_view(&s, "a.csv", Some("c3"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("no whisker `c3`") && e.contains("c1, c2"), "{e}");
    }

    #[test]
    fn rate_from_the_times() {
        let t: Vec<f64> = (0..11).map(|k| 0.5 + k as f64 * 5e-4).collect();
        let r =
            Recording::from_columns("r", t, columns(11), None, &[0, 1], Reader::Filter).unwrap();
        assert_eq!(r.rate, 2000.0);
        assert!(r.values[2].is_empty());
        assert_eq!(r.constant_channels(&[0, 1]), vec![(0, 0.0)]);
    }

    #[test]
    fn refuses_gaps_missing_channels_and_nans() {
        let mut t: Vec<f64> = (0..11).map(|k| k as f64 * 1e-3).collect();
        t[6] += 1e-3;
        let e = Recording::from_columns("r", t, columns(11), None, &[0, 1], Reader::Filter)
            .unwrap_err()
            .to_string();
        assert!(e.contains("sample step before data row 7"), "{e}");
        let t: Vec<f64> = (0..11).map(|k| k as f64 * 1e-3).collect();
        let e = Recording::from_columns(
            "r",
            t.clone(),
            columns(11),
            None,
            &[2],
            Reader::Method("knn"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("method knn needs column m0"), "{e}");
        let mut c = columns(11);
        c[1].as_mut().unwrap()[3] = f64::NAN;
        let e = Recording::from_columns(
            "r",
            t.clone(),
            c.clone(),
            None,
            &[1],
            Reader::Complete("shape-krr"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("non-finite value in data row 4"), "{e}");
        // One missing value of 11 is filled in for a discriminative method, skipped by the
        // filter.
        assert!(
            Recording::from_columns("r", t.clone(), c.clone(), None, &[1], Reader::Filter).is_ok()
        );
        assert!(Recording::from_columns(
            "r",
            t.clone(),
            c.clone(),
            None,
            &[1],
            Reader::Method("knn")
        )
        .is_ok());
        // Three of 11 are more than a discriminative method fills in (a tenth); an infinity is
        // no gap.
        for k in [5, 7] {
            c[1].as_mut().unwrap()[k] = f64::NAN;
        }
        let e = Recording::from_columns("r", t.clone(), c, None, &[1], Reader::Method("knn"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("column theta12 misses 3 of its 11 values")
                && e.contains("10%")
                && e.contains("--method pf"),
            "{e}"
        );
        let mut c = columns(11);
        c[0].as_mut().unwrap()[2] = f64::INFINITY;
        let e = Recording::from_columns("r", t.clone(), c, None, &[0], Reader::Method("knn"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("column theta01 has an infinite value in data row 3"),
            "{e}"
        );
        let e = Recording::from_columns("r", t, columns(10), None, &[1], Reader::Filter)
            .unwrap_err()
            .to_string();
        assert!(e.contains("10 values for 11 sample times"), "{e}");
    }

    #[test]
    fn a_file_s_bad_row_is_named_by_its_line() {
        let mut series = Series::new(&["t", "theta01", "theta12"]);
        for k in 0..6 {
            let y = if k == 3 { f64::NAN } else { 0.0 };
            series.push_row(&[k as f64 * 1e-3, 0.0, y]);
        }
        // A comment line and the header before the data: row k + 1 is on line k + 3.
        let lines: Vec<usize> = (3..9).collect();
        let knn = Reader::Complete("knn");
        let e = Recording::from_series_at_lines(&series, "r", &[1], knn, &lines)
            .unwrap_err()
            .to_string();
        assert!(e.contains("non-finite value in line 6"), "{e}");
        assert!(!e.contains("data row"), "{e}");
        // Without the lines, the data row.
        let e = Recording::from_series(&series, "r", &[1], knn)
            .unwrap_err()
            .to_string();
        assert!(e.contains("non-finite value in data row 4"), "{e}");
        // Lines that do not reach the row leave the message as it is.
        let e = Recording::from_series_at_lines(&series, "r", &[1], knn, &[3])
            .unwrap_err()
            .to_string();
        assert!(e.contains("data row 4"), "{e}");
    }

    #[test]
    fn missing_values_are_interpolated_in_time_and_held_at_the_ends() {
        let t: Vec<f64> = (0..8).map(|k| k as f64 * 1e-3).collect();
        let nan = f64::NAN;
        let mut c = columns(8);
        c[0] = Some(vec![nan, 1.0, 2.0, nan, nan, 8.0, 9.0, nan]);
        c[1] = Some(vec![0.0, 1.0, nan, 3.0, 4.0, 5.0, 6.0, 7.0]);
        // Read as the filter reads it (a discriminative method would refuse theta01's four gaps
        // in eight); filled wherever asked for.
        let rec = Recording::from_columns("r", t, c, None, &[0, 1], Reader::Filter).unwrap();
        let (filled, gaps) = rec.filled(&[0, 1, 2]);
        assert_eq!(filled.values[0], [1.0, 1.0, 2.0, 4.0, 6.0, 8.0, 9.0, 9.0]);
        assert_eq!(filled.values[1], [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
        assert_eq!(
            gaps,
            [
                Gaps {
                    channel: 0,
                    missing: 4,
                    longest: 2
                },
                Gaps {
                    channel: 1,
                    missing: 1,
                    longest: 1
                }
            ]
        );
        // The recording itself keeps its missing values (its noise is measured from the rest).
        assert!(rec.values[0][0].is_nan());
        let (_, none) = rec.filled(&[2]);
        assert!(none.is_empty());
    }

    /// A strike-like recording of `n` samples: every channel a pulse with a little wobble,
    /// but those of `flat`, which hold `value`.
    fn strike(n: usize, flat: &[usize], value: f64) -> Recording {
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let columns = (0..5)
            .map(|c| {
                Some(
                    (0..n)
                        .map(|k| {
                            if flat.contains(&c) {
                                return value;
                            }
                            let x = k as f64 / n as f64;
                            let wobble = 0.01 * ((k * (7 + c)) as f64).sin();
                            (1.0 + c as f64) * ((-((x - 0.5) / 0.1).powi(2)).exp() + wobble)
                        })
                        .collect(),
                )
            })
            .collect();
        Recording::from_columns("r", t, columns, None, &[0, 1, 2, 3, 4], Reader::Filter).unwrap()
    }

    #[test]
    fn a_channel_that_recorded_nothing_beside_others_that_vary() {
        let names = ["a.csv".to_string(), "b.csv".to_string()];
        let all = [0, 1, 2, 3, 4];
        let batch = [strike(300, &[], 0.0), strike(300, &[2], 1e30)];
        // The filter leaves m0 out, naming the recording that shows it.
        let (kept, warnings) = recorded_channels(&names, &batch, &all);
        assert_eq!(kept, [0, 1, 3, 4]);
        assert_eq!(warnings.len(), 1);
        assert!(
            warnings[0].contains("`b.csv`") && warnings[0].contains("`m0`"),
            "{warnings:?}"
        );
        // A method that reads it is refused before anything is trained.
        let e = batch_noise(&names, &batch, &all, &[None; 5], "--noise")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`b.csv`") && e.contains("`m0`") && e.contains("1000000000000000000"),
            "{e}"
        );
        // Without m0 the batch is read, and no channel is flat.
        let report = batch_noise(&names, &batch, &kept, &[None; 5], "--noise").unwrap();
        assert!(report.warnings.is_empty(), "{:?}", report.warnings);
        assert!(report
            .levels
            .iter()
            .all(|l| kept.iter().all(|&c| l[c] > 0.0)));
        // Nothing left to read: every channel kept, as the caller asked.
        let (kept, _) = recorded_channels(&names[1..], &batch[1..], &[2]);
        assert_eq!(kept, [2]);
    }
}
