//! Drawing boxes from the prior: the initial particles (with hypothesis injection) and the
//! waiting group's redraws, each weighted back to the prior.

use super::config::{Config, Prior};
use super::sampling::{truncated_density, truncated_normal};
use super::transition::{ObjState, Y};
use vibrissa_core::rng::Rng;

/// Share of the redrawn boxes that arrive within [`ARRIVAL_WINDOW`] of now.
const ARRIVAL_SHARE: f64 = 0.5;
/// How soon a favoured arrival comes, s.
const ARRIVAL_WINDOW: f64 = 3e-3;

/// Redraws the box of every particle whose box has not come within `zone` (m) of the whisker by
/// time `t` (marking the others as arrived), from the prior restricted to boxes that have not
/// arrived yet. Half of the draws arrive within [`ARRIVAL_WINDOW`]; each draw is weighted by
/// prior / proposal density, and the redrawn group keeps its total weight.
pub(super) fn redraw_waiting(
    config: &Config,
    objs: &mut [ObjState],
    logw: &mut [f64],
    arrived: &mut [bool],
    t: f64,
    zone: f64,
    mut rng: Rng,
) {
    let pr = &config.priors;
    let travel = config.gap - zone;
    let uni = |rng: &mut Rng, lo: f64, hi: f64| lo + (hi - lo) * rng.uniform();
    let (mut old_mass, mut new_mass) = (0.0f64, 0.0f64);
    let mut group = Vec::new();
    for i in 0..objs.len() {
        if arrived[i] {
            continue;
        }
        let o = &objs[i];
        if o[Y] + o[1] * t >= -zone {
            arrived[i] = true;
            continue;
        }
        if logw[i] == f64::NEG_INFINITY {
            continue;
        }
        // Importance ratio π/q of the draw (π uniform on the allowed region).
        // With hypothesis injection, a share of the speeds and distances comes from the injected
        // estimate (weighted back like the initial draws).
        let inj = config.injection;
        let (v, t0, ratio) = if pr[2].is_free() {
            // Speed from the prior (or the injection), then the arrival time a = t0 + travel/v
            // after t.
            let (v, ratio_v) = match &inj {
                _ if !pr[1].is_free() => (pr[1].lo, 1.0),
                Some(j) => {
                    let v = if rng.uniform() < j.fraction {
                        truncated_normal(&mut rng, j.mean[1], j.std[1], &pr[1])
                    } else {
                        uni(&mut rng, pr[1].lo, pr[1].hi)
                    };
                    let prior = 1.0 / (pr[1].hi - pr[1].lo);
                    let mix = j.fraction * truncated_density(v, j.mean[1], j.std[1], &pr[1])
                        + (1.0 - j.fraction) * prior;
                    (v, prior / mix)
                }
                None => (uni(&mut rng, pr[1].lo, pr[1].hi), 1.0),
            };
            let (lo, hi) = ((pr[2].lo + travel / v).max(t), pr[2].hi + travel / v);
            if hi <= lo {
                (v, pr[2].lo, 0.0)
            } else {
                let soon = ARRIVAL_WINDOW.min(hi - lo);
                let a = if rng.uniform() < ARRIVAL_SHARE {
                    uni(&mut rng, lo, lo + soon)
                } else {
                    uni(&mut rng, lo, hi)
                };
                let q = ARRIVAL_SHARE * f64::from(u8::from(a <= lo + soon)) / soon
                    + (1.0 - ARRIVAL_SHARE) / (hi - lo);
                (v, a - travel / v, ratio_v / q)
            }
        } else if !pr[1].is_free() {
            // Known start and speed: the box arrives when it arrives.
            let (t0, v) = (pr[2].lo, pr[1].lo);
            (v, t0, if t0 + travel / v > t { 1.0 } else { 0.0 })
        } else {
            // Known start: the speeds whose box arrives after t.
            let t0 = pr[2].lo;
            let cap = if t > t0 && travel > 0.0 {
                pr[1].hi.min(travel / (t - t0))
            } else if t > t0 {
                pr[1].lo
            } else {
                pr[1].hi
            };
            if cap <= pr[1].lo {
                (pr[1].lo, t0, 0.0)
            } else {
                // Speeds arriving within the window: v >= travel / (t + window - t0).
                let fast = if travel > 0.0 {
                    (travel / (t + ARRIVAL_WINDOW - t0)).clamp(pr[1].lo, cap)
                } else {
                    pr[1].lo
                };
                let soon = cap - fast;
                let range = Prior::uniform(pr[1].lo, cap);
                let injected = inj.filter(|j| rng.uniform() < j.fraction);
                let v = if let Some(j) = injected {
                    truncated_normal(&mut rng, j.mean[1], j.std[1], &range)
                } else if soon > 0.0 && rng.uniform() < ARRIVAL_SHARE {
                    uni(&mut rng, fast, cap)
                } else {
                    uni(&mut rng, pr[1].lo, cap)
                };
                let share = if soon > 0.0 { ARRIVAL_SHARE } else { 0.0 };
                let q = share * f64::from(u8::from(v >= fast)) / soon.max(f64::MIN_POSITIVE)
                    + (1.0 - share) / (cap - pr[1].lo);
                let q = match &inj {
                    Some(j) => {
                        j.fraction * truncated_density(v, j.mean[1], j.std[1], &range)
                            + (1.0 - j.fraction) * q
                    }
                    None => q,
                };
                (v, t0, 1.0 / q)
            }
        };
        let mut o = [0.0; 5];
        let ratio = match &inj {
            Some(j) if pr[0].is_free() => {
                o[0] = if rng.uniform() < j.fraction {
                    truncated_normal(&mut rng, j.mean[0], j.std[0], &pr[0])
                } else {
                    uni(&mut rng, pr[0].lo, pr[0].hi)
                };
                let prior = 1.0 / (pr[0].hi - pr[0].lo);
                let mix = j.fraction * truncated_density(o[0], j.mean[0], j.std[0], &pr[0])
                    + (1.0 - j.fraction) * prior;
                ratio * prior / mix
            }
            _ => {
                o[0] = uni(&mut rng, pr[0].lo, pr[0].hi);
                ratio
            }
        };
        o[1] = v;
        o[Y] = -config.gap - v * t0;
        o[3] = uni(&mut rng, pr[3].lo, pr[3].hi);
        o[4] = uni(&mut rng, pr[4].lo, pr[4].hi);
        objs[i] = o;
        old_mass += logw[i].exp();
        let lw = logw[i] + ratio.ln();
        new_mass += lw.exp();
        logw[i] = lw;
        group.push(i);
    }
    if new_mass > 0.0 && old_mass > 0.0 {
        let shift = (old_mass / new_mass).ln();
        for i in group {
            logw[i] += shift;
        }
    }
}

/// One particle's initial object state and log importance weight (0 without injection).
pub(super) fn draw_initial(config: &Config, rng: &mut Rng) -> (ObjState, f64) {
    let pr = &config.priors;
    let uni = |rng: &mut Rng, p: &Prior| p.lo + (p.hi - p.lo) * rng.uniform();
    let mut o: ObjState = [0.0; 5];
    let mut lw = 0.0;
    let injected = config.injection;
    let from_proposal = match &injected {
        Some(inj) => rng.uniform() < inj.fraction,
        None => false,
    };
    for k in [0usize, 1] {
        o[k] = if from_proposal {
            let inj = injected.as_ref().expect("checked above");
            truncated_normal(rng, inj.mean[k], inj.std[k], &pr[k])
        } else {
            uni(rng, &pr[k])
        };
    }
    let t0 = uni(rng, &pr[2]);
    o[3] = uni(rng, &pr[3]);
    o[4] = uni(rng, &pr[4]);
    o[Y] = -config.gap - o[1] * t0;
    if let Some(inj) = &injected {
        // prior / mixture density on (d, v).
        let mut prior = 1.0;
        let mut prop = 1.0;
        for k in [0usize, 1] {
            if pr[k].is_free() {
                prior /= pr[k].hi - pr[k].lo;
                prop *= truncated_density(o[k], inj.mean[k], inj.std[k], &pr[k]);
            }
        }
        let mix = (1.0 - inj.fraction) * prior + inj.fraction * prop;
        lw = (prior / mix).ln();
    }
    (o, lw)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pf::config::Injection;
    use crate::pf::transition::start_delay;

    #[test]
    fn injected_particles_are_weighted_back_to_the_prior() {
        // With importance weights prior / mixture, the weighted cloud has the prior's mean even
        // though half of it sits near the injected estimate.
        let mut c = Config::e2([1.0; 5], 1, 3);
        c.injection = Some(Injection {
            fraction: 0.5,
            mean: [0.016, 1.4],
            std: [0.001, 0.05],
        });
        let mut rng = Rng::stream(11, 0);
        let (mut sw, mut sd, mut sv, mut near) = (0.0, 0.0, 0.0, 0usize);
        let n = 40000;
        for _ in 0..n {
            let (o, lw) = draw_initial(&c, &mut rng);
            let w = lw.exp();
            sw += w;
            sd += w * o[0];
            sv += w * o[1];
            near += usize::from((o[0] - 0.016).abs() < 0.002);
        }
        assert!(near > n / 2, "{near}");
        assert!((sd / sw - 0.0225).abs() < 2e-4, "{}", sd / sw);
        assert!((sv / sw - 0.9).abs() < 0.015, "{}", sv / sw);
    }

    #[test]
    fn waiting_boxes_are_redrawn_from_the_prior_given_no_arrival() {
        // Weighted redraws against plain rejection sampling of the prior: same mean start delay
        // and speed among boxes that have not arrived by t, and the group keeps its weight.
        let mut c = Config::e2([1.0; 5], 1, 3);
        c.priors[2] = Prior::uniform(0.0, 0.05);
        let (t, zone, n) = (0.01, 3e-4, 40_000);
        // n waiting boxes of equal weight, redrawn once: their states and new weights.
        let redraw = |c: &Config, seed: u64| {
            let mut objs = vec![[0.02, 1.0, -1.0, 0.01, 0.0]; n];
            let mut logw = vec![(1.0 / n as f64).ln(); n];
            let mut arrived = vec![false; n];
            let rng = Rng::stream(seed, 0);
            redraw_waiting(c, &mut objs, &mut logw, &mut arrived, t, zone, rng);
            let w: Vec<f64> = logw.iter().map(|l| l.exp()).collect();
            (objs, w)
        };
        let (objs, w) = redraw(&c, 5);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        let travel = c.gap - zone;
        let mut soon = 0usize;
        for o in &objs {
            let a = start_delay(o, c.gap) + travel / o[1];
            assert!(a > t, "{o:?}");
            soon += usize::from(a < t + ARRIVAL_WINDOW);
        }
        assert!(soon > n / 3, "{soon}");
        let mean = |f: &dyn Fn(&ObjState) -> f64| -> f64 {
            objs.iter().zip(&w).map(|(o, w)| w * f(o)).sum()
        };
        let (t0_w, v_w) = (mean(&|o| start_delay(o, c.gap)), mean(&|o| o[1]));
        let mut rng = Rng::stream(6, 0);
        let (mut t0_r, mut v_r, mut k) = (0.0, 0.0, 0usize);
        while k < 200_000 {
            let (v, t0) = (0.2 + 1.4 * rng.uniform(), 0.05 * rng.uniform());
            if t0 + travel / v > t {
                t0_r += t0;
                v_r += v;
                k += 1;
            }
        }
        let (t0_r, v_r) = (t0_r / k as f64, v_r / k as f64);
        assert!((t0_w - t0_r).abs() < 6e-4, "{t0_w} vs {t0_r}");
        assert!((v_w - v_r).abs() < 0.02, "{v_w} vs {v_r}");

        // With half the draws injected near d = 16 mm, v = 1.4 m/s, the weights still give the
        // prior's conditional means.
        c.injection = Some(Injection {
            fraction: 0.5,
            mean: [0.016, 1.4],
            std: [0.001, 0.05],
        });
        let (objs, w) = redraw(&c, 7);
        let near = objs.iter().filter(|o| (o[0] - 0.016).abs() < 0.002).count();
        assert!(near > n / 2, "{near}");
        let d_w: f64 = objs.iter().zip(&w).map(|(o, w)| w * o[0]).sum();
        let v_w: f64 = objs.iter().zip(&w).map(|(o, w)| w * o[1]).sum();
        assert!((d_w - 0.0225).abs() < 3e-4, "{d_w}");
        assert!((v_w - v_r).abs() < 0.03, "{v_w} vs {v_r}");
    }

    #[test]
    fn a_known_speed_and_start_is_kept_while_waiting() {
        // e1: v fixed; the waiting boxes keep it and their weights.
        let mut c = Config::e2([1.0; 5], 1, 3);
        c.priors[1] = Prior::fixed(0.6);
        let mut objs = vec![[0.02, 0.6, -1e-3, 0.01, 0.0]; 8];
        let mut logw = vec![(1.0f64 / 8.0).ln(); 8];
        let mut arrived = vec![false; 8];
        redraw_waiting(
            &c,
            &mut objs,
            &mut logw,
            &mut arrived,
            0.0,
            3e-4,
            Rng::stream(1, 0),
        );
        for (o, l) in objs.iter().zip(&logw) {
            assert_eq!(o[1], 0.6);
            assert!((l.exp() - 0.125).abs() < 1e-12);
        }
    }
}
