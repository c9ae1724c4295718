//! The joint angles' gains learnt from a batch of recordings made with one whisker and one way
//! of reading its angles.
//!
//! A recorded joint angle is the model's angle times a gain that stands for more than the
//! sensor: the recording's own chain (a joint angle is the curvature times the joint spacing, so
//! a chain of other segments reads other angles for the same bend) and how its angles were
//! tracked. The filter therefore leaves each angle's gain free within about a factor of two and
//! learns it from the recording (see `sensors`). One strike says little about it, since the
//! distance and the whisker can mimic it; but every strike of a batch shares the chain and the
//! tracker, so what each says about the gains adds up.
//!
//! The batch is combined as in expectation propagation, once. Each recording of the first
//! filtering, begun under the nominal prior `p`, ends with a posterior `q` over each angle's gain
//! (the particles' beliefs mixed and matched to one normal); its message is `q / p`, a
//! precision `1/σq² − 1/σp²` and a precision-weighted mean, and nothing where `q` is not
//! narrower than `p` (a message never adds uncertainty). Every later filtering of a recording
//! begins under the nominal prior times the other recordings' messages, its own left out so
//! that no recording counts twice, and widened by how much the messages scatter beyond their
//! own spreads ([`batch_priors`]). The messages are not renewed from the later filterings:
//! divided by a prior that is already narrow, a posterior of a few thousand particles leaves a
//! message whose mean is mostly Monte Carlo noise.
//!
//! The base wrench's gains are not pooled. They are known to a few percent a priori, and the
//! part of the transition model's error in the wrench that looks like a gain (a coarser chain
//! than the recording's) is the same on every strike: pooled, it becomes a confident wrong gain
//! that the distance follows (on a stand-in recorded by a 50-segment chain, a pooled wrench
//! gain of 0.86 against the true 0.95–1.0 moved every distance by 1 mm). Offsets are not pooled
//! either: a sensor may be zeroed again between strikes.

use super::config::Config;
use serde::Serialize;

/// A normal belief over the gains of `theta01` and `theta12`, each on its own.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AngleGains {
    /// Mean gain of each joint angle.
    pub mean: [f64; 2],
    /// Variance of each.
    pub var: [f64; 2],
}

/// What one recording says about the angles' gains: per angle, a precision and a
/// precision-weighted mean (zero where it says nothing).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GainMessage {
    /// Precision of each angle's gain.
    pub precision: [f64; 2],
    /// Precision times mean of each.
    pub shift: [f64; 2],
}

impl AngleGains {
    /// The prior of `config` over the angles' gains: its [`Config::angle_gains`] where set, else
    /// its sensors' gains spread by its [`Config::sensor_spread`].
    pub fn of(config: &Config) -> AngleGains {
        config
            .angle_gains
            .unwrap_or_else(|| AngleGains::nominal(config))
    }

    /// The prior of `config`'s nominal gains and spread, whatever its [`Config::angle_gains`].
    pub fn nominal(config: &Config) -> AngleGains {
        let (g, s) = (config.sensor_gain, config.sensor_spread.angle_gain);
        AngleGains {
            mean: [g[0], g[1]],
            var: [0, 1].map(|j| (s * g[j]).powi(2)),
        }
    }

    /// Whether every mean is finite and not zero, and every variance finite and not negative.
    pub fn is_valid(&self) -> bool {
        self.mean.iter().all(|g| g.is_finite() && *g != 0.0)
            && self.var.iter().all(|v| v.is_finite() && *v >= 0.0)
    }

    /// The message of a recording whose filter, begun under `prior`, ended at `self`:
    /// `self / prior`, nothing for an angle whose belief did not narrow.
    pub fn divided_by(&self, prior: &AngleGains) -> GainMessage {
        let mut m = GainMessage::default();
        for j in 0..2 {
            let (q, p) = (self.var[j], prior.var[j]);
            if q > 0.0 && q < p {
                m.precision[j] = 1.0 / q - 1.0 / p;
                m.shift[j] = self.mean[j] / q - prior.mean[j] / p;
            }
        }
        m
    }
}

/// Each recording's prior of the angles' gains for the filterings of a batch after the first,
/// from what every other recording said in the first (`messages[r]`, `None` for one not
/// filtered then), which began under `nominal`.
///
/// The gains are taken to vary a little between recordings about the batch's own (a random
/// effect): a constant gain is exact only where the recording's chain is the model's, and
/// another chain's joint angles relate to the model's by a ratio that moves with where the
/// object bends the whisker. How much they vary, `τ²` per angle, is read off the messages
/// themselves (the DerSimonian–Laird estimate: their scatter beyond what each one's own
/// variance explains), at most the nominal variance. Recording `r`'s prior is then the batch's
/// gain as the other recordings give it (each weighted by its variance plus `τ²`, under the
/// nominal prior less `τ²`), spread by `τ²`: the product of the others' messages when they
/// agree, and nearer the nominal the more they scatter.
pub fn batch_priors(nominal: &AngleGains, messages: &[Option<GainMessage>]) -> Vec<AngleGains> {
    let spread: [f64; 2] = std::array::from_fn(|j| between(nominal.var[j], messages, j));
    (0..messages.len())
        .map(|r| {
            let mut prior = *nominal;
            for (j, &tau2) in spread.iter().enumerate() {
                let v0 = nominal.var[j];
                if v0 <= 0.0 || tau2 >= v0 {
                    continue;
                }
                let (mut precision, mut shift) = (1.0 / (v0 - tau2), nominal.mean[j] / (v0 - tau2));
                for (s, m) in messages.iter().enumerate() {
                    if let Some(m) = m.filter(|m| s != r && m.precision[j] > 0.0) {
                        let (mean, var) = (m.shift[j] / m.precision[j], 1.0 / m.precision[j]);
                        precision += 1.0 / (var + tau2);
                        shift += mean / (var + tau2);
                    }
                }
                prior.mean[j] = shift / precision;
                prior.var[j] = 1.0 / precision + tau2;
            }
            prior
        })
        .collect()
}

/// The DerSimonian–Laird estimate of how much angle `j`'s gain varies between the recordings
/// whose `messages` speak of it, at most `most`; `most` where fewer than two do.
fn between(most: f64, messages: &[Option<GainMessage>], j: usize) -> f64 {
    let said: Vec<(f64, f64)> = messages
        .iter()
        .flatten()
        .filter(|m| m.precision[j] > 0.0)
        .map(|m| (m.shift[j] / m.precision[j], m.precision[j]))
        .collect();
    if said.len() < 2 {
        return most;
    }
    let w: f64 = said.iter().map(|(_, w)| w).sum();
    let w2: f64 = said.iter().map(|(_, w)| w * w).sum();
    let mean = said.iter().map(|(m, w)| m * w).sum::<f64>() / w;
    let q: f64 = said.iter().map(|(m, w)| w * (m - mean) * (m - mean)).sum();
    let excess = q - (said.len() - 1) as f64;
    (excess / (w - w2 / w)).clamp(0.0, most)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `prior` times the `messages`: the belief that holds them all. An angle whose
    /// prior fixes its gain (variance 0) keeps it.
    fn times<'a>(
        prior: &AngleGains,
        messages: impl IntoIterator<Item = &'a GainMessage>,
    ) -> AngleGains {
        let (mut precision, mut shift) = ([0.0; 2], [0.0; 2]);
        for m in messages {
            for j in 0..2 {
                precision[j] += m.precision[j];
                shift[j] += m.shift[j];
            }
        }
        let mut out = *prior;
        for j in 0..2 {
            let p = prior.var[j];
            if p > 0.0 && precision[j] > 0.0 {
                let total = 1.0 / p + precision[j];
                out.var[j] = 1.0 / total;
                out.mean[j] = (prior.mean[j] / p + shift[j]) / total;
            }
        }
        out
    }

    fn normal(mean: f64, sd: f64) -> AngleGains {
        AngleGains {
            mean: [mean, 1.0],
            var: [sd * sd, 0.25],
        }
    }

    #[test]
    fn a_message_times_its_prior_gives_back_the_posterior() {
        let prior = normal(1.0, 0.5);
        let post = normal(0.42, 0.05);
        let back = times(&prior, [&post.divided_by(&prior)]);
        assert!((back.mean[0] - 0.42).abs() < 1e-12, "{back:?}");
        assert!((back.var[0] - 0.0025).abs() < 1e-15, "{back:?}");
        // The other angle's belief did not narrow: it says nothing there.
        assert_eq!((back.mean[1], back.var[1]), (1.0, 0.25));
    }

    #[test]
    fn messages_of_a_batch_add_up_as_independent_measurements() {
        // Three recordings each measuring the gain 0.4 ± 0.1 under the prior 1 ± 0.5: a batch
        // holds their product, the sum of the precisions.
        let prior = normal(1.0, 0.5);
        let one = |m: f64| {
            let p = 1.0 / 0.25 + 1.0 / 0.01;
            let mean = (1.0 / 0.25 + m / 0.01) / p;
            AngleGains {
                mean: [mean, 1.0],
                var: [1.0 / p, 0.25],
            }
            .divided_by(&prior)
        };
        let msgs = vec![Some(one(0.4)), Some(one(0.5)), None, Some(one(0.3))];
        let all = batch_priors(&prior, &msgs);
        assert_eq!(all.len(), 4);
        // Recording 2 was not filtered: its prior holds all three messages.
        let p = 1.0 / 0.25 + 3.0 / 0.01;
        assert!((all[2].var[0] - 1.0 / p).abs() < 1e-12);
        assert!((all[2].mean[0] - (1.0 / 0.25 + 1.2 / 0.01) / p).abs() < 1e-9);
        // Recording 0's leaves its own out: the prior and the measurements 0.5 and 0.3.
        let p = 1.0 / 0.25 + 2.0 / 0.01;
        assert!((all[0].mean[0] - (1.0 / 0.25 + 0.8 / 0.01) / p).abs() < 1e-9);
        assert!(all.iter().all(|g| g.is_valid()));
    }

    #[test]
    fn gains_that_scatter_beyond_their_spreads_are_pooled_less() {
        // Four recordings each sure of their gain to ±0.02, scattered by about 0.26: the batch
        // cannot hold one gain, and each prior spreads by their scatter about the others' mean.
        let prior = normal(1.0, 0.5);
        let measured = [0.2, 0.6, 0.4, 0.8];
        let msgs: Vec<Option<GainMessage>> = measured
            .iter()
            .map(|&m| {
                Some(GainMessage {
                    precision: [1.0 / 4e-4, 0.0],
                    shift: [m / 4e-4, 0.0],
                })
            })
            .collect();
        let all = batch_priors(&prior, &msgs);
        // The scatter: the sample variance of the four less their own, 0.0667 − 0.0004.
        let mean = measured.iter().sum::<f64>() / 4.0;
        let tau2 = measured
            .iter()
            .map(|m| (m - mean) * (m - mean))
            .sum::<f64>()
            / 3.0
            - 4e-4;
        assert!((between(0.25, &msgs, 0) - tau2).abs() < 1e-12);
        for (r, p) in all.iter().enumerate() {
            // The nominal prior less the scatter, and the other three each as sure as their
            // own variance plus the scatter.
            let (p0, each) = (1.0 / (0.25 - tau2), 1.0 / (4e-4 + tau2));
            let others = measured.iter().sum::<f64>() - measured[r];
            let precision = p0 + 3.0 * each;
            let want = (p0 + each * others) / precision;
            assert!(
                (p.mean[0] - want).abs() < 1e-12,
                "{r}: {} vs {want}",
                p.mean[0]
            );
            assert!((p.var[0] - (1.0 / precision + tau2)).abs() < 1e-12);
            // Far wider than the product of the messages would be (4e-4 / 3).
            assert!(p.var[0] > tau2, "{r}: {}", p.var[0]);
        }
        // A second angle no recording spoke of keeps the nominal prior.
        assert!(all.iter().all(|p| p.mean[1] == 1.0 && p.var[1] == 0.25));
        // One recording alone says nothing of the scatter: the others keep the nominal.
        let one = batch_priors(&prior, &[msgs[0], None]);
        assert_eq!(one[1], prior);
    }

    #[test]
    fn a_wider_posterior_or_a_fixed_gain_sends_nothing() {
        let prior = normal(1.0, 0.1);
        assert_eq!(normal(0.7, 0.2).divided_by(&prior), GainMessage::default());
        let fixed = normal(1.0, 0.0);
        let msg = normal(0.5, 0.05).divided_by(&normal(1.0, 0.5));
        assert_eq!(times(&fixed, [&msg]), fixed);
    }
}
