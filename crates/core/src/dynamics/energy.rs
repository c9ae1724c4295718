//! Energies and momentum of a state (diagnostics; not used by the step).

use super::state::State;
use super::workspace::Workspace;
use crate::chain::Model;
use crate::planar::{dot3, shift_force, sym_mul};

/// Kinetic energy of a state, J.
pub fn kinetic_energy(model: &Model, state: &State, ws: &mut Workspace) -> f64 {
    ws.evaluate(model, state);
    (0..model.n)
        .map(|i| {
            let v = ws.seg[i].vel;
            0.5 * dot3(v, sym_mul(&ws.inertia(model, i), v))
        })
        .sum()
}

/// Elastic energy stored in the joint springs, J.
pub fn potential_energy(model: &Model, state: &State) -> f64 {
    (0..model.n)
        .map(|i| 0.5 * model.stiffness[i] * (state.q()[i] - model.rest[i]).powi(2))
        .sum()
}

/// Spatial momentum of the whole chain about the origin: (angular N·m·s, px, py N·s).
pub fn momentum(model: &Model, state: &State, ws: &mut Workspace) -> [f64; 3] {
    ws.evaluate(model, state);
    let mut h = [0.0; 3];
    for i in 0..model.n {
        // Momentum about the joint, moved to the origin.
        let o = ws.node[i];
        let m = shift_force(sym_mul(&ws.inertia(model, i), ws.seg[i].vel), -o[0], -o[1]);
        for k in 0..3 {
            h[k] += m[k];
        }
    }
    h
}
