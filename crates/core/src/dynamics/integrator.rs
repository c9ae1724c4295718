//! The integrator's settings ([`Integrator`]) and the checked coefficients a step uses
//! ([`Stepper`]).

use crate::error::{Error, Result};

/// Largest time step accepted, s.
pub const MAX_DT: f64 = 1.0e-3;

/// Generalized-α settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Integrator {
    /// Time step, s, in (0, [`MAX_DT`]].
    pub dt: f64,
    /// Spectral radius at infinite frequency, in [0.5, 1]: 1 keeps every mode undamped.
    pub rho_inf: f64,
    /// Convergence tolerance of the geometric iterations, rad: a step is repeated with updated
    /// geometry until no segment's direction moves by more than this between evaluation point
    /// and result. 0 always uses `max_iterations`.
    pub tolerance: f64,
    /// Most geometric iterations per step (1 = linearly implicit, one solve per step).
    pub max_iterations: usize,
    /// Substeps of a step near contact, 1 to [`MAX_CONTACT_SUBSTEPS`]: a step that starts in
    /// contact, or with an object closer to the whisker than both can move in two steps, is taken
    /// as this many equal substeps, so that impacts, sliding and release are resolved at
    /// `dt / contact_substeps` while the free whisker keeps the step `dt`
    /// ([`step_with`](super::step_with)). 1, the default, takes every step whole.
    pub contact_substeps: usize,
    /// Steps taken whole (those not in substeps near contact) use a copy of the chain whose
    /// masses and inertias are scaled so that its first mode rings at the chain's own first
    /// natural frequency despite the method's period error at this step (−0.87% at 1 ms for the
    /// w30 whisker), and statics are unchanged ([`step_with`](super::step_with)). false, the
    /// default, steps the chain as it is.
    pub fit_first_mode: bool,
}

impl Default for Integrator {
    fn default() -> Self {
        Integrator {
            dt: 1.0e-4,
            rho_inf: DEFAULT_RHO_INF,
            tolerance: DEFAULT_TOLERANCE,
            max_iterations: DEFAULT_MAX_ITERATIONS,
            contact_substeps: 1,
            fit_first_mode: false,
        }
    }
}

impl Integrator {
    /// Default settings with time step `dt`.
    pub fn with_dt(dt: f64) -> Self {
        Integrator {
            dt,
            ..Default::default()
        }
    }
}

/// Most substeps of a step near contact ([`Integrator::contact_substeps`]).
pub const MAX_CONTACT_SUBSTEPS: usize = 1000;

/// Default geometric tolerance, rad.
pub const DEFAULT_TOLERANCE: f64 = 1.0e-5;

/// Default cap on geometric iterations per step.
pub const DEFAULT_MAX_ITERATIONS: usize = 6;

/// Default high-frequency spectral radius. Smaller values damp unresolved stiff modes faster but
/// make the method overshoot when a stiff, heavily damped mode is kicked (a release, an impact):
/// at N = 100 and dt = 1 ms, a release from a large deflection briefly multiplies the energy by
/// 16 at 0.9 and by 2 at 0.95, and not at all at 0.99.
pub const DEFAULT_RHO_INF: f64 = 0.99;

impl Integrator {
    /// Checks the settings and derives the method's coefficients.
    pub fn check(&self) -> Result<Stepper> {
        let h = self.dt;
        if !(h.is_finite() && h > 0.0 && h <= MAX_DT) {
            return Err(Error::invalid(
                "dt",
                h,
                format!("a time step in (0, {MAX_DT}] s"),
            ));
        }
        let r = self.rho_inf;
        if !(r.is_finite() && (0.5..=1.0).contains(&r)) {
            return Err(Error::invalid("rho_inf", r, "a number in [0.5, 1]"));
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return Err(Error::invalid(
                "tolerance",
                self.tolerance,
                "a finite number >= 0 (rad)",
            ));
        }
        if !(1..=20).contains(&self.max_iterations) {
            return Err(Error::invalid(
                "max_iterations",
                self.max_iterations,
                "an integer from 1 to 20",
            ));
        }
        if !(1..=MAX_CONTACT_SUBSTEPS).contains(&self.contact_substeps) {
            return Err(Error::invalid(
                "contact_substeps",
                self.contact_substeps,
                format!("an integer from 1 (no substeps) to {MAX_CONTACT_SUBSTEPS}"),
            ));
        }
        // Hilber–Hughes–Taylor parameters in the generalized-α family (αm = 0).
        let alpha_m = 0.0;
        let alpha_f = (1.0 - r) / (1.0 + r);
        let gamma = 0.5 + alpha_f - alpha_m;
        let beta = 0.25 * (gamma + 0.5).powi(2);
        let ratio = (1.0 - alpha_f) / (1.0 - alpha_m);
        Ok(Stepper {
            dt: h,
            rho_inf: r,
            tolerance: self.tolerance,
            max_iterations: self.max_iterations,
            contact_substeps: self.contact_substeps,
            fit_first_mode: self.fit_first_mode,
            alpha_m,
            alpha_f,
            gamma,
            beta,
            dq: h * h * beta * ratio,
            dv: h * gamma * ratio,
        })
    }
}

/// Checked integrator settings with derived coefficients. Obtain from [`Integrator::check`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stepper {
    /// Time step, s.
    pub dt: f64,
    /// Spectral radius at infinite frequency.
    pub rho_inf: f64,
    /// Geometric tolerance, rad.
    pub tolerance: f64,
    /// Most geometric iterations per step.
    pub max_iterations: usize,
    /// Substeps of a step near contact (1: none).
    pub contact_substeps: usize,
    /// Whole steps on a chain whose first mode is fitted to the step.
    pub fit_first_mode: bool,
    pub(super) alpha_m: f64,
    pub(super) alpha_f: f64,
    pub(super) gamma: f64,
    pub(super) beta: f64,
    /// ∂q_{n+1}/∂q̈_{n+1}, s².
    pub(super) dq: f64,
    /// ∂v_{n+1}/∂q̈_{n+1}, s.
    pub(super) dv: f64,
}

impl Stepper {
    /// The settings these coefficients were derived from.
    pub fn integrator(&self) -> Integrator {
        Integrator {
            dt: self.dt,
            rho_inf: self.rho_inf,
            tolerance: self.tolerance,
            max_iterations: self.max_iterations,
            contact_substeps: self.contact_substeps,
            fit_first_mode: self.fit_first_mode,
        }
    }
    /// The method's αf: forces balance at `t_{n+1} - αf·dt`.
    pub fn alpha_f(&self) -> f64 {
        self.alpha_f
    }
    pub(crate) fn alpha_f_coef(&self) -> f64 {
        self.alpha_f
    }
    pub(crate) fn beta_coef(&self) -> f64 {
        self.beta
    }
    pub(crate) fn gamma_coef(&self) -> f64 {
        self.gamma
    }
    pub(crate) fn alpha_m_coef(&self) -> f64 {
        self.alpha_m
    }
}
