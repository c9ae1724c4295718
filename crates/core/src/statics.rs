//! Static equilibrium of the chain under dead point loads.
//!
//! Solves `K (q - q_rest) = τ(q)` exactly (Newton's method with the analytic Jacobian and load
//! continuation), where `τ_j = Σ (p_load - p_j) × F` is the moment of the loads beyond joint `j`.
//! This is the chain's own static answer, independent of time stepping, and the reference that
//! the dynamics must settle to.

use crate::chain::Model;
pub use crate::dynamics::check_loads;
use crate::dynamics::PointLoad;
use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};

/// The chain at rest under loads.
#[derive(Debug, Clone, PartialEq)]
pub struct Equilibrium {
    /// Joint angles, rad: `[N]`.
    pub q: Vec<f64>,
    /// Node positions, m: `[N+1][2]` (node 0 at the base, node N the tip).
    pub nodes: Vec<[f64; 2]>,
    /// Wrench the base applies to the whisker, world frame: (moment N·m, fx N, fy N).
    pub base_wrench: [f64; 3],
    /// Newton iterations used in all.
    pub iterations: usize,
}

/// Node positions for joint angles `q` with the base along `base_angle`.
pub fn nodes(model: &Model, q: &[f64], base_angle: f64) -> Vec<[f64; 2]> {
    let mut out = vec![[0.0; 2]; model.n + 1];
    let mut phi = base_angle;
    for i in 0..model.n {
        phi += q[i];
        let (s, c) = phi.sin_cos();
        out[i + 1] = [out[i][0] + model.len[i] * c, out[i][1] + model.len[i] * s];
    }
    out
}

fn load_point(model: &Model, nodes: &[[f64; 2]], load: &PointLoad) -> [f64; 2] {
    let (p, q) = (nodes[load.segment], nodes[load.segment + 1]);
    let f = load.along / model.len[load.segment];
    [p[0] + f * (q[0] - p[0]), p[1] + f * (q[1] - p[1])]
}

/// Solves for the equilibrium of `model` (base along +x) under the dead `loads`.
pub fn solve(model: &Model, loads: &[PointLoad]) -> Result<Equilibrium> {
    check_loads(model, loads)?;
    let n = model.n;
    let mut q = model.rest.clone();
    let mut iterations = 0;
    // Load continuation: the full load in as few increments as converge.
    let mut fraction = 0.0;
    let mut increment = 1.0f64;
    while fraction < 1.0 {
        let target = (fraction + increment).min(1.0);
        match newton(model, loads, target, &q) {
            Ok((qn, it)) => {
                q = qn;
                iterations += it;
                fraction = target;
                increment *= 2.0;
            }
            Err(e) => {
                increment *= 0.25;
                if increment < 1e-4 {
                    return Err(e);
                }
            }
        }
    }
    let nodes = nodes(model, &q, 0.0);
    let mut w = [0.0; 3];
    for l in loads {
        let p = load_point(model, &nodes, l);
        w[0] -= p[0] * l.force[1] - p[1] * l.force[0];
        w[1] -= l.force[0];
        w[2] -= l.force[1];
    }
    debug_assert_eq!(q.len(), n);
    Ok(Equilibrium {
        q,
        nodes,
        base_wrench: w,
        iterations,
    })
}

/// Newton iterations at load scale `scale` from `q0`.
fn newton(model: &Model, loads: &[PointLoad], scale: f64, q0: &[f64]) -> Result<(Vec<f64>, usize)> {
    let n = model.n;
    let mut q = q0.to_vec();
    let kmax = model.stiffness.iter().cloned().fold(0.0, f64::max);
    for it in 1..=50 {
        let nodes = nodes(model, &q, 0.0);
        // Residual K(q - rest) - τ and Jacobian diag(K) + Σ (p_L - p_max(j,k))·F.
        let mut r = DVector::from_iterator(
            n,
            (0..n).map(|j| model.stiffness[j] * (q[j] - model.rest[j])),
        );
        let mut jac = DMatrix::from_diagonal(&DVector::from_column_slice(&model.stiffness));
        for l in loads {
            let f = [scale * l.force[0], scale * l.force[1]];
            let p = load_point(model, &nodes, l);
            for j in 0..=l.segment {
                let rj = [p[0] - nodes[j][0], p[1] - nodes[j][1]];
                r[j] -= rj[0] * f[1] - rj[1] * f[0];
                for k in 0..=l.segment {
                    let m = nodes[j.max(k)];
                    jac[(j, k)] += (p[0] - m[0]) * f[0] + (p[1] - m[1]) * f[1];
                }
            }
        }
        let norm = r.amax();
        let dq = jac.lu().solve(&r).ok_or_else(|| Error::NoConvergence {
            what: "static equilibrium".into(),
            detail: "singular stiffness (a buckling load?)".into(),
        })?;
        for j in 0..n {
            q[j] -= dq[j];
        }
        if !q.iter().all(|x| x.is_finite()) || dq.amax() > 1.0 {
            break;
        }
        if norm <= 1e-14 * kmax || dq.amax() < 1e-15 {
            return Ok((q, it));
        }
    }
    Err(Error::NoConvergence {
        what: "static equilibrium".into(),
        detail: format!("Newton did not converge at load fraction {scale}"),
    })
}
