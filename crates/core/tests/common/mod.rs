//! Helpers shared by the integration tests.

use vibrissa_core::dynamics::Integrator;
use vibrissa_core::scenes::e2_box;
use vibrissa_core::sim::{self, Scenario};

/// The `e2` run at (d, v) with the integrator `integrator`.
pub fn e2(d: f64, v: f64, integrator: Integrator) -> sim::Output {
    let scenario = Scenario {
        objects: vec![e2_box(d, v)],
        integrator,
        ..Scenario::default()
    };
    sim::run(&scenario, &mut |_| {}).unwrap()
}
