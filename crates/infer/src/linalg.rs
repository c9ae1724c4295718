//! Dense linear algebra that the estimators' fits spend their time in.
//!
//! [`cholesky`] factorises a symmetric positive definite matrix by blocks: each diagonal block
//! by nalgebra's own factorisation, the panel below it by a triangular solve and the trailing
//! matrix by one matrix product (nalgebra's `gemm`, which runs on `matrixmultiply`'s kernels).
//! nalgebra's factorisation works one column at a time with vector updates; for the 800–1000
//! unknowns of the kernel and read-out fits the blocked one does the same arithmetic in matrix
//! products, several times faster. The result is the same factor up to rounding.
//!
//! [`add_gram_lower`] accumulates `Φ·Φᵀ` by blocks on and below the diagonal only, about half of
//! a full product's arithmetic; [`mirror_lower`] then copies the lower triangle above.
//! [`mul_lower_transposed`] multiplies by the transpose of a lower triangular matrix without
//! the products of its zeros.

use nalgebra::{Cholesky, DMatrix, Dyn};

/// Columns per block of [`cholesky`]; matrices up to this size are factorised directly.
const BLOCK: usize = 96;

/// The Cholesky factorisation of the symmetric positive definite `a` (only its lower triangle is
/// read), or `None` where `a` is not positive definite, as `a.cholesky()` but by blocks.
pub fn cholesky(mut a: DMatrix<f64>) -> Option<Cholesky<f64, Dyn>> {
    let n = a.nrows();
    assert_eq!(n, a.ncols(), "cholesky: the matrix must be square");
    if n <= BLOCK {
        return a.cholesky();
    }
    let mut k = 0;
    while k < n {
        let kb = BLOCK.min(n - k);
        let l11 = a.view((k, k), (kb, kb)).clone_owned().cholesky()?.unpack();
        a.view_mut((k, k), (kb, kb)).copy_from(&l11);
        let rest = n - k - kb;
        if rest > 0 {
            // The panel: A21 ← A21·L11⁻ᵀ, i.e. L11·A21ᵀ = (old A21)ᵀ.
            let mut panel_t = a.view((k + kb, k), (rest, kb)).transpose();
            if !l11.solve_lower_triangular_mut(&mut panel_t) {
                return None;
            }
            let panel = panel_t.transpose();
            a.view_mut((k + kb, k), (rest, kb)).copy_from(&panel);
            // The trailing matrix: A22 ← A22 − A21·A21ᵀ (the whole block; only its lower
            // triangle is read later).
            a.view_mut((k + kb, k + kb), (rest, rest))
                .gemm(-1.0, &panel, &panel_t, 1.0);
        }
        k += kb;
    }
    Some(Cholesky::pack_dirty(a))
}

/// Rows per block of [`add_gram_lower`].
const GRAM_BLOCK: usize = 128;

/// `gram += phi·phiᵀ` on and below the diagonal of `gram` (`f × f`, `phi` `f × k`, `phi_t` its
/// transpose, which callers often hold already), by blocks of rows: the blocks above the
/// diagonal blocks are left as they were. [`mirror_lower`] completes the symmetric matrix once
/// every term has been added.
pub fn add_gram_lower(gram: &mut DMatrix<f64>, phi: &DMatrix<f64>, phi_t: &DMatrix<f64>) {
    let (f, k) = phi.shape();
    assert_eq!(gram.shape(), (f, f), "add_gram_lower: sizes differ");
    assert_eq!(
        phi_t.shape(),
        (k, f),
        "add_gram_lower: phi_t is not phi's transpose"
    );
    let mut i = 0;
    while i < f {
        let ib = GRAM_BLOCK.min(f - i);
        gram.view_mut((i, 0), (ib, i + ib)).gemm(
            1.0,
            &phi.view((i, 0), (ib, k)),
            &phi_t.view((0, 0), (k, i + ib)),
            1.0,
        );
        i += ib;
    }
}

/// Copies the strictly lower triangle of the square `m` onto its upper triangle.
pub fn mirror_lower(m: &mut DMatrix<f64>) {
    let n = m.nrows();
    for j in 1..n {
        for r in 0..j {
            m[(r, j)] = m[(j, r)];
        }
    }
}

/// Columns per block of [`mul_lower_transposed`].
const TRIANGLE_BLOCK: usize = 128;

/// `x · lᵀ` for a lower triangular `l` (its entries above the diagonal are taken as zero):
/// column `i` of the product needs the first `i + 1` columns of `x` only, so it is formed by
/// blocks of columns, each one matrix product over the columns it needs, about half the
/// arithmetic of a full product.
pub fn mul_lower_transposed(x: &DMatrix<f64>, l: &DMatrix<f64>) -> DMatrix<f64> {
    let (rows, b) = x.shape();
    assert_eq!(l.shape(), (b, b), "mul_lower_transposed: sizes differ");
    let lt = l.transpose();
    let mut out = DMatrix::zeros(rows, b);
    let mut i = 0;
    while i < b {
        let ib = TRIANGLE_BLOCK.min(b - i);
        let k = i + ib;
        let mut block = lt.view((0, i), (k, ib)).clone_owned();
        // The part of the diagonal block above the diagonal of `l` (below it in `lᵀ`'s view).
        for c in 0..ib {
            for r in i + c + 1..k {
                block[(r, c)] = 0.0;
            }
        }
        out.view_mut((0, i), (rows, ib))
            .gemm(1.0, &x.view((0, 0), (rows, k)), &block, 0.0);
        i = k;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use vibrissa_core::rng::Rng;

    /// A random symmetric positive definite matrix of size `n`, `B·Bᵀ + n·I`.
    fn spd(n: usize, seed: u64) -> DMatrix<f64> {
        let mut rng = Rng::new(seed);
        let b = DMatrix::from_fn(n, n, |_, _| rng.normal());
        &b * b.transpose() + DMatrix::identity(n, n) * n as f64
    }

    #[test]
    fn blocked_factor_reproduces_the_matrix_and_nalgebras_factor() {
        for (n, seed) in [(1, 1), (50, 2), (96, 3), (97, 4), (250, 5), (401, 6)] {
            let a = spd(n, seed);
            let ours = cholesky(a.clone()).expect("positive definite").unpack();
            let theirs = a.clone().cholesky().expect("positive definite").unpack();
            let scale = a.amax();
            assert!(
                (&ours * ours.transpose() - &a).amax() < 1e-12 * scale,
                "n = {n}: L·Lᵀ differs from the matrix"
            );
            assert!(
                (&ours - &theirs).amax() < 1e-10 * theirs.amax(),
                "n = {n}: the factor differs from nalgebra's"
            );
            // Only the lower triangle is read: garbage above it changes nothing.
            let mut dirty = a.clone();
            for j in 1..n {
                for i in 0..j {
                    dirty[(i, j)] = f64::NAN;
                }
            }
            let again = cholesky(dirty).expect("positive definite").unpack();
            assert_eq!(again, ours, "n = {n}: the upper triangle was read");
            // Solving agrees with the matrix.
            let x = DMatrix::from_fn(n, 2, |i, j| (i + 3 * j) as f64);
            let b = &a * &x;
            let solved = cholesky(a).expect("positive definite").solve(&b);
            assert!((solved - x).amax() < 1e-8 * n as f64, "n = {n}: solve");
        }
    }

    #[test]
    fn gram_by_lower_blocks_equals_the_full_product() {
        let mut rng = Rng::new(9);
        for (f, k) in [(5, 3), (128, 10), (300, 64)] {
            let mut full = DMatrix::<f64>::zeros(f, f);
            let mut ours = DMatrix::<f64>::zeros(f, f);
            for _ in 0..3 {
                let phi = DMatrix::from_fn(f, k, |_, _| rng.normal());
                full.gemm(1.0, &phi, &phi.transpose(), 1.0);
                add_gram_lower(&mut ours, &phi, &phi.transpose());
            }
            mirror_lower(&mut ours);
            assert!((&ours - &full).amax() < 1e-12 * full.amax(), "f = {f}");
            assert_eq!(ours, ours.transpose(), "f = {f}: not symmetric");
        }
    }

    #[test]
    fn product_with_a_triangle_equals_the_full_product() {
        let mut rng = Rng::new(10);
        for (rows, b) in [(3, 1), (7, 128), (20, 129), (9, 300)] {
            let x = DMatrix::from_fn(rows, b, |_, _| rng.normal());
            // Garbage above the diagonal must be ignored.
            let l = DMatrix::from_fn(b, b, |i, j| if j <= i { rng.normal() } else { f64::NAN });
            let clean = DMatrix::from_fn(b, b, |i, j| if j <= i { l[(i, j)] } else { 0.0 });
            let full = &x * clean.transpose();
            let ours = mul_lower_transposed(&x, &l);
            assert!(
                (&ours - &full).amax() < 1e-12 * full.amax().max(1.0),
                "{rows} × {b}"
            );
        }
    }

    #[test]
    fn a_matrix_that_is_not_positive_definite_is_refused() {
        // Indefinite in its last block only.
        let mut a = spd(300, 7);
        a[(299, 299)] = -1.0;
        assert!(cholesky(a).is_none());
        // Indefinite in its first block.
        let mut a = spd(300, 8);
        a[(0, 0)] = -1.0;
        assert!(cholesky(a).is_none());
    }
}
