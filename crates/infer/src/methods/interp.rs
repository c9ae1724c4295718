//! Least-squares fit of a piecewise (bi)linear interpolation between runs on a rectangular grid
//! of parameters: the template grid (`template-interp`) or a dense simulated grid (`emulator`).

use crate::error::{Error, Result};
use crate::experiment::{Sample, CHANNELS};
use crate::family::Family;
use crate::features::{channel_scales, coverage_factor, dist2, flatten};
use crate::method::{Budget, Estimate, Method, Training};

/// The series model `m(d, v)` is the (bi)linear interpolation of the normalised series of the
/// grid's runs; the estimate minimises `Σ (m(d, v) − o)²` over all channels, each divided by its
/// standard deviation over the grid. Its std is the Laplace approximation
/// `σ̂²·(JᵀJ)⁻¹` with `σ̂²` the residual variance, scaled per unknown so that 90% intervals
/// cover 90% of held-out runs.
#[derive(Debug, Clone)]
pub struct Interp {
    /// Which runs it learns from.
    budget: Budget,
    /// Channel scales, `[CHANNELS]`.
    scales: Vec<f64>,
    /// Grid distances, m, increasing.
    d_nodes: Vec<f64>,
    /// Grid speeds, m/s, increasing (one for `e1`).
    v_nodes: Vec<f64>,
    /// Normalised series at the nodes: `[v_nodes][d_nodes][CHANNELS·SAMPLES]`.
    nodes: Vec<Vec<Vec<f64>>>,
    /// Unknowns: 1 (`e1`) or 2 (`e2`).
    unknowns: usize,
    /// Std factors per unknown from the calibration.
    factors: Vec<f64>,
}

/// Squared-error minimum of one grid cell.
#[derive(Debug, Clone, Copy)]
struct CellFit {
    /// Residual sum of squares.
    sse: f64,
    /// Parameters `[d, v]`.
    p: [f64; 2],
    /// `JᵀJ` in physical units, `[[dd, dv], [dv, vv]]`.
    jtj: [[f64; 2]; 2],
}

impl Interp {
    /// `template-interp`: fitted on the templates.
    pub fn paper() -> Interp {
        Interp::with_budget(Budget::Paper)
    }

    /// `emulator`: fitted on a dense simulated grid ([`Interp::design`]).
    pub fn free() -> Interp {
        Interp::with_budget(Budget::Free)
    }

    fn with_budget(budget: Budget) -> Interp {
        Interp {
            budget,
            scales: Vec::new(),
            d_nodes: Vec::new(),
            v_nodes: Vec::new(),
            nodes: Vec::new(),
            unknowns: 0,
            factors: Vec::new(),
        }
    }

    /// The emulator's grid for `family`, every combination of per-unknown nodes (the first
    /// unknown fastest): each range's ends and the midpoints between the family's grid values,
    /// each gap first cut into equal parts no wider than a twelfth of the range, so that no node
    /// is an evaluated run. For `e2`: d = 15, 15.5, 16.5, …, 29.5, 30 mm and v = 0.3, 0.35,
    /// 0.45, …, 1.45, 1.5 m/s.
    pub fn design(family: &Family) -> Vec<Vec<f64>> {
        let axes: Vec<Vec<f64>> = family
            .ranges()
            .iter()
            .zip(family.grid_values())
            .map(|(&[lo, hi], grid)| {
                let mut g = grid.clone();
                g.sort_by(f64::total_cmp);
                g.dedup();
                let widest = (hi - lo) / 12.0;
                let mut nodes = vec![lo];
                for w in g.windows(2) {
                    let parts = ((w[1] - w[0]) / widest - 1e-9).ceil().max(1.0) as usize;
                    let step = (w[1] - w[0]) / parts as f64;
                    nodes.extend((0..parts).map(|k| w[0] + (k as f64 + 0.5) * step));
                }
                nodes.push(hi);
                nodes
            })
            .collect();
        let mut out = vec![Vec::new()];
        for axis in &axes {
            out = axis
                .iter()
                .flat_map(|x| {
                    out.iter().map(move |p| {
                        let mut q: Vec<f64> = p.clone();
                        q.push(*x);
                        q
                    })
                })
                .collect();
        }
        out
    }

    /// Builds the grid from `samples` (which must fill a rectangle of parameters).
    fn build(&mut self, samples: &[Sample], unknowns: usize) -> Result<()> {
        let name = self.name();
        let fail = |detail: String| Error::Fit {
            method: name.into(),
            detail,
        };
        let (ds, vs) = grid_axes(samples, unknowns, 0.0, name)?;
        let channels: Vec<usize> = (0..CHANNELS.len()).collect();
        self.scales = channel_scales(samples, &channels);
        let mut nodes = vec![vec![Vec::new(); ds.len()]; vs.len()];
        for s in samples {
            let i = ds.iter().position(|d| (d - s.params[0]).abs() < 1e-9);
            let j = if unknowns == 2 {
                vs.iter().position(|v| (v - s.params[1]).abs() < 1e-9)
            } else {
                Some(0)
            };
            let (Some(i), Some(j)) = (i, j) else {
                return Err(fail("a run off the grid".into()));
            };
            nodes[j][i] = flatten(&s.series, &channels, &self.scales)?;
        }
        if nodes.iter().flatten().any(|n| n.is_empty()) {
            return Err(fail("a grid node without a run".into()));
        }
        self.d_nodes = ds;
        self.v_nodes = vs;
        self.nodes = nodes;
        self.unknowns = unknowns;
        self.factors = vec![1.0; unknowns];
        Ok(())
    }

    /// Best fit to the normalised observation `x`, without calibration: `(params, std)`.
    fn fit_raw(&self, x: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let (nd, nv) = (self.d_nodes.len(), self.v_nodes.len());
        // The nearest node picks the cells to search: those around it.
        let mut best_node = (f64::INFINITY, 0, 0);
        for j in 0..nv {
            for i in 0..nd {
                let e = dist2(&self.nodes[j][i], x);
                if e < best_node.0 {
                    best_node = (e, i, j);
                }
            }
        }
        let (_, bi, bj) = best_node;
        let cells_d: Vec<usize> = (bi.saturating_sub(1)..=bi.min(nd - 2)).collect();
        let cells_v: Vec<usize> = if nv == 1 {
            vec![0]
        } else {
            (bj.saturating_sub(1)..=bj.min(nv - 2)).collect()
        };
        let mut best: Option<CellFit> = None;
        for &j in &cells_v {
            for &i in &cells_d {
                let f = self.fit_cell(x, i, j);
                if best.is_none_or(|b| f.sse < b.sse) {
                    best = Some(f);
                }
            }
        }
        let f = best.expect("at least one cell");
        // Laplace: cov = σ̂² (JᵀJ)⁻¹ with σ̂² the residual variance per value.
        let dof = (x.len() as f64 - self.unknowns as f64).max(1.0);
        let s2 = f.sse / dof;
        let std = if self.unknowns == 1 {
            vec![(s2 / f.jtj[0][0].max(1e-300)).sqrt()]
        } else {
            let [[a, b], [_, c]] = f.jtj;
            let det = (a * c - b * b).max(1e-300);
            vec![(s2 * c / det).sqrt(), (s2 * a / det).sqrt()]
        };
        (f.p[..self.unknowns].to_vec(), std)
    }

    // Index loops over the 4×4 Gram matrix read more plainly than iterator chains.
    #[allow(clippy::needless_range_loop)]
    /// Least squares over cell `(i, j)` (d between nodes i and i+1, v between j and j+1).
    fn fit_cell(&self, x: &[f64], i: usize, j: usize) -> CellFit {
        let dd = self.d_nodes[i + 1] - self.d_nodes[i];
        if self.v_nodes.len() == 1 {
            // r(u) = a + u·b: a quadratic in u.
            let (m0, m1) = (&self.nodes[0][i], &self.nodes[0][i + 1]);
            let (mut gab, mut gbb, mut gaa) = (0.0, 0.0, 0.0);
            for k in 0..x.len() {
                let a = m0[k] - x[k];
                let b = m1[k] - m0[k];
                gaa += a * a;
                gab += a * b;
                gbb += b * b;
            }
            let u = if gbb > 0.0 {
                (-gab / gbb).clamp(0.0, 1.0)
            } else {
                0.0
            };
            return CellFit {
                sse: (gaa + 2.0 * u * gab + u * u * gbb).max(0.0),
                p: [self.d_nodes[i] + u * dd, self.v_nodes[0]],
                jtj: [[gbb / (dd * dd), 0.0], [0.0, 1.0]],
            };
        }
        let dv = self.v_nodes[j + 1] - self.v_nodes[j];
        let (m00, m10) = (&self.nodes[j][i], &self.nodes[j][i + 1]);
        let (m01, m11) = (&self.nodes[j + 1][i], &self.nodes[j + 1][i + 1]);
        // r(u, w) = a + u·b + w·c + u·w·e; G is the Gram matrix of (a, b, c, e).
        let mut g = [[0.0; 4]; 4];
        for k in 0..x.len() {
            let v = [
                m00[k] - x[k],
                m10[k] - m00[k],
                m01[k] - m00[k],
                m11[k] - m10[k] - m01[k] + m00[k],
            ];
            for p in 0..4 {
                for q in p..4 {
                    g[p][q] += v[p] * v[q];
                }
            }
        }
        for p in 0..4 {
            for q in 0..p {
                g[p][q] = g[q][p];
            }
        }
        let sse = |u: f64, w: f64| {
            let phi = [1.0, u, w, u * w];
            let mut s = 0.0;
            for p in 0..4 {
                for q in 0..4 {
                    s += phi[p] * g[p][q] * phi[q];
                }
            }
            s.max(0.0)
        };
        // Start from the best of a coarse lattice, then minimise along u and w in turn (each
        // is a clamped quadratic).
        let (mut u, mut w, mut e) = (0.0, 0.0, f64::INFINITY);
        for a in 0..=6 {
            for b in 0..=6 {
                let (uu, ww) = (a as f64 / 6.0, b as f64 / 6.0);
                let s = sse(uu, ww);
                if s < e {
                    (u, w, e) = (uu, ww, s);
                }
            }
        }
        for _ in 0..50 {
            // Fixed w: r = P + u·Q with P = a + w·c, Q = b + w·e.
            let pq = g[0][1] + w * (g[0][3] + g[2][1]) + w * w * g[2][3];
            let qq = g[1][1] + 2.0 * w * g[1][3] + w * w * g[3][3];
            if qq > 0.0 {
                u = (-pq / qq).clamp(0.0, 1.0);
            }
            // Fixed u: r = P + w·Q with P = a + u·b, Q = c + u·e.
            let pq = g[0][2] + u * (g[0][3] + g[1][2]) + u * u * g[1][3];
            let qq = g[2][2] + 2.0 * u * g[2][3] + u * u * g[3][3];
            if qq > 0.0 {
                w = (-pq / qq).clamp(0.0, 1.0);
            }
        }
        // Jacobian columns: ∂r/∂d = (b + w·e)/Δd, ∂r/∂v = (c + u·e)/Δv.
        let jd = g[1][1] + 2.0 * w * g[1][3] + w * w * g[3][3];
        let jv = g[2][2] + 2.0 * u * g[2][3] + u * u * g[3][3];
        let jdv = g[1][2] + u * g[1][3] + w * g[3][2] + u * w * g[3][3];
        CellFit {
            sse: sse(u, w),
            p: [self.d_nodes[i] + u * dd, self.v_nodes[j] + w * dv],
            jtj: [
                [jd / (dd * dd), jdv / (dd * dv)],
                [jdv / (dd * dv), jv / (dv * dv)],
            ],
        }
    }

    /// Calibration pairs `(error, std)` per unknown for `samples`.
    fn pairs(&self, samples: &[Sample]) -> Result<Vec<Vec<(f64, f64)>>> {
        let channels: Vec<usize> = (0..CHANNELS.len()).collect();
        super::residual_pairs(samples, self.unknowns, |s| {
            Ok(self.fit_raw(&flatten(&s.series, &channels, &self.scales)?))
        })
    }
}

impl Method for Interp {
    fn name(&self) -> &'static str {
        match self.budget {
            Budget::Paper => "template-interp",
            Budget::Free => "emulator",
        }
    }

    fn budget(&self) -> Budget {
        self.budget
    }

    fn channels(&self) -> Vec<usize> {
        (0..CHANNELS.len()).collect()
    }

    fn fit(&mut self, training: &Training) -> Result<()> {
        let unknowns = training.family.unknowns().len();
        if unknowns > 2 {
            return Err(Error::Fit {
                method: self.name().into(),
                detail: format!("interpolates over one or two unknowns, not {unknowns}"),
            });
        }
        let pairs = match self.budget {
            // Held-out check under the paper's budget: the corner templates alone predict the
            // other templates (a coarser grid than the final one, so the factor is cautious).
            Budget::Paper => {
                let ranges = training.family.ranges();
                let corner = |s: &Sample| {
                    s.params
                        .iter()
                        .zip(&ranges)
                        .all(|(p, r)| (p - r[0]).abs() < 1e-9 || (p - r[1]).abs() < 1e-9)
                };
                let (corners, rest): (Vec<Sample>, Vec<Sample>) =
                    training.samples.iter().cloned().partition(|s| corner(s));
                let mut coarse = Interp::paper();
                coarse.build(&corners, unknowns)?;
                coarse.pairs(&rest)?
            }
            Budget::Free => Vec::new(),
        };
        self.build(&training.samples, unknowns)?;
        let pairs = match self.budget {
            Budget::Paper => pairs,
            Budget::Free => self.pairs(&training.calibration)?,
        };
        self.factors = pairs.iter().map(|p| coverage_factor(p)).collect();
        Ok(())
    }

    fn predict(&self, obs: &[Vec<f64>]) -> Result<Vec<Estimate>> {
        if self.nodes.is_empty() {
            return Err(Error::Fit {
                method: self.name().into(),
                detail: "not fitted".into(),
            });
        }
        let channels: Vec<usize> = (0..CHANNELS.len()).collect();
        let x = flatten(obs, &channels, &self.scales)?;
        let (p, sd) = self.fit_raw(&x);
        Ok((0..self.unknowns)
            .map(|u| Estimate::normal(p[u], sd[u] * self.factors[u]))
            .collect())
    }

    fn settings(&self) -> Vec<(String, f64)> {
        super::interp::grid_settings(&self.d_nodes, &self.v_nodes, &self.factors)
    }
}

/// The distinct distances and speeds of runs that fill a rectangle of parameters (`speed` stands
/// for the single speed of a one-unknown experiment), ascending; an error naming `method` if they
/// do not fill it.
pub(crate) fn grid_axes(
    samples: &[Sample],
    unknowns: usize,
    speed: f64,
    method: &str,
) -> Result<(Vec<f64>, Vec<f64>)> {
    let mut ds: Vec<f64> = samples.iter().map(|s| s.params[0]).collect();
    let mut vs: Vec<f64> = if unknowns == 2 {
        samples.iter().map(|s| s.params[1]).collect()
    } else {
        vec![speed]
    };
    for x in [&mut ds, &mut vs] {
        x.sort_by(|a, b| a.total_cmp(b));
        x.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    }
    if ds.len() < 2 || ds.len() * vs.len() != samples.len() {
        return Err(Error::Fit {
            method: method.into(),
            detail: format!(
                "needs runs that fill a grid ({} runs for {} × {} values)",
                samples.len(),
                ds.len(),
                vs.len()
            ),
        });
    }
    Ok((ds, vs))
}

/// Settings reported by the grid-interpolating methods: grid size and interval scale factors.
pub(crate) fn grid_settings(
    d_nodes: &[f64],
    v_nodes: &[f64],
    factors: &[f64],
) -> Vec<(String, f64)> {
    let mut s = vec![("grid_runs".into(), (d_nodes.len() * v_nodes.len()) as f64)];
    for (u, f) in factors.iter().enumerate() {
        s.push((format!("std_factor_{u}"), *f));
    }
    s
}
