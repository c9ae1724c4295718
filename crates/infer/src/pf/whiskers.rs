//! The posterior over the whiskers a filter entertains: each whisker parameter that differs
//! between them, summarised over the particles' weights like any other unknown and named by its
//! scenario key.

use super::posterior::summarise;
use crate::method::Estimate;
use vibrissa_core::whisker::{Damping, Follicle, WhiskerParams};

/// The whisker parameters reported, by the key under which the estimate object holds them.
/// The follicle is reported by its compliance (rad per N·m, zero for a clamped follicle), so
/// that clamped and sprung follicles lie on one finite scale.
pub const KEYS: [&str; 7] = [
    "whisker.youngs_modulus",
    "whisker.density",
    "whisker.tip_radius",
    "whisker.damping.ratio",
    "whisker.damping.q",
    "whisker.damping.beta",
    "whisker.follicle.compliance",
];

/// The value of each of [`KEYS`] for `w`, `None` where the parameter does not apply (a damping
/// of another kind).
fn values(w: &WhiskerParams) -> [Option<f64>; 7] {
    let (ratio, q, beta) = match w.damping {
        Damping::ModalRatio { ratio } => (Some(ratio), None, None),
        Damping::SegmentQ { q } => (None, Some(q), None),
        Damping::StiffnessProportional { beta } => (None, None, Some(beta)),
        Damping::None => (None, None, None),
    };
    let compliance = match w.follicle {
        Follicle::Spring { stiffness, .. } => 1.0 / stiffness,
        Follicle::Clamped => 0.0,
    };
    [
        Some(w.youngs_modulus),
        Some(w.density),
        Some(w.tip_radius),
        ratio,
        q,
        beta,
        Some(compliance),
    ]
}

/// The parameters that differ between a filter's whiskers, with each whisker's value.
#[derive(Debug, Clone, Default)]
pub(super) struct WhiskerValues {
    /// `(key, value per whisker)` for every key of [`KEYS`] that every whisker has and that is
    /// not the same for all of them.
    columns: Vec<(&'static str, Vec<f64>)>,
}

impl WhiskerValues {
    /// The varying parameters of `whiskers` (none for a single whisker).
    pub(super) fn new<'a>(whiskers: impl IntoIterator<Item = &'a WhiskerParams>) -> WhiskerValues {
        let rows: Vec<[Option<f64>; 7]> = whiskers.into_iter().map(values).collect();
        let columns = KEYS
            .iter()
            .enumerate()
            .filter_map(|(k, &key)| {
                let col: Option<Vec<f64>> = rows.iter().map(|r| r[k]).collect();
                let col = col?;
                let first = *col.first()?;
                col.iter().any(|x| *x != first).then_some((key, col))
            })
            .collect();
        WhiskerValues { columns }
    }

    /// Whether no parameter varies (a filter told its whisker).
    pub(super) fn is_empty(&self) -> bool {
        self.columns.is_empty()
    }

    /// The posterior of each varying parameter, given the weight of each whisker of
    /// [`WhiskerValues::new`] (summing to 1).
    pub(super) fn posterior(&self, per_whisker: &[f64]) -> Vec<(&'static str, Estimate)> {
        self.columns
            .iter()
            .map(|(key, col)| (*key, summarise(col, per_whisker)))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_parameters_that_differ_are_reported_and_weighed_by_their_particles() {
        let a = WhiskerParams::w30();
        let mut b = a.clone();
        b.youngs_modulus *= 2.0;
        b.follicle = Follicle::Spring {
            stiffness: 1e-4,
            damping: 1e-8,
        };
        let values = WhiskerValues::new([&a, &b]);
        let keys: Vec<&str> = values.columns.iter().map(|(k, _)| *k).collect();
        assert_eq!(
            keys,
            ["whisker.youngs_modulus", "whisker.follicle.compliance"]
        );
        // Whisker 0 weighs 0.3, whisker 1 0.7.
        let post = values.posterior(&[0.3, 0.7]);
        let e = post[0].1;
        let want = 0.3 * a.youngs_modulus + 0.7 * b.youngs_modulus;
        assert!((e.mean - want).abs() < 1e-6 * want, "{e:?}");
        assert_eq!(e.ci90, [a.youngs_modulus, b.youngs_modulus]);
        let c = post[1].1;
        assert!((c.mean - 0.7e4).abs() < 1e-6, "{c:?}");
        assert_eq!(c.ci90, [0.0, 1e4]);
        // One whisker, or several alike: nothing varies.
        assert!(WhiskerValues::new([&a]).is_empty());
        assert!(WhiskerValues::new([&a, &a.clone()]).is_empty());
        assert!(WhiskerValues::new([&a]).posterior(&[1.0]).is_empty());
    }
}
