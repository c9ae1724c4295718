//! Gauss–Legendre quadrature: the rule's nodes and weights, and integration with it (the
//! chain's lumped stiffnesses and masses, and the beam's compliances, integrate profiles with it).

/// Gauss–Legendre nodes and weights on [-1, 1], by Newton iteration on P_n.
pub(crate) fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        // Chebyshev-like first guess for root i, then Newton on the three-term recurrence.
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            let p = if n == 0 { 1.0 } else { p1 };
            let pm1 = if n == 1 { 1.0 } else { p0 };
            dp = n as f64 * (x * p - pm1) / (x * x - 1.0);
            let dx = p / dp;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        out.push((x, 2.0 / ((1.0 - x * x) * dp * dp)));
    }
    out
}

/// Integrates `f` over `[a, b]` with the given Gauss–Legendre rule.
pub(crate) fn integrate(rule: &[(f64, f64)], a: f64, b: f64, mut f: impl FnMut(f64) -> f64) -> f64 {
    let (mid, half) = (0.5 * (a + b), 0.5 * (b - a));
    rule.iter()
        .map(|&(x, w)| w * f(mid + half * x))
        .sum::<f64>()
        * half
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_n_point_rule_integrates_polynomials_up_to_degree_2n_minus_1_exactly() {
        for n in [1, 2, 5, 16] {
            let rule = gauss_legendre(n);
            assert_eq!(rule.len(), n);
            let total: f64 = rule.iter().map(|(_, w)| w).sum();
            assert!(
                (total - 2.0).abs() < 1e-13,
                "n = {n}: weights sum to {total}"
            );
            let k = (2 * n - 1) as i32;
            let got = integrate(&rule, 0.5, 2.0, |x| x.powi(k));
            let want = (2f64.powi(k + 1) - 0.5f64.powi(k + 1)) / (k + 1) as f64;
            assert!(
                (got - want).abs() < 1e-12 * want,
                "n = {n}: {got} vs {want}"
            );
        }
        // One degree more is not exact.
        let rule = gauss_legendre(2);
        let got = integrate(&rule, 0.0, 1.0, |x| x.powi(4));
        assert!((got - 0.2).abs() > 1e-3);
    }
}
