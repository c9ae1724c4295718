//! Natural frequencies of a clamped–free beam: closed forms for a uniform one, Hermite finite
//! elements for any profile, and Kaneko's massless-beam / tip-mass frequency.
//!
//! # Why a Hermite finite-element model for tapered beams
//!
//! Tapered clamped–free beams have closed forms only for special tapers (Kirchhoff's
//! cone and wedge, in Bessel functions), so a general reference needs a discretisation
//! with a provable, fast convergence rate. Cubic Hermite elements (w and w' per node)
//! are conforming (C¹) for the fourth-order Euler–Bernoulli operator, so with the
//! consistent mass matrix the method is Rayleigh–Ritz: each eigenvalue converges
//! monotonically from above with error `O(h⁴)` for smooth EI(s), ρA(s). Element
//! integrals use 5-point Gauss–Legendre quadrature, exact for polynomials of degree 9:
//! the stiffness integrand EI·N''ᵢN''ⱼ is exact for EI of degree ≤ 7 (a conical taper
//! has degree 4) and the mass integrand ρA·NᵢNⱼ for ρA of degree ≤ 3 (a cone has 2), so
//! for these tapers the only error is the `h⁴` discretisation error, which Richardson
//! extrapolation over two meshes removes. The tests check the result against the
//! uniform closed form and against Kirchhoff's cone and wedge values.

use super::BeamProfile;
use crate::error::{check_positive, Error, Result};
use nalgebra::linalg::{Cholesky, SymmetricEigen};
use nalgebra::{DMatrix, DVector};
use std::f64::consts::PI;

// ---------------------------------------------------------------------------
// 1. Clamped–free natural frequencies
// ---------------------------------------------------------------------------

/// The first `n` roots βL of `cos x·cosh x = −1` (clamped–free beam), ascending.
///
/// Solved as `cos x + 1/cosh x = 0` (no overflow) by safeguarded Newton on the
/// bracket `[(k−1)π, kπ]`, which holds exactly the k-th root.
pub fn clamped_free_roots(n: usize) -> Vec<f64> {
    let g = |x: f64| x.cos() + 1.0 / x.cosh();
    let dg = |x: f64| -x.sin() - x.tanh() / x.cosh();
    (1..=n)
        .map(|k| {
            // Bracket and start at the asymptote (k − ½)π.
            let (mut lo, mut hi) = ((k - 1) as f64 * PI, k as f64 * PI);
            let lo_positive = g(lo) > 0.0;
            let mut x = (k as f64 - 0.5) * PI;
            for _ in 0..200 {
                // Shrink the bracket, then Newton or bisect if Newton leaves it.
                let gx = g(x);
                if gx == 0.0 {
                    break;
                }
                if (gx > 0.0) == lo_positive {
                    lo = x;
                } else {
                    hi = x;
                }
                let newton = x - gx / dg(x);
                let next = if newton > lo && newton < hi {
                    newton
                } else {
                    0.5 * (lo + hi)
                };
                let done = (next - x).abs() <= 2.0 * f64::EPSILON * x;
                x = next;
                if done {
                    break;
                }
            }
            x
        })
        .collect()
}

/// Closed-form natural frequencies (Hz) of a uniform clamped–free beam:
/// `f = (βL)²/(2π L²)·sqrt(EI/ρA)`.
pub fn clamped_free_uniform(ei: f64, rho_a: f64, length: f64, n: usize) -> Vec<f64> {
    let c = (ei / rho_a).sqrt() / (2.0 * PI * length * length);
    clamped_free_roots(n)
        .into_iter()
        .map(|b| b * b * c)
        .collect()
}

/// Five-point Gauss–Legendre rule mapped to `[0, 1]`: (node, weight) pairs.
fn gauss5() -> [(f64, f64); 5] {
    let a = 2.0 * (10.0f64 / 7.0).sqrt();
    let (x1, x2) = ((5.0 - a).sqrt() / 3.0, (5.0 + a).sqrt() / 3.0);
    let r = 13.0 * 70.0f64.sqrt();
    let (w1, w2) = ((322.0 + r) / 900.0, (322.0 - r) / 900.0);
    let map = |x: f64, w: f64| (0.5 * (1.0 + x), 0.5 * w);
    [
        map(-x2, w2),
        map(-x1, w1),
        map(0.0, 128.0 / 225.0),
        map(x1, w1),
        map(x2, w2),
    ]
}

/// One Gauss point of one element: weighted EI and ρA, shape values and curvatures.
struct GaussSample {
    wei: f64,
    wra: f64,
    n: [f64; 4],
    b: [f64; 4],
}

/// Global (clamped-reduced) index of local dof `i` of element `e`; `None` at the clamp.
fn fem_dof(e: usize, i: usize) -> Option<usize> {
    (2 * e + i).checked_sub(2)
}

/// Rayleigh quotient `∫EI w''² / ∫ρA w²` of the FE field with reduced dofs `x`,
/// summed as element energies (no cancellation between large stiffness entries).
fn fem_rayleigh(samples: &[GaussSample], x: &DVector<f64>) -> f64 {
    let (mut strain, mut kinetic) = (0.0, 0.0);
    for (q, g) in samples.iter().enumerate() {
        // Nodal values of the element, zero at the clamp.
        let xe: [f64; 4] = std::array::from_fn(|i| fem_dof(q / 5, i).map_or(0.0, |d| x[d]));
        let curv: f64 = (0..4).map(|i| g.b[i] * xe[i]).sum();
        let w: f64 = (0..4).map(|i| g.n[i] * xe[i]).sum();
        strain += g.wei * curv * curv;
        kinetic += g.wra * w * w;
    }
    strain / kinetic
}

/// Natural frequencies (Hz, ascending, the first `n`) of a clamped–free beam of any
/// profile by a Hermite-cubic Euler–Bernoulli finite-element model with `elements`
/// equal elements, consistent mass, and 5-point Gauss–Legendre quadrature.
///
/// The generalized problem `K x = ω² M x` is reduced with the Cholesky factor of `M`
/// and solved by a dense symmetric eigen-solve; since that solve is accurate only to
/// `ε·ω²_max`, each wanted eigenvalue is then recomputed as the Rayleigh quotient of
/// its eigenvector, which has a second-order (negligible) error.
///
/// Errors: `elements == 0`, `n > 2·elements`, or a non-positive EI or ρA along the beam
/// give [`Error::InvalidParameter`].
pub fn clamped_free_fem(profile: &dyn BeamProfile, elements: usize, n: usize) -> Result<Vec<f64>> {
    // Validate the inputs.
    let len = check_positive("profile.length", profile.length())?;
    if elements == 0 {
        return Err(Error::invalid("elements", elements, "at least 1"));
    }
    let dofs = 2 * elements;
    if n > dofs {
        return Err(Error::invalid(
            "n",
            n,
            format!("at most {dofs} (two per element)"),
        ));
    }
    // Section properties, Hermite shape functions and curvatures at every Gauss point.
    let h = len / elements as f64;
    let mut samples = Vec::with_capacity(5 * elements);
    for e in 0..elements {
        for (xi, wq) in gauss5() {
            let s = (e as f64 + xi) * h;
            let (ei, ra) = (profile.ei(s), profile.rho_a(s));
            if !(ei.is_finite() && ei > 0.0) {
                return Err(Error::invalid("profile.ei", ei, "a finite number > 0"));
            }
            if !(ra.is_finite() && ra > 0.0) {
                return Err(Error::invalid("profile.rho_a", ra, "a finite number > 0"));
            }
            let (x2, x3) = (xi * xi, xi * xi * xi);
            samples.push(GaussSample {
                wei: wq * h * ei,
                wra: wq * h * ra,
                n: [
                    1.0 - 3.0 * x2 + 2.0 * x3,
                    h * (xi - 2.0 * x2 + x3),
                    3.0 * x2 - 2.0 * x3,
                    h * (x3 - x2),
                ],
                b: [
                    (12.0 * xi - 6.0) / (h * h),
                    (6.0 * xi - 4.0) / h,
                    (6.0 - 12.0 * xi) / (h * h),
                    (6.0 * xi - 2.0) / h,
                ],
            });
        }
    }
    // Assemble K and M; dof 2j−2 is w, 2j−1 is w' at node j ≥ 1 (node 0 clamped).
    let (mut k, mut m) = (
        DMatrix::<f64>::zeros(dofs, dofs),
        DMatrix::<f64>::zeros(dofs, dofs),
    );
    for (q, g) in samples.iter().enumerate() {
        for i in 0..4 {
            for j in 0..4 {
                if let (Some(a), Some(b)) = (fem_dof(q / 5, i), fem_dof(q / 5, j)) {
                    k[(a, b)] += g.wei * g.b[i] * g.b[j];
                    m[(a, b)] += g.wra * g.n[i] * g.n[j];
                }
            }
        }
    }
    // Reduce K x = λ M x to the standard form L⁻¹ K L⁻ᵀ with M = L Lᵀ.
    let l = Cholesky::new(m)
        .ok_or_else(|| Error::NoConvergence {
            what: "FEM mass matrix Cholesky".into(),
            detail: "mass matrix is not positive definite".into(),
        })?
        .l();
    let no_solve = || Error::NoConvergence {
        what: "FEM triangular solve".into(),
        detail: "singular Cholesky factor".into(),
    };
    let y = l.solve_lower_triangular(&k).ok_or_else(no_solve)?;
    let a = l
        .solve_lower_triangular(&y.transpose())
        .ok_or_else(no_solve)?;
    let eig = SymmetricEigen::new((&a + a.transpose()) * 0.5);
    // Lowest n modes: back-transform x = L⁻ᵀ y and refine λ by the Rayleigh quotient.
    let mut order: Vec<usize> = (0..dofs).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let mut freqs = order[..n]
        .iter()
        .map(|&i| {
            let x = l
                .tr_solve_lower_triangular(&eig.eigenvectors.column(i).into_owned())
                .ok_or_else(no_solve)?;
            Ok(fem_rayleigh(&samples, &x).sqrt() / (2.0 * PI))
        })
        .collect::<Result<Vec<f64>>>()?;
    freqs.sort_by(f64::total_cmp);
    Ok(freqs)
}

/// Reference natural frequencies (Hz, the first `n`) of a clamped–free beam of any
/// profile: Richardson extrapolation `(16 f_fine − f_coarse)/15` of
/// [`clamped_free_fem`] at `E` and `2E` elements, `E = max(100, 10 n)`, which removes
/// the `h⁴` leading error of the Hermite elements (good to about `1e-7` relative).
pub fn clamped_free_tapered(profile: &dyn BeamProfile, n: usize) -> Result<Vec<f64>> {
    // Two refinements, then eliminate the h⁴ term.
    let elements = (10 * n).max(100);
    let coarse = clamped_free_fem(profile, elements, n)?;
    let fine = clamped_free_fem(profile, 2 * elements, n)?;
    Ok(coarse
        .iter()
        .zip(&fine)
        .map(|(c, f)| (16.0 * f - c) / 15.0)
        .collect())
}

// ---------------------------------------------------------------------------
// 2. Kaneko's massless-beam / tip-mass frequency
// ---------------------------------------------------------------------------

/// Kaneko's natural angular frequency (rad/s) of a massless cantilever of stiffness
/// `ei` (N·m²) and length `length` (m) carrying a tip mass `tip_mass` (kg), with a
/// point support at the fraction `c` of the length (dimensionless `C/L` in `[0, 1]`):
/// `ω = sqrt(12 EI / (M L³ (4 − c(3 − c)²)))`, exactly as the seed paper writes it
/// (the paper's `C` is this fraction). `c = 0` gives the free tip-mass cantilever
/// `sqrt(3EI/(M L³))`; `ω` grows without bound as `c → 1`.
pub fn kaneko_omega(ei: f64, tip_mass: f64, length: f64, c: f64) -> f64 {
    (12.0 * ei / (tip_mass * length.powi(3) * (4.0 - c * (3.0 - c).powi(2)))).sqrt()
}

#[cfg(test)]
mod tests {
    use super::super::test_profiles::{rel, taper, Taper, BEAM};
    use super::super::UniformBeam;
    use super::*;

    // ----- 1. Natural frequencies -----

    #[test]
    fn clamped_free_roots_are_exact() {
        let r = clamped_free_roots(30);
        let want = [
            1.875_104_068_7,
            4.694_091_133_0,
            7.854_757_438_2,
            10.995_540_734,
        ];
        for (a, b) in r.iter().zip(want) {
            assert!((a - b).abs() < 1e-9, "{a} vs {b}");
        }
        for (k, x) in r.iter().enumerate() {
            assert!((x.cos() + 1.0 / x.cosh()).abs() < 1e-15 * x, "root {k}");
            assert!((x - (k as f64 + 0.5) * PI).abs() < 0.31);
        }
        assert!(clamped_free_roots(0).is_empty());
    }

    #[test]
    fn clamped_free_uniform_matches_known_numbers() {
        let f = clamped_free_uniform(2.3562e-7, 3.4558e-5, 0.03, 3);
        for (a, b) in f.iter().zip([51.341, 321.75, 900.90]) {
            assert!(rel(*a, b) < 6e-5, "{a} vs {b}");
        }
    }

    #[test]
    fn fem_uniform_matches_closed_form() {
        let want = clamped_free_uniform(BEAM.ei, BEAM.rho_a, BEAM.length, 6);
        let got = clamped_free_tapered(&BEAM, 6).unwrap();
        for (k, (a, b)) in got.iter().zip(&want).enumerate() {
            eprintln!("uniform mode {}: rel err {:.2e}", k + 1, rel(*a, *b));
            assert!(rel(*a, *b) < 1e-7, "mode {}: {a} vs {b}", k + 1);
        }
        // Raw FEM is an upper bound and converges towards the closed form.
        let raw = clamped_free_fem(&BEAM, 20, 3).unwrap();
        assert!(raw
            .iter()
            .zip(&want)
            .all(|(a, b)| a >= b && rel(*a, *b) < 1e-4));
        assert!(raw.windows(2).all(|w| w[0] < w[1]));
    }

    /// First mode of a taper, as a multiple of sqrt(EI0/ρA0)/L².
    fn first_mode_ratio(p: &Taper) -> f64 {
        let f = clamped_free_tapered(p, 1).unwrap()[0];
        2.0 * PI * f * p.len * p.len / (p.ei0 / p.ra0).sqrt()
    }

    #[test]
    fn fem_cone_matches_kirchhoff() {
        // Complete cone (tip radius exactly zero): EI ∝ (1−s/L)⁴, ρA ∝ (1−s/L)².
        let r = first_mode_ratio(&taper(4, 2, 0.0, 0.0));
        eprintln!("cone: ω1 L²/sqrt(EI0/ρA0) = {r:.7} (Kirchhoff 8.7192)");
        assert!(rel(r, 8.7192) < 1e-3);
    }

    #[test]
    fn fem_wedge_matches_kirchhoff() {
        // Rectangular wedge: EI ∝ (1−s/L)³, ρA ∝ (1−s/L).
        let r = first_mode_ratio(&taper(3, 1, 0.0, 0.0));
        eprintln!("wedge: ω1 L²/sqrt(EI0/ρA0) = {r:.7} (Kirchhoff 5.3151)");
        assert!(rel(r, 5.3151) < 1e-3);
    }

    #[test]
    fn fem_extrapolation_is_converged() {
        // A whisker-like taper: the extrapolated value is stable under refinement.
        let p = taper(4, 2, 0.05, 0.0);
        let r = clamped_free_tapered(&p, 3).unwrap();
        let a = clamped_free_fem(&p, 150, 3).unwrap();
        let b = clamped_free_fem(&p, 300, 3).unwrap();
        for k in 0..3 {
            let fine = (16.0 * b[k] - a[k]) / 15.0;
            eprintln!(
                "taper mode {}: {:.9} Hz, change {:.2e}",
                k + 1,
                r[k],
                rel(r[k], fine)
            );
            assert!(rel(r[k], fine) < 1e-8);
        }
    }

    #[test]
    fn fem_rejects_bad_input() {
        assert!(clamped_free_fem(&BEAM, 0, 1).is_err());
        assert!(clamped_free_fem(&BEAM, 5, 11).is_err());
        assert_eq!(clamped_free_fem(&BEAM, 5, 10).unwrap().len(), 10);
        assert!(clamped_free_fem(&UniformBeam { rho_a: 0.0, ..BEAM }, 5, 1).is_err());
        assert!(clamped_free_fem(
            &UniformBeam {
                ei: f64::NAN,
                ..BEAM
            },
            5,
            1
        )
        .is_err());
        assert!(clamped_free_tapered(
            &UniformBeam {
                length: -1.0,
                ..BEAM
            },
            1
        )
        .is_err());
    }

    // ----- 2. Kaneko -----

    #[test]
    fn kaneko_limits() {
        let (ei, m, l) = (2e-7, 1e-5, 0.05f64);
        let free = (3.0 * ei / (m * l.powi(3))).sqrt();
        assert!(rel(kaneko_omega(ei, m, l, 0.0), free) < 1e-15);
        // Monotonic growth without bound as the support reaches the tip.
        let w: Vec<f64> = [0.0, 0.3, 0.9, 0.999, 1.0 - 1e-9]
            .iter()
            .map(|&c| kaneko_omega(ei, m, l, c))
            .collect();
        assert!(w.windows(2).all(|p| p[0] < p[1]));
        assert!(w[4] > 1e4 * free);
        assert!(kaneko_omega(ei, m, l, 1.0).is_infinite());
    }
}
