//! A second pass over the whiskers: alternatives drawn again around those the first pass
//! favoured, each weighted by prior/proposal.
//!
//! On a randomised family the filter entertains the scenario's whisker and a few dozen drawn from
//! the prior. With five or so uncertain whisker parameters, few of those lie near the
//! recording's whisker, and what the nearest one misses leans the object's estimate. A second
//! pass draws the alternatives again from a mixture of the prior and of kernels around the first
//! pass's whiskers, each kernel weighted by its whisker's posterior weight (adaptive importance
//! sampling over the static unknowns, as population Monte Carlo does), and starts each
//! alternative's particles with the importance weight prior/proposal. The second pass's
//! posterior is therefore still the posterior under the family's prior, with its whiskers where
//! the recording puts them.
//!
//! The draws live in the space of the uniform numbers behind a randomised whisker
//! ([`Around::apply_uniforms`]), where the prior is uniform on the unit cube: the kernels are
//! Gaussian, reflected at the cube's faces, and a whisker's prior density is 1. The kernels' widths
//! and the prior's share set only how well the proposal finds the whiskers that matter, not the
//! posterior they give.

use crate::error::Result;
use crate::randomise::{Around, UNIFORMS, WHISKER_UNIFORMS};
use vibrissa_core::rng::Rng;
use vibrissa_core::whisker::WhiskerParams;

/// Share of the second pass's draws taken from the prior itself: a defensive mixture, so that no
/// importance weight exceeds `1/PRIOR_SHARE` and a first pass that favoured the wrong whiskers
/// cannot exclude the right ones.
const PRIOR_SHARE: f64 = 0.2;

/// Narrowest and widest kernel, as a share of each uniform number's range: about the spacing of
/// 64 draws in a handful of dimensions at the widest, a twentieth of the prior at the narrowest.
const KERNEL_WIDTH: (f64, f64) = (0.05, 0.25);

/// The uniform numbers of one draw.
pub type Uniforms = [f64; UNIFORMS];

/// The uniform numbers that stand for a scenario's own whisker among its draws: every factor 1,
/// its follicle and taper as they are.
pub fn nominal_uniforms() -> Uniforms {
    let mut u = [0.5; UNIFORMS];
    // At the top of their range: a clamped follicle stays clamped, no taper is added.
    u[4] = 1.0;
    u[7] = 1.0;
    u
}

/// The mixture the second pass draws its alternatives from.
#[derive(Debug, Clone)]
pub struct Proposal {
    centres: Vec<Uniforms>,
    /// Normalised weight of each centre.
    weights: Vec<f64>,
    /// Kernel width per whisker dimension.
    width: [f64; WHISKER_UNIFORMS],
}

impl Proposal {
    /// Kernels around `centres` (the first pass's whiskers), weighted by `weights` (their
    /// posterior weights), each as wide as the weighted spread of the centres in its dimension,
    /// within [`KERNEL_WIDTH`]. `None` when no centre has weight.
    pub fn around(centres: &[Uniforms], weights: &[f64]) -> Option<Proposal> {
        let total: f64 = weights.iter().filter(|w| w.is_finite() && **w > 0.0).sum();
        if total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
            || centres.len() != weights.len()
        {
            return None;
        }
        let (mut kept, mut norm) = (Vec::new(), Vec::new());
        for (c, w) in centres.iter().zip(weights) {
            if w.is_finite() && *w > 0.0 {
                kept.push(*c);
                norm.push(w / total);
            }
        }
        let width = std::array::from_fn(|d| {
            let mean: f64 = kept.iter().zip(&norm).map(|(c, w)| w * c[d]).sum();
            let var: f64 = kept
                .iter()
                .zip(&norm)
                .map(|(c, w)| w * (c[d] - mean).powi(2))
                .sum();
            var.sqrt().clamp(KERNEL_WIDTH.0, KERNEL_WIDTH.1)
        });
        Some(Proposal {
            centres: kept,
            weights: norm,
            width,
        })
    }

    /// One draw (the numbers beyond the whisker's uniform, like the prior's).
    pub fn draw(&self, rng: &mut Rng) -> Uniforms {
        let mut u: Uniforms = std::array::from_fn(|_| rng.uniform());
        if rng.uniform() < PRIOR_SHARE {
            return u;
        }
        let pick = rng.uniform();
        let mut acc = 0.0;
        let mut j = self.centres.len() - 1;
        for (k, w) in self.weights.iter().enumerate() {
            acc += w;
            if pick < acc {
                j = k;
                break;
            }
        }
        for ((u, c), h) in u.iter_mut().zip(&self.centres[j]).zip(&self.width) {
            *u = reflect(c + h * rng.normal());
        }
        u
    }

    /// The mixture's density at `u` over the whisker's uniform numbers (the prior's is 1).
    pub fn density(&self, u: &Uniforms) -> f64 {
        let kernels: f64 = self
            .centres
            .iter()
            .zip(&self.weights)
            .map(|(c, w)| {
                w * (0..WHISKER_UNIFORMS)
                    .map(|d| reflected_normal(u[d], c[d], self.width[d]))
                    .product::<f64>()
            })
            .sum();
        PRIOR_SHARE + (1.0 - PRIOR_SHARE) * kernels
    }
}

/// `x` folded into [0, 1] by reflection at its ends.
fn reflect(x: f64) -> f64 {
    let mut x = x.rem_euclid(2.0);
    if x > 1.0 {
        x = 2.0 - x;
    }
    x
}

/// Density at `u` of a normal of mean `c` and std `h` folded into [0, 1] (its images about 0 and
/// 1 and their next images, beyond which a kernel no wider than [`KERNEL_WIDTH`] has nothing).
fn reflected_normal(u: f64, c: f64, h: f64) -> f64 {
    let phi = |x: f64| (-0.5 * (x / h).powi(2)).exp() / (h * (2.0 * std::f64::consts::PI).sqrt());
    phi(u - c) + phi(u + c) + phi(2.0 - u - c) + phi(u - c - 2.0) + phi(u - c + 2.0)
}

/// The second pass's alternative whiskers and every whisker's prior log weight (the scenario's
/// own first, at 0): `count` draws from the proposal around `first` (the first pass's
/// alternatives' uniform numbers, the scenario's own whisker as [`nominal_uniforms`] first) with
/// `weights` (their posterior weights), each weighted by prior/proposal. `None` when the first pass
/// gave no whisker weight.
pub fn second_pass(
    around: &Around,
    base: &vibrissa_core::sim::Scenario,
    first: &[Uniforms],
    weights: &[f64],
    count: usize,
    seed: u64,
) -> Result<Option<(Vec<WhiskerParams>, Vec<f64>)>> {
    let Some(proposal) = Proposal::around(first, weights) else {
        return Ok(None);
    };
    let mut rng = Rng::stream(seed, SECOND_PASS_STREAM);
    let mut whiskers = Vec::with_capacity(count);
    let mut log_weights = Vec::with_capacity(count + 1);
    log_weights.push(0.0);
    for _ in 0..count {
        let u = proposal.draw(&mut rng);
        let mut s = base.clone();
        around.apply_uniforms(&mut s, &u);
        whiskers.push(s.whisker);
        log_weights.push(-proposal.density(&u).ln());
    }
    Ok(Some((whiskers, log_weights)))
}

/// Stream of the second pass's draws.
const SECOND_PASS_STREAM: u64 = 0x2_0a55;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_folded_kernel_integrates_to_one_on_the_unit_interval() {
        for (c, h) in [
            (0.5, 0.05),
            (0.02, 0.25),
            (0.97, 0.1),
            (0.0, 0.25),
            (1.0, 0.05),
        ] {
            let n = 20_000;
            let integral: f64 = (0..n)
                .map(|i| reflected_normal((i as f64 + 0.5) / n as f64, c, h))
                .sum::<f64>()
                / n as f64;
            assert!(
                (integral - 1.0).abs() < 1e-6,
                "c = {c}, h = {h}: {integral}"
            );
        }
    }

    #[test]
    fn draws_follow_the_density_they_are_weighted_by() {
        // A proposal around two centres; the importance weights 1/q of its draws average to the
        // prior's mass, 1, and the draws land where q is high as often as q says.
        let mut a = nominal_uniforms();
        a[0] = 0.1;
        let mut b = nominal_uniforms();
        b[0] = 0.8;
        b[7] = 0.3;
        let p = Proposal::around(&[a, b], &[0.7, 0.3]).unwrap();
        let mut rng = Rng::new(5);
        let n = 40_000;
        let mean_weight: f64 = (0..n)
            .map(|_| 1.0 / p.density(&p.draw(&mut rng)))
            .sum::<f64>()
            / n as f64;
        assert!((mean_weight - 1.0).abs() < 0.03, "{mean_weight}");
        // No weight above 1/PRIOR_SHARE.
        let worst = (0..1000)
            .map(|_| 1.0 / p.density(&p.draw(&mut rng)))
            .fold(0.0, f64::max);
        assert!(worst <= 1.0 / PRIOR_SHARE + 1e-12, "{worst}");
    }

    #[test]
    fn the_nominal_uniforms_give_the_scenario_s_own_whisker() {
        let family = crate::Family::builtin("e2").unwrap();
        let prior = crate::randomise::Randomisation::default();
        let around = Around::new(family.base(), prior).unwrap();
        let mut s = family.base().clone();
        around.apply_uniforms(&mut s, &nominal_uniforms());
        assert_eq!(s.whisker, family.base().whisker);
    }

    #[test]
    fn a_first_pass_without_weight_gives_no_second() {
        assert!(Proposal::around(&[nominal_uniforms()], &[0.0]).is_none());
        assert!(Proposal::around(&[nominal_uniforms()], &[f64::NAN]).is_none());
    }
}
