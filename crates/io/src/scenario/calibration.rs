//! The `[sensors]` table (gains and offsets of the observed channels) and the informational
//! `[calibration]` table that `vibrissa calibrate` writes into a fitted scenario.

use super::schema::Ctx;
use crate::error::Result;
use serde::{Deserialize, Serialize};
use vibrissa_core::sim::{Response, SensorResponse};

/// `[sensors]`: per-channel `{ gain, offset }`, each key optional.
#[derive(Debug, Default, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub(super) struct SensorsTable {
    theta01: Option<ResponseTable>,
    theta12: Option<ResponseTable>,
    m0: Option<ResponseTable>,
    fx: Option<ResponseTable>,
    fy: Option<ResponseTable>,
}

/// One channel of `[sensors]`.
#[derive(Debug, Default, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct ResponseTable {
    gain: Option<f64>,
    offset: Option<f64>,
}

impl SensorsTable {
    /// The responses; an absent gain is 1, an absent offset 0 (checked later by core).
    pub(super) fn into_response(self) -> SensorResponse {
        let one = |t: Option<ResponseTable>| {
            let t = t.unwrap_or_default();
            Response {
                gain: t.gain.unwrap_or(1.0),
                offset: t.offset.unwrap_or(0.0),
            }
        };
        SensorResponse {
            theta01: one(self.theta01),
            theta12: one(self.theta12),
            m0: one(self.m0),
            fx: one(self.fx),
            fy: one(self.fy),
        }
    }
}

/// What a calibration found, as recorded in a fitted scenario's `[calibration]` table.
///
/// Informational: it does not change the simulation. Quantities are SI; residual RMS values and
/// noise levels are in each channel's unit (rad, N·m, N).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Calibration {
    /// The folder of labelled recordings the fit used.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub labelled: Option<String>,
    /// How many labelled recordings were fitted.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub recordings: Option<usize>,
    /// Residual RMS of each channel with the nominal scenario.
    pub rms_before: ChannelValues,
    /// Residual RMS of each channel with the fitted scenario.
    pub rms_after: ChannelValues,
    /// Sensor noise standard deviation of each channel, as the fit estimated it.
    pub noise: ChannelValues,
    /// Every parameter the fit considered, determined or not.
    pub parameters: Vec<CalibratedParameter>,
    /// Correlations of the determined parameters' errors (absent in files written before it
    /// was recorded).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub correlation: Option<Correlation>,
}

/// `[calibration.correlation]`: the correlation matrix of the determined parameters' errors, in
/// the order of `keys`. With each parameter's standard error it gives their joint covariance:
/// how the errors of, say, the modulus and the density move together.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Correlation {
    /// The parameters' keys, as in `[[calibration.parameters]]`.
    pub keys: Vec<String>,
    /// One row per key, each with one entry per key: symmetric, ones on the diagonal, every
    /// entry in [-1, 1].
    pub matrix: Vec<Vec<f64>>,
}

impl Correlation {
    /// The pairs of recorded parameters, both passing `keep`, whose errors are correlated by at
    /// least `min` in size, strongest first: `(a, b, r)` with `a` before `b` in `keys`.
    pub fn strongest(&self, min: f64, keep: impl Fn(&str) -> bool) -> Vec<(&str, &str, f64)> {
        let mut pairs = Vec::new();
        for (i, a) in self.keys.iter().enumerate() {
            for (j, b) in self.keys.iter().enumerate().skip(i + 1) {
                let r = self.matrix[i][j];
                if r.abs() >= min && keep(a) && keep(b) {
                    pairs.push((a.as_str(), b.as_str(), r));
                }
            }
        }
        pairs.sort_by(|x, y| y.2.abs().total_cmp(&x.2.abs()));
        pairs
    }

    /// The correlation of the errors of `a` and `b`, if both are recorded.
    pub fn get(&self, a: &str, b: &str) -> Option<f64> {
        let i = self.keys.iter().position(|k| k == a)?;
        let j = self.keys.iter().position(|k| k == b)?;
        Some(self.matrix[i][j])
    }
}

/// One number per observed channel (absent where the recordings lack the channel).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ChannelValues {
    /// `theta01`, rad.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub theta01: Option<f64>,
    /// `theta12`, rad.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub theta12: Option<f64>,
    /// `m0`, N·m.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub m0: Option<f64>,
    /// `fx`, N.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fx: Option<f64>,
    /// `fy`, N.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fy: Option<f64>,
}

impl ChannelValues {
    /// Values given in the contract's channel order (theta01, theta12, m0, fx, fy).
    pub fn from_array(v: [Option<f64>; 5]) -> Self {
        let [theta01, theta12, m0, fx, fy] = v;
        ChannelValues {
            theta01,
            theta12,
            m0,
            fx,
            fy,
        }
    }

    /// The values in the contract's channel order.
    pub fn to_array(&self) -> [Option<f64>; 5] {
        [self.theta01, self.theta12, self.m0, self.fx, self.fy]
    }
}

/// One fitted (or held) parameter: `[[calibration.parameters]]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibratedParameter {
    /// The scenario key it sets (`whisker.youngs_modulus`, `sensors.m0.gain`), or a name of its
    /// own for what is no scenario key (`time_offset`, s).
    pub key: String,
    /// Its value in the nominal scenario.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nominal: Option<f64>,
    /// Its value in the fitted scenario (the nominal one where not determined).
    pub value: f64,
    /// Standard error of `value`, in its unit (absent where not determined).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std_error: Option<f64>,
    /// Whether the recordings determined it; if not, it was held at `value`.
    pub determined: bool,
    /// Why it was held, or how to read it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

impl Calibration {
    /// Checks that every number is finite and standard errors are not negative.
    pub(super) fn check(&self, ctx: &Ctx) -> Result<()> {
        let bad = |field: String, what: &str| Err(ctx.field(field, what.to_string()));
        for (table, values) in [
            ("rms_before", &self.rms_before),
            ("rms_after", &self.rms_after),
            ("noise", &self.noise),
        ] {
            for (name, v) in vibrissa_core::sensors::CHANNELS
                .iter()
                .zip(values.to_array())
            {
                if v.is_some_and(|v| !(v.is_finite() && v >= 0.0)) {
                    return bad(
                        format!("calibration.{table}.{name}"),
                        "must be a finite number >= 0",
                    );
                }
            }
        }
        for (k, p) in self.parameters.iter().enumerate() {
            let at = |f: &str| format!("calibration.parameters[{k}].{f}");
            // A clamped follicle has no nominal stiffness and, kept clamped, an infinite one.
            let clamped = p.value == f64::INFINITY && p.nominal.is_none();
            if !(p.value.is_finite() || clamped) || p.nominal.is_some_and(|x| !x.is_finite()) {
                return bad(
                    at("value"),
                    "and nominal must be finite numbers (value = inf only without a nominal: \
                     a clamped follicle)",
                );
            }
            if p.std_error.is_some_and(|x| !(x.is_finite() && x >= 0.0)) {
                return bad(at("std_error"), "must be a finite number >= 0");
            }
        }
        if let Some(c) = &self.correlation {
            c.check(ctx, &self.parameters)?;
        }
        Ok(())
    }
}

impl Correlation {
    /// Checks that every key names a determined parameter once, and that the matrix is square
    /// over the keys, symmetric, with ones on its diagonal and entries in [-1, 1].
    fn check(&self, ctx: &Ctx, parameters: &[CalibratedParameter]) -> Result<()> {
        let bad = |field: String, what: String| Err(ctx.field(field, what));
        let n = self.keys.len();
        for (i, key) in self.keys.iter().enumerate() {
            let field = format!("calibration.correlation.keys[{i}]");
            if !parameters.iter().any(|p| &p.key == key && p.determined) {
                return bad(
                    field,
                    format!(
                        "{key:?} must name a determined parameter of [[calibration.parameters]]"
                    ),
                );
            }
            if self.keys[..i].contains(key) {
                return bad(field, format!("{key:?} must appear once"));
            }
        }
        if self.matrix.len() != n {
            return bad(
                "calibration.correlation.matrix".into(),
                format!("must have one row per key ({n}), has {}", self.matrix.len()),
            );
        }
        for (i, row) in self.matrix.iter().enumerate() {
            if row.len() != n {
                return bad(
                    format!("calibration.correlation.matrix[{i}]"),
                    format!("must have one entry per key ({n}), has {}", row.len()),
                );
            }
        }
        for (i, row) in self.matrix.iter().enumerate() {
            for (j, &r) in row.iter().enumerate() {
                let field = format!("calibration.correlation.matrix[{i}][{j}]");
                if !(r.is_finite() && (-1.0..=1.0).contains(&r)) {
                    return bad(field, format!("= {r}: allowed is a number in [-1, 1]"));
                }
                if i == j && (r - 1.0).abs() > 1e-9 {
                    return bad(field, format!("= {r}: a diagonal entry must be 1"));
                }
                if (r - self.matrix[j][i]).abs() > 1e-9 {
                    return bad(
                        field,
                        format!("= {r}: the matrix must be symmetric (entry [{j}][{i}] differs)"),
                    );
                }
            }
        }
        Ok(())
    }
}
