//! The integrator's settings ([`Integrator`]) and the checked coefficients a step uses
//! ([`Stepper`]).

use crate::error::{Error, Result};

/// Largest time step accepted, s.
pub const MAX_DT: f64 = 1.0e-3;

/// The fewest equal steps into which `span` divides so that none is longer than `longest` (at
/// least one; a span a rounding error longer than a whole number of steps takes no extra step).
pub fn equal_steps(span: f64, longest: f64) -> usize {
    ((span / longest) * (1.0 - 1e-9)).ceil().max(1.0) as usize
}

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
    /// Spectral radius at infinite frequency of the steps that begin in lasting contact (an
    /// object carried force in the step before), in [0.5, 1]. A contact held against the
    /// whisker stiffens it beyond what the step resolves, and with almost no damping of that
    /// stiff motion (`rho_inf` = 0.99) its force alternates from step to step about the force
    /// that holds it: the motion stays right but every recorded force is off (the push of a tip
    /// held against a face up to twice its value). [`DEFAULT_CONTACT_RHO_INF`] damps it within a
    /// few steps; `rho_inf`'s value here steps contact as every other step.
    pub contact_rho_inf: f64,
    /// Held contacts: a contact point of the whisker that carried force in the previous step
    /// stays a contact while the step would end with it open by less than it is still closing in
    /// a step, and may then close half that gap within the step, instead of being let go for a
    /// step and struck again in the next. A tip pressed against a surface that turns away from it
    /// (a peg sliding past it) otherwise flickers in and out of contact from step to step, and its
    /// base forces with it, by several times a sensor's noise, in a pattern that changes with
    /// sub-micrometre moves of the object (docs/contact.md, "Held contacts"). false, the default,
    /// judges every contact afresh each step.
    pub hold_contacts: bool,
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
            contact_rho_inf: DEFAULT_CONTACT_RHO_INF,
            hold_contacts: false,
        }
    }
}

impl Integrator {
    /// Substeps near contact that step contact no longer than `longest` seconds at this time
    /// step (at most [`MAX_CONTACT_SUBSTEPS`]), or this integrator's own count where that is
    /// finer.
    pub fn contact_substeps_within(&self, longest: f64) -> usize {
        let wanted = equal_steps(self.dt, longest).min(MAX_CONTACT_SUBSTEPS);
        wanted.max(self.contact_substeps)
    }

    /// Default settings with time step `dt`.
    pub fn with_dt(dt: f64) -> Self {
        Integrator {
            dt,
            ..Default::default()
        }
    }

    /// A warning when this step meets objects coarsely: longer than 0.25 ms with no contact
    /// substeps, where impacts and releases fall on whole steps (the `e2` grid's angles are then
    /// up to 6% of their range off at 0.25 ms and 29% at 1 ms; docs/contact.md). `None`
    /// otherwise, or without objects.
    pub fn coarse_contact_warning(&self, objects: bool) -> Option<String> {
        (objects && self.dt > 2.5e-4 && self.contact_substeps == 1).then(|| {
            format!(
                "dt = {} s steps contact coarsely: impacts and releases fall on whole steps (on \
                 the e2 grid at 1 ms, up to 29% of a channel's range off); set \
                 contact_substeps = 20 and fit_first_mode = true (`--set contact_substeps=20 \
                 --set fit_first_mode=true`: the angles within 1% at 1 ms) or shorten the step",
                self.dt
            )
        })
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

/// Default spectral radius of steps that begin in lasting contact
/// ([`Integrator::contact_rho_inf`]). Measured on the `e2` grid at 0.1 ms against a 1 µs
/// reference: fx within 18.6% of its range (mean 2.6%) instead of 24.5% (3.6%), and the 1 µs and
/// 2 µs references within 3.2% of each other in fx instead of 9.1%; 0.9, 0.95 and 0.6 did no
/// better. Impacts and steps free of contact keep `rho_inf`.
pub const DEFAULT_CONTACT_RHO_INF: f64 = 0.8;

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
        let rc = self.contact_rho_inf;
        if !(rc.is_finite() && (0.5..=1.0).contains(&rc)) {
            return Err(Error::invalid(
                "contact_rho_inf",
                rc,
                "a number in [0.5, 1]",
            ));
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
        let free = Coefs::new(h, r);
        Ok(Stepper {
            dt: h,
            rho_inf: r,
            tolerance: self.tolerance,
            max_iterations: self.max_iterations,
            contact_substeps: self.contact_substeps,
            fit_first_mode: self.fit_first_mode,
            contact_rho_inf: rc,
            hold_contacts: self.hold_contacts,
            alpha_m: free.alpha_m,
            alpha_f: free.alpha_f,
            gamma: free.gamma,
            beta: free.beta,
            dq: free.dq,
            dv: free.dv,
            in_contact: Coefs::new(h, rc),
        })
    }
}

/// The method's coefficients at one step and spectral radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Coefs {
    alpha_m: f64,
    alpha_f: f64,
    gamma: f64,
    beta: f64,
    dq: f64,
    dv: f64,
}

impl Coefs {
    /// Hilber–Hughes–Taylor parameters in the generalized-α family (αm = 0) for step `h` and
    /// spectral radius `r`.
    fn new(h: f64, r: f64) -> Coefs {
        let alpha_m = 0.0;
        let alpha_f = (1.0 - r) / (1.0 + r);
        let gamma = 0.5 + alpha_f - alpha_m;
        let beta = 0.25 * (gamma + 0.5).powi(2);
        let ratio = (1.0 - alpha_f) / (1.0 - alpha_m);
        Coefs {
            alpha_m,
            alpha_f,
            gamma,
            beta,
            dq: h * h * beta * ratio,
            dv: h * gamma * ratio,
        }
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
    /// Spectral radius of steps that begin in lasting contact.
    pub contact_rho_inf: f64,
    /// Whether contacts that carried force are held ([`Integrator::hold_contacts`]).
    pub hold_contacts: bool,
    pub(super) alpha_m: f64,
    pub(super) alpha_f: f64,
    pub(super) gamma: f64,
    pub(super) beta: f64,
    /// ∂q_{n+1}/∂q̈_{n+1}, s².
    pub(super) dq: f64,
    /// ∂v_{n+1}/∂q̈_{n+1}, s.
    pub(super) dv: f64,
    /// The coefficients at `contact_rho_inf`.
    in_contact: Coefs,
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
            contact_rho_inf: self.contact_rho_inf,
            hold_contacts: self.hold_contacts,
        }
    }
    /// These settings for a step that begins in lasting contact: the coefficients of
    /// `contact_rho_inf` in place of `rho_inf`'s.
    pub(super) fn in_contact(&self) -> Stepper {
        let c = self.in_contact;
        Stepper {
            rho_inf: self.contact_rho_inf,
            alpha_m: c.alpha_m,
            alpha_f: c.alpha_f,
            gamma: c.gamma,
            beta: c.beta,
            dq: c.dq,
            dv: c.dv,
            ..*self
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
