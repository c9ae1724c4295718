//! Static references: the small-deflection cubic of a cantilever under a point force, and the
//! large-deflection elastica of any profile by shooting on the base moment (RK4, Newton and
//! load continuation).

use super::BeamProfile;
use crate::error::{check_finite, check_positive, Error, Result};

// ---------------------------------------------------------------------------
// 1. Small-deflection point load
// ---------------------------------------------------------------------------

/// Small-deflection (linear) solution of a uniform cantilever clamped at `x = 0`
/// under a transverse point force `w` at distance `c` from the base.
///
/// With `k = w/ei` the deflection is `k (c x²/2 − x³/6)` for `x < c` and the straight
/// continuation `k (c² x/2 − c³/6)` beyond the load.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointLoadCubic {
    /// Bending stiffness E·I, N·m².
    pub ei: f64,
    /// Transverse force, N.
    pub w: f64,
    /// Distance of the force from the base, m.
    pub c: f64,
}

impl PointLoadCubic {
    /// Transverse deflection v(x), m.
    pub fn deflection(&self, x: f64) -> f64 {
        let (c, k) = (self.c, self.w / self.ei);
        if x < c {
            k * (c * x * x / 2.0 - x.powi(3) / 6.0)
        } else {
            k * (c * c * x / 2.0 - c.powi(3) / 6.0)
        }
    }

    /// Slope v'(x), rad (small-angle).
    pub fn slope(&self, x: f64) -> f64 {
        let (c, k) = (self.c, self.w / self.ei);
        if x < c {
            k * (c * x - x * x / 2.0)
        } else {
            k * c * c / 2.0
        }
    }

    /// Curvature v''(x), 1/m.
    pub fn curvature(&self, x: f64) -> f64 {
        if x < self.c {
            self.w / self.ei * (self.c - x)
        } else {
            0.0
        }
    }

    /// Bending moment `w (c − x)` for `x < c`, zero beyond the load, N·m.
    pub fn moment(&self, x: f64) -> f64 {
        if x < self.c {
            self.w * (self.c - x)
        } else {
            0.0
        }
    }
}

/// Force `W` (N) at distance `c` that gives a small-deflection tip deflection
/// `tip_deflection` (m) of a uniform cantilever of stiffness `ei` and length `length`.
pub fn load_for_tip_deflection(ei: f64, length: f64, c: f64, tip_deflection: f64) -> f64 {
    // Tip deflection per unit W/EI, then scale linearly.
    let unit = PointLoadCubic { ei: 1.0, w: 1.0, c }.deflection(length);
    tip_deflection * ei / unit
}

/// Small-deflection compliance of the straight clamped `profile` at arc length `s`: the
/// deflection there under a unit force at `s` square to it, `∫₀ˢ (s − x)² / EI(x) dx` (m/N), by
/// Gauss–Legendre quadrature on 16 pieces (exact for a uniform beam).
pub fn point_compliance(profile: &dyn BeamProfile, s: f64) -> f64 {
    let rule = crate::quadrature::gauss_legendre(5);
    let pieces = 16;
    let h = s / pieces as f64;
    (0..pieces)
        .map(|i| {
            let a = i as f64 * h;
            crate::quadrature::integrate(&rule, a, a + h, |x| (s - x).powi(2) / profile.ei(x))
        })
        .sum()
}

// ---------------------------------------------------------------------------
// 2. Large-deflection elastica
// ---------------------------------------------------------------------------

/// RK4 steps per beam length on the first (coarsest) grid.
const BASE_STEPS: usize = 4096;
/// Finest grid tried before giving up.
const MAX_STEPS: usize = 1 << 21;
/// Largest shooting gain |∂M(at)/∂M0| accepted (round-off is amplified by it).
const MAX_GAIN: f64 = 1e7;

/// One stored RK4 node of the deformed centreline.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Node {
    s: f64,
    theta: f64,
    kappa: f64,
    m: f64,
    x: f64,
    y: f64,
}

/// Large-deflection equilibrium of a clamped beam under one dead point force.
///
/// The beam is clamped at `s = 0` with its tangent along +x at the origin. The force
/// `F = (fx, fy)` acts at arc length `at` and keeps its direction. Sign conventions:
/// angles and moments are counter-clockwise positive; the internal bending moment
/// `M(s) = (r(at) − r(s)) × F` (moment of the distal load about the point `s`), so
/// `θ'(s) = κ0(s) + M(s)/EI(s)`.
///
/// The base reaction is the wrench the clamp applies to the beam: force `−F` and
/// moment `m0 = −(x_at·fy − y_at·fx) = −M(0)`, so that reaction and load balance.
#[derive(Debug, Clone, PartialEq)]
pub struct Elastica {
    force: [f64; 2],
    at: f64,
    base_moment: f64,
    load_index: usize,
    nodes: Vec<Node>,
}

impl Elastica {
    /// Beam length, m.
    pub fn length(&self) -> f64 {
        self.nodes[self.nodes.len() - 1].s
    }

    /// Applied force (fx, fy), N.
    pub fn force(&self) -> [f64; 2] {
        self.force
    }

    /// Arc length of the load point, m.
    pub fn at(&self) -> f64 {
        self.at
    }

    /// Number of RK4 steps of the stored (finest) grid.
    pub fn steps(&self) -> usize {
        self.nodes.len() - 1
    }

    /// Tip position (x, y), m.
    pub fn tip(&self) -> [f64; 2] {
        let n = &self.nodes[self.nodes.len() - 1];
        [n.x, n.y]
    }

    /// Position of the load point (x, y), m.
    pub fn load_point(&self) -> [f64; 2] {
        let n = &self.nodes[self.load_index];
        [n.x, n.y]
    }

    /// Base reaction moment `m0 = −(x_at·fy − y_at·fx)`, N·m, counter-clockwise positive,
    /// with `(x_at, y_at)` the deformed load point. It is taken from the shooting solution
    /// as `−M(0)`, which equals that expression up to the shooting residual `M(at)`
    /// (round-off level, about `1e-13·|F|·at` or less when well conditioned).
    pub fn base_moment(&self) -> f64 {
        self.base_moment
    }

    /// Base reaction force `−F`, N.
    pub fn base_force(&self) -> [f64; 2] {
        [-self.force[0], -self.force[1]]
    }

    /// Centreline position at arc length `s` (clamped to `[0, L]`), m.
    pub fn point(&self, s: f64) -> [f64; 2] {
        // Cubic Hermite with the exact tangents x' = cos θ, y' = sin θ at the nodes.
        let (i, t, h) = self.segment(s);
        let (a, b) = (&self.nodes[i], &self.nodes[i + 1]);
        let (sa, ca) = a.theta.sin_cos();
        let (sb, cb) = b.theta.sin_cos();
        [
            hermite(t, h, a.x, ca, b.x, cb),
            hermite(t, h, a.y, sa, b.y, sb),
        ]
    }

    /// Tangent angle θ(s) from +x, rad (s clamped to `[0, L]`).
    pub fn angle(&self, s: f64) -> f64 {
        // Cubic Hermite with the nodal curvatures as derivatives.
        let (i, t, h) = self.segment(s);
        let (a, b) = (&self.nodes[i], &self.nodes[i + 1]);
        hermite(t, h, a.theta, a.kappa, b.theta, b.kappa)
    }

    /// Internal bending moment M(s) = (r(at) − r(s)) × F, N·m (zero beyond the load).
    pub fn moment(&self, s: f64) -> f64 {
        // Cubic Hermite with M' = −(cos θ·fy − sin θ·fx) on loaded segments.
        let (i, t, h) = self.segment(s);
        let (a, b) = (&self.nodes[i], &self.nodes[i + 1]);
        let f = if i < self.load_index {
            self.force
        } else {
            [0.0; 2]
        };
        let dm = |th: f64| -(th.cos() * f[1] - th.sin() * f[0]);
        hermite(t, h, a.m, dm(a.theta), b.m, dm(b.theta))
    }

    /// Segment index, local coordinate in [0, 1] and step length containing `s`.
    fn segment(&self, s: f64) -> (usize, f64, f64) {
        let last = self.nodes.len() - 1;
        let s = s.clamp(0.0, self.nodes[last].s);
        let i = self.nodes.partition_point(|n| n.s <= s).clamp(1, last) - 1;
        let h = self.nodes[i + 1].s - self.nodes[i].s;
        (i, (s - self.nodes[i].s) / h, h)
    }
}

/// Cubic Hermite interpolant on a step of length `h` at local coordinate `t`.
fn hermite(t: f64, h: f64, p0: f64, d0: f64, p1: f64, d1: f64) -> f64 {
    let (t2, t3) = (t * t, t * t * t);
    (2.0 * t3 - 3.0 * t2 + 1.0) * p0
        + (t3 - 2.0 * t2 + t) * h * d0
        + (3.0 * t2 - 2.0 * t3) * p1
        + (t3 - t2) * h * d1
}

/// Elastica state `[θ, M, x, y, δθ, δM]`, the last two being ∂/∂M0 (variational).
type State = [f64; 6];

/// Right-hand side of the elastica equations and their variation w.r.t. M0.
fn rhs(u: &State, ei: f64, k0: f64, f: [f64; 2]) -> State {
    let (sn, cs) = u[0].sin_cos();
    [
        k0 + u[1] / ei,
        -(cs * f[1] - sn * f[0]),
        cs,
        sn,
        u[5] / ei,
        (sn * f[1] + cs * f[0]) * u[4],
    ]
}

/// Step nodes and section samples (at nodes and mid-steps) for the RK4 sweep.
struct Grid {
    s: Vec<f64>,
    ei: Vec<f64>,
    k0: Vec<f64>,
    loaded: usize,
}

impl Grid {
    /// Grid with about `per_length` steps per beam length, with a node exactly at `at`.
    fn new(profile: &dyn BeamProfile, at: f64, per_length: usize) -> Result<Grid> {
        // Uniform steps on [0, at] and on [at, L].
        let len = profile.length();
        let n_at = ((at / len * per_length as f64).ceil() as usize).max(64);
        let n_tail = ((len - at) / len * per_length as f64).ceil() as usize;
        let mut s: Vec<f64> = (0..=n_at).map(|i| at * i as f64 / n_at as f64).collect();
        s.extend((1..=n_tail).map(|i| at + (len - at) * i as f64 / n_tail as f64));
        // Sample EI and κ0 at nodes and midpoints, checking them.
        let mut ei = Vec::with_capacity(2 * s.len());
        let mut k0 = Vec::with_capacity(2 * s.len());
        for i in 0..s.len() {
            let mid = s.get(i + 1).map(|b| 0.5 * (s[i] + b));
            for p in std::iter::once(s[i]).chain(mid) {
                let e = profile.ei(p);
                if !(e.is_finite() && e > 0.0) {
                    return Err(Error::invalid("profile.ei", e, "a finite number > 0"));
                }
                ei.push(e);
                k0.push(check_finite(
                    "profile.rest_curvature",
                    profile.rest_curvature(p),
                )?);
            }
        }
        Ok(Grid {
            s,
            ei,
            k0,
            loaded: n_at,
        })
    }

    /// One classical RK4 step over segment `i`.
    fn step(&self, i: usize, u: &State, f: [f64; 2]) -> State {
        let h = self.s[i + 1] - self.s[i];
        let (j, m, k) = (2 * i, 2 * i + 1, 2 * i + 2);
        let add =
            |v: &State, c: f64, d: &State| -> State { std::array::from_fn(|n| v[n] + c * d[n]) };
        let k1 = rhs(u, self.ei[j], self.k0[j], f);
        let k2 = rhs(&add(u, h / 2.0, &k1), self.ei[m], self.k0[m], f);
        let k3 = rhs(&add(u, h / 2.0, &k2), self.ei[m], self.k0[m], f);
        let k4 = rhs(&add(u, h, &k3), self.ei[k], self.k0[k], f);
        std::array::from_fn(|n| u[n] + h / 6.0 * (k1[n] + 2.0 * (k2[n] + k3[n]) + k4[n]))
    }

    /// Sweep from the base to the load point: state at `at` for base moment `m0`.
    fn shoot(&self, m0: f64, f: [f64; 2]) -> State {
        let mut u = [0.0, m0, 0.0, 0.0, 0.0, 1.0];
        for i in 0..self.loaded {
            u = self.step(i, &u, f);
        }
        u
    }

    /// Full sweep to the tip, recording every node.
    fn trace(&self, m0: f64, f: [f64; 2]) -> Vec<Node> {
        let node = |i: usize, u: &State| Node {
            s: self.s[i],
            theta: u[0],
            kappa: self.k0[2 * i] + u[1] / self.ei[2 * i],
            m: u[1],
            x: u[2],
            y: u[3],
        };
        let mut u = [0.0, m0, 0.0, 0.0, 0.0, 1.0];
        let mut nodes = vec![node(0, &u)];
        for i in 0..self.s.len() - 1 {
            // Beyond the load the beam carries no moment and follows κ0 only.
            if i == self.loaded {
                u[1] = 0.0;
            }
            let fi = if i < self.loaded { f } else { [0.0; 2] };
            u = self.step(i, &u, fi);
            nodes.push(node(i + 1, &u));
        }
        nodes
    }

    /// Newton on M0 for M(at) = 0 with the exact (variational) derivative.
    /// Returns M0 and θ(at); `Ok(None)`: no convergence from this guess; `Err`:
    /// hopelessly ill-conditioned.
    fn newton(&self, f: [f64; 2], guess: f64, scale: f64) -> Result<Option<(f64, f64)>> {
        let mut m0 = guess;
        let mut u = self.shoot(m0, f);
        for _ in 0..20 {
            let (r, dr) = (u[1], u[5]);
            if !(r.is_finite() && dr.is_finite()) || dr == 0.0 {
                return Ok(None);
            }
            // Round-off grows with the shooting gain; past MAX_GAIN 1e-8 is out of reach.
            if dr.abs() > MAX_GAIN {
                return Err(Error::NoConvergence {
                    what: "elastica shooting".into(),
                    detail: format!("shooting gain ∂M(at)/∂M0 = {dr:.3e} exceeds {MAX_GAIN:.0e}"),
                });
            }
            // Converged when the residual or the correction is at round-off level.
            let delta = -r / dr;
            if r.abs() <= 1e-13 * scale || delta.abs() <= 1e-15 * (m0.abs() + scale) {
                return Ok(Some((m0, u[0])));
            }
            // Newton step with backtracking on |M(at)|.
            let mut t = 1.0;
            loop {
                let trial = self.shoot(m0 + t * delta, f);
                if trial[1].is_finite() && trial[1].abs() < r.abs() {
                    m0 += t * delta;
                    u = trial;
                    break;
                }
                t *= 0.5;
                if t < 0.02 {
                    // No further progress: accept only a round-off-limited correction.
                    return Ok((delta.abs() <= 1e-12 * (m0.abs() + scale)).then_some((m0, u[0])));
                }
            }
        }
        Ok(None)
    }

    /// Load continuation from the unloaded shape up to the full force (at most 400 tries).
    fn continuation(&self, force: [f64; 2], scale: f64) -> Result<f64> {
        // Small-deflection predictor: moment of the force at the unloaded load point.
        let r0 = self.shoot(0.0, [0.0; 2]);
        let mut slope = r0[2] * force[1] - r0[3] * force[0];
        // Shooting exponent γ = ∫ sqrt(|F|/EI) ds (γ² = W·at²/EI when uniform).
        let fmag = force[0].hypot(force[1]);
        let gamma: f64 = (0..self.loaded)
            .map(|i| (self.s[i + 1] - self.s[i]) * (fmag / self.ei[2 * i + 1]).sqrt())
            .sum();
        // Load increments of about one unit of γ², growing to four after successes.
        let first = 1.0 / (gamma * gamma).ceil().clamp(1.0, 100.0);
        let (mut lam, mut m0, mut dlam, mut theta) = (0.0, 0.0, first, r0[0]);
        for attempt in 0.. {
            if lam >= 1.0 {
                break;
            }
            // Predict along the last secant, correct with Newton.
            let next = (lam + dlam).min(1.0);
            let f = [next * force[0], next * force[1]];
            let solved = self.newton(f, m0 + slope * (next - lam), next * scale)?;
            // Accept only a small turn of the load point (no jump to another branch).
            match solved.filter(|&(_, th)| (th - theta).abs() < 0.25) {
                Some((m, th)) => {
                    slope = (m - m0) / (next - lam);
                    (lam, m0, dlam, theta) = (next, m, (1.5 * dlam).min(4.0 * first), th);
                }
                None if dlam > 1e-6 && attempt < 400 => dlam *= 0.5,
                None => {
                    return Err(Error::NoConvergence {
                        what: "elastica shooting".into(),
                        detail: format!(
                            "load continuation stalled at {lam:.6} of the force \
                             (shooting exponent ∫√(|F|/EI) ds = {gamma:.1})"
                        ),
                    })
                }
            }
        }
        Ok(m0)
    }
}

/// Large-deflection equilibrium of `profile`, clamped at `s = 0` along +x, under the
/// dead force `force = [fx, fy]` (N) applied at arc length `at` in `(0, L]`.
///
/// Shooting on the base moment M0: RK4 integration of `θ' = κ0 + M/EI`,
/// `M' = −(cos θ·fy − sin θ·fx)`, `x' = cos θ`, `y' = sin θ` to `at`, Newton (exact
/// variational derivative) on `M(at) = 0`, with load continuation from the
/// small-deflection guess `M0 = at·fy`. The step is halved until the tip moves less
/// than `1e-9·L`, so positions and angles are accurate to about `1e-8` relative.
/// Compressive loads are followed along the branch connected to the unloaded beam.
///
/// Simple shooting amplifies round-off by the gain `|∂M(at)/∂M0|`, up to about
/// `exp(∫ sqrt(|F|/EI) ds)` over `[0, at]`; when it exceeds `1e7` (e.g. a very soft
/// tip under a large load) the solve stops with [`Error::NoConvergence`] rather than
/// return a result short of the stated accuracy. A uniform beam under a tip load is
/// fine up to `W L²/EI ≈ 200`.
///
/// Errors: non-finite `force` or `at` outside `(0, L]` give [`Error::InvalidParameter`];
/// a non-positive EI or non-finite κ0 along the beam likewise; a failed solve gives
/// [`Error::NoConvergence`].
pub fn elastica(profile: &dyn BeamProfile, force: [f64; 2], at: f64) -> Result<Elastica> {
    // Validate the inputs.
    let len = check_positive("profile.length", profile.length())?;
    if !force.iter().all(|f| f.is_finite()) {
        return Err(Error::invalid(
            "force",
            format!("{force:?}"),
            "two finite components",
        ));
    }
    if !(at > 0.0 && at <= len) {
        return Err(Error::invalid("at", at, format!("in (0, {len}]")));
    }
    let scale = force[0].hypot(force[1]) * at;
    // Coarse grid: continuation in load.
    let mut per_length = BASE_STEPS;
    let mut grid = Grid::new(profile, at, per_length)?;
    let mut m0 = grid.continuation(force, scale)?;
    let mut nodes = grid.trace(m0, force);
    // Halve the step until the tip settles.
    loop {
        per_length *= 2;
        if per_length > MAX_STEPS {
            return Err(Error::NoConvergence {
                what: "elastica step refinement".into(),
                detail: format!("tip still moving at {} steps per length", per_length / 2),
            });
        }
        let fine = Grid::new(profile, at, per_length)?;
        let m = match fine.newton(force, m0, scale)? {
            Some((m, _)) => m,
            None => fine.continuation(force, scale)?,
        };
        let fine_nodes = fine.trace(m, force);
        let (a, b) = (&nodes[nodes.len() - 1], &fine_nodes[fine_nodes.len() - 1]);
        let moved = (a.x - b.x).hypot(a.y - b.y);
        (grid, m0, nodes) = (fine, m, fine_nodes);
        if moved < 1e-9 * len {
            break;
        }
    }
    Ok(Elastica {
        force,
        at,
        base_moment: -m0,
        load_index: grid.loaded,
        nodes,
    })
}

#[cfg(test)]
mod tests {
    use super::super::test_profiles::{rel, taper, BEAM};
    use super::super::UniformBeam;
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn point_compliance_is_the_cantilever_formula_on_a_uniform_beam() {
        let w = crate::whisker::WhiskerParams::w30().check().unwrap();
        let ei = w.ei(0.0);
        for s in [0.01, 0.02, 0.03] {
            let exact = s * s * s / (3.0 * ei);
            assert!((point_compliance(&w, s) / exact - 1.0).abs() < 1e-12);
        }
    }

    // ----- Carlson symmetric integrals (duplication until the arguments agree) -----

    /// R_F(x, y, z).
    fn carlson_rf(mut x: f64, mut y: f64, mut z: f64) -> f64 {
        loop {
            let a = (x + y + z) / 3.0;
            if [x, y, z].iter().all(|v| (v - a).abs() <= 1e-9 * a) {
                // Second-order term vanishes by symmetry; E2 ~ 1e-18 remains.
                let (dx, dy) = (1.0 - x / a, 1.0 - y / a);
                let dz = -(dx + dy);
                let e2 = dx * dy - dz * dz;
                return (1.0 - e2 / 10.0) / a.sqrt();
            }
            let l = x.sqrt() * y.sqrt() + y.sqrt() * z.sqrt() + z.sqrt() * x.sqrt();
            (x, y, z) = ((x + l) / 4.0, (y + l) / 4.0, (z + l) / 4.0);
        }
    }

    /// R_D(x, y, z).
    fn carlson_rd(mut x: f64, mut y: f64, mut z: f64) -> f64 {
        let (mut sum, mut fac) = (0.0, 1.0);
        loop {
            let a = (x + y + 3.0 * z) / 5.0;
            if [x, y, z].iter().all(|v| (v - a).abs() <= 1e-9 * a) {
                return 3.0 * sum + fac / (a * a.sqrt());
            }
            let l = x.sqrt() * y.sqrt() + y.sqrt() * z.sqrt() + z.sqrt() * x.sqrt();
            sum += fac / (z.sqrt() * (z + l));
            fac /= 4.0;
            (x, y, z) = ((x + l) / 4.0, (y + l) / 4.0, (z + l) / 4.0);
        }
    }

    /// Incomplete elliptic integrals F(φ, k) and E(φ, k) (modulus k).
    fn elliptic_fe(phi: f64, k: f64) -> (f64, f64) {
        let (s, c) = phi.sin_cos();
        let q = 1.0 - k * k * s * s;
        let f = s * carlson_rf(c * c, q, 1.0);
        (f, f - k * k * s.powi(3) / 3.0 * carlson_rd(c * c, q, 1.0))
    }

    /// Tip-loaded cantilever (α = W L²/EI, perpendicular dead load): (θ_tip, x/L, y/L).
    ///
    /// From EI θ'²/2 = W (sin θt − sin θ) with 1 + sin θ = 2p² sin²φ:
    /// √α = K(p) − F(p, φ1), x/L = sqrt(2 sin θt / α), y/L = 1 − 2 (E(p) − E(p, φ1))/√α.
    fn elliptic_tip(alpha: f64) -> (f64, f64, f64) {
        let parts = |th: f64| {
            let p = ((1.0 + th.sin()) / 2.0).sqrt();
            let phi1 = (1.0 / (2.0f64.sqrt() * p)).min(1.0).asin();
            let (kf, ke) = elliptic_fe(PI / 2.0, p);
            let (f1, e1) = elliptic_fe(phi1, p);
            (kf - f1, ke - e1)
        };
        // Bisection on θt: (K − F)² increases from 0 at θt = 0 to ∞ at π/2.
        let (mut lo, mut hi) = (0.0, PI / 2.0);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if parts(mid).0.powi(2) < alpha {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let th = 0.5 * (lo + hi);
        let (_, de) = parts(th);
        (
            th,
            (2.0 * th.sin() / alpha).sqrt(),
            1.0 - 2.0 * de / alpha.sqrt(),
        )
    }

    #[test]
    fn carlson_matches_known_values() {
        // K(1/√2) = Γ(1/4)²/(4√π) = 1.854074677301372, E(1/√2) = 1.350643881047675.
        let (k, e) = elliptic_fe(PI / 2.0, 0.5f64.sqrt());
        assert!(rel(k, 1.854_074_677_301_372) < 1e-14, "{k}");
        assert!(rel(e, 1.350_643_881_047_675) < 1e-14, "{e}");
        // F(φ, 0) = E(φ, 0) = φ.
        let (f, e) = elliptic_fe(0.7, 0.0);
        assert!((f - 0.7).abs() < 1e-15 && (e - 0.7).abs() < 1e-15);
    }

    // ----- 1. The small-deflection cubic -----

    #[test]
    fn cubic_is_continuous_and_consistent() {
        let b = PointLoadCubic {
            ei: 2e-7,
            w: 1e-4,
            c: 0.03,
        };
        // Continuity of deflection and slope across the load point.
        let (lo, hi) = (b.c * (1.0 - 1e-12), b.c);
        assert!(rel(b.deflection(lo), b.deflection(hi)) < 1e-10);
        assert!(rel(b.slope(lo), b.slope(hi)) < 1e-10);
        assert!(b.curvature(lo) < 1e-10 * b.curvature(0.0) && b.moment(hi) == 0.0);
        // Central differences: v' = slope, slope' = curvature, EI·curvature = moment.
        let h = 1e-6;
        for x in [0.004, 0.012, 0.025, 0.036, 0.05] {
            let dv = (b.deflection(x + h) - b.deflection(x - h)) / (2.0 * h);
            assert!((dv - b.slope(x)).abs() < 1e-8 * b.slope(b.c), "x = {x}");
            let ds = (b.slope(x + h) - b.slope(x - h)) / (2.0 * h);
            assert!(
                (ds - b.curvature(x)).abs() < 1e-8 * b.curvature(0.0),
                "x = {x}"
            );
            assert!((b.ei * b.curvature(x) - b.moment(x)).abs() < 1e-15);
        }
        // Tip-deflection inverse, load inside and at the tip.
        for c in [0.03, 0.05] {
            let w = load_for_tip_deflection(2e-7, 0.05, c, 1e-3);
            let d = PointLoadCubic { ei: 2e-7, w, c }.deflection(0.05);
            assert!(rel(d, 1e-3) < 1e-14);
        }
        let w = load_for_tip_deflection(2e-7, 0.05, 0.05, 1e-3);
        assert!(rel(w, 3.0 * 2e-7 * 1e-3 / 0.05f64.powi(3)) < 1e-14);
    }

    // ----- 2. The elastica -----

    #[test]
    fn elastica_small_load_matches_cubic() {
        let l = BEAM.length;
        for c in [l, 0.6 * l] {
            // α = W L²/EI = 1e-4: nonlinear corrections are ~α² relative.
            let w = 1e-4 * BEAM.ei / (l * l);
            let e = elastica(&BEAM, [0.0, w], c).unwrap();
            let cubic = PointLoadCubic { ei: BEAM.ei, w, c };
            let (vt, st) = (cubic.deflection(l), cubic.slope(l));
            for s in [0.1, 0.33, 0.5, 0.6, 0.77, 0.9, 1.0].map(|f| f * l) {
                assert!(
                    (e.point(s)[1] - cubic.deflection(s)).abs() < 1e-6 * vt,
                    "c {c} s {s}"
                );
                assert!(
                    (e.angle(s) - cubic.slope(s)).abs() < 1e-6 * st,
                    "c {c} s {s}"
                );
                assert!(
                    (e.moment(s) - cubic.moment(s)).abs() < 1e-6 * w * c,
                    "c {c} s {s}"
                );
            }
        }
    }

    #[test]
    fn elastica_tip_load_matches_elliptic_solution() {
        let l = BEAM.length;
        for alpha in [1.0, 3.0, 10.0, 30.0, 100.0] {
            let e = elastica(&BEAM, [0.0, alpha * BEAM.ei / (l * l)], l).unwrap();
            let (th, x, y) = elliptic_tip(alpha);
            let tip = e.tip();
            eprintln!(
                "alpha {alpha}: shooting tip/L ({:.10}, {:.10}) angle {:.10}; elliptic ({x:.10}, {y:.10}) angle {th:.10}; steps {}",
                tip[0] / l,
                tip[1] / l,
                e.angle(l),
                e.steps()
            );
            // Continuation stayed on the primary branch (no loop) and matches to 1e-8.
            assert!((e.angle(l) - th).abs() < 1e-8 * th, "alpha {alpha}");
            assert!((tip[0] / l - x).abs() < 1e-8, "alpha {alpha}");
            assert!((tip[1] / l - y).abs() < 1e-8, "alpha {alpha}");
            // Interpolated shape keeps EI θ'²/2 + W sin θ = W sin θt between nodes.
            let w = alpha * BEAM.ei / (l * l);
            for s in [0.123_456, 0.5, 0.777_777, 0.999_9].map(|f| f * l) {
                let m = e.moment(s);
                let inv = m * m / (2.0 * BEAM.ei) + w * e.angle(s).sin();
                assert!((inv - w * th.sin()).abs() < 1e-8 * w, "alpha {alpha} s {s}");
            }
        }
    }

    #[test]
    fn elastica_equilibrium_and_reaction() {
        let l = BEAM.length;
        let q = BEAM.ei / (l * l);
        let curved = taper(4, 2, 0.2, 15.0);
        let cases: [(&dyn BeamProfile, [f64; 2], f64); 6] = [
            (&BEAM, [0.0, 3.0 * q], l),
            (&BEAM, [2.0 * q, -5.0 * q], 0.7 * l),
            (&BEAM, [-5.0 * q, 0.1 * q], l),
            (&BEAM, [0.0, 0.0], 0.5 * l),
            (&curved, [0.5 * q, 2.0 * q], 0.8 * curved.len),
            (&curved, [-q, -4.0 * q], curved.len),
        ];
        for (p, f, at) in cases {
            let e = elastica(p, f, at).unwrap();
            let r = e.load_point();
            let scale = f[0].hypot(f[1]) * p.length();
            let resid = e.base_moment() + (r[0] * f[1] - r[1] * f[0]);
            assert!(resid.abs() <= 1e-12 * scale, "{f:?} at {at}: {resid}");
            assert_eq!(e.base_force(), [-f[0], -f[1]]);
            // The load point is the interpolated point at `at`; the tip is at s = L.
            assert_eq!(e.point(at), r);
            assert_eq!(e.point(p.length()), e.tip());
            // Internal moment is the moment of the distal load everywhere.
            for s in [0.0, 0.2, 0.45, 0.61, 0.9].map(|t| t * at) {
                let x = e.point(s);
                let m = (r[0] - x[0]) * f[1] - (r[1] - x[1]) * f[0];
                assert!((e.moment(s) - m).abs() <= 1e-9 * scale, "{f:?} s {s}");
            }
        }
    }

    #[test]
    fn elastica_non_uniform_profile() {
        // Unloaded curved beam: a circular arc θ = κ0 s.
        let k0 = 20.0;
        let p = taper(4, 2, 0.1, k0);
        let e = elastica(&p, [0.0, 0.0], p.len).unwrap();
        for s in [0.0011, 0.017, 0.031_234_5, 0.04] {
            let want = [(k0 * s).sin() / k0, (1.0 - (k0 * s).cos()) / k0];
            let got = e.point(s);
            assert!(
                (got[0] - want[0]).hypot(got[1] - want[1]) < 1e-10 * p.len,
                "s {s}"
            );
            assert!((e.angle(s) - k0 * s).abs() < 1e-10, "s {s}");
        }
        // Loaded tapered beam: the solution settles as the step is refined, and a
        // small load agrees with the linear (Castigliano) tip deflection ∫ (L−s)²/EI ds.
        let w = 1e-6 * p.ei0 / (p.len * p.len);
        let straight = taper(4, 2, 0.1, 0.0);
        let e = elastica(&straight, [0.0, w], p.len).unwrap();
        let n = 200_000;
        let lin: f64 = (0..n)
            .map(|i| {
                let s = (i as f64 + 0.5) * p.len / n as f64;
                (p.len - s).powi(2) / straight.ei(s) * p.len / n as f64
            })
            .sum::<f64>()
            * w;
        assert!(rel(e.tip()[1], lin) < 1e-6, "{} vs {lin}", e.tip()[1]);
        // A large load on a curved taper (tip EI 0.8 % of the base) converges.
        let soft = taper(4, 2, 0.3, k0);
        let q = soft.ei0 / (soft.len * soft.len);
        let big = elastica(&soft, [q, -5.0 * q], soft.len).unwrap();
        let r = big.load_point();
        assert!(r[1] < 0.0 && big.steps() >= 8192);
        assert!(
            (big.base_moment() + r[0] * -5.0 * q - r[1] * q).abs() < 1e-12 * 5.1 * q * soft.len
        );
        // Beyond the reach of simple shooting (exp ∫√(F/EI) ds ≈ e⁴⁵): an error, no panic.
        let hopeless = elastica(&p, [0.0, -20.0 * p.ei0 / (p.len * p.len)], p.len);
        assert!(
            matches!(hopeless, Err(Error::NoConvergence { .. })),
            "{hopeless:?}"
        );
    }

    #[test]
    fn elastica_rejects_bad_input() {
        let l = BEAM.length;
        let bad = [
            elastica(&BEAM, [f64::NAN, 0.0], l),
            elastica(&BEAM, [0.0, f64::INFINITY], l),
            elastica(&BEAM, [0.0, 1e-6], 0.0),
            elastica(&BEAM, [0.0, 1e-6], -0.01),
            elastica(&BEAM, [0.0, 1e-6], 1.01 * l),
            elastica(&BEAM, [0.0, 1e-6], f64::NAN),
        ];
        for (i, r) in bad.into_iter().enumerate() {
            let name = if i < 2 { "force" } else { "at" };
            assert!(
                matches!(r, Err(Error::InvalidParameter { name: ref n, .. }) if n == name),
                "{i}"
            );
        }
        let neg = UniformBeam { ei: -1.0, ..BEAM };
        assert!(elastica(&neg, [0.0, 1e-6], l).is_err());
        let zero = UniformBeam {
            length: 0.0,
            ..BEAM
        };
        assert!(elastica(&zero, [0.0, 1e-6], 0.0).is_err());
        // Interpolation never panics outside the beam or at NaN.
        let e = elastica(&BEAM, [0.0, 1e-6], l).unwrap();
        assert_eq!(e.point(-1.0), [0.0, 0.0]);
        assert_eq!(e.point(2.0 * l), e.tip());
        assert!(e.angle(f64::NAN).is_nan());
    }
}
