//! Equal-weight mixtures of estimates: several independent readings of one posterior (the
//! particle filter run as islands with their own random streams) merged into one estimate whose
//! interval holds their spread as well as their own widths.
//!
//! Each part is read as a two-piece normal: half its mass below its mean with the spread that
//! puts the lower end of its 90% interval at the 5% point, half above with the spread of its
//! upper end. The mixture's interval is the 5% and 95% points of the parts' average
//! distribution, found by bisection; its mean is the parts' mean and its standard deviation
//! follows the law of total variance.

use crate::method::{Estimate, Z90};

/// Bisection steps for a quantile: the bracket shrinks 2⁻⁶⁰ of its width.
const BISECTIONS: usize = 60;

/// The equal-weight mixture of `parts`; `None` when there are none. One part is returned as it
/// is.
pub fn mixture(parts: &[Estimate]) -> Option<Estimate> {
    match parts {
        [] => None,
        [one] => Some(*one),
        _ => {
            let n = parts.len() as f64;
            let mean = parts.iter().map(|e| e.mean).sum::<f64>() / n;
            let var = parts
                .iter()
                .map(|e| e.std * e.std + (e.mean - mean).powi(2))
                .sum::<f64>()
                / n;
            // Every part holds at most 5% of its mass below its lower end, at least 5% below its
            // mean: the mixture's 5% point lies between the least lower end and the largest.
            let lo = quantile(parts, 0.05, |e| e.ci90[0].min(e.mean));
            let hi = quantile(parts, 0.95, |e| e.ci90[1].max(e.mean));
            Some(Estimate {
                mean,
                std: var.sqrt(),
                ci90: [lo.min(mean), hi.max(mean)],
            })
        }
    }
}

/// The `q` point of the parts' average distribution, searched between the least and the
/// largest of `end` over the parts (each part's 90% interval's end on the side of `q`).
fn quantile(parts: &[Estimate], q: f64, end: impl Fn(&Estimate) -> f64) -> f64 {
    let (mut a, mut b) = parts
        .iter()
        .map(&end)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
    if !(a.is_finite() && b.is_finite()) {
        return f64::NAN;
    }
    let cdf = |x: f64| parts.iter().map(|e| part_cdf(e, x)).sum::<f64>() / parts.len() as f64;
    for _ in 0..BISECTIONS {
        let m = 0.5 * (a + b);
        if cdf(m) < q {
            a = m;
        } else {
            b = m;
        }
    }
    0.5 * (a + b)
}

/// The standard normal distribution function.
pub(crate) fn normal_cdf(z: f64) -> f64 {
    0.5 * libm::erfc(-z / std::f64::consts::SQRT_2)
}

/// The distribution function at `x` of part `e` read as a two-piece normal (a step where a side
/// has no width).
fn part_cdf(e: &Estimate, x: f64) -> f64 {
    let below = (e.mean - e.ci90[0]).max(0.0) / Z90;
    let above = (e.ci90[1] - e.mean).max(0.0) / Z90;
    if x < e.mean {
        if below > 0.0 {
            normal_cdf((x - e.mean) / below)
        } else {
            0.0
        }
    } else if above > 0.0 {
        normal_cdf((x - e.mean) / above)
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_part_is_itself_and_none_is_none() {
        let e = Estimate {
            mean: 1.0,
            std: 0.2,
            ci90: [0.6, 1.5],
        };
        assert_eq!(mixture(&[e]), Some(e));
        assert_eq!(mixture(&[]), None);
    }

    #[test]
    fn copies_of_a_normal_keep_its_interval() {
        let e = Estimate::normal(2.0, 0.3);
        let m = mixture(&[e, e, e]).unwrap();
        assert!((m.mean - 2.0).abs() < 1e-12);
        assert!((m.std - 0.3).abs() < 1e-12);
        for k in 0..2 {
            assert!((m.ci90[k] - e.ci90[k]).abs() < 1e-9, "{m:?}");
        }
    }

    #[test]
    fn parts_that_disagree_widen_the_interval_to_their_spread() {
        // Two narrow readings 1 apart: the mixture's 90% interval reaches past both, and its
        // ends are each part's own 10% point (5% of the mixture lies in one part's tail).
        let (a, b) = (Estimate::normal(0.0, 0.1), Estimate::normal(1.0, 0.1));
        let m = mixture(&[a, b]).unwrap();
        assert!((m.mean - 0.5).abs() < 1e-12);
        assert!((m.std - (0.01f64 + 0.25).sqrt()).abs() < 1e-12);
        let z10 = 1.281_551_565_545;
        assert!((m.ci90[0] - (0.0 - z10 * 0.1)).abs() < 1e-6, "{m:?}");
        assert!((m.ci90[1] - (1.0 + z10 * 0.1)).abs() < 1e-6, "{m:?}");
    }

    #[test]
    fn an_asymmetric_part_keeps_its_sides_and_a_point_part_is_a_step() {
        let skew = Estimate {
            mean: 0.0,
            std: 1.0,
            ci90: [-1.0, 3.0],
        };
        let m = mixture(&[skew, skew]).unwrap();
        assert!((m.ci90[0] + 1.0).abs() < 1e-9 && (m.ci90[1] - 3.0).abs() < 1e-9);
        // Two points: the mixture's interval runs from one to the other.
        let (p, q) = (Estimate::normal(1.0, 0.0), Estimate::normal(2.0, 0.0));
        let m = mixture(&[p, q]).unwrap();
        assert!(
            (m.ci90[0] - 1.0).abs() < 1e-9 && (m.ci90[1] - 2.0).abs() < 1e-9,
            "{m:?}"
        );
    }
}
