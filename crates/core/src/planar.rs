//! Small planar rigid-body helpers shared by the model and the step: fused multiply–add, packed
//! spatial inertias and their products and shifts, a fast `sin_cos` for small angles.
//!
//! Spatial vectors are planar: motion `(ω, vx, vy)`, force `(n, fx, fy)`; a packed spatial
//! inertia is the upper triangle of its symmetric 3×3 matrix, `[a, b, c, d, e, f]`.

/// `a·b + c`, fused where the target has FMA.
#[inline(always)]
pub(crate) fn fma(a: f64, b: f64, c: f64) -> f64 {
    #[cfg(target_feature = "fma")]
    {
        a.mul_add(b, c)
    }
    #[cfg(not(target_feature = "fma"))]
    {
        a * b + c
    }
}

/// Packs the spatial inertia of a body with mass `m` and central inertia `j` about a reference
/// point from which its centre of mass lies at `(cx, cy)`.
#[inline]
pub(crate) fn body_inertia(m: f64, j: f64, cx: f64, cy: f64) -> [f64; 6] {
    [j + m * (cx * cx + cy * cy), -m * cy, m * cx, m, 0.0, m]
}

/// Symmetric packed 3×3 times a vector.
#[inline]
pub(crate) fn sym_mul(a: &[f64; 6], v: [f64; 3]) -> [f64; 3] {
    [
        a[0] * v[0] + a[1] * v[1] + a[2] * v[2],
        a[1] * v[0] + a[3] * v[1] + a[4] * v[2],
        a[2] * v[0] + a[4] * v[1] + a[5] * v[2],
    ]
}

/// Taylor coefficients of sin(x)/x and cos(x) in powers of x²: (-1)^k/(2k+1)! and (-1)^k/(2k)!.
pub(crate) const SIN_TAYLOR: [f64; 6] = [
    1.0,
    -1.0 / 6.0,
    1.0 / 120.0,
    -1.0 / 5040.0,
    1.0 / 362_880.0,
    -1.0 / 39_916_800.0,
];
pub(crate) const COS_TAYLOR: [f64; 7] = [
    1.0,
    -1.0 / 2.0,
    1.0 / 24.0,
    -1.0 / 720.0,
    1.0 / 40_320.0,
    -1.0 / 3_628_800.0,
    1.0 / 479_001_600.0,
];

/// `(sin x, cos x)`: Taylor polynomials for the small joint angles of a whisker (|x| <= 0.25 rad,
/// truncation below 1e-17 relative), the double-angle formulas on them up to 0.5 rad (a coarse
/// chain's joints bend that far), the library routine beyond.
#[inline]
pub(crate) fn sin_cos(x: f64) -> (f64, f64) {
    let taylor = |x: f64| {
        let x2 = x * x;
        let s = SIN_TAYLOR.iter().rev().fold(0.0, |acc, &k| fma(acc, x2, k));
        let c = COS_TAYLOR.iter().rev().fold(0.0, |acc, &k| fma(acc, x2, k));
        (x * s, c)
    };
    let ax = x.abs();
    if ax <= 0.25 {
        taylor(x)
    } else if ax <= 0.5 {
        let (s, c) = taylor(0.5 * x);
        (2.0 * s * c, fma(c, c, -s * s))
    } else {
        x.sin_cos()
    }
}

#[inline]
pub(crate) fn dot3(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Moves a packed spatial inertia's reference point by `d = (dx, dy)` (new point minus old).
#[inline]
pub(crate) fn shift_inertia(i: &[f64; 6], dx: f64, dy: f64) -> [f64; 6] {
    let [a, b, c, d, e, f] = *i;
    let (p, q) = (dy, -dx);
    let t1 = fma(d, p, fma(e, q, b));
    let t2 = fma(e, p, fma(f, q, c));
    let t0 = fma(b, p, fma(c, q, a));
    [fma(p, t1, fma(q, t2, t0)), t1, t2, d, e, f]
}

/// Moves a spatial force's reference point by `d = (dx, dy)` (new point minus old).
#[inline]
pub(crate) fn shift_force(f: [f64; 3], dx: f64, dy: f64) -> [f64; 3] {
    [fma(dy, f[1], fma(-dx, f[2], f[0])), f[1], f[2]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn taylor_sin_cos_matches_library() {
        for k in -2000..=2000 {
            let x = k as f64 * 5e-4;
            let (s, c) = sin_cos(x);
            assert!(
                (s - x.sin()).abs() < 3e-16 && (c - x.cos()).abs() < 3e-16,
                "{x}"
            );
        }
        // The double-angle range.
        for k in -2000..=2000 {
            let x = k as f64 * 2.5e-4 + if k < 0 { -0.25 } else { 0.25 };
            let (s, c) = sin_cos(x);
            assert!(
                (s - x.sin()).abs() < 3e-16 && (c - x.cos()).abs() < 3e-16,
                "{x}"
            );
        }
    }
}
