//! The chain fitted to a long step ([`Integrator::fit_first_mode`](super::Integrator::fit_first_mode)):
//! a copy whose masses and inertias are scaled so that its first mode, stepped by the method,
//! rings at the source chain's own first natural frequency (see the `substeps` module for what
//! it is for and what it leaves).

use super::integrator::Stepper;
use crate::chain::Model;

/// A chain whose masses are scaled so that its first mode rings at the source chain's first
/// natural frequency when stepped at `dt`.
#[derive(Debug, Clone)]
pub(crate) struct Fitted {
    source: Model,
    dt: f64,
    rho_inf: f64,
    model: Model,
}

impl Fitted {
    /// The chain `model` fitted to the step of `st` (`model` itself where no fit exists).
    pub(super) fn new(model: &Model, st: &Stepper) -> Fitted {
        Fitted {
            source: model.clone(),
            dt: st.dt,
            rho_inf: st.rho_inf,
            model: fit(model, st).unwrap_or_else(|| model.clone()),
        }
    }

    /// The fitted chain.
    pub(super) fn model(&self) -> &Model {
        &self.model
    }

    /// Whether this was fitted to `model` at the step of `st`.
    pub(super) fn fits(&self, model: &Model, st: &Stepper) -> bool {
        let s = &self.source;
        self.dt == st.dt
            && self.rho_inf == st.rho_inf
            && s.n == model.n
            && s.mass == model.mass
            && s.inertia == model.inertia
            && s.com == model.com
            && s.len == model.len
            && s.stiffness == model.stiffness
            && s.damping == model.damping
            && s.rest == model.rest
            && s.radius == model.radius
    }
}

/// Angular frequency, rad/s, at which the method's step `st` makes an undamped oscillator of
/// angular frequency `w` ring: the argument of the complex eigenvalues of its amplification
/// matrix over the step.
fn discrete_frequency(st: &Stepper, w: f64) -> f64 {
    let (h, af, beta, gamma) = (st.dt, st.alpha_f_coef(), st.beta_coef(), st.gamma_coef());
    let w2 = w * w;
    let mut amp = nalgebra::Matrix3::<f64>::zeros();
    for j in 0..3 {
        let (q, v, a) = (
            (j == 0) as u8 as f64,
            (j == 1) as u8 as f64,
            (j == 2) as u8 as f64,
        );
        let a1 = -w2 * ((1.0 - af) * (q + h * v + h * h * (0.5 - beta) * a) + af * q)
            / (1.0 + w2 * (1.0 - af) * beta * h * h);
        let q1 = q + h * v + h * h * ((0.5 - beta) * a + beta * a1);
        let v1 = v + h * ((1.0 - gamma) * a + gamma * a1);
        amp[(0, j)] = q1;
        amp[(1, j)] = v1;
        amp[(2, j)] = a1;
    }
    // The oscillating pair (the third, spurious root is real).
    amp.complex_eigenvalues()
        .iter()
        .filter(|z| z.im != 0.0)
        .map(|z| z.im.atan2(z.re).abs())
        .fold(0.0, f64::max)
        / h
}

/// The chain `model` with masses and inertias scaled so that its first mode, stepped at `st`,
/// rings at `model`'s own first natural frequency. `None` when the modes cannot be found or the
/// step cannot resolve the first mode (its period under four steps).
fn fit(model: &Model, st: &Stepper) -> Option<Model> {
    let f1 = *model.modes().ok()?.frequencies.first()?;
    let w1 = 2.0 * std::f64::consts::PI * f1;
    if !(w1.is_finite() && w1 > 0.0 && w1 * st.dt < 0.5 * std::f64::consts::PI) {
        return None;
    }
    // The frequency that the method turns into w1, by fixed-point iteration.
    let mut w = w1;
    for _ in 0..50 {
        let wd = discrete_frequency(st, w);
        if !(wd.is_finite() && wd > 0.0) {
            return None;
        }
        let next = w * w1 / wd;
        let done = (next - w).abs() <= 1e-14 * w1;
        w = next;
        if done {
            break;
        }
    }
    let scale = (w1 / w).powi(2);
    if !(scale.is_finite() && (0.5..=1.0).contains(&scale)) {
        return None;
    }
    let mut fitted = model.clone();
    fitted.mass.iter_mut().for_each(|m| *m *= scale);
    fitted.inertia.iter_mut().for_each(|i| *i *= scale);
    Some(fitted)
}
