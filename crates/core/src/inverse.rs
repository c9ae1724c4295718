//! Beam-theory inverse estimators of the contact distance: the field's closed-form baselines.
//!
//! Each estimator is a pure function of base measurements and returns the arc length `C` from
//! the base to a single point contact (SI units). All rest on the small-deflection cantilever
//! clamped at the base with a transverse point force `W` at `C` (the seed paper's cubic,
//! [`crate::beam::PointLoadCubic`]):
//!
//! ```text
//! v(x) = (W/EI) (C x²/2 − x³/6),   v'(x) = (W/EI)(C x − x²/2),   M(x) = W (C − x)   (x < C)
//! ```
//!
//! * [`moment_over_force`]: `C = |m0| / |f|` (the M/F method).
//! * [`from_joint_angles`]: the chain's two base joint angles are moment samples
//!   (`θ = M/k` at joints 0 and 1), so `C = l M0 / (M0 − M1)`.
//! * [`from_chord_angles`]: the continuum's first two chord angles, solved in closed form.
//! * [`from_moment_and_angle`]: base moment and first chord angle (Birdwell's pair).
//! * [`kaneko_torque_angle`]: base rotation since first contact against a fixed point, and the
//!   base torque: `C = 3 EI Δψ / M`.
//! * [`birdwell_rates`]: Birdwell's pair in rate form, `C = 3 EI ψ̇ / ṁ0`.
//! * [`kaneko_frequency`]: inverts Kaneko's tip-mass frequency `ω(C)`.
//! * [`kaneko_frequency_beam`]: inverts the first frequency of the beam with its own mass,
//!   clamped at the base and propped at `C` ([`pinned_beam_omega`]).
//!
//! [`evaluate_peg_sweep`] runs every estimator on simulated whisks against stationary pegs and
//! tabulates the error against the true contact arc length.
//!
//! # The chord relations (continuum)
//!
//! With chords of length `l` from `x = 0` to `l` and `l` to `2l` (both proximal to the load,
//! `C ≥ 2l`), `k = W/EI`, small angles (angle = chord slope):
//!
//! ```text
//! θ01         = v(l)/l              = k (C l/2 − l²/6)
//! θ01 + θ12   = (v(2l) − v(l))/l    = k (3 C l/2 − 7 l²/6)
//! θ12                               = k (C l − l²)
//! ```
//!
//! Eliminating `k`: `C = l (6 θ01 − θ12) / (6 θ01 − 3 θ12)`, then `W = EI θ12 / (l (C − l))`.
//! The denominator `6θ01 − 3θ12 = 2 k l²` is a small difference of two `O(k C l)` terms, so
//! relative errors in the angles are amplified by about `C/l`.
//!
//! # Why the chain's joint angles are not chord angles of the cubic
//!
//! A segment chain's joint `i` is a rotational spring, so statically its angle is the bending
//! moment there over the joint stiffness: `θ_i = M(x_i)/k_i`. With the default stiffness rule
//! (hat-weighted compliance with Gregory's end correction) a uniform whisker has
//! `1/k0 = 5l/(12 EI)` and `1/k1 = 13l/(12 EI)`, hence
//! `θ01 = (5/12) k C l` rather than the continuum chord's `k (C l/2 − l²/6)`: the chain's first
//! node sits about 17 % below the cubic even though its tip deflection is third-order accurate.
//! The continuum chord formulas ([`from_chord_angles`], [`from_moment_and_angle`]) therefore do
//! not apply to a chain's observations; [`from_joint_angles`] uses the chain's own relation and is
//! exact for it in small deflection. For the same reason `θ01 = m0/k0` on a chain, so the pair
//! (m0, θ01) carries one number, not two.

use crate::beam::{kaneko_omega, BeamProfile};
use crate::chain::{Discretisation, Model};
use crate::dynamics::{step, Inputs, Integrator, State, Workspace};
use crate::error::{check_finite, check_positive, Error, Result};
use crate::scenes::peg;
use crate::sensors::Sensors;
use crate::sim::BaseDrive;
use crate::statics;
use crate::whisker::WhiskerParams;
use nalgebra::DMatrix;
use rayon::prelude::*;
use serde::Serialize;

/// Rayleigh's equivalent tip mass of a uniform cantilever, as a fraction of its mass (33/140).
pub const RAYLEIGH_TIP_MASS: f64 = 33.0 / 140.0;

fn nonzero(name: &str, value: f64) -> Result<f64> {
    if value.is_finite() && value != 0.0 {
        Ok(value)
    } else {
        Err(Error::invalid(name, value, "a finite non-zero number"))
    }
}

/// The M/F estimate `C = |m0| / |f|`, m (Solomon and Hartmann's moment over force).
///
/// For a point force on a straight whisker the base moment is the force times the distance of
/// its line of action from the base. With a frictionless contact the force is normal to the
/// whisker at the contact, so that distance is the arc length up to second order in the
/// contact slope `φ`. This variant divides by the whole force `|f| = hypot(fx, fy)`: for the
/// cubic it gives `s (1 + φ²/15)`, while dividing by the transverse component `fy` alone
/// ([`moment_over_transverse_force`]) gives `s (1 + 17 φ²/30)`, because the tilted force's
/// axial component shortens `fy` and adds the lever `cy·fx`. The two agree at small deflection.
///
/// Errors: non-finite input or a zero force.
pub fn moment_over_force(m0: f64, fx: f64, fy: f64) -> Result<f64> {
    check_finite("m0", m0)?;
    check_finite("fx", fx)?;
    check_finite("fy", fy)?;
    Ok(m0.abs() / nonzero("|f|", fx.hypot(fy))?)
}

/// The M/F variant `C = |m0| / |fy|` with the force perpendicular to the base direction, m.
///
/// See [`moment_over_force`]; this one over-reads by about `17 φ²/30` relative at contact
/// slope `φ`. Errors: non-finite input or `fy = 0`.
pub fn moment_over_transverse_force(m0: f64, fy: f64) -> Result<f64> {
    check_finite("m0", m0)?;
    Ok(m0.abs() / nonzero("fy", fy)?.abs())
}

/// Force `W` (N) and distance `C` (m) from the first two continuum chord angles.
///
/// `theta01` is the angle of the chord from the base to arc length `l`, `theta12` the angle of
/// the next chord (`l` to `2l`) relative to the first, both rad; `ei` is the bending stiffness
/// (N·m²). Closed form of the module's chord relations (valid for `C ≥ 2l`, small angles):
/// `C = l (6θ01 − θ12)/(6θ01 − 3θ12)`, `W = EI θ12 / (l (C − l))`. `W` takes the sign of the
/// deflection. Not for a segment chain's joint angles: use [`from_joint_angles`] there.
///
/// Errors: non-finite input, `l` or `ei` not positive, or degenerate angles.
pub fn from_chord_angles(theta01: f64, theta12: f64, l: f64, ei: f64) -> Result<(f64, f64)> {
    check_finite("theta01", theta01)?;
    check_finite("theta12", theta12)?;
    check_positive("l", l)?;
    check_positive("ei", ei)?;
    let den = nonzero("6·theta01 − 3·theta12", 6.0 * theta01 - 3.0 * theta12)?;
    let c = l * (6.0 * theta01 - theta12) / den;
    // W from θ01 = (W/EI)(C l/2 − l²/6), which has no singularity at C = l.
    let w = ei * theta01 / nonzero("C l/2 − l²/6", c * l / 2.0 - l * l / 6.0)?;
    Ok((w, c))
}

/// Force `W` (N) and distance `C` (m) from the base moment and the first chord angle.
///
/// Statics gives the bending moment at the base `W C`, which the base balances: with the
/// contract's sign (`m0` is the moment the base applies to the whisker) `W C = −m0`. With the
/// first chord angle `θ01 = (W/EI)(C l/2 − l²/6)` over chord length `l`:
/// `W = 6 (−m0 l/2 − EI θ01) / l²` and `C = −m0 / W`. The `W` term is the small difference
/// `m0 l/2 − EI θ01 = O(W l²)`, so errors are amplified by about `3C/l`. On a segment chain
/// `θ01 = m0/k0` exactly in statics and this pair is degenerate (see the module notes).
///
/// Errors: non-finite input, `l` or `ei` not positive, or a zero force.
pub fn from_moment_and_angle(m0: f64, theta01: f64, l: f64, ei: f64) -> Result<(f64, f64)> {
    check_finite("m0", m0)?;
    check_finite("theta01", theta01)?;
    check_positive("l", l)?;
    check_positive("ei", ei)?;
    let w = nonzero("W", 6.0 * (-m0 * l / 2.0 - ei * theta01) / (l * l))?;
    Ok((w, -m0 / w))
}

/// Force `W` (N) and distance `C` (m) from a chain's first two joint angles.
///
/// Statically joint `i` of a segment chain turns by the bending moment there over its
/// stiffness, `θ_i = M(x_i)/k_i`, so `M0 = k0 θ01` and `M1 = k1 θ12`. For a single point load
/// beyond the second joint, `M(x) = W (C − x)` and joint 1 sits at `x = l` (the first chord's
/// length), hence `W = (M0 − M1)/l` and `C = l M0 / (M0 − M1)`. Exact for the chain in small
/// deflection and for any stiffness profile; relative errors in the angles are amplified by
/// about `C/l`. `W` takes the sign of the deflection.
///
/// Errors: non-finite input, `l`, `k0` or `k1` not positive, or `M0 = M1`.
pub fn from_joint_angles(
    theta01: f64,
    theta12: f64,
    l: f64,
    k0: f64,
    k1: f64,
) -> Result<(f64, f64)> {
    check_finite("theta01", theta01)?;
    check_finite("theta12", theta12)?;
    check_positive("l", l)?;
    check_positive("k0", k0)?;
    check_positive("k1", k1)?;
    let (m0, m1) = (k0 * theta01, k1 * theta12);
    let w = nonzero("M0 − M1", m0 - m1)? / l;
    Ok((w, m0 / w))
}

/// Kaneko's rotation-and-torque estimate `C = 3 EI |Δψ| / |m0|`, m.
///
/// The base of a straight, unloaded whisker turns by `Δψ` (rad) after it first touches a fixed
/// point, and the base torque rises to `m0` (N·m). The touched point cannot move, so relative to
/// the rigidly rotated whisker it is deflected by `δ = C Δψ` (small angles). A clamped uniform
/// cantilever needs `W = 3 EI δ / C³` for that, and the base torque is `M = W C`:
/// `M = 3 EI Δψ / C`, so `C = 3 EI Δψ / M` (linear in `Δψ/M`, not a square root).
///
/// Assumptions: uniform `EI`, clamped base, straight and unloaded at first contact, a point
/// contact that neither moves nor slides along the whisker, small deflection, quasi-static
/// loading (no ringing, no damping lag).
///
/// Errors: non-finite input, `ei` not positive, or `m0 = 0`.
pub fn kaneko_torque_angle(delta_psi: f64, m0: f64, ei: f64) -> Result<f64> {
    check_finite("delta_psi", delta_psi)?;
    check_positive("ei", ei)?;
    Ok(3.0 * ei * delta_psi.abs() / nonzero("m0", m0)?.abs())
}

/// Kaneko's dynamic estimate: the `C` (m) at which [`kaneko_omega`] equals `omega` (rad/s).
///
/// Kaneko's model is a massless cantilever of stiffness `ei` and length `length` with a tip mass
/// `tip_mass`, propped at `C` while in contact; `ω(C)` rises monotonically from the free
/// tip-mass frequency `sqrt(3EI/(M L³))` at `C = 0` to infinity at `C = L`. Bisection on
/// `c = C/L ∈ [0, 1]` to round-off. A frequency below the free one returns 0; the result is
/// always in `[0, L)`.
///
/// A uniform whisker is not a massless beam with a tip mass: its mass is spread along it, and
/// propped at `C` its first frequency stays finite as `C → L` (the clamped–pinned beam), so the
/// estimate is biased; [`evaluate_peg_sweep`] measures by how much with Rayleigh's equivalent
/// tip mass ([`RAYLEIGH_TIP_MASS`]).
///
/// Errors: `omega`, `ei`, `tip_mass` or `length` not finite and positive.
pub fn kaneko_frequency(omega: f64, ei: f64, tip_mass: f64, length: f64) -> Result<f64> {
    check_positive("omega", omega)?;
    check_positive("ei", ei)?;
    check_positive("tip_mass", tip_mass)?;
    check_positive("length", length)?;
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    if kaneko_omega(ei, tip_mass, length, 0.0) >= omega {
        return Ok(0.0);
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if kaneko_omega(ei, tip_mass, length, mid) < omega {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok(0.5 * (lo + hi) * length)
}

/// First natural angular frequency (rad/s) of a uniform Euler–Bernoulli beam clamped at its base
/// and propped (pinned) at arc length `c`, free at its tip: the in-contact frequency of a whisker
/// touching a point, with its mass spread along it (Kaneko's analysis for a beam with mass rather
/// than a massless beam with a tip mass).
///
/// With `β⁴ = ρA ω² / EI`, the base span is `A(cosh − cos) + B(sinh − sin)`, the outer span
/// `a cosh + b sinh + c cos + d sin` of the distance beyond the prop; the prop (zero deflection,
/// continuous slope and moment) and the free tip (zero moment and shear) give six homogeneous
/// equations whose determinant vanishes at the natural frequencies. The first root in βL is
/// bracketed by a scan and refined by bisection: 1.8751 (prop at the base: the cantilever) to
/// 3.9266 (prop at the tip: the clamped–pinned beam).
///
/// Errors: `ei`, `rho_a` or `length` not finite and positive, or `c` outside `[0, length]`.
pub fn pinned_beam_omega(ei: f64, rho_a: f64, length: f64, c: f64) -> Result<f64> {
    check_positive("ei", ei)?;
    check_positive("rho_a", rho_a)?;
    check_positive("length", length)?;
    if !(c.is_finite() && (0.0..=length).contains(&c)) {
        return Err(Error::invalid("c", c, "an arc length in [0, length]"));
    }
    // A prop at the very base is the clamp itself (the base span would vanish).
    let c = c.max(1e-6 * length);
    let det = |bl: f64| -> f64 {
        let b = bl / length;
        let (x, y) = (b * c, b * (length - c));
        let (chc, shc, cc, sc) = (x.cosh(), x.sinh(), x.cos(), x.sin());
        let (chd, shd, cd, sd) = (y.cosh(), y.sinh(), y.cos(), y.sin());
        // Unknowns A, B, a, b, c, d.
        let m = DMatrix::from_row_slice(
            6,
            6,
            &[
                chc - cc,
                shc - sc,
                0.0,
                0.0,
                0.0,
                0.0, //
                0.0,
                0.0,
                1.0,
                0.0,
                1.0,
                0.0, //
                -(shc + sc),
                -(chc - cc),
                0.0,
                1.0,
                0.0,
                1.0, //
                -(chc + cc),
                -(shc + sc),
                1.0,
                0.0,
                -1.0,
                0.0, //
                0.0,
                0.0,
                chd,
                shd,
                -cd,
                -sd, //
                0.0,
                0.0,
                shd,
                chd,
                sd,
                -cd,
            ],
        );
        m.determinant()
    };
    // Scan βL from below the cantilever's root for the first sign change, then bisect.
    let (mut lo, mut flo) = (1.0f64, det(1.0));
    let mut hi = lo;
    let mut found = false;
    while hi < 5.0 {
        hi = lo + 0.01;
        let fhi = det(hi);
        if flo == 0.0 || flo.signum() != fhi.signum() {
            found = true;
            break;
        }
        (lo, flo) = (hi, fhi);
    }
    if !found {
        return Err(Error::NoConvergence {
            what: "propped-beam frequency".into(),
            detail: format!("no root of the frequency equation below βL = 5 (c = {c} m)"),
        });
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        let fm = det(mid);
        if fm == 0.0 {
            (lo, hi) = (mid, mid);
            break;
        }
        if fm.signum() == flo.signum() {
            (lo, flo) = (mid, fm);
        } else {
            hi = mid;
        }
    }
    let beta = 0.5 * (lo + hi) / length;
    Ok(beta * beta * (ei / rho_a).sqrt())
}

/// Where the propped beam's first frequency peaks, as a fraction of the length: beyond it the
/// frequency falls again toward the clamped–pinned beam's, so one frequency belongs to two props
/// (the bi-valued estimator the seed paper warns of). Found by a golden-section search.
pub fn pinned_beam_peak(ei: f64, rho_a: f64, length: f64) -> Result<f64> {
    let f = |x: f64| pinned_beam_omega(ei, rho_a, length, x * length);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut a, mut b) = (0.5f64, 1.0f64);
    let (mut x1, mut x2) = (b - g * (b - a), a + g * (b - a));
    let (mut f1, mut f2) = (f(x1)?, f(x2)?);
    for _ in 0..60 {
        if f1 > f2 {
            b = x2;
            (x2, f2) = (x1, f1);
            x1 = b - g * (b - a);
            f1 = f(x1)?;
        } else {
            a = x1;
            (x1, f1) = (x2, f2);
            x2 = a + g * (b - a);
            f2 = f(x2)?;
        }
    }
    Ok(0.5 * (a + b))
}

/// Kaneko's frequency method with the beam's own mass: the contact arc length `C` (m) at which
/// [`pinned_beam_omega`] equals the measured in-contact frequency `omega` (rad/s), on the branch
/// where the frequency rises with `C` (from the free cantilever's up to its peak at
/// [`pinned_beam_peak`]); a frequency outside that range gives `0` or the peak's `C`. Props
/// beyond the peak cannot be told from props before it by the frequency alone.
///
/// Errors: as [`pinned_beam_omega`], or `omega` not finite and positive.
pub fn kaneko_frequency_beam(omega: f64, ei: f64, rho_a: f64, length: f64) -> Result<f64> {
    check_positive("omega", omega)?;
    let peak = pinned_beam_peak(ei, rho_a, length)? * length;
    if pinned_beam_omega(ei, rho_a, length, 0.0)? >= omega {
        return Ok(0.0);
    }
    if pinned_beam_omega(ei, rho_a, length, peak)? <= omega {
        return Ok(peak);
    }
    let (mut lo, mut hi) = (0.0f64, peak);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if pinned_beam_omega(ei, rho_a, length, mid)? < omega {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok(0.5 * (lo + hi))
}

/// Birdwell's pair in its temporal-derivative form: while the base turns at `psi_rate` (rad/s)
/// against a fixed point, the base torque changes at `m0_rate` (N·m/s), and the small-deflection
/// cantilever gives `C = 3 EI ψ̇ / ṁ0` (the rate form of [`kaneko_torque_angle`]; it needs no
/// first-contact angle).
///
/// Errors: a rate that is zero or not finite, or `ei` not finite and positive.
pub fn birdwell_rates(psi_rate: f64, m0_rate: f64, ei: f64) -> Result<f64> {
    check_positive("ei", ei)?;
    let psi_rate = nonzero("psi_rate", psi_rate)?;
    let m0_rate = nonzero("m0_rate", m0_rate)?;
    Ok(3.0 * ei * (psi_rate / m0_rate).abs())
}

/// Lowest undamped natural angular frequency (rad/s) of `model` with its centreline point at
/// arc length `s` held against motion normal to the whisker (a bilateral pin), linearised about
/// the rest shape with the base fixed. This is the in-contact frequency a frequency-based
/// estimator assumes it measures.
///
/// Errors: `s` outside `[0, L]`, or a failed factorisation.
pub fn pinned_frequency(model: &Model, s: f64) -> Result<f64> {
    let n = model.n;
    let (seg, along) = model.locate(s)?;
    let nodes = statics::nodes(model, &model.rest, 0.0);
    let (a, b) = (nodes[seg], nodes[seg + 1]);
    let dir = [
        (b[0] - a[0]) / model.len[seg],
        (b[1] - a[1]) / model.len[seg],
    ];
    let p = [a[0] + along * dir[0], a[1] + along * dir[1]];
    let normal = [-dir[1], dir[0]];
    // Normal velocity of p per unit rate of joint j (j ≤ seg): ẑ × (p − node j), projected.
    let g: Vec<f64> = (0..n)
        .map(|j| {
            if j > seg {
                0.0
            } else {
                let r = [p[0] - nodes[j][0], p[1] - nodes[j][1]];
                normal[0] * -r[1] + normal[1] * r[0]
            }
        })
        .collect();
    let mass = model.mass_matrix(&model.rest);
    let piv = (0..n)
        .max_by(|&i, &j| g[i].abs().total_cmp(&g[j].abs()))
        .unwrap_or(0);
    // Null-space basis of g: columns e_j − (g_j/g_piv) e_piv, j ≠ piv (identity if g = 0).
    let z = if g[piv] == 0.0 {
        DMatrix::identity(n, n)
    } else {
        let mut z = DMatrix::zeros(n, n - 1);
        for (col, j) in (0..n).filter(|&j| j != piv).enumerate() {
            z[(j, col)] = 1.0;
            z[(piv, col)] = -g[j] / g[piv];
        }
        z
    };
    let k = DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(&model.stiffness));
    let mr = z.transpose() * mass * &z;
    let kr = z.transpose() * k * &z;
    let fail = |detail: &str| Error::NoConvergence {
        what: "pinned modal analysis".into(),
        detail: detail.into(),
    };
    let chol = mr
        .cholesky()
        .ok_or_else(|| fail("reduced mass matrix is not positive definite"))?;
    let linv = chol
        .l()
        .try_inverse()
        .ok_or_else(|| fail("singular Cholesky factor"))?;
    let a = &linv * kr * linv.transpose();
    let a = (&a + a.transpose()) * 0.5;
    let low = a.symmetric_eigen().eigenvalues.min();
    Ok(low.max(0.0).sqrt())
}

/// The estimators [`evaluate_peg_sweep`] compares.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Estimator {
    /// [`moment_over_force`] (`|m0|/|f|`).
    MomentOverForce,
    /// [`moment_over_transverse_force`] (`|m0|/|fy|`).
    MomentOverTransverseForce,
    /// [`from_joint_angles`] with the chain's joint stiffnesses.
    JointAngles,
    /// [`from_chord_angles`] (continuum chord relations) fed the chain's joint angles.
    ChordAngles,
    /// [`from_moment_and_angle`] (continuum) fed m0 and the chain's theta01.
    MomentAndAngle,
    /// [`kaneko_torque_angle`] with the base rotation since first contact.
    KanekoTorqueAngle,
    /// [`kaneko_frequency`] on the chain's pinned frequency with Rayleigh's tip mass.
    KanekoFrequency,
    /// [`birdwell_rates`] with the base's turning rate and the torque's rate over the last
    /// millisecond.
    BirdwellRates,
    /// [`kaneko_frequency_beam`] on the chain's pinned frequency.
    KanekoFrequencyBeam,
}

impl Estimator {
    /// All estimators, in table order.
    pub const ALL: [Estimator; 9] = [
        Estimator::MomentOverForce,
        Estimator::MomentOverTransverseForce,
        Estimator::JointAngles,
        Estimator::ChordAngles,
        Estimator::MomentAndAngle,
        Estimator::KanekoTorqueAngle,
        Estimator::BirdwellRates,
        Estimator::KanekoFrequency,
        Estimator::KanekoFrequencyBeam,
    ];

    /// Short name for tables.
    pub fn name(self) -> &'static str {
        match self {
            Estimator::MomentOverForce => "m/|f|",
            Estimator::MomentOverTransverseForce => "m/fy",
            Estimator::JointAngles => "joint angles",
            Estimator::ChordAngles => "chord angles",
            Estimator::MomentAndAngle => "m0 + theta01",
            Estimator::KanekoTorqueAngle => "kaneko rotation",
            Estimator::KanekoFrequency => "kaneko frequency",
            Estimator::BirdwellRates => "birdwell rates",
            Estimator::KanekoFrequencyBeam => "kaneko freq. beam",
        }
    }
}

/// One estimate against the truth.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct InverseResult {
    /// The estimator.
    pub estimator: Estimator,
    /// Distance of the peg's centre from the base along x, m.
    pub d: f64,
    /// Requested tip deflection, fraction of L (0 for [`Estimator::KanekoFrequency`], which uses
    /// the contact's ringing rather than a deflection).
    pub level: f64,
    /// Tip deflection at the sample, relative to the rotated base, fraction of L.
    pub tip_deflection: f64,
    /// Time from first contact to the sample, s.
    pub since_contact: f64,
    /// True arc length of the contact, m.
    pub true_s: f64,
    /// Estimated contact distance, m (NaN where the estimator gave none).
    pub estimate: f64,
    /// `estimate / true_s − 1`.
    pub relative_error: f64,
}

/// The simulated protocol of [`evaluate_peg_sweep`].
#[derive(Debug, Clone, PartialEq)]
pub struct PegSweep {
    /// Peg centres' distances from the base along x, m.
    pub distances: Vec<f64>,
    /// Tip-deflection levels, fractions of L, ascending.
    pub levels: Vec<f64>,
    /// Levels up to this fraction are sampled no earlier than `settle` after first contact.
    pub settle_below: f64,
    /// Settling time for the small levels, s.
    pub settle: f64,
    /// Whisking rate, rad/s.
    pub rate: f64,
    /// Segment count N.
    pub segments: usize,
    /// Time step, s.
    pub dt: f64,
    /// Longest simulated time per peg, s.
    pub max_time: f64,
}

impl Default for PegSweep {
    /// Pegs at 5, 7, …, 29 mm; levels 0.5, 2, 5, 10, 20 % of L; 0.3 s settling for levels up
    /// to 0.5 %; 0.05 rad/s; N = 20; 0.1 ms steps; at most 6 s per peg.
    fn default() -> Self {
        PegSweep {
            distances: (0..13).map(|k| 0.005 + 0.002 * k as f64).collect(),
            levels: vec![0.005, 0.02, 0.05, 0.10, 0.20],
            settle_below: 0.005,
            settle: 0.3,
            rate: 0.05,
            segments: 20,
            dt: 1e-4,
            max_time: 6.0,
        }
    }
}

/// The sensors at one level crossing.
#[derive(Debug, Clone, Copy)]
struct Sample {
    level: f64,
    tip: f64,
    since: f64,
    s: f64,
    sensors: Sensors,
    delta_psi: f64,
    /// Base turning rate and base-torque rate over the last millisecond, rad/s and N·m/s.
    psi_rate: f64,
    m0_rate: f64,
}

/// Whisks the w30 whisker (ζ1 = 0.05) at `sweep.rate` into a stationary frictionless peg of
/// radius 0.5 mm whose surface is 0.02 mm clear of the whisker's upper surface, centred at
/// `d` along x, for every distance; at every tip-deflection level applies all estimators to the
/// sensors and returns one row per (estimator, distance, level) sample reached.
///
/// A level is sampled at the first step with contact whose tip deflection (relative to the
/// rotated base) reaches it, and for levels up to `settle_below` no sooner than `settle` after
/// first contact; at a constant whisking rate such a level is therefore read at a larger
/// deflection, recorded in [`InverseResult::tip_deflection`]. The Kaneko rotation uses the base
/// angle's rise since first contact; the frequency method one row per peg, from
/// [`pinned_frequency`] at the first contact's arc length. Levels not reached before the peg
/// slips off the whisker or `max_time` give no rows.
pub fn evaluate_peg_sweep(sweep: &PegSweep) -> Result<Vec<InverseResult>> {
    let w = WhiskerParams::w30().check()?;
    let model = Model::new(&w, sweep.segments, Discretisation::Gregory)?;
    let stepper = Integrator::with_dt(sweep.dt).check()?;
    let rows: Vec<Vec<InverseResult>> = sweep
        .distances
        .par_iter()
        .map(|&d| one_peg(&model, &stepper, sweep, d))
        .collect::<Result<_>>()?;
    Ok(rows.into_iter().flatten().collect())
}

fn one_peg(
    model: &Model,
    stepper: &crate::dynamics::Stepper,
    sweep: &PegSweep,
    d: f64,
) -> Result<Vec<InverseResult>> {
    let w = &model.whisker;
    let (ei, length) = (w.ei(0.0), w.length());
    let radius = 0.5e-3;
    let objects = [peg(d, radius + w.radius(d) + 0.02e-3, radius, 0.0)];
    let drive = BaseDrive::Ramp {
        rate: sweep.rate,
        start: 0.0,
        stop: f64::INFINITY,
        smoothing: 0.02,
    };
    let mut s = State::at_rest(model, 0);
    let mut ws = Workspace::new(model);
    let mut first: Option<(f64, f64, f64)> = None; // (t, base angle, s)
    let mut last_contact = 0.0;
    let mut samples: Vec<Sample> = Vec::new();
    let mut next = 0;
    // The last millisecond of (t, base angle, m0), for the rates.
    let lag = ((1e-3 / stepper.dt).round() as usize).max(1);
    let mut recent: std::collections::VecDeque<(f64, f64, f64)> =
        std::collections::VecDeque::with_capacity(lag + 1);
    let steps = (sweep.max_time / stepper.dt).ceil() as usize;
    for k in 1..=steps {
        let inputs = Inputs {
            base: drive.at(k as f64 * stepper.dt),
            objects: &objects,
            ..Default::default()
        };
        step(model, stepper, &mut s, &inputs, &mut ws)?;
        recent.push_back((s.t, s.base.angle, Sensors::read(&s).m0));
        if recent.len() > lag + 1 {
            recent.pop_front();
        }
        let Some(c) = s.contact else {
            // Slipped off the peg after a settled contact: nothing more to read.
            if let Some((t0, _, _)) = first {
                if s.t - t0 > sweep.settle && s.t - last_contact > 0.05 {
                    break;
                }
            }
            continue;
        };
        last_contact = s.t;
        let (t0, psi0, _) = *first.get_or_insert((s.t, s.base.angle, c.s));
        ws.evaluate(model, &s);
        let (sn, cs) = s.base.angle.sin_cos();
        let tip = ws.nodes()[model.n];
        let tip = (-sn * tip[0] + cs * tip[1]).abs() / length;
        while next < sweep.levels.len() && tip >= sweep.levels[next] {
            let level = sweep.levels[next];
            if level <= sweep.settle_below && s.t - t0 < sweep.settle {
                break;
            }
            let (&(ta, pa, ma), &(tb, pb, mb)) = (
                recent.front().expect("this step is recorded"),
                recent.back().expect("this step is recorded"),
            );
            let span = (tb - ta).max(f64::MIN_POSITIVE);
            samples.push(Sample {
                level,
                tip,
                since: s.t - t0,
                s: c.s,
                sensors: Sensors::read(&s),
                delta_psi: s.base.angle - psi0,
                psi_rate: (pb - pa) / span,
                m0_rate: (mb - ma) / span,
            });
            next += 1;
        }
        if next == sweep.levels.len() {
            break;
        }
    }
    let row = |estimator, level, tip, since, true_s: f64, estimate: Result<f64>| {
        let estimate = estimate.unwrap_or(f64::NAN);
        InverseResult {
            estimator,
            d,
            level,
            tip_deflection: tip,
            since_contact: since,
            true_s,
            estimate,
            relative_error: estimate / true_s - 1.0,
        }
    };
    let (l, k0, k1) = (model.len[0], model.stiffness[0], model.stiffness[1]);
    let mut out = Vec::new();
    for p in &samples {
        let x = &p.sensors;
        let ests = [
            (
                Estimator::MomentOverForce,
                moment_over_force(x.m0, x.fx, x.fy),
            ),
            (
                Estimator::MomentOverTransverseForce,
                moment_over_transverse_force(x.m0, x.fy),
            ),
            (
                Estimator::JointAngles,
                from_joint_angles(x.theta01, x.theta12, l, k0, k1).map(|r| r.1),
            ),
            (
                Estimator::ChordAngles,
                from_chord_angles(x.theta01, x.theta12, model.arc, ei).map(|r| r.1),
            ),
            (
                Estimator::MomentAndAngle,
                from_moment_and_angle(x.m0, x.theta01, model.arc, ei).map(|r| r.1),
            ),
            (
                Estimator::KanekoTorqueAngle,
                kaneko_torque_angle(p.delta_psi, x.m0, ei),
            ),
            (
                Estimator::BirdwellRates,
                birdwell_rates(p.psi_rate, p.m0_rate, ei),
            ),
        ];
        for (e, v) in ests {
            out.push(row(e, p.level, p.tip, p.since, p.s, v));
        }
    }
    if let Some((_, _, s0)) = first {
        let omega = pinned_frequency(model, s0)?;
        let est = kaneko_frequency(omega, ei, RAYLEIGH_TIP_MASS * w.mass(), length);
        out.push(row(Estimator::KanekoFrequency, 0.0, 0.0, 0.0, s0, est));
        // Only where the frequency identifies the contact: before its peak.
        let rho_a = w.mass() / length;
        if s0 <= pinned_beam_peak(ei, rho_a, length)? * length {
            let est = kaneko_frequency_beam(omega, ei, rho_a, length);
            out.push(row(Estimator::KanekoFrequencyBeam, 0.0, 0.0, 0.0, s0, est));
        }
    }
    Ok(out)
}

/// Largest |relative error| over distances for each (estimator, level) in `rows`, in the order
/// first seen: `(estimator, level, worst, rows)`. NaN estimates count as infinite error.
pub fn worst_over_distances(rows: &[InverseResult]) -> Vec<(Estimator, f64, f64, usize)> {
    let mut out: Vec<(Estimator, f64, f64, usize)> = Vec::new();
    for r in rows {
        let e = if r.relative_error.is_nan() {
            f64::INFINITY
        } else {
            r.relative_error.abs()
        };
        match out
            .iter_mut()
            .find(|o| o.0 == r.estimator && o.1 == r.level)
        {
            Some(o) => {
                o.2 = o.2.max(e);
                o.3 += 1;
            }
            None => out.push((r.estimator, r.level, e, 1)),
        }
    }
    out
}
