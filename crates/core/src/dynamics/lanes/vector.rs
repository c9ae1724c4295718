//! [`LANES`] `f64`s handled as one value: the unit of the lane-batched step.
//!
//! Every operation acts element by element with the same IEEE operation the single-state step
//! uses (`a·b + c` fused exactly where [`planar::fma`](crate::planar::fma) is), so a lane computes
//! the same bits as the single-state step on the same state. Plain arrays let the compiler use the
//! target's vector registers and, as importantly, interleave independent dependency chains where
//! one state's recursion (the articulated-body pass, a division per joint) would wait on each
//! result.

use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub};

/// How many states a lane group steps together. Measured with `vibrissa bench` (free batch,
/// N = 20, one thread, 2-core x86-64 development machine): 4 lanes 2.7 M state-steps/s, 8 lanes
/// 4.0 M, 16 lanes 5.2 M, 32 lanes 2.9 M, against 1.2 M one state at a time; compiling the lanes
/// for AVX2 as well as the baseline's SSE2 changed nothing measurable.
pub const LANES: usize = 16;

/// One value per lane.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[repr(C, align(64))]
pub(crate) struct Wide(pub(crate) [f64; LANES]);

impl Wide {
    /// The same value in every lane.
    #[inline(always)]
    pub(crate) fn splat(x: f64) -> Wide {
        Wide([x; LANES])
    }

    #[inline(always)]
    fn zip(self, o: Wide, f: impl Fn(f64, f64) -> f64) -> Wide {
        let (a, b) = (self.0, o.0);
        Wide(std::array::from_fn(|l| f(a[l], b[l])))
    }

    /// `a·b + c` per lane, fused exactly where the single-state step fuses it.
    #[inline(always)]
    pub(crate) fn fma(a: Wide, b: Wide, c: Wide) -> Wide {
        let (a, b, c) = (a.0, b.0, c.0);
        Wide(std::array::from_fn(|l| {
            crate::planar::fma(a[l], b[l], c[l])
        }))
    }

    /// Lane-wise maximum (as `f64::max`).
    #[inline(always)]
    pub(crate) fn max(self, o: Wide) -> Wide {
        self.zip(o, f64::max)
    }

    /// Lane-wise minimum (as `f64::min`).
    #[inline(always)]
    pub(crate) fn min(self, o: Wide) -> Wide {
        self.zip(o, f64::min)
    }

    /// Lane-wise square root.
    #[inline(always)]
    pub(crate) fn sqrt(self) -> Wide {
        Wide(self.0.map(f64::sqrt))
    }

    /// Lane-wise absolute value.
    #[inline(always)]
    pub(crate) fn abs(self) -> Wide {
        Wide(self.0.map(f64::abs))
    }

    /// Lane `l`'s value where `take[l]`, else `other`'s.
    #[inline(always)]
    pub(crate) fn select(take: [bool; LANES], this: Wide, other: Wide) -> Wide {
        Wide(std::array::from_fn(|l| {
            if take[l] {
                this.0[l]
            } else {
                other.0[l]
            }
        }))
    }
}

impl Add for Wide {
    type Output = Wide;
    #[inline(always)]
    fn add(self, o: Wide) -> Wide {
        self.zip(o, |a, b| a + b)
    }
}

impl AddAssign for Wide {
    #[inline(always)]
    fn add_assign(&mut self, o: Wide) {
        *self = *self + o;
    }
}

impl Sub for Wide {
    type Output = Wide;
    #[inline(always)]
    fn sub(self, o: Wide) -> Wide {
        self.zip(o, |a, b| a - b)
    }
}

impl Mul for Wide {
    type Output = Wide;
    #[inline(always)]
    fn mul(self, o: Wide) -> Wide {
        self.zip(o, |a, b| a * b)
    }
}

impl Div for Wide {
    type Output = Wide;
    #[inline(always)]
    fn div(self, o: Wide) -> Wide {
        self.zip(o, |a, b| a / b)
    }
}

impl Neg for Wide {
    type Output = Wide;
    #[inline(always)]
    fn neg(self) -> Wide {
        Wide(self.0.map(|a| -a))
    }
}

/// `(sin x, cos x)` per lane, bit for bit as [`planar::sin_cos`](crate::planar::sin_cos): its
/// Taylor polynomials on all four lanes at once when every lane is within their range, lane by
/// lane otherwise.
#[inline(always)]
pub(crate) fn sin_cos(x: Wide) -> (Wide, Wide) {
    if x.0.iter().all(|v| v.abs() <= 0.25) {
        let x2 = x * x;
        let s = crate::planar::SIN_TAYLOR
            .iter()
            .rev()
            .fold(Wide::splat(0.0), |acc, &k| {
                Wide::fma(acc, x2, Wide::splat(k))
            });
        let c = crate::planar::COS_TAYLOR
            .iter()
            .rev()
            .fold(Wide::splat(0.0), |acc, &k| {
                Wide::fma(acc, x2, Wide::splat(k))
            });
        (x * s, c)
    } else {
        let mut s = Wide::default();
        let mut c = Wide::default();
        for l in 0..LANES {
            (s.0[l], c.0[l]) = crate::planar::sin_cos(x.0[l]);
        }
        (s, c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A lane vector from a pattern of four, repeated.
    fn wide(p: [f64; 4]) -> Wide {
        Wide(std::array::from_fn(|l| {
            p[l % 4] * (1.0 + 0.01 * (l / 4) as f64)
        }))
    }

    #[test]
    fn lanes_compute_the_bits_of_the_scalar_helpers() {
        // Some lanes beyond the Taylor polynomials' range, then all within it.
        for xs in [wide([0.1, -0.24, 0.3, -1.2]), wide([0.1, -0.24, 0.2, 1e-3])] {
            let (s, c) = sin_cos(xs);
            for l in 0..LANES {
                let (ws, wc) = crate::planar::sin_cos(xs.0[l]);
                assert_eq!(
                    (s.0[l].to_bits(), c.0[l].to_bits()),
                    (ws.to_bits(), wc.to_bits())
                );
            }
        }
        let (a, b, d) = (
            wide([1.5, -2.0, 3.0, 0.1]),
            Wide::splat(0.3),
            Wide::splat(1e-9),
        );
        let f = Wide::fma(a, b, d);
        for l in 0..LANES {
            assert_eq!(f.0[l], crate::planar::fma(a.0[l], b.0[l], d.0[l]));
        }
        let take = std::array::from_fn(|l| l % 2 == 0);
        let m = Wide::select(take, a, b);
        for l in 0..LANES {
            assert_eq!(m.0[l], if l % 2 == 0 { a.0[l] } else { 0.3 });
        }
    }
}
