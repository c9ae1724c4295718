//! The segment chain: a whisker cut into N rigid segments joined by rotational springs.
//!
//! Segment `i` runs from node `i` to node `i + 1` (node 0 is the base, node N the tip) along the
//! chord of the whisker's rest curve. Joint `i` sits at node `i` and sets the angle of segment `i`
//! against segment `i - 1` (joint 0: against the base direction), so `theta01` is joint 0 and
//! `theta12` joint 1.
//!
//! Three rules give the joint stiffnesses:
//! - [`Discretisation::Gregory`] (default): joint `i` carries the bending compliance of the
//!   whisker weighted by the piecewise-linear "hat" function of node `i`,
//!   `1/k_i = ∫ φ_i(s)/EI(s) ds`, with Gregory's end correction at the clamped base (a twelfth of a
//!   segment's compliance moved from joint 0 to joint 1). A chain's deflection is a quadrature of
//!   the continuum's `v(x) = ∫ κ(s)(x - s) ds` with the joint compliances as weights; the hat
//!   weights are the trapezoidal rule, and the end correction removes its leading
//!   Euler–Maclaurin error term at the base. For a uniform whisker the compliances are
//!   `5/12, 13/12, 1, 1, …` times `l/EI`; tip deflection under a tip load is exact to `1/(4N³)`.
//! - [`Discretisation::Trapezoid`]: the hat weights without the end correction (`l/2EI` at the
//!   base, `l/EI` elsewhere), second-order accurate.
//! - [`Discretisation::Seed`]: the seed paper's rule, `k = EI/l` at every joint including the
//!   base, which overstates the base compliance by half a segment (error falling as 1/N).
//! - [`Discretisation::Nodal`]: the compliances that make the chain deflect exactly as the
//!   Euler–Bernoulli beam does at every node under a force there, `Σ_j (x_i − s_j)² c_j =
//!   ∫₀^{x_i} (x_i − s)²/EI(s) ds` for the nodes `x_i` (a lower-triangular system, solved node by
//!   node from the base). Whatever the taper, a chain of few segments then has the whisker's
//!   static response where contacts meet it: with 8 segments, a whisker tapered to half its base
//!   radius is within 0.8% of the beam's deflection everywhere along its outer two thirds, against
//!   4.9% with the hat weights. Meant for coarse chains (a filter's transition model); with many
//!   segments the hat weights are as good.
//!
//! Masses, centres of mass and rotational inertias are integrated exactly over each segment's
//! arc, so only the stiffness rule differs between the two.

use crate::beam::BeamProfile;
use crate::error::{Error, Result};
use crate::quadrature::{gauss_legendre, integrate};
use crate::whisker::{Damping, Follicle, Whisker};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Largest segment count accepted.
pub const MAX_SEGMENTS: usize = 200;

/// How joint stiffnesses are derived from the beam.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Discretisation {
    /// Hat-weighted compliance with Gregory's end correction at the base: third-order accurate.
    #[default]
    Gregory,
    /// Hat-weighted compliance (the trapezoidal rule): second-order accurate.
    Trapezoid,
    /// The seed paper's `k = EI/l` at every joint, the first at the base.
    Seed,
    /// Compliances matched to the beam's deflection under a point force at every node.
    Nodal,
}

/// Names accepted by [`Discretisation::from_name`].
pub const DISCRETISATIONS: [&str; 4] = ["gregory", "trapezoid", "seed", "nodal"];

impl Discretisation {
    /// Parses `gregory`, `trapezoid`, `seed` or `nodal`.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "gregory" => Ok(Discretisation::Gregory),
            "trapezoid" => Ok(Discretisation::Trapezoid),
            "seed" => Ok(Discretisation::Seed),
            "nodal" => Ok(Discretisation::Nodal),
            _ => Err(Error::invalid(
                "discretisation",
                name,
                format!("one of {}", DISCRETISATIONS.join(", ")),
            )),
        }
    }

    /// The name used in files and reports.
    pub fn name(self) -> &'static str {
        match self {
            Discretisation::Gregory => "gregory",
            Discretisation::Trapezoid => "trapezoid",
            Discretisation::Seed => "seed",
            Discretisation::Nodal => "nodal",
        }
    }
}

/// The immutable physical model of a discretised whisker, shared by any number of states.
///
/// Per-segment arrays are indexed by segment (equivalently by its proximal joint).
#[derive(Debug, Clone)]
pub struct Model {
    /// The whisker this chain discretises.
    pub whisker: Whisker,
    /// Stiffness rule used.
    pub discretisation: Discretisation,
    /// Segment count N.
    pub n: usize,
    /// Arc length of every segment, m (L/N).
    pub arc: f64,
    /// Chord length of segment i, m: `[N]`.
    pub len: Vec<f64>,
    /// Mass of segment i, kg: `[N]`.
    pub mass: Vec<f64>,
    /// Centre of mass of segment i in its own frame (x along the chord from node i), m: `[N][2]`.
    pub com: Vec<[f64; 2]>,
    /// Moment of inertia of segment i about its centre of mass, kg·m²: `[N]`.
    pub inertia: Vec<f64>,
    /// Rotational stiffness of joint i, N·m/rad: `[N]`.
    pub stiffness: Vec<f64>,
    /// Rotational damping of joint i, N·m·s/rad: `[N]`.
    pub damping: Vec<f64>,
    /// Rest angle of joint i, rad: `[N]`.
    pub rest: Vec<f64>,
    /// Whisker radius at node i, m: `[N+1]` (contact happens at the surface).
    pub radius: Vec<f64>,
}

/// The joint compliances of [`Discretisation::Nodal`] for `whisker` cut into `n` segments: node
/// by node from the base, the one joint that the force at node `i` newly reaches (joint `i − 1`,
/// a segment length away) takes what the beam's deflection there leaves after the joints below
/// it. Refused when a compliance comes out non-positive or not finite (a profile that `n`
/// segments cannot follow this way).
fn nodal_compliances(whisker: &Whisker, n: usize) -> Result<Vec<f64>> {
    let arc = whisker.length() / n as f64;
    let mut c: Vec<f64> = Vec::with_capacity(n);
    for i in 1..=n {
        let x = i as f64 * arc;
        let below: f64 = c
            .iter()
            .enumerate()
            .map(|(j, cj)| (x - j as f64 * arc).powi(2) * cj)
            .sum();
        let ci = (crate::beam::point_compliance(whisker, x) - below) / (arc * arc);
        if !(ci.is_finite() && ci > 0.0) {
            return Err(Error::invalid(
                "discretisation",
                "nodal",
                format!(
                    "a rule that gives every joint a positive compliance; with {n} segments joint {} \
                     gets {ci:e} rad/(N·m) for this whisker (use gregory)",
                    i - 1
                ),
            ));
        }
        c.push(ci);
    }
    Ok(c)
}

/// Point of the rest curve at arc length `s` (constant curvature `kappa`), base at the origin along +x.
fn rest_point(kappa: f64, s: f64) -> [f64; 2] {
    let a = kappa * s;
    if a.abs() < 1e-6 {
        // Series of sin(a)/kappa and (1-cos a)/kappa, exact to double precision here.
        [s * (1.0 - a * a / 6.0), s * a * (0.5 - a * a / 24.0)]
    } else {
        [a.sin() / kappa, (1.0 - a.cos()) / kappa]
    }
}

impl Model {
    /// Discretises `whisker` into `segments` rigid segments with the given stiffness rule.
    pub fn new(
        whisker: &Whisker,
        segments: usize,
        discretisation: Discretisation,
    ) -> Result<Model> {
        if !(2..=MAX_SEGMENTS).contains(&segments) {
            return Err(Error::invalid(
                "segments",
                segments,
                format!("an integer from 2 to {MAX_SEGMENTS}"),
            ));
        }
        let n = segments;
        let length = whisker.length();
        let kappa = whisker.params().rest_curvature;
        let arc = length / n as f64;
        let rule = gauss_legendre(16);
        let node = |i: usize| rest_point(kappa, i as f64 * arc);

        // Geometry and mass properties of each segment, integrated over its arc.
        let (mut len, mut mass, mut com, mut inertia) = (vec![], vec![], vec![], vec![]);
        let mut chord_angle = Vec::with_capacity(n);
        for i in 0..n {
            let (p0, p1) = (node(i), node(i + 1));
            let (dx, dy) = (p1[0] - p0[0], p1[1] - p0[1]);
            let l = dx.hypot(dy);
            let (c, s) = (dx / l, dy / l);
            // Rest-curve point expressed in the segment frame (origin at node i, x along the chord).
            let local = |sa: f64| {
                let p = rest_point(kappa, sa);
                let (rx, ry) = (p[0] - p0[0], p[1] - p0[1]);
                [c * rx + s * ry, -s * rx + c * ry]
            };
            let (a, b) = (i as f64 * arc, (i + 1) as f64 * arc);
            let m = integrate(&rule, a, b, |sa| whisker.rho_a(sa));
            let mx = integrate(&rule, a, b, |sa| whisker.rho_a(sa) * local(sa)[0]) / m;
            let my = integrate(&rule, a, b, |sa| whisker.rho_a(sa) * local(sa)[1]) / m;
            // Rotational inertia of a thin rod about the centre of mass, plus the section's own
            // (rotary) inertia ρI, which Euler–Bernoulli neglects but is harmless and exact here.
            let j = integrate(&rule, a, b, |sa| {
                let r = local(sa);
                whisker.rho_a(sa) * ((r[0] - mx).powi(2) + (r[1] - my).powi(2))
            });
            len.push(l);
            mass.push(m);
            com.push([mx, my]);
            inertia.push(j);
            chord_angle.push(dy.atan2(dx));
        }

        // Rest angle of each joint: the change of chord direction across it.
        let rest: Vec<f64> = (0..n)
            .map(|i| chord_angle[i] - if i == 0 { 0.0 } else { chord_angle[i - 1] })
            .collect();

        // Joint compliance from the chosen rule.
        let hat = |i: usize| {
            let si = i as f64 * arc;
            // Rising half of the hat (absent at the base), then the falling half.
            let up = if i == 0 {
                0.0
            } else {
                integrate(&rule, si - arc, si, |s| {
                    (s - (si - arc)) / arc / whisker.ei(s)
                })
            };
            up + integrate(&rule, si, si + arc, |s| {
                ((si + arc) - s) / arc / whisker.ei(s)
            })
        };
        let mut compliance: Vec<f64> = match discretisation {
            Discretisation::Seed => (0..n).map(|i| arc / whisker.ei(i as f64 * arc)).collect(),
            Discretisation::Gregory | Discretisation::Trapezoid => (0..n).map(hat).collect(),
            Discretisation::Nodal => nodal_compliances(whisker, n)?,
        };
        if discretisation == Discretisation::Gregory {
            // Euler–Maclaurin end correction h/12·(g1 - g0) of the trapezoidal rule at the base.
            compliance[0] -= arc / 12.0 / whisker.ei(0.0);
            compliance[1] += arc / 12.0 / whisker.ei(arc);
        }
        let mut stiffness: Vec<f64> = compliance.iter().map(|c| 1.0 / c).collect();

        // A compliant follicle (a spring k_f and a damper c_f side by side) acts in series with
        // the whisker's own compliance at joint 0. The joint's stiffness is the series one, k;
        // its damper is the follicle's seen through the series: at joint-0 rate ω the follicle
        // turns by k/k_f of the joint's angle, so it dissipates c_f·(k/k_f)² per unit squared
        // rate. That is the first-order term of the pair's exact complex stiffness,
        // 1/(1/k0 + 1/(k_f + iωc_f)) = k + iω·c_f·(k/k_f)² + O(ω²), and it vanishes as the
        // follicle stiffens, so a stiff follicle tends to the clamped one.
        let mut follicle_damping = 0.0;
        if let Follicle::Spring {
            stiffness: kf,
            damping: df,
        } = whisker.params().follicle
        {
            stiffness[0] = 1.0 / (1.0 / stiffness[0] + 1.0 / kf);
            let share = stiffness[0] / kf;
            follicle_damping = df * share * share;
        }

        let mut model = Model {
            whisker: whisker.clone(),
            discretisation,
            n,
            arc,
            len,
            mass,
            com,
            inertia,
            damping: vec![0.0; n],
            stiffness,
            rest,
            radius: (0..=n).map(|i| whisker.radius(i as f64 * arc)).collect(),
        };

        // Joint dampers from the damping rule.
        let damping: Vec<f64> = match whisker.params().damping {
            Damping::None => vec![0.0; n],
            Damping::StiffnessProportional { beta } => {
                model.stiffness.iter().map(|k| beta * k).collect()
            }
            Damping::ModalRatio { ratio } => {
                let omega1 = 2.0 * std::f64::consts::PI * model.modes()?.frequencies[0];
                let beta = 2.0 * ratio / omega1;
                model.stiffness.iter().map(|k| beta * k).collect()
            }
            Damping::SegmentQ { q } => (0..n)
                .map(|i| {
                    let c = model.com[i];
                    let j_joint = model.inertia[i] + model.mass[i] * (c[0] * c[0] + c[1] * c[1]);
                    (j_joint * model.stiffness[i]).sqrt() / q
                })
                .collect(),
        };
        model.damping = damping;
        model.damping[0] += follicle_damping;
        Ok(model)
    }

    /// The whisker's arc length, m.
    pub fn whisker_length(&self) -> f64 {
        self.arc * self.n as f64
    }

    /// Segment and distance along its chord (m from its proximal node) of arc length `s`.
    ///
    /// Arc length maps linearly onto the chord; the tip is `(N-1, len[N-1])`.
    pub fn locate(&self, s: f64) -> Result<(usize, f64)> {
        let length = self.whisker.length();
        if !(s.is_finite() && (0.0..=length).contains(&s)) {
            return Err(Error::invalid(
                "arc length",
                s,
                format!("a number in [0, {length}]"),
            ));
        }
        let i = ((s / self.arc) as usize).min(self.n - 1);
        let frac = (s - i as f64 * self.arc) / self.arc;
        Ok((i, frac * self.len[i]))
    }

    /// Joint-space mass matrix at joint angles `q` (base fixed along +x), `[N×N]`, kg·m².
    pub fn mass_matrix(&self, q: &[f64]) -> DMatrix<f64> {
        let n = self.n;
        // Node positions and segment directions.
        let mut nodes = vec![[0.0f64; 2]; n + 1];
        let mut dirs = vec![[1.0f64, 0.0]; n];
        let mut phi = 0.0;
        for i in 0..n {
            phi += q[i];
            let (s, c) = phi.sin_cos();
            dirs[i] = [c, s];
            nodes[i + 1] = [nodes[i][0] + self.len[i] * c, nodes[i][1] + self.len[i] * s];
        }
        // Composite spatial inertia (about the origin) of segments i..N, from the tip inwards.
        let mut comp = vec![[0.0f64; 6]; n + 1];
        for i in (0..n).rev() {
            let [c, s] = dirs[i];
            let cl = self.com[i];
            let cx = nodes[i][0] + c * cl[0] - s * cl[1];
            let cy = nodes[i][1] + s * cl[0] + c * cl[1];
            let b = crate::planar::body_inertia(self.mass[i], self.inertia[i], cx, cy);
            for k in 0..6 {
                comp[i][k] = comp[i + 1][k] + b[k];
            }
        }
        // M_ij = S_iᵀ Ic_max(i,j) S_j with the revolute motion vectors S_i = (1, y_i, -x_i).
        let mut m = DMatrix::zeros(n, n);
        for i in 0..n {
            let si = [1.0, nodes[i][1], -nodes[i][0]];
            for j in i..n {
                let sj = [1.0, nodes[j][1], -nodes[j][0]];
                let ic = crate::planar::sym_mul(&comp[j], sj);
                let v = si[0] * ic[0] + si[1] * ic[1] + si[2] * ic[2];
                m[(i, j)] = v;
                m[(j, i)] = v;
            }
        }
        m
    }

    /// Undamped small-oscillation modes about the rest shape.
    pub fn modes(&self) -> Result<Modes> {
        let m = self.mass_matrix(&self.rest);
        let chol = m.cholesky().ok_or_else(|| Error::NoConvergence {
            what: "modal analysis".into(),
            detail: "mass matrix is not positive definite".into(),
        })?;
        let l = chol.l();
        let linv = l
            .clone()
            .try_inverse()
            .ok_or_else(|| Error::NoConvergence {
                what: "modal analysis".into(),
                detail: "singular Cholesky factor".into(),
            })?;
        let k = DMatrix::from_diagonal(&DVector::from_column_slice(&self.stiffness));
        let a = &linv * k * linv.transpose();
        let a = (&a + a.transpose()) * 0.5;
        let eig = a.symmetric_eigen();
        let mut order: Vec<usize> = (0..self.n).collect();
        order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
        let frequencies = order
            .iter()
            .map(|&i| eig.eigenvalues[i].max(0.0).sqrt() / (2.0 * std::f64::consts::PI))
            .collect();
        // Joint-space shapes x = L⁻ᵀ y, scaled to unit mass-normalised amplitude.
        let shapes = order
            .iter()
            .map(|&i| {
                let y = eig.eigenvectors.column(i).into_owned();
                let x = linv.transpose() * y;
                x.iter().copied().collect()
            })
            .collect();
        Ok(Modes {
            frequencies,
            shapes,
        })
    }
}

/// Small-oscillation modes of a chain.
#[derive(Debug, Clone)]
pub struct Modes {
    /// Undamped natural frequencies, Hz, ascending.
    pub frequencies: Vec<f64>,
    /// Mass-normalised joint-space mode shapes (`shapes[k][i]`: joint i in mode k), rad.
    pub shapes: Vec<Vec<f64>>,
}
